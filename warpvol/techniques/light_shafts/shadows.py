"""The light shafts' shadow maps on the host side: one map per light (cube map for point lights,
perspective for spot, orthographic for directional), rendered by ``geometry.shadowmap`` from
the rasteriser's triangles or by casting rays through the surfaces' BVH, and the
``ShadowedLights`` struct the kernels read them through."""

from __future__ import annotations

import warp as wp

from ...geometry.shadowmap import ShadowedLights, ShadowMap, shadow_map_depths
from ...physics.constants import INF
from ...upload import shadow_map_structs


class ShadowMaps:
    """A technique's shadow maps (``maps``, the texels' distances in ``depth``); its settings
    ``shadow_map_res`` and ``depth_bias`` size and offset them."""

    def __init__(self, technique, light_volume):
        self.t = technique
        self.light_volume = light_volume
        self.maps = None
        self.depth = wp.full(1, INF, dtype=float, device=technique.device)

    def structs(self, occluders: bool) -> list[ShadowMap]:
        t = self.t
        return shadow_map_structs(t.scene, t.settings["shadow_map_res"], t.settings["depth_bias"], occluders)

    def render(self, mesh=None, tiled: bool = False):
        """Every light's map, from the rasteriser's triangles ``mesh`` (points, indices) or,
        without, by ray casts through the uploaded surfaces."""
        structs = self.structs(occluders=True)
        if mesh is not None:
            self.depth = shadow_map_depths(structs, self.t.device, *mesh, tiled=tiled)
        else:
            self.depth = shadow_map_depths(structs, self.t.device, surfaces=self.t.uploads.surfaces)
        self.maps = wp.array(structs, dtype=ShadowMap, device=self.t.device)

    def when_skipped(self):
        """Without a shadow pass (no surfaces or no lights) every map says "lit"."""
        scene = self.t.scene
        if not (scene.surfaces and scene.lights):
            self.maps = wp.array(self.structs(occluders=False) or [ShadowMap()], dtype=ShadowMap,
                                 device=self.t.device)

    def lights(self) -> ShadowedLights:
        """The scene's lights with their maps (and the light-depth volume where it is on)."""
        sl = ShadowedLights()
        sl.lights, sl.maps, sl.depth = self.t.uploads.lights, self.maps, self.depth
        return self.light_volume.attach(sl)
