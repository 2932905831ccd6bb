"""The solve: the solver's prepared set-up and its add-ons, where a solve starts, the iteration loops (plain, Anderson,
L-BFGS), single steps, the vertex partition and the result.
"""
