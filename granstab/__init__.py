"""granstab: stability, bifurcation and softening of granular clusters after Kuhn & Chang.

Public API (each function's docstring gives its parameters and array shapes; N particles, M contacts, n_dof dofs)::

    scene = granstab.load_scene("presets/two_particle.toml")   # a scene file or a snapshot → Scene
    loaded = granstab.load("dump/")                            # loaded.scene + loaded.report (import warnings)
    granstab.save_scene(scene, "scene.npz")                    # .json or .npz; scene_to_dict / scene_from_dict
    scene = granstab.build_scene(2, names, x, arrays)          # from arrays (see Scene for the fields)
    K = granstab.stiffness(scene, mask=None, sparse=False)     # K.H = K.Hg1 + K.Hg2 + K.Hg3 + K.Hm, (n_dof, n_dof)
    result = granstab.analyze(scene)                           # branches, verdicts, errors, timings
    granstab.analyze(scene, metric="inertia")                 # one projection metric (default: the family)
    result.to_dict()                                           # the `granstab analyze --json` object
    granstab.second_order_work(result, motion)                 # dUᵀ𝓗dU of a motion (n_dof,)
    granstab.load_response(result, load_increment)             # ℍ^i dU = d𝕓 on every branch: Type-1 non-uniqueness
    m = granstab.moduli(periodic_scene)                        # C (d,d,d,d), stress, bulk, shear, branches, verdicts

The notation and the paper's equations: docs/equations.md.
"""
import sys

_program_hook = sys.excepthook


def _interrupted_while_starting(kind, value, tb):
    """A Ctrl-C that ends the program while granstab's modules load (a command's first second, before cli.main can
    answer it): one line and exit 130, as cli.main says it later, not a traceback of imports. Any other uncaught
    exception goes to the hook that was there."""
    frames, at = [], tb
    while at is not None:
        frames.append(at.tb_frame.f_code)
        at = at.tb_next
    if issubclass(kind, KeyboardInterrupt) and any(c.co_name == "<module>" and c.co_filename.startswith(__path__[0])
                                                   for c in frames):
        print("granstab: interrupted (Ctrl-C) while starting; nothing was done", file=sys.stderr, flush=True)
        import os
        os._exit(130)
    _program_hook(kind, value, tb)


sys.excepthook = _interrupted_while_starting     # only while granstab's modules load: restored below
from .analysis import Analysis, analyze  # noqa: E402 (the hook first)
from .io import Loaded, load, load_scene  # noqa: E402 (the hook first)
from .io.scenes import save_scene, scene_from_dict, scene_to_dict  # noqa: E402 (the hook first)
from .mechanics.stiffness import Stiffness, stiffness  # noqa: E402 (the hook first)
from .mechanics.verdicts import load_response, second_order_work  # noqa: E402 (the hook first)
from .model.scene import Scene, SceneError, build_scene  # noqa: E402 (the hook first)
from .model.tolerances import Tolerances  # noqa: E402 (the hook first)
from .moduli import CellBranch, Moduli, moduli  # noqa: E402 (the hook first)

sys.excepthook = _program_hook     # loaded: the program's own hook again

__all__ = ["Analysis", "CellBranch", "Loaded", "Moduli", "Scene", "SceneError", "Stiffness", "Tolerances", "analyze", "build_scene", "load",
           "load_response", "load_scene", "moduli", "save_scene", "scene_from_dict", "scene_to_dict", "second_order_work", "stiffness"]
