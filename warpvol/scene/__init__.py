"""Scenes: dataclasses, TOML loading with validation, built-in scenes, Mitsuba export."""

from .load import SceneError, apply_overrides, load_scene, scene_from_dict
from .mitsuba import to_mitsuba
from .model import (
    Camera,
    GridMedium,
    HomogeneousMedium,
    Light,
    Medium,
    ParticleMedium,
    Phase,
    RBFMedium,
    Scene,
    Surface,
)
from .procedural import BUILTIN

__all__ = [
    "BUILTIN", "Camera", "GridMedium", "HomogeneousMedium", "Light", "Medium", "ParticleMedium", "Phase",
    "RBFMedium", "Scene", "SceneError", "Surface", "apply_overrides", "load_scene", "scene_from_dict", "to_mitsuba",
]
