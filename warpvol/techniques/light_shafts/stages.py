"""The light shafts' stage graph on the host: which stages run, in what order, what each reads and
when each is skipped, and what the stages share (the scene's uploads, the multiple-scattering
lattice, the light-depth volume, the shadow maps and the buffers). The stages that launch the
technique's own kernels are ``LightShafts``' methods, beside those kernels in
``warpvol.techniques.light_shafts``."""

from __future__ import annotations

from ...pipeline import Stage, Technique
from ...scattering import MultipleScattering
from ...scattering import check_settings as check_ms_settings
from ...scattering import leaves_out as ms_leaves_out
from ...scene.model import MediumKind
from ...shading import LightDepthVolume
from ...upload import SceneUploads
from .buffers import ShaftBuffers, tiled
from .shadows import ShadowMaps


class ShaftStages(Technique):
    """The base of ``LightShafts``: its stages, and the ``shadow_maps`` stage (the maps are drawn by
    ``geometry.shadowmap``). A subclass runs ``visible``, ``surface``, ``march`` and the block sums."""

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        self.uploads = SceneUploads(self)
        self.multiple = MultipleScattering.over(self, self.uploads)
        self.light_volume = LightDepthVolume(self, lambda: self.uploads.media.struct, lambda: self.uploads.lights)
        self.shadows = ShadowMaps(self, self.light_volume)
        self.buffers = ShaftBuffers(device)
        self.segs = self.face = self.t_hit = self.radiance = self.terms = self.rows = self.image = None

    def check_settings(self, settings):
        check_ms_settings(self.NAME, settings)

    def leaves_out(self) -> list[str]:
        return [*ms_leaves_out(self.settings), *super().leaves_out()]

    def diagnostics(self) -> dict:
        return {**self.multiple.diagnostics(), **self.uploads.diagnostics()}

    def effective_block(self) -> int:
        """M, limited to the image so a window always holds all M^2 residue classes."""
        cam = self.scene.camera
        return max(1, min(self.settings["block"], cam.width, cam.height))

    def stages(self):
        scene = self.scene
        occluders = bool(scene.surfaces)
        interleaved = self.effective_block() > 1 and self.settings["scattering"] == 1 and bool(scene.media)
        depth_aware = self.settings["edges"] == 1 and occluders  # depth comes from the surface pass
        return self.uploads.stages() + [
            Stage("shadow_maps", self._shadow_maps, reads=("lights",),
                  settings=("shadow_map_res", "depth_bias", "raster", "raster_tiles"),
                  after=("surfaces", "lights"), needed=occluders and bool(scene.lights)),
            Stage("visible", self._visible, reads=("camera",), settings=("raster", "raster_tiles"),
                  after=("medium", "surfaces")),
            *self.multiple.stages(after=("medium", "surfaces", "lights")),
            self.light_volume.stage(),
            Stage("surface", self._surface, reads=("camera", "background"),
                  settings=("shadow_steps", "steps", "multiple_scattering", "shadow_grid"),
                  after=("medium", "surfaces", "lights", "shadow_maps", "visible", "multiple_view", "light_volume"),
                  needed=occluders),
            Stage("march", self._march, reads=("camera", "background"),
                  settings=("steps", "block", "jitter", "scattering", "shadow_steps", "seed", "spacing",
                            "multiple_scattering", "light_ball", "shadow_grid", "edges", "edge_tolerance"),
                  after=("medium", "lights", "shadow_maps", "visible", "surface", "multiple_view", "light_volume")),
            Stage("block_rows", self._block_rows, settings=("block",), after=("march",),
                  needed=interleaved and not depth_aware),
            Stage("block_cols", self._block_cols, settings=("block",), after=("block_rows",),
                  needed=interleaved and not depth_aware),
            Stage("block_edges", self._block_edges, settings=("block", "edge_tolerance"), after=("march",),
                  needed=interleaved and depth_aware),
        ]

    def _shadow_maps(self):
        if self.settings["raster"]:
            points, indices, _ = self.buffers.raster_mesh(self.scene, self.uploads._surfaces)
            self.shadows.render((points, indices), tiled(self.settings["raster_tiles"], self.device))
        else:
            self.shadows.render()

    def _view_samples(self) -> int:
        """Density samples along a pixel's view ray: one a step in heterogeneous media (their
        optical depth is marched), none where every medium has a closed form."""
        return self.settings["steps"] if any(m.type != MediumKind.HOMOGENEOUS for m in self.scene.media) else 0

    def output(self):
        return self.image
