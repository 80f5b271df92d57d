"""The window estimator: hypotheses, the posterior over K, the per-cluster strategy and the
pipeline that wires domain, formulations and solvers.
"""
