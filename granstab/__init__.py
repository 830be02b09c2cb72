"""granstab: stability, bifurcation and softening of granular clusters after Kuhn & Chang.

Public API::

    scene = granstab.load_scene("presets/two_particle.toml")   # or scene_from_dict / build_scene
    loaded = granstab.load("dump/")                            # scene + validation report (snapshots, scene files)
    K = granstab.stiffness(scene, mask=None, sparse=False)     # H, Hm, Hg1, Hg2, Hg3, dofs
    result = granstab.analyze(scene)                           # branches, verdicts, errors, timings
    granstab.analyze(scene, metric="inertia")                 # one projection metric (default: the family)
    result.to_dict()                                           # the `granstab analyze --json` object
"""
from .analysis import Analysis, analyze
from .io import Loaded, load, load_scene
from .io.scenes import save_scene, scene_from_dict, scene_to_dict
from .mechanics.stiffness import Stiffness, stiffness
from .mechanics.verdicts import load_response, second_order_work
from .model.scene import Scene, SceneError, build_scene
from .model.tolerances import Tolerances

__all__ = ["Analysis", "Loaded", "Scene", "SceneError", "Stiffness", "Tolerances", "analyze", "build_scene", "load",
           "load_response", "load_scene", "save_scene", "scene_from_dict", "scene_to_dict", "second_order_work", "stiffness"]
