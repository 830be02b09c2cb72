"""The scan's `data_robust` and `robust_margin` columns (issue 42): each cluster's verdict under the data's stated
uncertainty (granstab.uncertainty.data_robustness on the cluster's own scene, with the scan's boundary; the
embedded boundary's verdict on the cluster's modes)."""
from __future__ import annotations

import numpy as np

from ..mechanics.uncertainty import Band
from ..model.scene import SceneError
from ..uncertainty import data_robustness
from .batch import EMBEDDED_INSIDE
from .clusters import boundary_rings, cluster


def robust_columns(scene, centers, member_lists, verdicts, options: dict, graph, sub_index) -> dict:
    """data_robust (holds / depends / undecided; "" where the row is an error) and robust_margin (the factor of the
    band the bound proves) of each centre, in the order of `centers`; `verdicts`: the rows' verdicts (a cluster
    whose verdict here differs from its row's is undecided). options["uncertainty"]: Band fields."""
    band = Band(**options["uncertainty"])
    boundary = options.get("boundary", "loads")
    embedded = boundary_rings(boundary)[0] == "embedded"
    metric = "L" if options["metric"] == "family" else options["metric"]
    robust = np.full(len(centers), "", dtype=object)
    margin = np.full(len(centers), np.nan)
    for i, (c, keep) in enumerate(zip(centers, member_lists)):
        if verdicts[i] == "error":
            continue
        try:
            sub = cluster(scene, c, options["rings"], boundary, graph=graph)
            inside = (sub_index(sub, scene, keep), EMBEDDED_INSIDE) if embedded else None
            got = data_robustness(sub, band, metric=metric, max_sliding=options["max_sliding"], inside=inside)
        except (SceneError, ValueError):
            robust[i] = "undecided"
            continue
        robust[i] = got.robust if got.verdict == verdicts[i] else "undecided"
        margin[i] = got.margin if np.isfinite(got.margin) else (np.inf if got.margin > 0 else -np.inf)
    return {"data_robust": robust, "robust_margin": margin}
