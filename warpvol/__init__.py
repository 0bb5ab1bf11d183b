"""warpvol: participating media rendered with NVIDIA Warp kernels.

    import warpvol as wv
    frame = wv.render("fog-box", technique="reference", spp=64)
    wv.save_image("fog.exr", frame.image)

    r = wv.Renderer("smoke-grid", technique="raymarch", shadow_grid=32)
    r.render(); r.update(lights=[...]); frame = r.render()   # re-runs only what the lights feed
"""

import warp as _wp

_wp.config.log_level = _wp.LOG_WARNING  # no init banner, no "Module ... load" lines (device.set_verbose)

from .animation import Animation, animate, save_animation  # noqa: E402
from .api import Renderer, render, technique_class, technique_names  # noqa: E402
from .image import load_image, save_image  # noqa: E402
from .media.grid import save_volume  # noqa: E402
from .metrics import hdr_flip, relative_rmse, rmse  # noqa: E402
from .pipeline import Frame, SettingsError  # noqa: E402
from .scene import Scene, SceneError, load_scene  # noqa: E402
from .upload import extinction_volume  # noqa: E402

__version__ = "0.1.0"

__all__ = ["Animation", "Frame", "Renderer", "animate", "save_animation", "Scene", "SceneError", "SettingsError", "extinction_volume", "hdr_flip", "load_image", "load_scene", "relative_rmse", "render", "rmse", "save_image", "save_volume", "technique_class", "technique_names"]
