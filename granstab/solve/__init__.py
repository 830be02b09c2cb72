"""Eigen solvers for the branches: dense stacked LAPACK, low-rank updates of the elastic problem, sparse
shift-invert; the array namespace (numpy or CuPy), BLAS threads and the time budget.
"""
