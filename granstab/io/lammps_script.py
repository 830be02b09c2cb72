"""The input script of a LAMMPS or LIGGGHTS run, as the dump readers need it (lammps.py, multisphere.py,
polygons.py, liggghts_superquadric.py): dimension, the computes that name a local dump's columns, the contact law
(pair style and coefficients; LIGGGHTS's `fix property/global`), and what kind of run it is (multisphere, body)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from .lines import is_number

# LIGGGHTS compute pair/gran/local: its columns come in this order whatever the keyword order (3.8.0, checked on
# Debian's liggghts); no keyword = pos vel id force torque history contactArea. `history` has as many columns as
# the pair style keeps (3 for tangential history): the columns after it are ignored.
GRAN_LOCAL = {"pos": ["-"] * 6, "vel": ["-"] * 6, "id": ["id1", "id2", "-"], "force": ["fx", "fy", "fz"],
              "force_normal": ["fnx", "fny", "fnz"], "force_tangential": ["ftx", "fty", "ftz"], "torque": ["-"] * 3,
              "history": None, "contactArea": ["-"], "delta": ["delta"], "heatFlux": ["-"],
              "contactPoint": ["cx", "cy", "cz"]}
GRAN_LOCAL_DEFAULT = ("pos", "vel", "id", "force", "torque", "history", "contactArea")
# pair granular single() (LAMMPS 2022): p1-p3 tangential force, p5-p7 rolling resistance force f_r, p9 twisting
# torque (reported only at its sliding limit: not read), p10-p12 branch vector
GRANULAR_P = {1: "ftx", 2: "fty", 3: "ftz", 5: "frx", 6: "fry", 7: "frz", 10: "delx", 11: "dely", 12: "delz"}


def read_script(path: Path) -> dict:
    """What an input script says about the dumps: dimension, compute columns, the contact law (a short file,
    read line by line; ${name} variables with numeric values are substituted)."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    variables, computes, properties = {}, {}, {}
    info = {"dimension": None, "pair": None, "coeff": None, "source": str(path), "properties": properties}
    lines = text.splitlines()
    starts = [n for n in range(1, len(lines) + 1) if n == 1 or not lines[n - 2].rstrip().endswith("&")]
    for number, raw in zip(starts, re.sub(r"&[ \t\r]*\n", " ", text).splitlines()):   # & joins lines: 1st's number
        words = re.sub(r"\$\{(\w+)\}|\$(\w)", lambda m: variables.get(m.group(1) or m.group(2), m.group(0)),
                       raw.split("#", 1)[0]).split()
        if not words:
            continue
        if words[0] == "variable" and len(words) >= 4 and words[2] in ("equal", "index", "string"):
            variables[words[1]] = words[3]
        elif words[0] == "dimension" and len(words) > 1:
            info["dimension"] = int(words[1]) if words[1] in ("2", "3") else None
        elif words[0] == "compute" and len(words) >= 4:
            computes[words[1]] = (words[3], words[4:])
        elif words[0] == "pair_style":
            info["pair"], info["pair_line"] = words[1:], number
        elif words[0] == "pair_coeff" and words[1:3] == ["*", "*"]:
            info["coeff"], info["coeff_line"] = words[3:], number
        elif words[:1] == ["fix"] and words[3:4] == ["property/global"] and len(words) >= 7:
            properties[words[4]] = (words[5:], number)    # LIGGGHTS: name peratomtype[pair] [n] values
        elif words[0] == "atom_style":
            info["atom_style"] = (words[1:], number)
        elif words[:1] == ["fix"] and words[3:4] in (["gravity"], ["multisphere"]):
            info[words[3]] = (words[4:], number)           # LIGGGHTS: magnitude vector gx gy gz; clumps
    info["computes"] = computes
    return info


def compute_columns(computes: dict, pair_style: str | None) -> dict:
    """c_ID[k] → column name for the computes a local dump can name."""
    names = {}
    for cid, (style, args) in computes.items():
        if style == "property/local":
            cols = [{"patom1": "id1", "patom2": "id2"}.get(a, "-") for a in args]
        elif style == "pair/local":
            cols = []
            for a in args:
                if a in ("fx", "fy", "fz"):  # granular styles: the normal part only (single() returns F_n / r)
                    cols.append("fn" + a[1] if pair_style == "granular" or pair_style.startswith("gran/") else a)
                elif re.fullmatch(r"p\d+", a) and (pair_style == "granular" or pair_style.startswith("gran/")):
                    cols.append(GRANULAR_P.get(int(a[1:]), "-") if pair_style == "granular"
                                else {1: "ftx", 2: "fty", 3: "ftz"}.get(int(a[1:]), "-"))
                else:
                    cols.append("-")
        elif style in ("pair/gran/local", "wall/gran/local"):     # a wall's id: mesh, triangle, atom
            keys = [k for k in GRAN_LOCAL if k in args] if args else GRAN_LOCAL_DEFAULT
            cols = [c for a in keys[:keys.index("history") if "history" in keys else None]
                    for c in (["-", "-", "id1"] if a == "id" and style == "wall/gran/local" else GRAN_LOCAL[a])]
            if "history" in keys:
                names[f"c_{cid}[*]"] = "-"   # history and what follows it: width unknown here, ignored
        else:
            continue
        for k, name in enumerate(cols, 1):
            names[f"c_{cid}[{k}]"] = name
        if len(cols) == 1:
            names[f"c_{cid}"] = cols[0]
    return names


def contact_law(script: dict | None, radius_p, radius_q, delta) -> tuple[dict, list]:
    """k, α, μ per contact from pair_style/pair_coeff (module docstring), with where they came from."""
    if script is None or script["pair"] is None:
        return {}, ["no input script: k, α, μ from the command line or defaults"]
    style, where = script["pair"][0], f"{Path(script['source']).name} line"
    if style == "gran":                          # LIGGGHTS
        return _liggghts_law(script)
    a = np.sqrt(radius_p * radius_q / (radius_p + radius_q) * np.maximum(delta, 0.0))
    try:
        if style in ("gran/hooke/history", "gran/hooke", "gran/hertz/history"):
            args = script["pair"][1:]
            kn = float(args[0])
            kt = 2.0 / 7.0 * kn if args[1] == "NULL" else float(args[1])
            mu = float(args[4])
            line = f"{where} {script['pair_line']} ({style})"
            if style == "gran/hertz/history":
                return {"k": (1.5 * kn * a, f"{line}: Hertz tangent stiffness 1.5 k_n a"),
                        "alpha": (kt / (1.5 * kn) + 0 * a, f"{line}: k_t a / (1.5 k_n a)"), "mu": (mu, line)}, []
            return {"k": (kn, line), "alpha": (kt / kn, f"{line}: k_t/k_n"), "mu": (mu, line)}, []
        if style == "granular" and script["coeff"]:
            words = script["coeff"]
            line = f"{where} {script['coeff_line']} (pair_coeff)"
            normal, kn = words[0], float(words[1])
            t = words.index("tangential")
            tangential, targs = words[t + 1], words[t + 2:]
            notes = []
            if "rolling" in words:
                notes.append("rolling resistance: contact moments R_eff f_r × n from pair/local p5 p6 p7 where "
                             "the local dump has them (else none); the rolling stiffness is not converted")
            if "twisting" in words:
                notes.append("twisting resistance: not converted (pair granular single() reports the twisting torque "
                             "only at its sliding limit, so no dump holds it): the moment imbalance shows it")
            if normal not in ("hooke", "hertz") or tangential not in ("linear_history", "mindlin"):
                return {}, [f"{line}: model {normal}/{tangential} not converted: give --k --alpha --mu"] + notes
            kt, mu = (float(targs[0]) if targs[0] != "NULL" else np.nan), float(targs[2])
            k_normal = kn if normal == "hooke" else 1.5 * kn * a
            k_tangent = kt if tangential == "linear_history" else kt * a
            law = {"k": (k_normal + 0 * a, f"{line}: {normal} k_n" + ("" if normal == "hooke" else " → 1.5 k_n a")),
                   "alpha": (k_tangent / k_normal + 0 * a, f"{line}: {tangential} k_t / k"), "mu": (mu, line)}
            return law, notes
    except (ValueError, IndexError):
        raise SceneError(f"{script['source']}: pair_coeff: cannot read the {style} parameters") from None
    return {}, [f"pair_style {style} not converted: give --k --alpha --mu"]


def _liggghts_law(script: dict) -> tuple[dict, list]:
    """LIGGGHTS `pair_style gran model hooke/stiffness tangential history`: F_n = k_n δ, F_t = k_t u_t, with k_n,
    k_t and coefficientFriction from `fix property/global` (one value, or equal values for every type pair)."""
    words, name = script["pair"], Path(script["source"]).name
    model = words[words.index("model") + 1] if "model" in words[:-1] else None
    tangential = words[words.index("tangential") + 1] if "tangential" in words[:-1] else None
    notes = ["rolling friction in the script: contact moments are not converted (pair/gran/local's torque leaves "
             "out the rolling friction torque)"] if "rolling_friction" in words else []
    line = f"{name} line {script['pair_line']} (gran model {model} tangential {tangential})"
    if model != "hooke/stiffness" or tangential != "history":
        return {}, [f"{line}: not converted (only hooke/stiffness with tangential history): give --k --alpha --mu"] + notes
    value = {}
    for key in ("kn", "kt", "coefficientFriction"):
        value[key] = liggghts_property(script, key)
        if isinstance(value[key], str):
            where = value[key] if value[key].startswith(name) else f"{line}: {value[key]}"
            return {}, [f"{where}: give --k --alpha --mu"] + notes
    (kn, kn_at), (kt, kt_at), (mu, mu_at) = value["kn"], value["kt"], value["coefficientFriction"]
    return {"k": (kn, kn_at), "alpha": (kt / kn, f"{kt_at} / kn"), "mu": (mu, mu_at)}, notes


def liggghts_property(script: dict, key: str):
    """(value, where) of a LIGGGHTS `fix property/global KEY` with one value (or equal values for every atom type
    or type pair); else a string saying why not (absent, or differing between types). Malformed: one-line error."""
    name = Path(script["source"]).name
    if key not in script["properties"]:
        return f"no fix property/global {key}"
    words, number = script["properties"][key]
    n = int(words[1]) ** 2 if words[0] == "peratomtypepair" and words[1:2] and words[1].isdigit() else None
    cells = words[2:2 + n] if n else words[1:]
    try:
        numbers = np.array([float(c) for c in cells])
    except ValueError:
        bad = next(c for c in cells if not is_number(c))
        raise SceneError(f"{script['source']}: line {number}: {key}: not a number ({bad!r})") from None
    if numbers.size == 0 or (n and numbers.size != n):
        raise SceneError(f"{script['source']}: line {number}: {key}: expected {n or 'a'} value(s), got {numbers.size}")
    if np.ptp(numbers) != 0:
        return f"{name} line {number}: {key} differs between atom types"
    return float(numbers[0]), f"{name} line {number} (fix property/global {key})"
