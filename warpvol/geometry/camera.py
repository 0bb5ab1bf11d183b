"""Pinhole camera: look_at, vertical field of view, rays through pixel positions."""

import warp as wp

from .raster import RasterView


@wp.struct
class PinholeCamera:
    origin: wp.vec3
    forward: wp.vec3  # unit
    right: wp.vec3  # scaled by tan(fov_y / 2) * aspect
    up: wp.vec3  # scaled by tan(fov_y / 2)
    width: int
    height: int


def camera_view(cam: PinholeCamera) -> RasterView:
    """The camera's image as a raster view (row 0 at the top): what kernels take, so that a
    pixel's ray is ``view_ray`` / ``pixel_ray`` / ``view_ray_at`` (geometry/raster.py)."""
    v = RasterView()
    v.origin, v.fwd, v.right, v.up = cam.origin, cam.forward, cam.right, cam.up
    v.ortho, v.y_down, v.width, v.height, v.base = 0, 1, cam.width, cam.height, 0
    return v
