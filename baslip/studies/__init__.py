"""Studies: many fixed points or simulations from one problem file (thesis chapter 4).

A problem file with a ``study:`` section is run by :func:`baslip.studies.registry.run_study`
(``python -m baslip.solve FILE`` does this): sweeps and random samples of fixed points,
convergence regions, and per-stride re-optimised control.
"""
