"""Views and their rays: a ``RasterView`` names an image of ``width`` x ``height`` pixels seen from
one point (a pinhole camera, a shadow-map face) or along one direction (an orthographic map).
Pixel (i, j) has image coordinates sx = 2 (i + 1/2) / width - 1 and sy = 2 (j + 1/2) / height - 1
(negated when ``y_down``: row 0 at the top, as in camera images). Its ray is

* perspective: from ``origin`` along normalize(fwd + sx right + sy up);
* orthographic: from origin + sx right + sy up along fwd,

with ``right`` and ``up`` scaled to the half extent of the image (so fwd, right and up are
orthogonal, fwd a unit vector). ``view_ray`` is the one definition of a pixel's ray: camera rays,
shadow-map texel rays and the rasteriser's (geometry/raster.py) are all made by it.
"""

import warp as wp

from .. import device as dev

dev.kernel_module(__name__)


@wp.struct
class RasterView:
    origin: wp.vec3
    fwd: wp.vec3  # unit
    right: wp.vec3  # half width of the image (at unit depth for perspective views)
    up: wp.vec3  # half height
    ortho: int
    y_down: int  # 1: row 0 at the top
    width: int
    height: int
    base: int  # index of pixel (0, 0) in the output array


@wp.func
def image_coords_at(v: RasterView, x: float, y: float):
    """(sx, sy) in [-1, 1]^2 of image position (x, y) in pixels: pixel (i, j) covers
    [i, i + 1) x [j, j + 1), its centre is (i + 1/2, j + 1/2)."""
    sx = 2.0 * x / float(v.width) - 1.0
    sy = 2.0 * y / float(v.height) - 1.0
    if v.y_down == 1:
        sy = 1.0 - 2.0 * y / float(v.height)
    return sx, sy


@wp.func
def image_coords(v: RasterView, i: int, j: int):
    """(sx, sy) in [-1, 1]^2 of the centre of pixel (i, j)."""
    return image_coords_at(v, float(i) + 0.5, float(j) + 0.5)


@wp.func
def view_ray_at(v: RasterView, x: float, y: float):
    """(origin, unit direction) of the ray through image position (x, y) in pixels (sub-pixel
    positions: jittered samples)."""
    sx, sy = image_coords_at(v, x, y)
    if v.ortho == 1:
        return v.origin + sx * v.right + sy * v.up, v.fwd
    return v.origin, wp.normalize(v.fwd + sx * v.right + sy * v.up)


@wp.func
def view_ray(v: RasterView, i: int, j: int):
    """(origin, unit direction) of the ray through the centre of pixel (i, j)."""
    return view_ray_at(v, float(i) + 0.5, float(j) + 0.5)


@wp.func
def pixel_ray(v: RasterView, p: int):
    """``view_ray`` of pixel p = j width + i of the image (row by row)."""
    return view_ray(v, p % v.width, p / v.width)


@wp.func
def view_depth(v: RasterView, p: wp.vec3) -> float:
    return wp.dot(p - v.origin, v.fwd)


@wp.func
def image_point(v: RasterView, p: wp.vec3) -> wp.vec2:
    """Where p lands in pixel units (the centre of pixel (i, j) at (i, j)); p in front of the view."""
    q = p - v.origin
    sx = wp.dot(q, v.right) / wp.dot(v.right, v.right)
    sy = wp.dot(q, v.up) / wp.dot(v.up, v.up)
    if v.ortho == 0:
        z = wp.dot(q, v.fwd)
        sx = sx / z
        sy = sy / z
    if v.y_down == 1:
        sy = -sy
    # clamped well outside the image, so far points (and ones on the clip plane) stay finite ints
    return wp.vec2(wp.clamp((sx + 1.0) * 0.5 * float(v.width) - 0.5, -2.0, float(v.width) + 1.0),
                   wp.clamp((sy + 1.0) * 0.5 * float(v.height) - 0.5, -2.0, float(v.height) + 1.0))




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
    pixel's ray is ``view_ray`` / ``pixel_ray`` / ``view_ray_at``."""
    v = RasterView()
    v.origin, v.fwd, v.right, v.up = cam.origin, cam.forward, cam.right, cam.up
    v.ortho, v.y_down, v.width, v.height, v.base = 0, 1, cam.width, cam.height, 0
    return v
