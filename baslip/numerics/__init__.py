"""Numerical methods that know no model: pseudo-arclength continuation with its special
points, and the Newton-Broyden corrector of manifolds. The gait layers above give them
their systems of equations."""
