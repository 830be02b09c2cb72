"""Where the explorer's camera looks from: one pose for a session's scene (the explorer's and the published page's),
fitted to the canvas the side panels leave free.
"""
from __future__ import annotations

import numpy as np

from .scenes import IMAGE_REACH, cell_edges

COVERED_PX = 0            # px of the canvas under a panel: none (viser 1.1 docks panels beside the canvas, which
                          # is the free part; 430 + 400 here kept a 1024 px page's pair at 56 px of its 186)
PHONE_PX, PHONE_BAND = 480, 0.38      # a portrait canvas narrower than PHONE_PX px: viser's panel covers all but its
                          # top ~40 % (390×844: from y = 337 px), so the scene is fitted into the top PHONE_BAND; a
                          # 1400×900 page's canvas between both docked columns is 570×900 (600 here shrank its pair)
TOP, OBLIQUE = "top-down", "oblique (heights readable)"     # the 2D camera views


def camera_pose(s, oblique: bool, surface: bool, fit, above: float = 0.0) -> dict:
    """Where the camera looks at session `s` from: near, far, up_direction, position, look_at (in the order to set
    them). 2D from above (or `oblique`: from the front and above, heights readable; the λ⁽⁶⁾ surface included when
    `surface` is shown), `fit(half_w, half_h)` the distance that fits the scene; 3D from an oblique corner; `above`
    particle sizes of room above the scene (the published page's badge). The explorer's camera
    (DisplayPanel.set_camera) and the published page's (app/publish.py)."""
    bodies = s.bodies()
    x = np.array([b.x for b in bodies])
    reach = 1.2 * np.array([max(b.axes) for b in bodies])[:, None]   # each body by its own size (hand_in_glove's
                                                                      # q is larger than the mean)
    lo, hi = (x - reach).min(axis=0), (x + reach).max(axis=0)
    edges = None if s.scene is None or s.on_map else cell_edges(s.scene)
    if edges is not None:                        # the periodic images beside the cell's outline are in view too
        beyond = (IMAGE_REACH + 1.2) * s.size
        lo = np.minimum(lo, edges.reshape(-1, s.scene.dim).min(axis=0) - beyond)
        hi = np.maximum(hi, edges.reshape(-1, s.scene.dim).max(axis=0) + beyond)
    hi[-1] += above * s.size                                          # 2D: y, 3D: z
    span = float(np.max(hi - lo))
    pose = {"near": 1e-3 * span, "far": 1e2 * span}                     # packings in px or in m
    c = 0.5 * (lo + hi)
    if s.scene_dim == 2:
        if s.field() is not None and surface:
            lo[1] = min(lo[1], -4.9 * s.field_scale)
            c = 0.5 * (lo + hi)
        distance = fit(0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]))
        if oblique:
            pose.update(up_direction=(0.0, 0.0, 1.0),
                        position=(float(c[0]), float(c[1]) - 0.8 * distance, 0.75 * distance))
        else:
            pose.update(up_direction=(0.0, 1.0, 0.0), position=(float(c[0]), float(c[1]), distance))
        pose["look_at"] = (float(c[0]), float(c[1]), 0.0)
        return pose
    extent = float(np.max(hi - lo))
    view = np.array([0.55, -0.65, 0.5])
    pose.update(up_direction=(0.0, 0.0, 1.0), position=tuple((c + 1.3 * extent * view / np.linalg.norm(view)).tolist()),
                look_at=tuple(c.tolist()))
    return pose


def fit_distance(half_w: float, half_h: float, camera, covered: float = COVERED_PX, fill: float = 0.9,
                 band: float = PHONE_BAND) -> float:
    """How far above a 2D scene of half-sizes (half_w, half_h) the camera must be for the scene to fill at most `fill`
    of the canvas that the side panels (`covered` px of its width) leave free (on a `phone`, of its top `band`), for
    the camera's vertical field of view and the canvas's size in px (an opened cluster was cut at the canvas edge by a
    fixed distance)."""
    t = np.tan(0.5 * float(camera.fov))
    width, height = float(camera.image_width), float(camera.image_height)
    free = max(width - covered, 0.3 * width)
    band = band if phone(camera) else 1.0
    return max(half_h / (fill * t * band), half_w / (fill * t * free / height))


def phone(camera) -> bool:
    """A portrait canvas narrower than PHONE_PX: the control panel covers its lower part."""
    return float(camera.image_width) < PHONE_PX and float(camera.image_height) > 1.2 * float(camera.image_width)


def above_sheet(pose: dict, camera, band: float = PHONE_BAND) -> dict:
    """On a `phone` canvas, `pose` moved along the screen's up direction so that the scene's centre sits in the middle
    of the top `band` of the canvas (above the panel that covers the rest; fit_distance fits it there)."""
    if not phone(camera):
        return pose
    position, target = np.array(pose["position"], float), np.array(pose["look_at"], float)
    view = (target - position) / np.linalg.norm(target - position)
    up = np.array(pose["up_direction"], float)
    up = up - (up @ view) * view
    up /= np.linalg.norm(up)
    shift = (1.0 - band) * np.linalg.norm(target - position) * np.tan(0.5 * float(camera.fov))
    return {**pose, "position": tuple((position - shift * up).tolist()), "look_at": tuple((target - shift * up).tolist())}
