"""Exact references of the theory, by full enumeration: the association vectors of W. Afzal,
"Track Association Problems in AD" (2022), and the n-object posterior and single-object
hypothesis sequences in clutter of L. Svensson et al., "Multi-Object Tracking for Automotive
Systems" (Chalmers University of Technology).  See the documentation's references page.
"""
