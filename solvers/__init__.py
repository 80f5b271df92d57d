"""Solver backends for the programs of :mod:`mapassoc.formulations`."""
