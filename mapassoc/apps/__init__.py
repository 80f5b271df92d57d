"""Applications: the command line, the benchmark, the demo and plots.
"""
