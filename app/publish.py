"""`granstab publish`: a scene recorded into one self-contained HTML page that plays offline, without Python.

viser 1.1 records what a server sends (`ViserServer.get_scene_serializer()` → `StateSerializer`, `insert_sleep(dt)`
between frames, `as_html()`: its single-file client with the recording embedded). The page is drawn by the explorer's
own SceneView (app/views.py) from a Session (app/state.py), with the explorer's camera (camera.camera_pose):
  - the pair preset (two_particle): a sweep of ρ/r across 1 (SWEEP), each step held, then its rolling mode played;
    the particles, contact, force arrows, osculating circles and the λ⁽⁶⁾ surface with its current-state marker;
  - any other scene: its lowest consistent modes (MODES at most, each motion once), each played in turn.
A recording carries no GUI: the verdict badge is a scene label that changes at each step, and a note on the page
(NOTE) says what the recording cannot do.
"""
from __future__ import annotations

import contextlib
import html
import io
import re
import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import viser

import granstab

from .camera import above_sheet, camera_pose, fit_distance
from .figures import contour_html
from .panel.modes import unstable
from .readings import SAME_MODE
from .state import Session
from .text import VERDICT_COLOR, plain_sentence
from .views import SceneView

SWEEP = np.round(np.linspace(0.5, 1.5, 11), 2)     # ρ/r of the pair's steps: sharp, round (1: neutral), flat
FPS = 20                                           # frames per second of a played mode
CYCLE = 1.6                                        # s: one period of a played mode
HOLD = 0.8                                         # s: a step shown at rest (contact drawings on) before its mode plays
MODES = 3                                          # the other scenes: their lowest consistent modes played, at most
AMPLITUDE = 0.35                                   # the explorer's default mode amplitude (× particle size)
NOTE_STYLE = ("#granstab-note{position:fixed;top:8px;right:8px;max-width:340px;max-height:calc(100vh - 90px);"
              "overflow:auto;z-index:1000;background:rgba(255,255,255,0.92);border:1px solid #bbb;border-radius:6px;"
              "padding:8px 10px;font:13px/1.35 sans-serif;color:#222}"
              "@media (max-width:600px){#granstab-note{left:8px;right:8px;top:auto;bottom:60px;max-width:none;"
              "max-height:30vh}}")  # a phone: the note at the bottom, the scene above it (in the style sheet: an
                                    # inline style outranks a media rule, and the note covered the whole phone)
MAX_BYTES = 5_000_000                              # the largest page written
VIEWPORT = SimpleNamespace(fov=75.0 * np.pi / 180.0, image_width=1600, image_height=1000)   # viser's default fov
PHONE_VIEWPORT = SimpleNamespace(fov=VIEWPORT.fov, image_width=390, image_height=844)   # a portrait phone: the scene
PHONE_BAND = 0.6                                   # in its top 60 %, above the note (from 63 % down: NOTE_STYLE)
BADGE_OVER, LAMP_OVER = 2.2, 1.4                   # particle sizes: the badge over the top particle, the lamp over it
BADGE_ROOM = 2.8                                   # particle sizes above the scene kept in view: badge, lamp
DETAIL_CHARS = 64                                  # the badge's detail line wrapped at: a phone's width
PHONE_CAMERA = ("<script>if(matchMedia('(max-width:600px) and (orientation:portrait)').matches&&"
                "!location.search.includes('initialCamera')){{const q=new URLSearchParams(location.search);"
                "{params}history.replaceState(null,'','?'+q+location.hash)}}</script>")   # before viser's client reads
                                    # its URL: its initialCamera* parameters outrank the recorded camera
NOTE = ("<b>A recording</b> of the granstab explorer ({title}). It plays {what}. The playback bar at the bottom "
        "pauses it (its left button) and scrubs through it; drag the view to turn the camera. A recording has no "
        "controls of its own: the particles cannot be dragged and there are no sliders — run <code>granstab-app</code> "
        "for those.")


def publish(preset: str, out: Path | str) -> dict:
    """Write the page of `preset` (a preset name or a scene file) to `out`; returns {"bytes", "seconds", "steps",
    "sweep", "badges", "cameras", "badge_at"}: badges lists each step's (ρ/r or mode eigenvalue, verdict word, λ⁽⁶⁾/k
    or None) as drawn; cameras the first step's pose on the page and on a phone; badge_at where its badge hangs.
    Raises granstab.SceneError (one line) when the scene cannot be read or analysed, or the page would be too large."""
    folder = Path(out).resolve().parent
    if not folder.is_dir():
        raise granstab.SceneError(f"granstab publish: --out {out}: no folder {folder}")
    session = Session(preset)
    if session.error:
        raise granstab.SceneError(f"granstab publish: {session.error}")
    if session.on_map:
        raise granstab.SceneError(f"granstab publish: {preset}: a scan folder; publish one scene file of it")
    if session.deferred:
        session.analyse()
    if session.analysis is None:
        raise granstab.SceneError(f"granstab publish: {preset}: no analysis to record: {session.error}")
    page = Recording(session)
    try:
        steps = page.sweep() if session.kind == "two_particle" else page.modes()
        text = page.html(steps)
    finally:
        page.close()
    size = len(text.encode())
    if size > MAX_BYTES:
        raise granstab.SceneError(f"granstab publish: {preset}: the page would be {size / 1e6:.1f} MB, over the "
                                  f"{MAX_BYTES / 1e6:.0f} MB limit")
    Path(out).write_text(text, encoding="utf-8")
    return {"bytes": size, "seconds": page.seconds, "steps": steps, "sweep": session.kind == "two_particle",
            "badges": page.badges, "cameras": {"page": page.pose, "phone": page.phone_pose}, "badge_at": page.badge_at}


class Recording:
    """A viser server nobody connects to, whose scene is recorded while the explorer's SceneView draws into it."""

    def __init__(self, session: Session):
        self.session = session
        self.title = getattr(session.scene, "title", None) or session.preset      # the scene as it opens
        with contextlib.redirect_stdout(io.StringIO()):      # viser prints its address: nobody is to connect
            self.server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
        self.recorder = self.server.get_scene_serializer()
        self.seconds = 0.0
        self.badges: list[tuple] = []                       # what each step's badge states (publish's return)
        self.pose: dict = {}                                # the first step's camera (kept: no jumps)
        self.phone_pose: dict = {}                          # the same on a phone (phone_camera)
        self.badge_at: tuple = ()                           # where the last step's badge hangs
        scene = self.server.scene
        scene.configure_environment_map(hdri=None)          # as the explorer: no HDR map, plain lights
        scene.configure_default_lights(enabled=True, cast_shadow=False)
        self.view = SceneView(scene)
        self.view.static = True

    def close(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()

    def sleep(self, seconds: float) -> None:
        self.recorder.insert_sleep(seconds)
        self.seconds += seconds

    def draw(self, badge: str, detail: str, verdict: str | None = None) -> None:
        """The scene at rest as the explorer draws it, the camera, and the badge (two scene labels over it, beside a
        lamp in the verdict's colour: the page's badge colour in every frame)."""
        s, view = self.session, self.view
        with self.server.atomic():
            view.stop_animation()
            view.draw_particles(s)
            view.draw_contacts(s)
            view.draw_cell(s)
            field = s.field()
            if field is not None:
                view.draw_field(s, field, (s.params["rho_r"], s.params["f_kr"], s.rolling_eigenvalue()))
            if not self.badges[1:]:                          # the camera of the first step, kept (no jumps)
                self.fit_cameras(field is not None)
            x = np.array([b.x for b in s.bodies()])
            top = float(x[:, 1 if s.scene_dim == 2 else 2].max()) + BADGE_OVER * s.size   # room for the detail's lines
            at = self.badge_at = (float(x[:, 0].mean()), top, 0.0) if s.scene_dim == 2 else (
                float(x[:, 0].mean()), float(x[:, 1].mean()), top)
            self.server.scene.add_label("/badge", badge.replace(" · ", "\n"), position=at, font_screen_scale=1.6,
                                        anchor="bottom-center")           # the verdict, then the mode: a phone's width
            self.server.scene.add_label("/badge/detail", "\n".join(textwrap.wrap(detail, DETAIL_CHARS)),
                                        position=(0.0, 0.0, 0.0), font_screen_scale=0.9, anchor="top-center")
            rgb = tuple(int(VERDICT_COLOR.get(verdict, "#555555")[i:i + 2], 16) for i in (1, 3, 5))
            self.server.scene.add_icosphere("/badge/lamp", radius=0.3 * s.size, color=rgb,
                                            position=(0.0, LAMP_OVER * s.size, 0.0) if s.scene_dim == 2
                                            else (0.0, 0.0, LAMP_OVER * s.size))

    def fit_cameras(self, field: bool) -> None:
        """The page's camera (fitted to VIEWPORT, the λ⁽⁶⁾ surface included) and the phone's (PHONE_VIEWPORT: the
        particles only, above the note; phone_camera), each with BADGE_ROOM above the scene for the badge."""
        s, oblique = self.session, self.session.scene_dim == 2 and field
        self.pose, self.phone_pose = (camera_pose(s, oblique, surface, lambda w, h, v=v: fit_distance(
            w, h, v, 0.0, band=PHONE_BAND), above=BADGE_ROOM) for v, surface in ((VIEWPORT, True), (PHONE_VIEWPORT, False)))
        self.phone_pose = above_sheet(self.phone_pose, PHONE_VIEWPORT, PHONE_BAND)
        camera, pose = self.server.initial_camera, self.pose
        camera.position, camera.look_at, camera.up = pose["position"], pose["look_at"], pose["up_direction"]
        camera.near, camera.far = pose["near"], pose["far"]

    def colour(self, mode) -> None:
        """Particles coloured by their share of `mode` where the explorer does so (more than two particles)."""
        s = self.session
        names = [b.name for b in s.bodies()]
        index = {n: i for i, n in enumerate(s.scene.names)}
        on = mode is not None and s.scene.n_particles > 2
        self.view.colour_particles(names, s.particle_shares(mode)[[index[n] for n in names]] if on else None,
                                   unstable=mode is not None and unstable(mode, s.analysis))

    def play(self, mode) -> None:
        """One period of `mode` at FPS frames per second (the explorer's animation: SceneView.animate)."""
        s = self.session
        with self.server.atomic():                       # the rest position's ghost and the motion's arrows
            self.view.show_rest(s.bodies(), s.mode_bodies(mode, AMPLITUDE, 0.5 * np.pi), s.size)
        for k in range(int(round(CYCLE * FPS))):
            with self.server.atomic():
                self.view.animate(s.mode_bodies(mode, AMPLITUDE, 2 * np.pi * k / (CYCLE * FPS)))
            self.sleep(1.0 / FPS)

    def sweep(self) -> int:
        """The pair: each ρ/r of SWEEP held, then its rolling mode played; the badge states the step's verdict."""
        s = self.session
        for rho_r in SWEEP:
            s.set_params(rho_r=float(rho_r))
            word, lam = s.verdict, s.rolling_eigenvalue()
            self.badges.append((float(rho_r), word, lam))
            self.draw(f"ρ/r = {rho_r:.2f}: {(word or 'no verdict').upper()}",
                      f"rolling eigenvalue λ⁽⁶⁾/k = {0 if lam is None else lam:.3g} · {plain_sentence(s, word)}", word)
            self.sleep(HOLD)
            rolling = next((m for m in s.modes() if m.branch == 0 and m.label == "rolling"), None)
            if rolling is not None:
                self.play(rolling)
        return len(SWEEP)

    def modes(self) -> int:
        """Any other scene: its lowest consistent modes (each motion once), each held, then played."""
        s = self.session
        word = s.verdict
        reason = plain_sentence(s, word)
        chosen = lowest_modes(s, MODES)
        for i, m in enumerate(chosen, 1):
            self.badges.append((m.eigenvalue, word, None))
            self.draw(f"{(word or 'no verdict').upper()} · mode {i} of {len(chosen)}: {m.label}, λ = {m.eigenvalue:.3g}",
                      reason, word)
            self.colour(m)
            self.sleep(HOLD)
            self.play(m)
        if not chosen:
            self.draw(f"{(word or 'no verdict').upper()} · no consistent mode to play", reason, word)
            self.sleep(HOLD)
        return len(chosen)

    def html(self, steps: int) -> str:
        """The recording as one HTML document (viser's as_html) with the page's title and NOTE."""
        s = self.session
        what = (f"a sweep of ρ/r across 1 in {steps} steps, each step's verdict on its badge and its rolling mode "
                "animated" if s.kind == "two_particle" else
                f"the {steps} lowest consistent mode(s) of the scene, animated, the verdict on the badge")
        title = self.title
        title = title if len(str(title)) <= 90 else f"{str(title)[:89]}…"
        note = NOTE.format(title=html.escape(str(title)), what=what) + watch_html(s)
        text = self.recorder.as_html()
        box = f'<style>{NOTE_STYLE}</style><div id="granstab-note">{note}</div>'
        text = re.sub(r"<title>.*?</title>", f"<title>granstab: {html.escape(str(title))}</title>", text, count=1)
        text = text.replace("<head>", "<head>" + phone_camera(self.phone_pose), 1)
        return text.replace("</body>", box + "</body>", 1)


def phone_camera(pose: dict) -> str:
    """The page's first script: on a portrait phone the camera `pose` (the scene fitted above the note, as the
    explorer fits a phone: camera.above_sheet) given to viser's client as its initialCamera* URL parameters (the
    recorded camera is fitted to a 1600×1000 canvas: on a phone it cut the pair off at the sides)."""
    names = {"position": "initialCameraPosition", "look_at": "initialCameraLookAt", "up_direction": "initialCameraUp"}
    params = "".join(f"q.set('{name}','{','.join(f'{float(x):.6g}' for x in pose[key])}');"
                     for key, name in names.items())
    return PHONE_CAMERA.format(params=params)


def watch_html(s: Session) -> str:
    """What to look for, in 2-3 sentences (and the pair's λ⁽⁶⁾ contour): the page's hand-out text."""
    if s.kind == "two_particle":
        return ("<p><b>What to watch.</b> The two grains are drawn with the tip curvature of the contact: an ellipse "
                "of radius r along the line of centres whose tip has radius of curvature ρ. Below ρ/r = 1 the tips "
                "are sharper than a circle and the pair rolls apart (red lamp, UNSTABLE); at 1 it rolls freely "
                "(NEUTRAL); above, the flat sides rock back (green, STABLE). The grey outline is the rest position, "
                "the green arrows the motion.</p>" + contour_html(s.field()))
    return ("<p><b>What to watch.</b> The lamp beside the badge has the verdict's colour (red unstable, amber "
            "neutral, green stable). Each mode is played from its rest position (grey outline) along the green "
            "arrows; darker particles carry more of its motion (red where the mode is unstable, blue otherwise).</p>")


def lowest_modes(session: Session, most: int) -> list:
    """The `most` lowest consistent non-rigid modes of the session, a motion in several branches once (|cos| ≥
    SAME_MODE, as Session.distinct_modes counts them)."""
    a, out, seen = session.analysis, [], []
    for m in sorted((m for m in session.modes() if m.consistent and m.label != "rigid"), key=lambda m: m.eigenvalue):
        v = a.motion(a.branches[m.branch].stability_vectors[:, m.index])
        v = v / max(float(np.linalg.norm(v)), 1e-300)
        if any(abs(float(v @ w)) >= SAME_MODE for w in seen):
            continue
        seen.append(v)
        out.append(m)
        if len(out) == most:
            break
    return out
