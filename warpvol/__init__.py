"""warpvol: participating media rendered with NVIDIA Warp kernels.

    import warpvol as wv
    frame = wv.render("fog-box", technique="reference", spp=64)
    wv.save_image("fog.exr", frame.image)
"""

import warp as _wp

_wp.config.quiet = True  # before any struct or kernel initialises Warp

from .api import render, techniques  # noqa: E402
from .image import load_image, save_image  # noqa: E402
from .pipeline import Frame, SettingsError  # noqa: E402
from .scene import Scene, SceneError, load_scene  # noqa: E402

__version__ = "0.1.0"

__all__ = ["Frame", "Scene", "SceneError", "SettingsError", "load_image", "load_scene", "render", "save_image", "techniques"]
