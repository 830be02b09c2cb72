"""The pair's λ⁽⁶⁾/k height surface in the 3D view: drawn once per field, its current-state marker moved at each
change, a click on it read back as (ρ/r, f/(kr)). A base of app/views.py's SceneView (its `api`, `options`,
`on_pick` and the `_field_key`, `_field_lim`, `_marker` it sets)."""
from __future__ import annotations

import numpy as np


class FieldView:
    def field_frame(self, field, size: float):
        """Where the surface sits: below the pair, x over ρ/r in [-1, 3]·r, y over f/(kr) in [-4.6, -2]·r."""
        x0, x1, y0, y1 = -1.0 * size, 3.0 * size, -4.6 * size, -2.0 * size

        def place(rho_r, f_kr):
            X = x0 + (np.asarray(rho_r) - field.rho_r[0]) / (field.rho_r[-1] - field.rho_r[0]) * (x1 - x0)
            Y = y0 + (np.asarray(f_kr) - field.f_kr[0]) / (field.f_kr[-1] - field.f_kr[0]) * (y1 - y0)
            return X, Y
        return place, (x0, x1, y0, y1)

    def draw_field(self, session, field, current) -> None:
        """The λ⁽⁶⁾/k field as a coloured height surface (red < 0, blue > 0) with the current state marked: the surface
        is sent once per field, then only the marker moves (its position: one small message per slider move)."""
        if field is None or not self.options["surface"]:
            self.clear_field()
            return
        size = session.field_scale      # fixed per pair: the cached surface and the marker share it
        key = (id(field), size)
        if self._field_key != key:
            self._field_key = key
            self._draw_surface(field, size)
        place, _ = self.field_frame(field, size)
        rho_r, f_kr, lam = current
        cx, cy = place(rho_r, f_kr)
        cz = (0.0 if lam is None else float(np.clip(lam / self._field_lim, -1.5, 1.5))) * 0.8 * size
        self._marker.position = (float(cx), float(cy), cz + 0.05 * size)

    def _draw_surface(self, field, size: float) -> None:
        """The surface, its frame, axis labels and the current-state marker (placed by draw_field)."""
        import trimesh
        place, (x0, x1, y0, y1) = self.field_frame(field, size)
        lim = self._field_lim = float(np.abs(field.lam).max()) or 1.0       # the height scale (1: a zero field)
        R, F = np.meshgrid(field.rho_r, field.f_kr)
        X, Y = place(R, F)
        Z = field.lam / lim * 0.8 * size
        V = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
        nr, nf = len(field.rho_r), len(field.f_kr)
        idx = np.arange(nr * nf).reshape(nf, nr)
        a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
        faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
        v = field.lam.reshape(-1) / lim
        colors = diverging(np.sign(v) * np.sqrt(np.abs(v)))     # √ stretch: the small values near 0 show too
        mesh = trimesh.Trimesh(V, faces, vertex_colors=colors, process=False)
        surface = self.api.add_mesh_trimesh("/field/surface", mesh)
        surface.on_click(lambda event: self._picked(event, field, place, Z))
        self.api.add_line_segments("/field/frame", np.array([
            [[x0, y0, 0], [x1, y0, 0]], [[x1, y0, 0], [x1, y1, 0]], [[x1, y1, 0], [x0, y1, 0]],
            [[x0, y1, 0], [x0, y0, 0]]]), (90, 90, 90), thickness=1.5, thickness_units="screen")
        self.api.add_label("/field/xlabel", "ρ/r →", position=(0.5 * (x0 + x1), y0 - 0.25 * size, 0))
        self.api.add_label("/field/ylabel", "f/(kr) ↑", position=(x0 - 0.55 * size, 0.5 * (y0 + y1), 0))
        self.api.add_label("/field/title", "λ⁽⁶⁾/k: red < 0 < blue", position=(0.5 * (x0 + x1), y1 + 0.25 * size, 0))
        self._marker = self.api.add_icosphere("/field/current", radius=0.09 * size, color=(255, 200, 0))

    def _picked(self, event, field, place, Z) -> None:
        """A click on the surface: march along the ray to where it meets the height field, report (ρ/r, f/(kr))."""
        if self.on_pick is None:
            return
        hit = ray_heightfield(np.asarray(event.ray_origin), np.asarray(event.ray_direction), field, place, Z)
        if hit is not None:
            self.on_pick(*hit)

    def clear_field(self) -> None:
        """No surface (another scene, or switched off): removed once, nothing sent while there is none."""
        if self._field_key is not None:
            self._field_key = self._marker = None
            self.api.remove_by_name("/field")


def ray_heightfield(origin, direction, field, place, Z, n: int = 2000):
    """First crossing of the ray with the surface z = Z(ρ/r, f/(kr)) placed by `place`, as (ρ/r, f/(kr)) or None."""
    from scipy.interpolate import RegularGridInterpolator
    xs, _ = place(field.rho_r, field.f_kr[0])
    _, ys = place(field.rho_r[0], field.f_kr)
    height = RegularGridInterpolator((ys, xs), Z, bounds_error=False, fill_value=np.nan)
    span = 4.0 * max(xs[-1] - xs[0], ys[-1] - ys[0]) + np.linalg.norm(origin)
    t = np.linspace(0.0, span, n)
    pts = origin + t[:, None] * direction / np.linalg.norm(direction)
    gap = pts[:, 2] - height(pts[:, [1, 0]])
    inside = np.flatnonzero(np.isfinite(gap[:-1]) & np.isfinite(gap[1:]) & (np.sign(gap[:-1]) != np.sign(gap[1:])))
    if inside.size == 0:
        return None
    k = inside[0]
    w = gap[k] / (gap[k] - gap[k + 1])
    x, y = (pts[k] + w * (pts[k + 1] - pts[k]))[:2]
    rho = field.rho_r[0] + (x - xs[0]) / (xs[-1] - xs[0]) * (field.rho_r[-1] - field.rho_r[0])
    f = field.f_kr[0] + (y - ys[0]) / (ys[-1] - ys[0]) * (field.f_kr[-1] - field.f_kr[0])
    return float(rho), float(f)


def diverging(v: np.ndarray) -> np.ndarray:
    """RGBA uint8 of values in [-1, 1]: red (negative) – white (0) – blue (positive), like the contour plot."""
    v = np.clip(np.asarray(v, float), -1, 1)[:, None]
    red, white, blue = np.array([178, 24, 43]), np.array([247, 247, 247]), np.array([33, 102, 172])
    rgb = np.where(v < 0, white + (-v) * (red - white), white + v * (blue - white))
    return np.concatenate([rgb, np.full((len(rgb), 1), 255)], axis=1).astype(np.uint8)
