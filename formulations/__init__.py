"""Solver-neutral programs built from track hypotheses, and their decoders."""
