"""Sparse linear algebra for the global step: compressed-row builders and permutations, fill-reducing orderings (METIS,
computed beside the set-up), the elimination tree and the Cholesky back ends.
"""
