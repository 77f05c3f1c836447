"""Families of gaits: generic continuation, the fixed-point system it follows, bifurcation
curves, the local manifold dimension, stability-optimal descent, and stride-to-stride
controllers."""
