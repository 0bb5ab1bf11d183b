"""A technique bound to a scene and kept between frames (``Renderer``), and the techniques by name."""

from __future__ import annotations

import dataclasses

from . import device as dev
from .names import did_you_mean
from .pipeline import PARTS, Frame, Pipeline, SettingsError, resolve_settings
from .scene import load_scene
from .scene.load import parse_part


def technique_names() -> list[str]:
    from .techniques import TECHNIQUES

    return sorted(TECHNIQUES)


def technique_class(name: str):
    """The technique called ``name`` (its ``SETTINGS``, ``QUALITY``, ``LEAVES_OUT``); an unknown
    name raises SettingsError with the allowed ones."""
    from .techniques import TECHNIQUES

    if name not in TECHNIQUES:
        raise SettingsError(f"unknown technique {name!r}{did_you_mean(name, TECHNIQUES)} "
                            f"(allowed: {', '.join(sorted(TECHNIQUES))}, or auto with target_error)")
    return TECHNIQUES[name]


class Renderer:
    """A technique bound to a scene, kept between frames.

    >>> r = Renderer("point-in-fog", technique="raymarch", shadow_grid=32)
    >>> r.render().stages["light_volume"].status
    'ran'
    >>> r.update(camera=dict(origin=[0, 0, 5], target=[0, 0, 0]))
    >>> r.render().stages["light_volume"].status      # the camera does not move the light
    'cached'

    ``scene`` is a Scene, a .toml path, a built-in name or a dict; settings are the
    technique's (``warpvol.techniques.TECHNIQUES[name].SETTINGS``). Bad names and values
    raise before anything runs. ``one_shot``: each frame is to be a finished one, so an
    iterative technique (illumination_network) runs to convergence instead of the paper's
    per-frame iterations.
    """

    def __init__(self, scene, technique: str = "reference", device: str | None = None, progress: bool = False,
                 *, one_shot: bool = False, overrides: list[str] | dict | None = None, **settings):
        cls = technique_class(technique)
        resolved = resolve_settings(technique, cls.SETTINGS, settings)
        self._technique = cls(load_scene(scene, overrides), dev.pick(device), resolved, progress)
        self._technique.one_shot = bool(one_shot)
        self._pipeline = Pipeline(self._technique)
        dev.scratch_user(self)  # the CPU launches' per-core scratch is freed with the last Renderer

    @property
    def scene(self):
        return self._technique.scene

    @property
    def technique(self):
        """The technique object, for its own state (e.g. an iteration's history)."""
        return self._technique

    @property
    def settings(self) -> dict:
        return dict(self._technique.settings)

    @property
    def device(self) -> str:
        return self._technique.device

    def update(self, *, lights=None, medium=None, camera=None, surfaces=None, background=None,
               settings: dict | None = None) -> None:
        """Replace scene parts or settings and mark them changed.

        ``lights``, ``medium`` and ``surfaces`` take one item or a list (model objects or
        tables as in a scene file), ``camera`` a Camera, or a table of the keys to change
        (``camera=dict(origin=...)`` keeps the size, field of view and the rest),
        ``background`` an RGB triple, ``settings`` a dict of technique settings. Passing the
        scene's own part again (after editing it in place) marks it changed.
        """
        t = self._technique
        if isinstance(camera, dict):
            camera = {**dataclasses.asdict(t.scene.camera), **camera}
        changes, parts = {}, []
        for part, value, field in (("lights", lights, "lights"), ("medium", medium, "media"),
                                   ("surfaces", surfaces, "surfaces"), ("camera", camera, "camera")):
            if value is not None:
                changes[field] = parse_part(part, value)
                parts.append(part)
        if background is not None:
            changes["background"] = tuple(float(v) for v in background)
            parts.append("background")
        if settings:
            resolved = resolve_settings(t.NAME, t.SETTINGS, settings, base=t.settings)
            t.check_settings(resolved)
            t.settings = resolved
        if changes:
            t.scene = dataclasses.replace(t.scene, **changes)
        self._pipeline.changed(*parts)

    def touch(self, *parts: str) -> None:
        """Mark scene parts (``medium``, ``lights``, ``camera``, ``surfaces``, ``background``;
        none named: all of them) changed without replacing them: after an edit in place, or
        to time a full frame."""
        self._pipeline.changed(*(parts or PARTS))

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """The technique's intermediate arrays after the last frame (numpy), e.g. light_shafts'
        shadow-map depth surfaces and lit slice; {} for techniques with none to show.
        ``for_view`` and ``resolution``: see ``Technique.arrays``."""
        return self._technique.arrays(for_view=for_view, resolution=resolution)

    def diagnostics(self) -> dict:
        """The technique's named figures of the last frame (``Technique.diagnostics``)."""
        return self._technique.diagnostics()

    def run_stage(self, name: str) -> float:
        """Run one stage of the technique again after a ``render()``, with its inputs as the last
        frame left them, and return its device-synchronised time in ms: how benchmarks time one
        pass (e.g. light_shafts' ``march``) apart from the frame. The frame's cache is unchanged."""
        return self._pipeline.run_stage(name)

    def render(self) -> Frame:
        """Run the stages the scene calls for and the changes invalidated; return the Frame."""
        t = self._technique
        stages = self._pipeline.run()
        cam = t.scene.camera
        return Frame(t.output(), (cam.height, cam.width), t.NAME, t.device, dict(t.settings), stages, t.leaves_out())


def render_once(scene, technique: str, device: str | None = None, progress: bool = False, **settings) -> Frame:
    """One finished frame at ``settings``: an iterative technique (illumination_network) iterates
    until it converges (a ``Renderer`` runs its per-frame iterations instead)."""
    return Renderer(scene, technique, device, progress, one_shot=True, **settings).render()
