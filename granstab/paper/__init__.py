"""The paper's examples (Sec. 4): each example's study (data only) beside its report (figures, CSV, its section of
REPRODUCTION.md), and `granstab reproduce NAME --out DIR`.

- `two_particle`: the symmetric two-particle cluster (Sec. 4.1, Appendix C): closed forms of λ⁽⁵⁾ and λ⁽⁶⁾, the
  batched λ⁽⁶⁾ field over (ρ/r, f/(kr)), sample-point tables, checks against the core.
- `gear`: the gear-like mode of a regular square packing (Fig. 6) and its removal by rolling stiffness.
- `four_disk`: the four-disk rhombus (Sec. 4.2): 16-branch tables for sym(𝓗^i) and ℍ^i, tolerance and parameter
  sweeps, the continued-sliding path of Fig. 7c and its second-order work.
- `sliding_contact`: eigenvalues of the symmetric part of the sliding contact stiffness (Sec. 4.2, erratum 3,
  docs/errata.md).
The studies import no matplotlib; the `*_report` modules do, and only `reproduce` imports them.

NAME is one of two-particle, gear, four-disk, sliding-contact, all. Each runs its study (which returns
data only), writes CSV data (and an .npz with the full-precision arrays) and figures (PNG and SVG) into DIR,
and returns a summary with the claims of Sec. 4 it checks: the paper's statement or number, ours, and a verdict.
`all` also writes REPRODUCTION.md: at `root` when it is given (a repository root; its links point into DIR), else
into DIR; one copy either way. Each `NAME_report` module has `run`, `steps`, its figures and its REPRODUCTION.md section;
`examples` lists them in report order, `markdown` writes the file, `figures` holds the shared formats.
matplotlib is imported by the reports and `figures` only (object-oriented API: no pyplot, no global backend
switch); only the CLI's reproduce command imports them.
"""
from __future__ import annotations

import os
import time
from pathlib import Path


def reproduce(name: str, out_dir: Path, progress: bool = True, root: Path | None = None) -> dict:
    """Run one example (or `all`), writing data and figures into out_dir; returns {name: summary, ...}.

    Each summary has `claims` (id, section, claim, paper, ours, verdict, note), `files` written and `seconds`.
    progress: a tqdm bar on stderr, with one line of results per example as it finishes.
    root: with name == "all", write REPRODUCTION.md at this path (a directory; links into out_dir) instead of in out_dir.
    """
    from tqdm import tqdm

    from .examples import EXAMPLES, NAMES
    from .markdown import markdown
    if name != "all" and name not in NAMES:
        raise ValueError(f"unknown example {name!r}: choose from {', '.join(NAMES)}, all")
    names = NAMES if name == "all" else (name,)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    with tqdm(total=sum(EXAMPLES[n].steps() for n in names), disable=not progress, desc="reproduce", unit="step",
              leave=False) as bar:
        for n in names:
            bar.set_description(n)
            start = time.perf_counter()
            results[n] = EXAMPLES[n].run(out, lambda: bar.update(1), bar.write if progress else (lambda s: None))
            results[n]["seconds"] = time.perf_counter() - start
            if progress:
                verdicts = [c["verdict"] for c in results[n]["claims"]]
                bad = [c["id"] for c in results[n]["claims"] if c["verdict"].startswith("DIFFERS")]
                bar.write(f"{n}: {len(verdicts)} claims, {len(verdicts) - len(bad)} reproduced/extended"
                          + (f", DIFFERS: {', '.join(bad)}" if bad else "") + f" ({results[n]['seconds']:.1f} s)")
    if name == "all":                   # one REPRODUCTION.md: at `root` (links into out_dir), else in out_dir
        where = out if root is None else Path(root)
        prefix = "" if root is None else os.path.relpath(out.resolve(), where.resolve()).replace(os.sep, "/") + "/"
        (where / "REPRODUCTION.md").write_text(markdown(results, prefix=prefix), encoding="utf-8")
        results["markdown"] = [where / "REPRODUCTION.md"]
    if progress:
        claims = [c for n in names for c in results[n]["claims"]]
        bad = [c["id"] for c in claims if "DIFFERS" in c["verdict"]]
        print(f"{len(claims)} claims checked, {len(bad)} differ{': ' + ', '.join(bad) if bad else ''}; wrote "
              f"{len(list(out.iterdir()))} files to {out}"
              + (f" and {', '.join(str(p) for p in results['markdown'])}" if "markdown" in results else ""))
    return results
