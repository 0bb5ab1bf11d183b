"""Triangle rasterisation for views from one point (pinhole cameras, shadow-map faces) or
along one direction (orthographic maps): the visible surface of every pixel without a BVH.

Every pixel's ray is ``camera.view_ray`` (a ``camera.RasterView``): camera rays and
shadow-map texel rays are both made by it, so the rasteriser finds exactly the surface that a
ray cast through the pixel centre would.

Rasterising a triangle (``triangle_pixels``) bounds the pixels whose centres it can
cover: its vertices are projected, after clipping the triangle to the half-space in front
of a perspective view's origin (a triangle crossing the origin's plane otherwise projects
to an unbounded region). Each pixel of that box then intersects its own ray with the
triangle: the three edge functions (linear in the image coordinates) say whether the ray
passes through it, and its plane gives the distance. The nearest hit is kept with an atomic
minimum, so the result does not depend on the order in which triangles arrive.

One set of kernels rasterises into any list of views (``rasterise``): a camera is one view
(keys of the nearest triangle), a shadow map one or six (``shadowmap.map_view``; depths).
A triangle is tried against every view, first with its bounding sphere (``sphere_outside``:
one point instead of three, as most (triangle, face) pairs of a cube map miss), then with
``triangle_pixels``' own test of its vertices.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import warp as wp

from .. import device as dev
from ..physics.constants import INF
from .camera import RasterView, image_coords, image_point, view_depth

dev.kernel_module(__name__)

NEAR = wp.constant(1.0e-6)  # a perspective view clips triangles to depth > NEAR (scene units)
BOX_SLACK = wp.constant(1.0e-3)  # pixels: a triangle's box is widened by this much for rounding
EDGE_SLACK = wp.constant(1.0e-6)  # barycentric slack: a pixel centre on a shared edge is covered by both
TILE = wp.constant(16)  # pixels per side of the pieces a large triangle is split into (tiled rasterising)


@wp.func
def edge_bounds(v: RasterView, p: wp.vec3, q: wp.vec3, lo: wp.vec2, hi: wp.vec2):
    """Grow the box (lo, hi) by vertex p and, where edge pq crosses the clip plane, by the crossing."""
    zp = view_depth(v, p)
    zq = view_depth(v, q)
    if v.ortho == 1 or zp > NEAR:
        x = image_point(v, p)
        lo = wp.min(lo, x)
        hi = wp.max(hi, x)
    if v.ortho == 0 and (zp > NEAR) != (zq > NEAR):
        x = image_point(v, p + (q - p) * ((NEAR - zp) / (zq - zp)))
        lo = wp.min(lo, x)
        hi = wp.max(hi, x)
    return lo, hi


@wp.func
def outside_sides(v: RasterView, p: wp.vec3, rr: float, uu: float) -> int:
    """Bit mask of the sides of the view's frustum that p lies beyond: left, right, bottom, top,
    and (perspective) behind the clip plane; rr = |right|^2 and uu = |up|^2 (once per view)."""
    q = p - v.origin
    x = wp.dot(q, v.right)  # sx |right|^2 z
    y = wp.dot(q, v.up)
    z = wp.where(v.ortho == 0, wp.dot(q, v.fwd), 1.0)
    zx = rr * z
    zy = uu * z
    # branch-free: most triangles miss most views, and these tests are data-dependent
    mask = wp.where(x < -zx, 1, 0) | wp.where(x > zx, 2, 0) | wp.where(y < -zy, 4, 0) | wp.where(y > zy, 8, 0)
    mask = mask | wp.where(v.ortho == 0 and z <= NEAR, 16, 0)
    return mask


@wp.func
def triangle_pixels(v: RasterView, a: wp.vec3, b: wp.vec3, c: wp.vec3):
    """(i0, j0, i1, j1): the pixels whose centres triangle abc may cover (empty: i0 > i1)."""
    rr = wp.dot(v.right, v.right)
    uu = wp.dot(v.up, v.up)
    if (outside_sides(v, a, rr, uu) & outside_sides(v, b, rr, uu) & outside_sides(v, c, rr, uu)) != 0:
        return 1, 1, 0, 0  # all three beyond one side of the frustum
    lo = wp.vec2(INF)
    hi = wp.vec2(-INF)
    lo, hi = edge_bounds(v, a, b, lo, hi)
    lo, hi = edge_bounds(v, b, c, lo, hi)
    lo, hi = edge_bounds(v, c, a, lo, hi)
    if lo[0] > hi[0]:  # wholly behind a perspective view
        return 1, 1, 0, 0
    # pixel centres inside the box, which is widened by BOX_SLACK pixels for rounding
    i0 = wp.max(int(wp.ceil(lo[0] - BOX_SLACK)), 0)
    j0 = wp.max(int(wp.ceil(lo[1] - BOX_SLACK)), 0)
    i1 = wp.min(int(wp.floor(hi[0] + BOX_SLACK)), v.width - 1)
    j1 = wp.min(int(wp.floor(hi[1] + BOX_SLACK)), v.height - 1)
    return i0, j0, i1, j1


@wp.func
def bounding_sphere(a: wp.vec3, b: wp.vec3, c: wp.vec3):
    """(centre, squared radius) of a sphere holding triangle abc: about a, through the farther of b
    and c (cheaper than the smallest one, and the triangles are small), widened against rounding."""
    return a, 1.002 * wp.max(wp.length_sq(b - a), wp.length_sq(c - a))


@wp.func
def sphere_outside(v: RasterView, m: wp.vec3, r2: float) -> bool:
    """Whether the sphere (centre m, squared radius r2) lies wholly beyond one side of the view's
    frustum, or (perspective) behind its origin: a triangle inside it covers no pixel centre. One
    point against the view instead of ``outside_sides``' three, for a triangle against many views
    (most of which it misses, as five of a cube map's six faces)."""
    q = m - v.origin
    x = wp.abs(wp.dot(q, v.right))
    y = wp.abs(wp.dot(q, v.up))
    rr = wp.dot(v.right, v.right)
    uu = wp.dot(v.up, v.up)
    # a side plane's normal: right - rr fwd (perspective, |n|^2 = rr + rr^2 as right is orthogonal
    # to the unit fwd), right (orthographic, offset rr): the centre beyond it by more than r |n|
    z = float(1.0)
    nx = rr
    ny = uu
    if v.ortho == 0:
        z = wp.dot(q, v.fwd)
        if z < 0.0 and z * z > r2:
            return True
        nx = rr * (1.0 + rr)
        ny = uu * (1.0 + uu)
    dx = x - rr * z
    dy = y - uu * z
    return (dx > 0.0 and dx * dx > r2 * nx) or (dy > 0.0 and dy * dy > r2 * ny)


@wp.func
def triangle_box(v: RasterView, a: wp.vec3, b: wp.vec3, c: wp.vec3, m: wp.vec3, r2: float):
    """``triangle_pixels`` of abc, after the cheaper ``sphere_outside`` test of its bounding sphere
    (m, r2); the same boxes."""
    if sphere_outside(v, m, r2):
        return 1, 1, 0, 0
    return triangle_pixels(v, a, b, c)


@wp.func
def box_tiles(i0: int, j0: int, i1: int, j1: int) -> int:
    """How many TILE x TILE pieces the pixel box [i0, i1] x [j0, j1] splits into (0: empty)."""
    if i0 > i1 or j0 > j1:
        return 0
    return ((i1 - i0) / TILE + 1) * ((j1 - j0) / TILE + 1)


@wp.func
def edge_coeffs(v: RasterView, p: wp.vec3, q: wp.vec3, w: wp.vec3):
    """(c0, c1, c2): the edge function of edge pq, c0 + c1 sx + sy c2, whose sign tells on which
    side of the edge the ray of image point (sx, sy) passes; w is the third vertex."""
    if v.ortho == 1:  # the ray from origin + sx right + sy up along fwd, against the prism over pq
        m = wp.cross(v.fwd, q - p)
        return wp.vec3(wp.dot(v.origin - p, m), wp.dot(v.right, m), wp.dot(v.up, m))
    n = wp.cross(p - v.origin, q - v.origin)  # the plane through the origin and pq
    return wp.vec3(wp.dot(v.fwd, n), wp.dot(v.right, n), wp.dot(v.up, n))


@wp.func
def triangle_edges(v: RasterView, a: wp.vec3, b: wp.vec3, c: wp.vec3):
    """The three edge functions of abc, signed so that rays through the triangle make all three
    positive, and whether the triangle faces the view at all (not edge-on)."""
    e0 = edge_coeffs(v, a, b, c)
    e1 = edge_coeffs(v, b, c, a)
    e2 = edge_coeffs(v, c, a, b)
    # at the centroid's image point every edge function is a third of this orientation
    orient = wp.dot(v.fwd, wp.cross(b - a, c - a))
    if v.ortho == 0:
        orient = wp.dot(a - v.origin, wp.cross(b - v.origin, c - v.origin))
    s = wp.where(orient < 0.0, -1.0, 1.0)
    return s * e0, s * e1, s * e2, orient != 0.0


NO_HIT = wp.constant(wp.int64(0x7FFFFFFFFFFFFFFF))  # key of a pixel no triangle covers
KEY_RANGE = 2.0e9  # quantised distances run over [0, KEY_RANGE] (below 2^31): t_scale = KEY_RANGE / farthest t
KEY_LIMIT = wp.constant(KEY_RANGE)


@wp.func
def raster_rect(v: RasterView, a: wp.vec3, b: wp.vec3, c: wp.vec3, face: int, i0: int, rect: wp.vec4i,
                with_keys: int, t_scale: float, out: wp.array(dtype=Any)):
    """Rasterise the pixels [x0, x1] x [y0, y1] (``rect``) of triangle ``face`` (abc) into view v, a part of its
    box whose first column is i0: per covered pixel, the nearest distance into ``out`` (float), or
    (with_keys = 1, ``out`` int64) the nearest (distance x t_scale, face) as one key. Image
    coordinates step from column i0 whatever the part, so every split of the box gives the same
    pixels the same values."""
    x0 = rect[0]
    x1 = rect[1]
    y0 = rect[2]
    y1 = rect[3]
    e0, e1, e2, facing = triangle_edges(v, a, b, c)
    if not facing:
        return
    # distance to abc's plane along the pixel's unit ray: num |D| / (D . n) with D = fwd + sx right +
    # sy up (perspective), or (num - sx right . n - sy up . n) / (fwd . n) (orthographic)
    n = wp.cross(b - a, c - a)
    num = wp.dot(a - v.origin, n)
    den = wp.vec3(wp.dot(v.fwd, n), wp.dot(v.right, n), wp.dot(v.up, n))
    rr = wp.dot(v.right, v.right)
    uu = wp.dot(v.up, v.up)
    dsx = 2.0 / float(v.width)
    for j in range(y0, y1 + 1):
        sx0, sy = image_coords(v, i0, j)
        r0 = e0[0] + sy * e0[2]
        r1 = e1[0] + sy * e1[2]
        r2 = e2[0] + sy * e2[2]
        for i in range(x0, x1 + 1):
            # the edge functions at the pixel centre: all >= 0 where its ray passes through abc
            sx = sx0 + float(i - i0) * dsx
            w0 = r0 + sx * e0[1]
            w1 = r1 + sx * e1[1]
            w2 = r2 + sx * e2[1]
            tol = -EDGE_SLACK * (wp.abs(w0) + wp.abs(w1) + wp.abs(w2))
            if w0 >= tol and w1 >= tol and w2 >= tol:
                t = float(0.0)
                if v.ortho == 1:
                    t = (num - sx * den[1] - sy * den[2]) / den[0]
                else:
                    t = num * wp.sqrt(1.0 + sx * sx * rr + sy * sy * uu) / (den[0] + sx * den[1] + sy * den[2])
                if t > 0.0:
                    k = v.base + j * v.width + i
                    if with_keys == 1:
                        q = wp.int64(wp.min(t * t_scale, KEY_LIMIT))
                        wp.atomic_min(out, k, out.dtype((q << wp.int64(32)) | wp.int64(face)))
                    else:
                        wp.atomic_min(out, k, out.dtype(t))


@wp.func
def owner(starts: wp.array(dtype=int), w: int) -> int:
    """The k with starts[k] <= w < starts[k + 1]: which item work unit w belongs to, when
    ``starts`` is the exclusive scan of the items' unit counts (binary search)."""
    lo = int(0)
    hi = int(starts.shape[0] - 1)
    while lo < hi:
        mid = (lo + hi + 1) / 2
        if starts[mid] <= w:
            lo = mid
        else:
            hi = mid - 1
    return lo


@wp.func
def triangle_at(points: wp.array(dtype=wp.vec3), indices: wp.array(dtype=int), f: int):
    """The three vertices of triangle f of an indexed mesh."""
    return points[indices[3 * f]], points[indices[3 * f + 1]], points[indices[3 * f + 2]]


@wp.func
def key_hit(key: wp.int64, points: wp.array(dtype=wp.vec3), indices: wp.array(dtype=int), o: wp.vec3, d: wp.vec3):
    """The surface a pixel's key names: (hit, t, unit geometric normal, face), as ``surface_hit``."""
    if key == NO_HIT:
        return False, INF, wp.vec3(0.0, 1.0, 0.0), int(-1)
    f = int(key & wp.int64(0xFFFFFFFF))
    a, b, c = triangle_at(points, indices, f)
    n = wp.normalize(wp.cross(b - a, c - a))
    return True, wp.dot(a - o, n) / wp.dot(d, n), n, f  # the ray meets the triangle's plane there


@wp.kernel
def raster_views(offset: int, points: wp.array(dtype=wp.vec3), indices: wp.array(dtype=int),
                 views: wp.array(dtype=RasterView), with_keys: int, t_scale: float, out: wp.array(dtype=Any)):
    """One thread per triangle: its nearest distances (or keys) into the pixels of every view it
    reaches (``triangle_box`` culls the others)."""
    f = wp.tid() + offset
    a, b, c = triangle_at(points, indices, f)
    m, r2 = bounding_sphere(a, b, c)
    for k in range(views.shape[0]):
        v = views[k]
        i0, j0, i1, j1 = triangle_box(v, a, b, c, m, r2)
        if i0 <= i1 and j0 <= j1:
            raster_rect(v, a, b, c, f, i0, wp.vec4i(i0, i1, j0, j1), with_keys, t_scale, out)


@wp.kernel
def count_view_tiles(offset: int, points: wp.array(dtype=wp.vec3), indices: wp.array(dtype=int),
                     views: wp.array(dtype=RasterView), counts: wp.array(dtype=int)):
    """Per triangle: its TILE x TILE pieces over all the views."""
    f = wp.tid() + offset
    a, b, c = triangle_at(points, indices, f)
    m, r2 = bounding_sphere(a, b, c)
    n = int(0)
    for k in range(views.shape[0]):
        i0, j0, i1, j1 = triangle_box(views[k], a, b, c, m, r2)
        n += box_tiles(i0, j0, i1, j1)
    counts[f] = n


@wp.kernel
def raster_view_tiles(offset: int, points: wp.array(dtype=wp.vec3), indices: wp.array(dtype=int),
                      views: wp.array(dtype=RasterView), starts: wp.array(dtype=int), with_keys: int, t_scale: float,
                      out: wp.array(dtype=Any)):
    """One thread per piece (``starts``: exclusive scan of ``count_view_tiles``): piece w - starts[f]
    of triangle f, counted over the views in turn and row by row within a view's box."""
    w = wp.tid() + offset
    f = owner(starts, w)
    a, b, c = triangle_at(points, indices, f)
    m, r2 = bounding_sphere(a, b, c)
    local = w - starts[f]
    for k in range(views.shape[0]):
        v = views[k]
        i0, j0, i1, j1 = triangle_box(v, a, b, c, m, r2)
        n = box_tiles(i0, j0, i1, j1)
        if local < n:
            nx = (i1 - i0) / TILE + 1
            x0 = i0 + (local % nx) * TILE
            y0 = j0 + (local / nx) * TILE
            rect = wp.vec4i(x0, wp.min(x0 + TILE - 1, i1), y0, wp.min(y0 + TILE - 1, j1))
            raster_rect(v, a, b, c, f, i0, rect, with_keys, t_scale, out)
            break
        local -= n


@wp.kernel
def min_into(offset: int, src: wp.array(dtype=Any), dst: wp.array(dtype=Any)):
    """dst = min(dst, src) elementwise: folds a private copy of a depth or key image into it."""
    tid = wp.tid() + offset
    dst[tid] = wp.min(dst[tid], src[tid])


for _t in (wp.float32, wp.int64):  # declared before the module first loads: it compiles once
    wp.overload(min_into, {"src": wp.array(dtype=_t), "dst": wp.array(dtype=_t)})
    wp.overload(raster_views, {"out": wp.array(dtype=_t)})
    wp.overload(raster_view_tiles, {"out": wp.array(dtype=_t)})


def rasterise(points: wp.array, indices: wp.array, views: wp.array, with_keys: int, t_scale: float, out: wp.array,
              tiled: bool, device: str) -> wp.array:
    """The nearest triangle of every pixel of every view, by rasterising: the one driver of
    camera images (keys) and shadow maps (depths).

    Parameters
    ----------
    points : wp.array of vec3, indices : wp.array of int (3 per triangle)
        The triangles (e.g. from ``split_long_edges``).
    views : wp.array of RasterView
        The images; pixel (i, j) of view v lands at out[v.base + j * v.width + i].
    with_keys : int
        1: ``out`` is int64 and takes (quantised distance << 32 | triangle) keys (see
        ``rasterise_visible``); 0: ``out`` is float and takes the distance (scene units).
    t_scale : float
        Keys: the distance's quantisation, KEY_RANGE / (a bound of the distances).
    out : wp.array of int64 or float
        Filled beforehand with ``NO_HIT`` (keys) or ``INF`` (depths) at the views' pixels.
    tiled : bool
        True: one thread per TILE x TILE piece of a triangle's box in a view (balanced for
        GPUs); False: one thread per triangle. Both give the same ``out``.

    Returns ``out``.
    """
    inputs = [points, indices, views]
    ntri = indices.shape[0] // 3
    if not tiled:
        dev.launch_private(raster_views, ntri, [*inputs, with_keys, t_scale], out, min_into, device)
        return out
    # pieces per triangle, their exclusive scan and the total: the one number read back to size the launch
    counts = wp.empty(ntri, dtype=int, device=device)
    starts = wp.empty(ntri, dtype=int, device=device)
    dev.launch(count_view_tiles, ntri, [*inputs, counts], device)
    wp.utils.array_scan(counts, starts, inclusive=False)
    total = int(np.concatenate([starts[ntri - 1:].numpy(), counts[ntri - 1:].numpy()]).sum())
    dev.launch_private(raster_view_tiles, total, [*inputs, starts, with_keys, t_scale], out, min_into, device)
    return out


def rasterise_visible(points: wp.array, indices: wp.array, view: RasterView, t_far: float, keys: wp.array,
                      tiled: bool, device: str) -> wp.array:
    """The nearest triangle of every pixel of ``view``, by rasterising.

    Parameters
    ----------
    points : wp.array of vec3, indices : wp.array of int (3 per triangle)
        The triangles (e.g. from ``split_long_edges``: points 3k..3k+2, indices 0..3F-1).
    view : RasterView
        The image; pixel (i, j) lands at keys[view.base + j * view.width + i].
    t_far : float
        A bound of the distance to any triangle (scene units): distances are quantised
        over [0, t_far] into the keys' upper 32 bits.
    keys : wp.array of int64
        Filled with ``NO_HIT`` beforehand; per covered pixel, (quantised distance << 32 |
        triangle) of the nearest triangle (``key_hit`` turns it back into a hit).
    tiled : bool
        True: one thread per TILE x TILE piece of a triangle (balanced for GPUs); False: one
        thread per triangle. Both give the same keys.

    Returns ``keys``.
    """
    views = wp.array([view], dtype=RasterView, device=device)
    return rasterise(points, indices, views, 1, KEY_RANGE / t_far, keys, tiled, device)


def split_long_edges(vertices: np.ndarray, faces: np.ndarray, max_edge: float):
    """Triangles for rasterising: each face of (vertices, faces) is split into four at its edge
    midpoints, repeatedly, until no edge is longer than ``max_edge``. A rasteriser thread takes
    one triangle, so this bounds the work of one thread (a floor of two triangles would otherwise
    leave one core, or one GPU thread, with half the image). The pieces are coplanar with their
    face. Returns (points (3 F', 3), the face each piece came from (F',)), a triangle list
    whose triangle k has points 3k, 3k + 1, 3k + 2."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces).reshape(-1, 3)]
    parent = np.arange(len(tri))
    while len(tri):
        edges = np.linalg.norm(tri - np.roll(tri, -1, axis=1), axis=2).max(axis=1)
        long = edges > max_edge
        if not long.any():
            break
        t = tri[long]
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        ab, bc, ca = 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)
        pieces = np.stack([np.stack(p, axis=1) for p in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
        tri = np.concatenate([tri[~long], pieces.reshape(-1, 3, 3)])
        parent = np.concatenate([parent[~long], np.tile(parent[long], 4)])
    return tri.reshape(-1, 3).astype(np.float32), parent.astype(np.int32)


# --- spheres binned to screen tiles: splatting particles and impostors front to back ------
