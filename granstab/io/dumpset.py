"""The frames of readers that take several LAMMPS dumps of one run (multisphere.py: atoms, contacts, walls,
bodies; polygons.py: atoms, vertices) and of those that read `lammps.index_lammps`'s pair their own way
(liggghts_superquadric.py), accounted for as every reader's are (issue 38; lammps.account): each dump indexed once,
the timesteps that all of them have are the frames, timesteps in some dumps only are named in one warning line, a
truncated last timestep is left out with a warning naming it, dumps of different runs are refused.

    index = Indexed(index_dumps(dumps, progress, script), read_one)     # registry.Format.index
    index.frames, index.warnings, index.read(timestep, request, progress)
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..model.errors import SceneError
from .lammps import _steps, account, index_dump


@dataclass
class DumpSet:
    """Dumps of one run indexed once: `paths` (as given), `blocks` (per dump: timestep → Block), the `frames` all
    have, the `warnings` (what was left out), the parsed input script and the data file (None: none given)."""

    paths: list
    blocks: list
    frames: list
    warnings: list
    script: dict | None = None
    data: Path | None = None

    def at(self, step) -> list:
        """[(path, Block)] of timestep `step` in every dump; a one-line error if one lacks it."""
        if step not in self.frames:
            raise SceneError(f"{self.paths[0]}: timestep {step}: timestep: not in every dump (they share "
                             f"{_steps(self.frames)})" + "".join(f"; {w}" for w in self.warnings))
        return [(path, blocks[step]) for path, blocks in zip(self.paths, self.blocks)]


def index_dumps(dumps: list[Path], progress=None, script: dict | None = None, data: Path | None = None) -> DumpSet:
    """One pass over each dump (lammps.index_dump) and their frames accounted for (lammps.account)."""
    update = None if progress is None else progress.update
    indexed = [(p, *index_dump(p, update)) for p in dumps]
    frames, warnings = account(indexed)
    return DumpSet(list(dumps), [{b.timestep: b for b in blocks} for _, blocks, _ in indexed], frames, warnings,
                   script, data)


@dataclass
class Indexed:
    """A format's index (registry.Format.index): the dumps' index (`index`: a DumpSet or lammps.DumpIndex) and
    `step(index, timestep, progress)`, the format's reader of one timestep (None: the last frame). Other
    attributes are the index's."""

    index: object
    step: Callable

    @property
    def frames(self) -> list:
        return self.index.frames

    @property
    def warnings(self) -> list:
        return self.index.warnings

    def read(self, frame, request, progress=None):
        return self.step(self.index, frame, progress)

    def __getattr__(self, name):
        if name.startswith("__") or "index" not in self.__dict__:
            raise AttributeError(name)
        return getattr(self.index, name)
