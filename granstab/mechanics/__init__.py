"""The paper's mathematics: contact blocks of H = Hg1 + Hg2 + Hg3 + Hm (eq:Hm), the rigid basis and projection
metric (eq:Moore1), consistency of eigenvectors with the sliding branches (eq:flow, Appendix D), per-eigenvalue
accuracy, verdicts. Pure functions of arrays; a single cluster and a stack of clusters call the same kernels.
"""
