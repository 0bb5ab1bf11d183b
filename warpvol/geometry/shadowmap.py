"""Shadow maps: perspective (spot), cube (point), orthographic (directional), each made by
rasterising the surfaces into its faces (``map_view``: raster views, see geometry/raster.py)
or by ray casting a ``wp.Mesh`` through their texels; lookups with 2x2 percentage-closer
filtering.

A map stores, per texel, the distance from the light to the nearest surface along the
texel's ray (radial distance for perspective and cube maps, distance from the map's plane
along the light's direction for orthographic ones; ``INF`` where the ray escapes). A point
x is lit when its own distance minus ``bias`` (scene units) does not exceed the stored
one; the four nearest texels' tests are blended bilinearly (PCF), which turns the
texel staircase into a one-texel ramp. Surfaces look themselves up from a point moved off
the surface along its normal by a fraction of a texel (``texel_world_size``: normal-offset
shadows), which removes self-shadowing "acne" that a constant bias cannot at grazing light.

Texels of all maps share one float array; ``ShadowMap.offset`` is a map's first texel.
A cube map holds six res x res faces in the order +x, -x, +y, -y, +z, -z.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from .. import device as dev
from ..physics.constants import INF
from ..physics.lights import Emitter
from .mesh import Surfaces
from .camera import RasterView, pixel_ray, view_ray
from .raster import owner, rasterise

dev.kernel_module(__name__)

NONE = wp.constant(0)  # no occluders: every point is lit
PERSPECTIVE = wp.constant(1)
CUBE = wp.constant(2)
ORTHOGRAPHIC = wp.constant(3)


@wp.struct
class ShadowMap:
    kind: int
    origin: wp.vec3  # light position; orthographic: centre of the map's plane
    right: wp.vec3  # unit axes of the map (perspective, orthographic)
    up: wp.vec3
    fwd: wp.vec3
    extent: float  # perspective: tan(half field of view); orthographic: half width
    res: int
    offset: int
    bias: float


@wp.struct
class ShadowedLights:
    """Lights and their shadow maps (``shading.light_arriving`` reads them), and optionally the
    media's optical depth toward each light baked on a lattice over the heterogeneous media
    (``shading.bake_light_depth``; ``baked_n`` = 0: marched instead)."""
    lights: wp.array(dtype=Emitter)
    maps: wp.array(dtype=ShadowMap)  # one per light
    depth: wp.array(dtype=float)  # the maps' texels
    baked: wp.array(dtype=wp.vec3)  # per light, baked_n^3 nodes of optical depth (x fastest)
    baked_n: int
    baked_lo: wp.vec3
    baked_hi: wp.vec3


@wp.func
def cube_face_axes(face: int):
    """(fwd, right, up) of cube face 0..5 = +x, -x, +y, -y, +z, -z."""
    axis = face / 2
    sign = 1.0 - 2.0 * float(face % 2)
    fwd = wp.vec3(0.0)
    fwd[axis] = sign
    helper = wp.vec3(0.0, 1.0, 0.0)
    if axis == 1:
        helper = wp.vec3(0.0, 0.0, 1.0)
    right = wp.cross(fwd, helper)  # unit: fwd and helper are orthonormal
    up = wp.cross(right, fwd)
    return fwd, right, up


@wp.func
def cube_face_of(p: wp.vec3) -> int:
    ax = wp.abs(p[0])
    ay = wp.abs(p[1])
    az = wp.abs(p[2])
    if ax >= ay and ax >= az:
        return wp.where(p[0] >= 0.0, 0, 1)
    if ay >= az:
        return wp.where(p[1] >= 0.0, 2, 3)
    return wp.where(p[2] >= 0.0, 4, 5)


@wp.func
def map_view(sm: ShadowMap, face: int) -> RasterView:
    """The image of one map (``face`` of a cube map, else 0) as a raster view; texel (i, j)
    is pixel (i, j), row 0 at the bottom."""
    v = RasterView()
    v.origin = sm.origin
    v.fwd = sm.fwd
    v.right = sm.extent * sm.right
    v.up = sm.extent * sm.up
    v.ortho = wp.where(sm.kind == ORTHOGRAPHIC, 1, 0)
    v.y_down = 0
    v.width = sm.res
    v.height = sm.res
    v.base = sm.offset
    if sm.kind == CUBE:
        fwd, right, up = cube_face_axes(face)
        v.fwd = fwd
        v.right = right
        v.up = up
        v.base = sm.offset + face * sm.res * sm.res
    return v


@wp.func
def texel_ray(sm: ShadowMap, texel: int):
    """(origin, unit direction) of the ray through texel ``texel`` (0 .. texels(sm) - 1)."""
    res = sm.res
    k = texel % (res * res)
    return view_ray(map_view(sm, texel / (res * res)), k % res, k / res)


@wp.func
def shadow_depth(sm: ShadowMap, depth: wp.array(dtype=float), base: int, fx: float, fy: float, dist: float) -> float:
    """PCF: the bilinear blend of the four nearest texels' lit (1) / shadowed (0) tests."""
    res = sm.res
    fx = wp.clamp(fx, 0.0, float(res - 1))
    fy = wp.clamp(fy, 0.0, float(res - 1))
    x0 = wp.min(int(fx), wp.max(res - 2, 0))
    y0 = wp.min(int(fy), wp.max(res - 2, 0))
    x1 = wp.min(x0 + 1, res - 1)
    y1 = wp.min(y0 + 1, res - 1)
    tx = fx - float(x0)
    ty = fy - float(y0)
    d = dist - sm.bias
    l00 = wp.where(depth[base + y0 * res + x0] >= d, 1.0, 0.0)
    l10 = wp.where(depth[base + y0 * res + x1] >= d, 1.0, 0.0)
    l01 = wp.where(depth[base + y1 * res + x0] >= d, 1.0, 0.0)
    l11 = wp.where(depth[base + y1 * res + x1] >= d, 1.0, 0.0)
    return (l00 * (1.0 - tx) + l10 * tx) * (1.0 - ty) + (l01 * (1.0 - tx) + l11 * tx) * ty


@wp.func
def shadow_visibility(sm: ShadowMap, depth: wp.array(dtype=float), x: wp.vec3) -> float:
    """Fraction of the light that reaches x past the surfaces, from the map (1 outside it)."""
    if sm.kind == NONE:
        return 1.0
    p = x - sm.origin
    res = float(sm.res)
    if sm.kind == ORTHOGRAPHIC:
        u = wp.dot(p, sm.right) / sm.extent
        v = wp.dot(p, sm.up) / sm.extent
        if wp.abs(u) > 1.0 or wp.abs(v) > 1.0:
            return 1.0
        return shadow_depth(sm, depth, sm.offset, (u * 0.5 + 0.5) * res - 0.5, (v * 0.5 + 0.5) * res - 0.5,
                            wp.dot(p, sm.fwd))
    dist = wp.length(p)
    if sm.kind == CUBE:
        face = cube_face_of(p)
        fwd, right, up = cube_face_axes(face)
        z = wp.dot(p, fwd)
        u = wp.dot(p, right) / z
        v = wp.dot(p, up) / z
        return shadow_depth(sm, depth, sm.offset + face * sm.res * sm.res, (u * 0.5 + 0.5) * res - 0.5,
                            (v * 0.5 + 0.5) * res - 0.5, dist)
    z = wp.dot(p, sm.fwd)
    if z <= 0.0:
        return 1.0
    u = wp.dot(p, sm.right) / (z * sm.extent)
    v = wp.dot(p, sm.up) / (z * sm.extent)
    if wp.abs(u) > 1.0 or wp.abs(v) > 1.0:
        return 1.0
    return shadow_depth(sm, depth, sm.offset, (u * 0.5 + 0.5) * res - 0.5, (v * 0.5 + 0.5) * res - 0.5, dist)


@wp.func
def texel_world_size(sm: ShadowMap, x: wp.vec3) -> float:
    """Width of one texel of the map at x, in scene units (for normal-offset lookups)."""
    if sm.kind == ORTHOGRAPHIC:
        return 2.0 * sm.extent / float(sm.res)
    ext = wp.where(sm.kind == CUBE, 1.0, sm.extent)
    return 2.0 * ext * wp.length(x - sm.origin) / float(sm.res)


@wp.kernel
def map_views(offset: int, maps: wp.array(dtype=ShadowMap), faces: wp.array(dtype=wp.vec2i),
              views: wp.array(dtype=RasterView)):
    """The raster view of each (map, face) pair (``map_view``)."""
    k = wp.tid() + offset
    views[k] = map_view(maps[faces[k][0]], faces[k][1])


@wp.kernel
def cast_views(offset: int, s: Surfaces, views: wp.array(dtype=RasterView), starts: wp.array(dtype=int),
               depth: wp.array(dtype=float)):
    """One ray per pixel of the views (``starts``: exclusive scan of their pixel counts) through the
    mesh's BVH: the distance to the nearest surface, ``INF`` where the ray escapes."""
    tid = wp.tid() + offset
    k = owner(starts, tid)
    v = views[k]
    p = tid - starts[k]
    o, d = pixel_ray(v, p)
    q = wp.mesh_query_ray(s.mesh, o, d, INF)
    depth[v.base + p] = wp.where(q.result, q.t, INF)


def shadow_map_depths(maps: list, device: str, points: wp.array | None = None, indices: wp.array | None = None,
                      surfaces: Surfaces | None = None, tiled: bool = False) -> wp.array:
    """The depth texels of ``maps`` (ShadowMaps whose ``offset`` places them in one array).

    Parameters
    ----------
    maps : list of ShadowMap
        From ``shadow_map_for``; texel k of a map lands at depth[map.offset + k].
    points, indices : wp.array of vec3 and int, optional
        Triangles to rasterise (3 indices per triangle): the maps are made by rasterising.
    surfaces : Surfaces, optional
        Otherwise: a ``wp.Mesh`` whose BVH one ray per texel is cast through.
    tiled : bool
        Rasterising: one thread per TILE x TILE piece of a triangle (GPUs) instead of one per
        triangle; the same depths.

    Returns a float array of sum(texels) entries (at least 1): per texel, the distance to the
    nearest surface along its ray (scene units; see the module docstring), ``INF`` where none.
    """
    total = max(sum(texels(sm.kind, sm.res) for sm in maps), 1)
    # every map's faces as raster views (``map_view``), map by map
    nfaces = [texels(sm.kind, sm.res) // max(sm.res * sm.res, 1) for sm in maps]
    pairs = [(m, f) for m, n in enumerate(nfaces) for f in range(n)]
    views = wp.empty(len(pairs), dtype=RasterView, device=device)
    if pairs:
        dev.launch(map_views, len(pairs), [wp.array(maps, dtype=ShadowMap, device=device),
                                           wp.array(pairs, dtype=wp.vec2i, device=device), views], device)
    if points is None:
        depth = wp.empty(total, dtype=float, device=device)
        if pairs:
            sizes = [maps[m].res * maps[m].res for m, _ in pairs]
            starts = wp.array(np.cumsum([0, *sizes[:-1]]), dtype=int, device=device)
            dev.launch(cast_views, sum(sizes), [surfaces, views, starts, depth], device)
        return depth
    depth = wp.full(total, INF, dtype=float, device=device)
    first = 0
    for n in nfaces:  # a map at a time: its texels stay in cache, and a triangle tries only its faces
        if n:
            rasterise(points, indices, views[first:first + n], 0, 0.0, depth, tiled, device)
        first += n
    return depth


def texels(kind: int, res: int) -> int:
    return 0 if kind == int(NONE) else (6 if kind == int(CUBE) else 1) * res * res


def shadow_map_for(light, res: int, bias: float, bounds: tuple[np.ndarray, np.ndarray], offset: int,
                   occluders: bool) -> ShadowMap:
    """The map that serves ``light`` (a scene Light) over a scene whose surfaces and media lie
    in ``bounds`` (min, max); kind NONE when there are no occluders."""
    sm = ShadowMap()
    sm.res, sm.offset, sm.bias = res, offset, bias
    sm.extent = 1.0
    sm.origin, sm.right, sm.up, sm.fwd = wp.vec3(0.0), wp.vec3(1.0, 0.0, 0.0), wp.vec3(0.0, 1.0, 0.0), wp.vec3(0.0, 0.0, 1.0)
    if not occluders:
        sm.kind = int(NONE)
        return sm
    if light.type == "point":
        sm.kind = int(CUBE)
        sm.origin = wp.vec3(*light.position)
        return sm
    fwd = np.asarray(light.direction, np.float64)
    fwd /= np.linalg.norm(fwd)
    helper = np.array([0.0, 1.0, 0.0]) if abs(fwd[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(fwd, helper)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    sm.right, sm.up, sm.fwd = wp.vec3(*right), wp.vec3(*up), wp.vec3(*fwd)
    if light.type == "spot":
        sm.kind = int(PERSPECTIVE)
        sm.origin = wp.vec3(*light.position)
        sm.extent = math.tan(math.radians(min(light.outer_angle, 85.0)))
        return sm
    lo, hi = (np.asarray(b, np.float64) for b in bounds)
    centre, radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo)) + 1e-3
    sm.kind = int(ORTHOGRAPHIC)
    sm.origin = wp.vec3(*(centre - 1.01 * radius * fwd))
    sm.extent = radius
    return sm
