"""The documentation: README.md fits in 20 kB, every relative link of README.md and docs/*.md points at a file that
exists, and docs/equations.md maps every equation label cited in granstab/, app/ and the docs to the number and
section the paper prints, re-derived here from its LaTeX source (../shared/paper beside the repository)."""
import re
from pathlib import Path

import pytest
from helpers import ROOT  # noqa: E402

PAPER = ROOT.parent / "shared" / "paper" / "kuhn-chang-stability.tex"
README_LIMIT = 20 * 1024

# Display environments that number their lines: one number per row (split at top-level \\) or one per environment.
ROWS = {"align", "gather", "eqnarray", "flalign", "alignat"}
WHOLE = {"equation", "multline"}
TOKEN = re.compile(r"\\\\|\\[{}%&$#_]|\\(?:begin|end)\{([A-Za-z*]+)\}|\\(section|subsection)(\*?)\s*\{|"
                   r"\\(label|tag|ref)\{([^{}]*(?:\{[^{}]*\}[^{}]*)*)\}|\\(nonumber|notag|appendix)(?![A-Za-z])|[{}]")


def _strip_comments(tex: str) -> str:
    return re.sub(r"(?<!\\)%[^\n]*", "", tex)


def _expand(tex: str) -> str:
    """The paper's two macros that open and close an environment (easymat's MAT): rows inside them are not lines
    of an align."""
    macros = dict(re.findall(r"\\newcommand\{\\(LB|RB)\}\{(.*)\}\s*$", tex, flags=re.M))
    for name, body in macros.items():
        tex = re.sub(rf"\\{name}(?![A-Za-z])", lambda _m, b=body: b, tex)
    return tex


def _braced(tex: str, start: int) -> tuple[str, int]:
    """The text up to the brace that closes the group opened just before `start`, and the index after it."""
    depth = 1
    i = start
    while depth:
        c = tex[i]
        if c == "\\":
            i += 2
            continue
        depth += {"{": 1, "}": -1}.get(c, 0)
        i += 1
    return tex[start:i - 1], i


def _letter(n: int) -> str:
    return chr(ord("A") + n - 1)


class _Numbering:
    """One pass over the paper's source, numbering as LaTeX's article class does: equations (1), (2), … once
    through the paper and its appendices; starred forms, \\nonumber and \\notag print none, \\tag{...} prints its
    own and takes no number; sections 1, 2, … and, after \\appendix, A, B, …"""

    def __init__(self, tex: str):
        self.tex = tex
        self.eq = self.sec = self.sub = 0
        self.appendix = False
        self.where = self.here = ""            # the current section's "Section 2.3: title" and its number
        self.found: dict[str, tuple[str, str]] = {}
        self.numbers: dict[str, str] = {}      # every label → what \\ref prints: equation or section number
        self.tagged: list[tuple[list, str]] = []
        self.env: str | None = None            # the outer numbered display, if inside one
        self.inner = self.braces = 0           # environments (split, MAT, cases, …) and braces nested in it
        self.starred = False
        self.row: dict = {}

    def new_row(self) -> dict:
        return {"labels": [], "off": self.starred, "tag": None, "text": ""}

    def close_row(self) -> None:
        r = self.row
        if r["tag"] is not None:
            self.tagged.append((r["labels"], r["tag"]))
        elif not r["off"]:
            self.eq += 1
            self.found.update({label: (str(self.eq), self.where) for label in r["labels"]})

    def heading(self, kind: str, starred: bool, title: str) -> None:
        title = re.sub(r"\s+", " ", title.replace("~", " ")).strip()
        if starred:
            self.where = title
        elif kind == "section":
            self.sec, self.sub = self.sec + 1, 0
            self.here = _letter(self.sec) if self.appendix else str(self.sec)
            self.where = f"{'Appendix' if self.appendix else 'Section'} {self.here}: {title}"
        else:
            self.sub += 1
            self.here = f"{_letter(self.sec) if self.appendix else self.sec}.{self.sub}"
            self.where = f"Section {self.here}: {title}"

    def environment(self, tok: str, name: str) -> None:
        base = name.rstrip("*")
        if tok.startswith("\\begin"):
            if self.env is None and base in ROWS | WHOLE:
                self.env, self.inner, self.braces, self.starred = base, 0, 0, name.endswith("*")
                self.row = self.new_row()
            elif self.env is not None:
                self.inner += 1
        elif self.env is not None and self.inner == 0 and base == self.env:
            r = self.row
            if self.env in WHOLE or r["labels"] or r["tag"] or r["text"].strip():
                self.close_row()               # amsmath ignores a \\ right before \end{align}
            self.env = None
        elif self.env is not None:
            self.inner -= 1

    def display(self, m: re.Match) -> None:
        """A token inside a numbered display."""
        tok = m.group(0)
        if tok == "\\\\":
            if self.env in ROWS and self.inner == 0 and self.braces == 0:
                self.close_row()
                self.row = self.new_row()
        elif tok in "{}":
            self.braces += 1 if tok == "{" else -1
        elif m.group(4) in ("label", "tag"):
            if m.group(4) == "label":
                self.row["labels"].append(m.group(5))
            else:
                self.row["tag"] = m.group(5)
        elif m.group(6) in ("nonumber", "notag"):
            self.row["off"] = True
        else:
            self.row["text"] += tok

    def run(self) -> dict[str, tuple[str, str]]:
        i = 0
        while (m := TOKEN.search(self.tex, i)) is not None:
            if self.env is not None:
                self.row["text"] += self.tex[i:m.start()]
            i = m.end()
            if m.group(2):                                          # \\section{…} / \\subsection{…}
                title, i = _braced(self.tex, i)
                self.heading(m.group(2), bool(m.group(3)), title)
            elif m.group(6) == "appendix":
                self.appendix, self.sec, self.sub = True, 0, 0
            elif m.group(1):
                self.environment(m.group(0), m.group(1))
            elif self.env is not None:
                self.display(m)
            elif m.group(4) == "label":                             # a section's label
                self.numbers[m.group(5)] = self.here
        for labels, tag in self.tagged:                             # \\tag{\\ref{eq:x}} prints x's number
            number = re.sub(r"\\ref\{([^}]*)\}", lambda r: self.found[r.group(1)][0], tag)
            self.found.update({label: (number, self.found.get(label, ("", ""))[1]) for label in labels})
        numbers = self.numbers | {k: v[0] for k, v in self.found.items()}
        return {k: (n, re.sub(r"\\ref\{([^}]*)\}", lambda r: numbers[r.group(1)], w))
                for k, (n, w) in self.found.items()}


def paper_equations(path: Path = PAPER) -> dict[str, tuple[str, str]]:
    """label → (printed number, "section number and title") for every label inside a numbered display of the
    paper (see `_Numbering`)."""
    tex = _expand(_strip_comments(path.read_text(encoding="utf-8")))
    assert "\\documentclass[11pt]{article}" in tex and "numberwithin" not in tex and "theequation" not in tex, \
        "the paper's equation numbering is no longer global: teach _Numbering the new scheme"
    return _Numbering(tex).run()


def cited_labels() -> set[str]:
    """Every eq: label named in the code of granstab/ and app/, in README.md and in docs/*.md."""
    files = [*(ROOT / "granstab").rglob("*.py"), *(ROOT / "app").rglob("*.py"), ROOT / "README.md",
             *(ROOT / "docs").glob("*.md")]
    return {label for f in files for label in re.findall(r"eq:[A-Za-z0-9_]+", f.read_text(encoding="utf-8"))}


def documented_equations() -> dict[str, tuple[str, str]]:
    """The rows of docs/equations.md's table: | `eq:label` | (number) | section |."""
    rows = re.findall(r"^\|\s*`(eq:[A-Za-z0-9_]+)`\s*\|\s*\(([^)]*)\)\s*\|\s*([^|]*?)\s*\|",
                      (ROOT / "docs" / "equations.md").read_text(encoding="utf-8"), flags=re.M)
    return {label: (number, section) for label, number, section in rows}


def test_paper_numbering_is_rederived_from_the_source():
    """Spot checks counted by hand in the source: unlabelled equations take numbers, an align numbers each row
    (but not a \\notag row), \\tag{\\ref{…}} reuses a number, the appendices continue the count, and titles have
    their references resolved."""
    eqs = paper_equations()
    assert eqs["eq:H"] == ("1", "Section 2: Stiffness of a granular region")
    assert eqs["eq:Deltav"][0] == "5"                   # after eq:piece (2) and two unlabelled equations
    assert [eqs[f"eq:{k}"][0] for k in ("dr", "df", "dm", "db", "dw")] == ["8", "9", "10", "11", "12"]  # one align
    assert eqs["eq:exampleH"][0] == "67" and eqs["eq:exampleH2"][0] == "68"    # its third row is \\notag
    assert eqs["eq:dfeval"] == ("72", "Appendix B: Derivations of Eqs. 13, 14, and 24")  # two \\tag'd equations before
    assert eqs["eq:exampleC"] == ("87", "Appendix C: Derivations of two-particle example, Section 4.1")
    assert eqs["eq:instab"] == ("65", "Section 3.2: Stability and softening")


def test_equation_map_lists_every_cited_label_with_the_printed_number():
    paper, docs = paper_equations(), documented_equations()
    cited = cited_labels()
    assert len(cited) > 30, "the code cites its equations by label; the scan found too few"
    missing_in_paper = sorted(cited - paper.keys())
    assert not missing_in_paper, f"labels cited in the code that the paper does not define: {missing_in_paper}"
    missing = sorted(cited - docs.keys())
    assert not missing, f"docs/equations.md lacks {missing}"
    wrong = {k: (docs[k], paper[k]) for k in docs if docs[k] != paper.get(k)}
    assert not wrong, f"docs/equations.md differs from the paper (docs, paper): {wrong}"


def test_readme_fits_in_20_kB():
    size = (ROOT / "README.md").stat().st_size
    assert size <= README_LIMIT, f"README.md is {size} bytes, more than {README_LIMIT}"


LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def anchors(path: Path) -> set[str]:
    """GitHub's anchors of a Markdown file's headings: lower case, punctuation dropped, spaces → hyphens, and
    -1, -2, … on repeats."""
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    seen: dict[str, int] = {}
    out = set()
    for title in re.findall(r"^#{1,6}\s+(.+?)\s*#*\s*$", text, flags=re.M):
        slug = re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")
        out.add(slug if slug not in seen else f"{slug}-{seen[slug]}")
        seen[slug] = seen.get(slug, 0) + 1
    return out


def test_anchors_follow_githubs_rule():
    assert anchors(ROOT / "docs" / "verification.md") >= {
        "verdicts-that-never-claim-more-than-the-numbers-prove",
        "which-results-are-properties-of-the-packing-and-which-depend-on-the-metric"}
    assert "binary-scenes-npz" in anchors(ROOT / "docs" / "formats.md")


@pytest.mark.parametrize("doc", ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))])
def test_relative_links_point_at_files(doc):
    """Every relative link (and its #anchor, for Markdown targets) of README.md and docs/*.md resolves."""
    path = ROOT / doc
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)   # code blocks hold commands
    targets = [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t)]
    assert targets or doc != "README.md", "README.md: no links found (the pattern is broken)"
    broken = []
    for target in targets:
        name, _, anchor = target.partition("#")
        file = (path.parent / name) if name else path
        if not file.exists():
            broken.append(target)
        elif anchor and file.suffix == ".md" and anchor not in anchors(file):
            broken.append(target)
    assert not broken, f"{doc}: links to missing files or headings {broken}"


REPO_PATH = re.compile(r"(?<![\w/.-])((?:granstab|app|benchmarks|tests|examples|presets|docs)/[\w/.-]*\w)")


@pytest.mark.parametrize("doc", ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))])
def test_repository_paths_named_in_the_docs_exist(doc):
    """A module or file the docs name (`granstab/model/shapes.py`, `examples/dem/run.sh`, …) exists: a move
    between rooms that leaves a doc behind fails here."""
    named = set(REPO_PATH.findall((ROOT / doc).read_text(encoding="utf-8")))
    missing = sorted(p for p in named if not (ROOT / p).exists())
    assert not missing, f"{doc} names paths that do not exist: {missing}"
