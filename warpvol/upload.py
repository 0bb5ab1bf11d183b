"""The first stages of every technique: scene parts copied to the device.

``SceneUploads`` owns the ``Media``, ``Surfaces`` and ``Light`` buffers and declares one
stage per part, so a change to the lights re-uploads the lights and nothing else, and a
scene without surfaces skips building a BVH.
"""

from __future__ import annotations

from .geometry.mesh import SurfaceBuffers
from .media.volume import MediaBuffers
from .pipeline import Stage, Technique
from .shading import light_array


class SceneUploads:
    """Device copies of a technique's scene: ``media``, ``surfaces`` and ``lights``."""

    def __init__(self, technique: Technique, medium: bool = True):
        self.t = technique
        self._medium = medium  # False: the technique builds its own view of the media
        self.media: MediaBuffers | None = None
        self.lights = None
        self._surfaces: SurfaceBuffers | None = None
        self._no_surfaces: SurfaceBuffers | None = None

    def stages(self) -> list[Stage]:
        return [Stage("medium", self._upload_medium, reads=("medium",))] * self._medium + [
            Stage("surfaces", self._upload_surfaces, reads=("surfaces",), needed=bool(self.t.scene.surfaces)),
            Stage("lights", self._upload_lights, reads=("lights",)),
        ]

    @property
    def surfaces(self):
        """The ``Surfaces`` struct; an empty one when the scene has no surfaces."""
        if self.t.scene.surfaces:
            return self._surfaces.struct
        if self._no_surfaces is None:
            self._no_surfaces = SurfaceBuffers(self.t.scene, self.t.device)
        return self._no_surfaces.struct

    def _upload_medium(self):
        self.media = MediaBuffers(self.t.scene, self.t.device)

    def _upload_surfaces(self):
        self._surfaces = SurfaceBuffers(self.t.scene, self.t.device)

    def _upload_lights(self):
        self.lights = light_array(self.t.scene, self.t.device)
