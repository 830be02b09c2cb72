"""Makes presets/superquadric_cluster.json: the one-ring cluster of grain 150 of the settled superquadric packing
(tests/data/liggghts_superquadric, made by run.sh), cut with the cut contacts' forces as dead loads (the paper's
isolated cluster, `granstab extract … --center 150 --boundary loads`), with each grain's true shape and orientation
(model/grains.py) so that the explorer draws the grains as they are.

    .venv/bin/python examples/liggghts_superquadric/make_preset.py
"""
import json
from pathlib import Path

from granstab.io import load
from granstab.io.scenes import scene_to_dict
from granstab.model.grains import from_loaded
from granstab.scan.clusters import extract

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "liggghts_superquadric"
CENTRE = "150"
TITLE = ("five blocky superquadrics from a settled LIGGGHTS packing (grain 150 and its neighbours, cut contacts as "
         "dead loads): corners on faces, radii of curvature smaller than the arms; lengths in m, forces in N")


def main() -> None:
    loaded = load([str(DATA / name) for name in ("atoms.dump", "contacts.dump", "in.settle")])
    cluster = extract(loaded.scene, CENTRE, rings=1, boundary="loads")
    data = scene_to_dict(cluster)
    data["title"] = TITLE
    index = {name: i for i, name in enumerate(loaded.scene.names)}
    entries = from_loaded(loaded).entries()
    for particle in data["particles"]:
        particle.update(entries[index[particle["name"]]])
    (ROOT / "presets" / "superquadric_cluster.json").write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
