"""The paper's examples (Sec. 4) as studies that return data; figures and REPRODUCTION.md live in granstab.report.

- `two_particle`: the symmetric two-particle cluster (Sec. 4.1, Appendix C): closed forms of λ⁽⁵⁾ and λ⁽⁶⁾, the
  batched λ⁽⁶⁾ field over (ρ/r, f/(kr)), sample-point tables, checks against the core.
- `gear`: the gear-like mode of a regular square packing (Fig. 6) and its removal by rolling stiffness.
- `four_disk`: the four-disk rhombus (Sec. 4.2): 16-branch tables for sym(𝓗^i) and ℍ^i, tolerance and parameter
  sweeps, the continued-sliding path of Fig. 7c and its second-order work.
- `sliding_contact`: eigenvalues of the symmetric part of the sliding contact stiffness (Sec. 4.2, erratum 3,
  docs/errata.md).

Every study is a plain function of its parameters returning dicts/arrays; nothing here imports matplotlib.
"""
__all__ = ["four_disk", "gear", "sliding_contact", "two_particle"]  # import the submodule you need
