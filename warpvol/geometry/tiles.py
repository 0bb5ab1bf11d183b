"""Spheres listed in the pixel tiles they may cover (``bin_spheres``), each tile's list sorted near
to far: a pixel composites its tile's list front to back (depth_impostors' blocks and particles,
illumination_network's splat), without a pass over every sphere per pixel."""

from __future__ import annotations

import warp as wp

from .. import device as dev
from .camera import RasterView, view_ray_at

dev.kernel_module(__name__)

# pixels per side of the tiles spheres are listed in (bin_spheres): 16 lists sprites a few pixels
# across in 4x the pixels they cover; 4 sorts more pairs than it saves
SPHERE_TILE = wp.constant(8)


SPLAT_DEPTH = wp.constant(wp.int64(1 << 31))  # depth quantisation of a (tile, depth) sort key


@wp.struct
class TileLists:
    """Spheres sorted by screen tile, then depth: tile k's are values[first[k]:last[k]]."""
    values: wp.array(dtype=int)
    first: wp.array(dtype=int)
    last: wp.array(dtype=int)
    tiles_x: int


@wp.func
def sphere_extent(xc: float, z: float, r: float):
    """Tangent slopes (x / z) bounding a circle of radius r at (xc, z), z > r."""
    root = wp.sqrt(wp.max(xc * xc + z * z - r * r, 0.0))
    den = z * z - r * r
    return (xc * z - r * root) / den, (xc * z + r * root) / den


@wp.kernel
def tile_cones(offset: int, cam: RasterView, tiles_x: int, cones: wp.array(dtype=wp.vec4)):
    """Per SPHERE_TILE tile: the cone about its centre ray through its corners, which holds
    the tile's rays, as (unit axis, cos of its half angle widened by 1e-4 rad for rounding)."""
    k = wp.tid() + offset
    x0 = float((k % tiles_x) * SPHERE_TILE)
    y0 = float((k / tiles_x) * SPHERE_TILE)
    s = float(SPHERE_TILE)
    o, axis = view_ray_at(cam, x0 + 0.5 * s, y0 + 0.5 * s)
    o, c00 = view_ray_at(cam, x0, y0)
    o, c10 = view_ray_at(cam, x0 + s, y0)
    o, c01 = view_ray_at(cam, x0, y0 + s)
    o, c11 = view_ray_at(cam, x0 + s, y0 + s)
    cos_half = wp.min(wp.min(wp.dot(axis, c00), wp.dot(axis, c10)), wp.min(wp.dot(axis, c01), wp.dot(axis, c11)))
    half = wp.acos(wp.clamp(cos_half, -1.0, 1.0)) + 1.0e-4
    cones[k] = wp.vec4(axis[0], axis[1], axis[2], wp.cos(wp.min(half, 3.14159265)))


@wp.func
def tile_meets_sphere(cone: wp.vec4, rel: wp.vec3, dist: float, sin_b: float, cos_b: float) -> bool:
    """Whether a sphere at ``rel`` from the eye (``dist`` = |rel| > its radius r, sin_b = r /
    dist, cos_b its angular radius's cosine) meets a tile's cone (``tile_cones``): the angle
    between the cone's axis and the centre is at most the cone's half angle h plus the
    sphere's angular radius b, cos(angle) >= cos(h + b). It cuts the corners of a sphere's
    tile rectangle, which its projection misses. cos_b < 0 (the eye inside the sphere): every
    tile."""
    if cos_b < 0.0:
        return True
    cos_h = cone[3]
    sin_h = wp.sqrt(wp.max(1.0 - cos_h * cos_h, 0.0))
    cos_a = (rel[0] * cone[0] + rel[1] * cone[1] + rel[2] * cone[2]) / dist
    return cos_a >= cos_h * cos_b - sin_h * sin_b


@wp.func
def sphere_seen_from(rel: wp.vec3, r: float):
    """|rel|, r / |rel| and the cosine of asin(r / |rel|) for ``tile_meets_sphere``; inside the
    sphere (|rel| <= r) cos_b = -1: it meets every tile."""
    dist = wp.length(rel)
    if dist <= r:
        return wp.max(dist, 1.0e-30), 0.0, -1.0
    sin_b = r / dist
    return dist, sin_b, wp.sqrt(wp.max(1.0 - sin_b * sin_b, 0.0))


@wp.struct
class Spheres:
    """The spheres to bin: centres and radii."""

    centres: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=float)


@wp.kernel
def sphere_tile_rect(offset: int, cam: RasterView, spheres: Spheres, tiles_x: int, tiles_y: int,
                     cones: wp.array(dtype=wp.vec4), rect: wp.array(dtype=wp.vec4i), count: wp.array(dtype=int)):
    """Tiles [x0, x1) x [y0, y1) sphere p's projection may touch (a perspective camera view), and how
    many of them ``tile_meets_sphere``."""
    p = wp.tid() + offset
    kx = wp.length(cam.right)
    ky = wp.length(cam.up)
    rel = spheres.centres[p] - cam.origin
    z = wp.dot(rel, cam.fwd)
    r = spheres.radius[p]
    x0 = int(0)
    x1 = tiles_x
    y0 = int(0)
    y1 = tiles_y
    if z <= r:
        if z < -r:  # wholly behind the eye
            x1 = 0
    else:
        ax, bx = sphere_extent(wp.dot(rel, cam.right) / kx, z, r)
        ay, by = sphere_extent(wp.dot(rel, cam.up) / ky, z, r)
        # slopes to pixels: px = (s / k + 1) W / 2, py = (1 - s / k) H / 2
        w = float(cam.width)
        h = float(cam.height)
        x0 = wp.clamp(int(wp.floor((ax / kx + 1.0) * 0.5 * w / float(SPHERE_TILE))), 0, tiles_x)
        x1 = wp.clamp(int(wp.floor((bx / kx + 1.0) * 0.5 * w / float(SPHERE_TILE))) + 1, 0, tiles_x)
        y0 = wp.clamp(int(wp.floor((1.0 - by / ky) * 0.5 * h / float(SPHERE_TILE))), 0, tiles_y)
        y1 = wp.clamp(int(wp.floor((1.0 - ay / ky) * 0.5 * h / float(SPHERE_TILE))) + 1, 0, tiles_y)
    rect[p] = wp.vec4i(x0, x1, y0, y1)
    n = int(0)
    dist, sin_b, cos_b = sphere_seen_from(rel, r)
    for ty in range(y0, y1):
        for tx in range(x0, x1):
            if tile_meets_sphere(cones[ty * tiles_x + tx], rel, dist, sin_b, cos_b):
                n += 1
    count[p] = n


@wp.kernel
def sphere_tile_pairs(offset: int, cam: RasterView, spheres: Spheres, cones: wp.array(dtype=wp.vec4),
                      rect: wp.array(dtype=wp.vec4i), start: wp.array(dtype=int), tiles_x: int, z_far: float,
                      keys: wp.array(dtype=wp.int64), values: wp.array(dtype=int)):
    """Key tile << 32 | depth for every (tile, sphere) pair of sphere p: the tiles of its
    rectangle that ``tile_meets_sphere``, as ``sphere_tile_rect`` counted them."""
    p = wp.tid() + offset
    b = rect[p]
    rel = spheres.centres[p] - cam.origin
    dist, sin_b, cos_b = sphere_seen_from(rel, spheres.radius[p])
    depth = wp.clamp(wp.dot(rel, cam.fwd) / z_far, 0.0, 1.0)
    q = wp.int64(depth * float(SPLAT_DEPTH - wp.int64(1)))
    k = start[p]
    for ty in range(b[2], b[3]):
        for tx in range(b[0], b[1]):
            if tile_meets_sphere(cones[ty * tiles_x + tx], rel, dist, sin_b, cos_b):
                keys[k] = wp.int64(ty * tiles_x + tx) * SPLAT_DEPTH * wp.int64(2) + q
                values[k] = p
                k += 1


@wp.kernel
def tile_ranges(offset: int, keys: wp.array(dtype=wp.int64), total: int, first: wp.array(dtype=int),
                last: wp.array(dtype=int)):
    k = wp.tid() + offset
    tile = int(keys[k] / (SPLAT_DEPTH * wp.int64(2)))
    if k == 0:
        first[tile] = 0
    elif int(keys[k - 1] / (SPLAT_DEPTH * wp.int64(2))) != tile:
        first[tile] = k
    if k == total - 1:
        last[tile] = total
    elif int(keys[k + 1] / (SPLAT_DEPTH * wp.int64(2))) != tile:
        last[tile] = k + 1


@wp.func
def pixel_tile(cam: RasterView, tid: int, tiles_x: int) -> int:
    """The index of pixel ``tid``'s tile."""
    return ((tid / cam.width) / SPHERE_TILE) * tiles_x + (tid % cam.width) / SPHERE_TILE


def bin_spheres(cam: RasterView, centres: wp.array, radius: wp.array, z_far: float, device) -> TileLists:
    """Every sphere (centre, radius) listed in the SPHERE_TILE x SPHERE_TILE pixel tiles its projection may
    touch, each tile's list sorted near to far by centre depth (one radix sort of (tile,
    depth) keys): a pixel composites its tile's list front to back. ``z_far`` bounds the
    depths (the quantisation's range)."""
    W, H = cam.width, cam.height
    tx, ty = -(-W // SPHERE_TILE), -(-H // SPHERE_TILE)
    tl = TileLists()
    tl.first = wp.zeros(tx * ty, dtype=int, device=device)
    tl.last = wp.zeros(tx * ty, dtype=int, device=device)
    tl.values = wp.zeros(1, dtype=int, device=device)
    tl.tiles_x = tx
    n = centres.shape[0]
    if not n:
        return tl
    cones = wp.empty(tx * ty, dtype=wp.vec4, device=device)
    dev.launch(tile_cones, tx * ty, [cam, tx, cones], device)
    rect = wp.empty(n, dtype=wp.vec4i, device=device)
    count = wp.empty(n, dtype=int, device=device)
    spheres = Spheres()
    spheres.centres, spheres.radius = centres, radius
    dev.launch(sphere_tile_rect, n, [cam, spheres, tx, ty, cones, rect, count], device, min_split=4096)
    start = wp.empty(n, dtype=int, device=device)
    wp.utils.array_scan(count, start, inclusive=False)
    total = int(start.numpy()[-1] + count.numpy()[-1])
    if total:
        keys = wp.empty(2 * total, dtype=wp.int64, device=device)
        tl.values = wp.empty(2 * total, dtype=int, device=device)
        dev.launch(sphere_tile_pairs, n, [cam, spheres, cones, rect, start, tx, z_far, keys, tl.values], device,
                   min_split=4096)
        wp.utils.radix_sort_pairs(keys, tl.values, total)
        dev.launch(tile_ranges, total, [keys, total, tl.first, tl.last], device)
    return tl
