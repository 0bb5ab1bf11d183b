"""The public entry points: render a scene with a technique, get a Frame."""

from __future__ import annotations

from . import device as dev
from .pipeline import Frame, SettingsError, resolve_settings
from .scene import load_scene


def techniques() -> list[str]:
    from .techniques import TECHNIQUES

    return sorted(TECHNIQUES)


def render(scene, technique: str = "reference", device: str | None = None, progress: bool = False, **settings) -> Frame:
    """Render ``scene`` (a Scene, a .toml path, a built-in name or a dict) with ``technique``.

    Settings are the technique's (``warpvol.techniques.TECHNIQUES[name].SETTINGS``); an
    unknown name or an out-of-range value raises before anything runs.
    """
    from .techniques import TECHNIQUES

    if technique not in TECHNIQUES:
        raise SettingsError(f"unknown technique {technique!r} (allowed: {', '.join(sorted(TECHNIQUES))})")
    module = TECHNIQUES[technique]
    resolved = resolve_settings(technique, module.SETTINGS, settings)
    scene = load_scene(scene)
    device = dev.pick(device)
    image, timings = module.render(scene, device, resolved, progress)
    return Frame(image=image, technique=technique, device=device, settings=resolved, timings=timings)
