"""`granstab publish`: the explorer's command in the `granstab` CLI, registered through the entry-point group
`granstab.commands` (pyproject.toml) so that the core never imports the explorer; viser is imported only when the
command runs."""
from __future__ import annotations

from pathlib import Path

from granstab.model.errors import require


def add(sub) -> None:
    p = sub.add_parser("publish", help="a scene recorded as one HTML page that plays offline (needs the app extra)")
    p.add_argument("scene", help="a preset name (presets/) or a scene file; two_particle: a sweep of ρ/r across 1")
    p.add_argument("--out", required=True, help="the HTML file to write (at most 5 MB)")
    p.set_defaults(run=cmd_publish)


def cmd_publish(args) -> int:
    """A scene recorded into one self-contained HTML page (issue 29): the explorer's drawing, played offline."""
    require("viser", "app", "granstab publish")
    from .publish import publish  # it needs viser; only this command needs it
    done = publish(args.scene, Path(args.out))
    print(f"wrote {args.out}: {done['bytes'] / 1e6:.2f} MB, {done['seconds']:.0f} s of recording, {done['steps']} "
          f"{'steps of ρ/r' if done['sweep'] else 'modes'}; it opens offline in a browser (no dragging, no sliders: "
          "its playback bar plays the recording)")
    return 0
