"""Studies: many fixed points or simulations from one problem file (thesis chapter 4).

A problem file with a ``study:`` section is run by :func:`baslip.studies.registry.run_study`
(``python -m baslip.solve FILE`` does this): sweeps and random samples of fixed points,
convergence regions, and per-stride re-optimised control.

The modules here import the figures' modules (:mod:`baslip.viz`, and with them
matplotlib) inside the functions that draw, not at their tops. The worker processes of a
study import the module of their task function; so they never load matplotlib, which
took a quarter of a second of each worker's start (measured on the 2-core machine: a
worker's imports 0.41 s before, 0.16 s after).
"""
