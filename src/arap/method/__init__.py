"""The method's kernels (Sorkine & Alexa 2007): edge weights, cells and their system, painted stiffness, the local step
(covariances, best rotations), smooth rotations, rigid regions, point handles, energies and folds; compiled with
numba, whose cache and threads live here too.
"""
