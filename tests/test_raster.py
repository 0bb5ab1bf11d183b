"""The rasteriser and the shadow-map drivers on their own (geometry/raster.py, geometry/shadowmap.py):
mesh and view in, key / depth arrays out, against closed forms and the BVH ray cast."""

import math

import numpy as np
import pytest
import warp as wp

from warpvol.geometry.mesh import Surfaces
from warpvol.geometry.camera import RasterView
from warpvol.geometry.raster import KEY_RANGE, NO_HIT, rasterise_visible, split_long_edges
from warpvol.geometry.tiles import SPHERE_TILE, bin_spheres
from warpvol.geometry.shadowmap import CUBE, ORTHOGRAPHIC, PERSPECTIVE, ShadowMap, shadow_map_depths, texels

# a unit box's six faces (12 triangles) centred at (0, 0, -3)
BOX_VERTICES = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-3.5, -2.5)], np.float32)
BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.int32)


def triangles(device, vertices, faces, max_edge=0.3):
    pts, _ = split_long_edges(vertices, faces, max_edge)
    return (wp.array(pts, dtype=wp.vec3, device=device),
            wp.array(np.arange(len(pts), dtype=np.int32), dtype=int, device=device))


def camera(width=40, height=30, fov_y=50.0) -> RasterView:
    """Looking down -z from the origin, row 0 at the top."""
    th = math.tan(math.radians(fov_y) / 2.0)
    v = RasterView()
    v.origin, v.fwd = wp.vec3(0.0, 0.0, 0.0), wp.vec3(0.0, 0.0, -1.0)
    v.right, v.up = wp.vec3(th * width / height, 0.0, 0.0), wp.vec3(0.0, th, 0.0)
    v.ortho, v.y_down, v.width, v.height, v.base = 0, 1, width, height, 0
    return v


def pixel_dirs(v: RasterView) -> np.ndarray:
    i, j = np.meshgrid(np.arange(v.width), np.arange(v.height))
    sx = 2.0 * (i + 0.5) / v.width - 1.0
    sy = 1.0 - 2.0 * (j + 0.5) / v.height
    d = np.asarray(v.fwd) + sx[..., None] * np.asarray(v.right) + sy[..., None] * np.asarray(v.up)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


@pytest.mark.parametrize("tiled", [False, True])
def test_visible_keys_find_the_front_face_at_its_distance(device, tiled):
    """Every pixel whose ray meets the box's front face z = -2.5 gets a key naming one of that
    face's triangles, at the distance 2.5 / |d_z| to within the key's quantisation (t_far /
    KEY_RANGE) plus float32 rounding; every other pixel keeps NO_HIT."""
    v = camera()
    points, indices = triangles(device, BOX_VERTICES, BOX_FACES)
    keys = wp.full(v.width * v.height, NO_HIT, dtype=wp.int64, device=device)
    t_far = 10.0
    rasterise_visible(points, indices, v, t_far, keys, tiled, device)
    k = keys.numpy().reshape(v.height, v.width)
    d = pixel_dirs(v)
    t = 2.5 / -d[..., 2]
    x, y = d[..., 0] * t, d[..., 1] * t
    inside = (np.abs(x) < 0.5 - 1e-3) & (np.abs(y) < 0.5 - 1e-3)
    outside = (np.abs(x) > 0.5 + 1e-3) | (np.abs(y) > 0.5 + 1e-3)
    assert inside.sum() > 20 and outside.sum() > 20
    assert np.all(k[outside] == int(NO_HIT))
    hit = k[inside]
    assert np.all(hit != int(NO_HIT))
    t_key = (hit >> 32).astype(np.float64) * t_far / KEY_RANGE
    np.testing.assert_allclose(t_key, t[inside], rtol=1e-5, atol=2 * t_far / KEY_RANGE)
    named = points.numpy().reshape(-1, 3, 3)[hit & 0xFFFFFFFF]
    assert np.abs(named[:, :, 2] + 2.5).max() < 1e-6  # the triangles named lie in the front face


def test_visible_keys_tiled_equal_one_thread_per_triangle(device):
    v = camera(53, 37)
    points, indices = triangles(device, BOX_VERTICES, BOX_FACES, max_edge=2.0)
    out = []
    for tiled in (False, True):
        keys = wp.full(v.width * v.height, NO_HIT, dtype=wp.int64, device=device)
        out.append(rasterise_visible(points, indices, v, 10.0, keys, tiled, device).numpy())
    np.testing.assert_array_equal(out[0], out[1])


def shadow_maps(res):
    """A spot light above the box looking down at it, a point light beside it (cube map) and a
    directional light along -z (orthographic map), packed into one texel array."""
    maps, offset = [], 0
    for kind in (PERSPECTIVE, CUBE, ORTHOGRAPHIC):
        sm = ShadowMap()
        sm.kind, sm.res, sm.offset, sm.bias, sm.extent = int(kind), res, offset, 0.0, 1.0
        sm.origin, sm.right, sm.up, sm.fwd = (wp.vec3(0.0, 3.0, -3.0), wp.vec3(1.0, 0.0, 0.0),
                                              wp.vec3(0.0, 0.0, 1.0), wp.vec3(0.0, -1.0, 0.0))
        if kind == CUBE:
            sm.origin = wp.vec3(2.0, 0.2, -2.8)
        if kind == ORTHOGRAPHIC:
            sm.origin, sm.up, sm.fwd = wp.vec3(0.0, 0.0, 2.0), wp.vec3(0.0, 1.0, 0.0), wp.vec3(0.0, 0.0, -1.0)
            sm.extent = 1.2
        maps.append(sm)
        offset += texels(sm.kind, res)
    return maps


def test_shadow_maps_rasterised_equal_ray_cast(device):
    """Each kind of map made by rasterising (one thread per triangle, or per piece) matches one
    ray per texel cast through a wp.Mesh: the same texels see the box, at the same distance
    (float32: 1e-4 relative), and texels off the box hold INF in both."""
    res = 24
    maps = shadow_maps(res)
    mesh = wp.Mesh(points=wp.array(BOX_VERTICES, dtype=wp.vec3, device=device),
                   indices=wp.array(BOX_FACES.ravel(), dtype=int, device=device))
    s = Surfaces()
    s.mesh, s.present = mesh.id, 1
    cast = shadow_map_depths(maps, device, surfaces=s).numpy()
    points, indices = triangles(device, BOX_VERTICES, BOX_FACES)
    untiled = shadow_map_depths(maps, device, points, indices, tiled=False).numpy()
    tiled = shadow_map_depths(maps, device, points, indices, tiled=True).numpy()
    np.testing.assert_array_equal(untiled, tiled)
    assert len(cast) == res * res * 8
    finite = np.isfinite(cast) & (cast < 1e30)
    assert finite.sum() > 50
    # texels whose ray grazes an edge may fall either side: allow a few in a thousand
    agree = (finite == (untiled < 1e30)).mean()
    assert agree > 0.995
    both = finite & (untiled < 1e30)
    np.testing.assert_allclose(untiled[both], cast[both], rtol=1e-4, atol=1e-5)


def _listed(tl, n_tiles: int) -> list[set]:
    first, last, values = tl.first.numpy(), tl.last.numpy(), tl.values.numpy()
    return [set(values[first[k]:last[k]].tolist()) for k in range(n_tiles)]


def test_binned_spheres_list_every_sphere_a_pixel_ray_meets(device):
    """bin_spheres is conservative: every sphere a pixel's ray meets (closed-form ray-sphere
    test in NumPy) is in the list of the pixel's tile. Spheres of every kind: small and
    large, across the image's edge, around the eye, straddling it and wholly behind it."""
    rng = np.random.default_rng(5)
    v = camera(width=72, height=40)
    centres = np.concatenate([rng.uniform([-3, -2, -8], [3, 2, -1], (60, 3)),
                              [[0.0, 0.0, 0.2], [0.5, 0.0, 0.3], [0.0, 0.0, 3.0]]]).astype(np.float32)
    radius = np.concatenate([rng.uniform(0.02, 0.8, 60), [0.5, 0.4, 0.6]]).astype(np.float32)
    tl = bin_spheres(v, wp.array(centres, dtype=wp.vec3, device=device), wp.array(radius, dtype=float, device=device),
                     20.0, device)
    tiles_x = -(-v.width // SPHERE_TILE)
    listed = _listed(tl, tiles_x * -(-v.height // SPHERE_TILE))
    d = pixel_dirs(v).reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tc = d @ centres.T  # origin at 0: |c - (d . c) d|^2 <= r^2 and the chord's far end in front
    miss2 = (centres ** 2).sum(1)[None] - tc ** 2
    hit = (miss2 <= radius[None] ** 2) & (tc + np.sqrt(np.maximum(radius[None] ** 2 - miss2, 0.0)) > 0.0)
    assert hit.any(axis=0).sum() > 40
    for p, s in zip(*np.nonzero(hit)):
        j, i = divmod(int(p), v.width)
        assert s in listed[(j // SPHERE_TILE) * tiles_x + i // SPHERE_TILE], (p, s)


def test_binned_sphere_skips_its_rectangles_corners(device):
    """A sphere on the view axis projects to a disc of radius rho = f tan(asin(r / d)) pixels;
    bin_spheres lists only tiles whose centre lies within rho plus the tile's half diagonal
    (their cones meet it), not the whole bounding rectangle of tiles."""
    v = camera(width=128, height=128, fov_y=60.0)
    r, dist = 0.3, 3.0
    tl = bin_spheres(v, wp.array([[0.0, 0.0, -dist]], dtype=wp.vec3, device=device),
                     wp.array([r], dtype=float, device=device), 10.0, device)
    tiles = -(-v.width // SPHERE_TILE)
    listed = [k for k, s in enumerate(_listed(tl, tiles * tiles)) if s]
    f = 0.5 * v.height / math.tan(math.radians(30.0))
    rho = f * math.tan(math.asin(r / dist))
    centre = np.array([(k % tiles + 0.5) * SPHERE_TILE - 64.0 for k in listed]), \
        np.array([(k // tiles + 0.5) * SPHERE_TILE - 64.0 for k in listed])
    far = np.hypot(*centre)
    assert far.max() <= rho + SPHERE_TILE / math.sqrt(2.0) + 1.0, (far.max(), rho)
    side = len({int(x) for x in centre[0]})
    assert len(listed) < side * side  # the rectangle's corners are left out
    assert far.min() < SPHERE_TILE  # and the middle is in
