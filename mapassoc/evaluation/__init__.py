"""Evaluation: GOSPA and other metrics, simulation, built-in scenarios and the oracle
smoother on the true associations.
"""
