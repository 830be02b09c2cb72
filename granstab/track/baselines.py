"""The field's per-particle baselines that need more than one frame or a learned model (issue 39), computed in the
prediction test from the track folder's tables (the soft spots, which need the frame's contacts, are frame.py's):

- `d2min_previous`: the particle's D²min over the window that ENDS at t, (t − W, t] (Falk & Langer; the
  persistence of rearrangement): the d2min column of the same particle (by name) at frame t − W; NaN for the first
  W frames.
- `softness` (Cubuk et al., PRL 114, 108001, 2015): radial structure functions of the particle's neighbourhood,
  G_k(i) = Σ_j exp(−(r_ij − μ_k)² / (2 L²)), μ_k = 0.4 d̄ … 3.0 d̄ in steps of 0.1 d̄, L = 0.1 d̄ (d̄ the frame's
  mean contact branch length, about one diameter; all neighbours, one species), standardised, and a logistic
  regression (scikit-learn, C = 1, balanced classes) trained on the rows of the first half of the frames with a
  window and scored (its decision function) on the second half only: never on the frames it was trained on.
"""
from __future__ import annotations

import numpy as np

from .motion import neighbours, pair_vectors

MU = np.round(np.arange(0.4, 3.0 + 1e-9, 0.1), 10)      # the G(r) shells, in units of d̄
WIDTH = 0.1
MISSING = "softness not computed: scikit-learn is not installed (pip install 'granstab[baselines]')"


def previous_d2min(code: np.ndarray, pos: np.ndarray, d2min: np.ndarray, window: int) -> np.ndarray:
    """Per row (particle `code`, frame position `pos`): d2min of the same particle at position pos − W (NaN where
    that row does not exist)."""
    span = int(pos.max()) + 1 if len(pos) else 1
    key = code.astype(np.int64) * span + pos
    order = np.argsort(key)
    want = key - window
    at = np.minimum(np.searchsorted(key[order], want), len(key) - 1)
    hit = (key[order][at] == want) & (pos >= window)
    return np.where(hit, d2min[order[at]], np.nan)


def radial_features(x: np.ndarray, cell: np.ndarray | None, scale: float) -> np.ndarray:
    """G_k(i) (N, len(MU)) of one frame's positions (module docstring), through the cell's images when periodic."""
    i, j = neighbours(x, (MU[-1] + 3 * WIDTH) * scale, cell)
    r = np.linalg.norm(pair_vectors(x, i, j, cell), axis=1) / scale
    g = np.exp(-((r[:, None] - MU[None, :]) ** 2) / (2 * WIDTH ** 2))
    return np.stack([np.bincount(i, weights=g[:, k], minlength=len(x)) for k in range(len(MU))], axis=1)


def frame_features(x: np.ndarray, pos: np.ndarray, cells: list, scales: np.ndarray) -> np.ndarray:
    """G(r) features of every row (rows of frame position p use cells[p] and scales[p])."""
    out = np.full((len(x), len(MU)), np.nan)
    for p in np.unique(pos):
        rows = np.flatnonzero(pos == p)
        if np.isfinite(scales[p]) and scales[p] > 0:
            out[rows] = radial_features(x[rows], cells[p], scales[p])
    return out


def softness(features: np.ndarray, label: np.ndarray, pos: np.ndarray, valid: np.ndarray) -> np.ndarray | None:
    """The logistic-regression score of each row in the second half of the frames (NaN elsewhere), trained on the
    valid rows of the first half; None without scikit-learn or without both classes in the training half."""
    try:
        from sklearn.linear_model import LogisticRegression
        from sklearn.pipeline import make_pipeline
        from sklearn.preprocessing import StandardScaler
    except ImportError:
        return None
    frames = np.unique(pos[valid])
    half = frames[len(frames) // 2] if len(frames) > 1 else np.inf
    ok = valid & np.all(np.isfinite(features), axis=1)
    train, test = ok & (pos < half), ok & (pos >= half)
    if len(np.unique(label[train])) < 2 or not test.any():
        return np.full(len(label), np.nan)
    model = make_pipeline(StandardScaler(), LogisticRegression(C=1.0, class_weight="balanced", max_iter=1000))
    model.fit(features[train], label[train])
    out = np.full(len(label), np.nan)
    out[test] = model.decision_function(features[test])
    return out
