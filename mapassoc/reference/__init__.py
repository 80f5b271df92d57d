"""The seeds' exact references: association vectors, the n-object posterior, single-object
hypothesis sequences.
"""
