"""The runner itself: named vector layouts, the dynamics (Lagrangian, phases, maps, guards,
energy), the hip law, and the vocabulary of problem quantities. Imports nothing else of
baslip but :mod:`baslip.errors`."""
