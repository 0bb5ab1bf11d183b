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


@wp.func
def camera_ray(cam: PinholeCamera, px: float, py: float) -> wp.vec3:
    """Unit direction through image position (px, py) in pixels; row 0 is the top."""
    sx = 2.0 * px / float(cam.width) - 1.0
    sy = 1.0 - 2.0 * py / float(cam.height)
    return wp.normalize(cam.forward + sx * cam.right + sy * cam.up)


def camera_view(cam: PinholeCamera) -> RasterView:
    """The camera's image as a raster view: pixel (i, j)'s ray is ``camera_ray`` at its centre."""
    v = RasterView()
    v.origin, v.fwd, v.right, v.up = cam.origin, cam.forward, cam.right, cam.up
    v.ortho, v.y_down, v.width, v.height, v.base = 0, 1, cam.width, cam.height, 0
    return v
