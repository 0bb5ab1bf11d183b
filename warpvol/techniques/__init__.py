"""One module per technique, each with NAME, SETTINGS and render(scene, device, settings, progress)."""

from . import raymarch, reference

TECHNIQUES = {m.NAME: m for m in (reference, raymarch)}

__all__ = ["TECHNIQUES"]
