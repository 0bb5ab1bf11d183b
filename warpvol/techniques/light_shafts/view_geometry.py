"""The light shafts' camera geometry on the host (NumPy): the rasteriser's far distance, a
pixel's width, and the plane the lit slice (``LightShafts.arrays``) is sampled on."""

from __future__ import annotations

import math

import numpy as np

from ...upload import scene_bounds


def far_distance(scene) -> float:
    """The distance from the camera to the farthest corner of the scene's bounds: nothing the
    rasteriser draws lies beyond it."""
    lo, hi = scene_bounds(scene)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return float(np.max(np.linalg.norm(corners - np.asarray(scene.camera.origin, float), axis=1)))


def pixel_width(cam) -> float:
    """A pixel's width per unit distance from the camera."""
    return 2.0 * math.tan(math.radians(cam.fov_y) / 2.0) / cam.height


def slice_plane(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(corner, edge_u, edge_v, view): the square through the camera's target facing the camera,
    as wide as the scene's bounds are at their widest, and the camera's unit viewing direction."""
    cam = scene.camera
    target, origin = np.asarray(cam.target, float), np.asarray(cam.origin, float)
    view = (target - origin) / np.linalg.norm(target - origin)
    right = np.cross(view, cam.up)
    right /= np.linalg.norm(right)
    lo, hi = scene_bounds(scene)
    half = 0.5 * float(np.max(hi - lo))
    up = np.asarray(cam.up, float) / np.linalg.norm(cam.up)
    corner = target - half * right - half * up
    return corner, 2 * half * right, 2 * half * up, view
