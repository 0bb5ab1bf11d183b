"""The light shafts' device arrays on the host side: the intermediate arrays kept from frame to
frame, the placeholders a kernel reads where a pass was skipped, and the triangles the
rasteriser takes (the surfaces split so that no edge is longer than 1/32 of the scene's
diagonal, ``geometry.raster.split_long_edges``)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ...geometry.raster import NO_HIT, split_long_edges
from ...upload import scene_bounds


def tiled(mode: int, device) -> bool:
    """Whether the rasteriser takes 16 x 16-pixel pieces of triangles (``raster_tiles`` = 1, or
    -1 on CUDA) rather than whole triangles."""
    return mode == 1 or (mode == -1 and str(device).startswith("cuda"))


class ShaftBuffers:
    """Arrays the stages share, on one device."""

    def __init__(self, device):
        self.device = device
        self.no_keys = wp.full(1, NO_HIT, dtype=wp.int64, device=device)  # "ray cast instead"
        self.no_index = wp.full(1, -1, dtype=int, device=device)
        self.no_points = wp.zeros(1, dtype=wp.vec3, device=device)
        self._arrays = {}
        self._raster_source = self._raster_mesh = None

    def scratch(self, name: str, n: int, dtype, fill=None):
        """An intermediate array kept from frame to frame (allocating and first touching ~6 MB per
        frame costs milliseconds on the CPU); ``fill`` resets it."""
        arr = self._arrays.get(name)
        if arr is None or arr.shape[0] != n:
            arr = self._arrays[name] = wp.empty(n, dtype=dtype, device=self.device)
        if fill is not None:
            arr.fill_(fill)
        return arr

    def raster_mesh(self, scene, buffers):
        """(points, indices, face of each triangle) of the triangles the rasteriser takes: the
        surfaces ``buffers`` (``upload.SurfaceBuffers``) with no edge longer than 1/32 of the
        scene's diagonal (``split_long_edges``), rebuilt when the surfaces are uploaded again."""
        if self._raster_source is not buffers:
            lo, hi = scene_bounds(scene)
            pts, parent = split_long_edges(buffers.mesh.points.numpy(), buffers.mesh.indices.numpy(),
                                           float(np.linalg.norm(hi - lo)) / 32.0)
            self._raster_mesh = (wp.array(pts, dtype=wp.vec3, device=self.device),
                                 wp.array(np.arange(len(pts), dtype=np.int32), dtype=int, device=self.device),
                                 wp.array(parent, dtype=int, device=self.device))
            self._raster_source = buffers
        return self._raster_mesh
