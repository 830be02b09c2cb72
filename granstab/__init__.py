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
from .analysis import Analysis, analyze
from .io import Loaded, load, load_scene
from .io.scenes import save_scene, scene_from_dict, scene_to_dict
from .mechanics.stiffness import Stiffness, stiffness
from .mechanics.verdicts import load_response, second_order_work
from .model.scene import Scene, SceneError, build_scene
from .model.tolerances import Tolerances
from .moduli import CellBranch, Moduli, moduli

__all__ = ["Analysis", "CellBranch", "Loaded", "Moduli", "Scene", "SceneError", "Stiffness", "Tolerances", "analyze", "build_scene", "load",
           "load_response", "load_scene", "moduli", "save_scene", "scene_from_dict", "scene_to_dict", "second_order_work", "stiffness"]
