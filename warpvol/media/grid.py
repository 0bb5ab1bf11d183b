"""Density grids: cell-centred samples, trilinear lookup, zero outside the bounds.

``data`` holds dense grids flattened with x fastest (the .npy layout [z, y, x]); sample
(i, j, k) sits at bounds_min + (i + 0.5, j + 0.5, k + 0.5) * cell. Inside the half-cell
border the lookup clamps to the outermost samples.

A NanoVDB grid (``wp.Volume``, Museth 2021) holds the same samples sparsely: voxel
``origin`` + (i, j, k) is sample (i, j, k), its value at the voxel's centre, so Warp's
index space is the grid's fractional sample index plus ``origin``. ``volume_trilinear``
reads the eight voxels around a point with ``wp.volume_lookup_f`` and blends them with the
dense lookup's arithmetic (``grid_corners``, ``trilinear_blend``): a grid and its NanoVDB
copy give bit-identical densities, so a seeded path tracer takes the same paths through
both. (``wp.volume_sample_f``'s LINEAR mode sums eight weights x values instead, which
differs in the last bit, and one flipped delta-tracking decision changes a whole path.)
Voxels outside the leaves read the background (0 for ``save_volume``'s files): empty space
costs no memory.
"""

from typing import Any

import numpy as np
import warp as wp

from .. import device as dev
from ..geometry.intersect import inside_box, ray_box
from ..physics.constants import INF, STREAM
from ..physics.sampling import sample_exponential

dev.kernel_module(__name__)


@wp.func
def grid_value(data: wp.array(dtype=Any), offset: int, dims: wp.vec3i, ix: int, iy: int, iz: int):
    return data[offset + (iz * dims[1] + iy) * dims[0] + ix]


@wp.func
def grid_corners(dims: wp.vec3i, bmin: wp.vec3, bmax: wp.vec3, x: wp.vec3):
    """The samples a trilinear lookup at x (inside [bmin, bmax]) blends: (lower corner, upper
    corner, weights of the upper one). Fractional sample index f = (x - bmin) / cell - 1/2,
    clamped to [0, dims - 1]."""
    g = wp.cw_div(x - bmin, bmax - bmin)
    fx = wp.clamp(g[0] * float(dims[0]) - 0.5, 0.0, float(dims[0] - 1))
    fy = wp.clamp(g[1] * float(dims[1]) - 0.5, 0.0, float(dims[1] - 1))
    fz = wp.clamp(g[2] * float(dims[2]) - 0.5, 0.0, float(dims[2] - 1))
    x0 = wp.min(int(fx), wp.max(dims[0] - 2, 0))
    y0 = wp.min(int(fy), wp.max(dims[1] - 2, 0))
    z0 = wp.min(int(fz), wp.max(dims[2] - 2, 0))
    lo = wp.vec3i(x0, y0, z0)
    hi = wp.vec3i(wp.min(x0 + 1, dims[0] - 1), wp.min(y0 + 1, dims[1] - 1), wp.min(z0 + 1, dims[2] - 1))
    return lo, hi, wp.vec3(fx - float(x0), fy - float(y0), fz - float(z0))


@wp.func
def trilinear_blend(c000: Any, c100: Any, c010: Any, c110: Any, c001: Any, c101: Any, c011: Any, c111: Any,
                    t: wp.vec3):
    """Trilinear interpolation of eight corner values (cXYZ: 1 = upper along that axis), x first."""
    c00 = c000 * (1.0 - t[0]) + c100 * t[0]
    c10 = c010 * (1.0 - t[0]) + c110 * t[0]
    c01 = c001 * (1.0 - t[0]) + c101 * t[0]
    c11 = c011 * (1.0 - t[0]) + c111 * t[0]
    return (c00 * (1.0 - t[1]) + c10 * t[1]) * (1.0 - t[2]) + (c01 * (1.0 - t[1]) + c11 * t[1]) * t[2]


@wp.func
def grid_trilinear(data: wp.array(dtype=Any), offset: int, dims: wp.vec3i, bmin: wp.vec3, bmax: wp.vec3, x: wp.vec3):
    """Trilinear between cell centres of a float or vec3 grid; zero outside [bmin, bmax]."""
    if not inside_box(x, bmin, bmax):
        return grid_value(data, offset, dims, 0, 0, 0) * 0.0  # the grid's own zero, float or vec3 (data are finite)
    a, b, t = grid_corners(dims, bmin, bmax, x)
    return trilinear_blend(grid_value(data, offset, dims, a[0], a[1], a[2]), grid_value(data, offset, dims, b[0], a[1], a[2]),
                           grid_value(data, offset, dims, a[0], b[1], a[2]), grid_value(data, offset, dims, b[0], b[1], a[2]),
                           grid_value(data, offset, dims, a[0], a[1], b[2]), grid_value(data, offset, dims, b[0], a[1], b[2]),
                           grid_value(data, offset, dims, a[0], b[1], b[2]), grid_value(data, offset, dims, b[0], b[1], b[2]),
                           t)


@wp.func
def volume_trilinear(volume: wp.uint64, origin: wp.vec3i, dims: wp.vec3i, bmin: wp.vec3, bmax: wp.vec3,
                     x: wp.vec3) -> float:
    """``grid_trilinear`` of a float NanoVDB volume whose voxel origin + (i, j, k) is sample
    (i, j, k) of a dims grid over [bmin, bmax]: the same corners and blend, the eight voxels read
    in index space with ``wp.volume_lookup_f``; zero outside [bmin, bmax]."""
    if not inside_box(x, bmin, bmax):
        return 0.0
    a, b, t = grid_corners(dims, bmin, bmax, x)
    a = a + origin
    b = b + origin
    # one lookup in a loop, not eight written out: the lookup inlines a NanoVDB tree walk, and
    # eight copies of it made the density lookup too large to inline into its callers, which then
    # copied the Media struct per call (light_shafts' march on a homogeneous medium: 2.5x the
    # time). The corner count is a runtime value so that Warp does not unroll the loop.
    v = wp.vector(length=8, dtype=float)
    corners = wp.where(volume != wp.uint64(0), 8, 0)
    for c in range(corners):
        v[c] = wp.volume_lookup_f(volume, wp.where(c & 1 == 0, a[0], b[0]), wp.where(c & 2 == 0, a[1], b[1]),
                                  wp.where(c & 4 == 0, a[2], b[2]))
    return trilinear_blend(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], t)


#: Majorant cells per axis at most (fewer where the grid has fewer samples).
MAJORANT_RES = 32


def majorant_ranges(n: int, r: int) -> list[tuple[int, int]]:
    """Per coarse cell a of r along an axis of n cell-centred samples: the first and last
    sample whose trilinear blending support reaches into the cell, [a, a + 1) / r of the axis
    (the lookup at fractional index f = x n - 1/2 blends samples floor(f) and floor(f) + 1)."""
    return [(max(int(np.floor(a * n / r - 0.5)), 0), min(int(np.floor((a + 1) * n / r - 0.5)) + 1, n - 1))
            for a in range(r)]


def majorant_grid(density: np.ndarray, res: int = MAJORANT_RES) -> np.ndarray:
    """A rigorous bound of the trilinear density over each cell of a coarse grid over the same
    bounds: (rz, ry, rx) float32, r = min(samples, ``res``) per axis, [z, y, x] like ``density``.
    A coarse cell's bound is the largest sample whose blending support reaches into the cell
    (``majorant_ranges``)."""
    out = np.asarray(density, np.float32)
    for axis in range(3):
        n = out.shape[axis]
        pieces = [np.take(out, np.arange(i0, i1 + 1), axis=axis).max(axis=axis, keepdims=True)
                  for i0, i1 in majorant_ranges(n, min(n, res))]
        out = np.concatenate(pieces, axis=axis)
    return out


@wp.kernel
def leaf_majorant(offset: int, volume: wp.uint64, leaves: wp.array(dtype=wp.vec3i), origin: wp.vec3i,
                  dims: wp.vec3i, cells: wp.array(dtype=wp.vec2i), first: wp.vec3i, res: wp.vec3i,
                  out: wp.array(dtype=float)):
    """Thread (leaf, voxel): the voxel's value into the bound of every coarse cell its sample's
    blending support reaches (``cells[first[axis] + sample]``: that cell range per axis)."""
    tid = wp.tid() + offset
    s = leaves[tid / 512] + wp.vec3i((tid / 64) % 8, (tid / 8) % 8, tid % 8) - origin
    if s[0] < 0 or s[1] < 0 or s[2] < 0 or s[0] >= dims[0] or s[1] >= dims[1] or s[2] >= dims[2]:
        return
    v = wp.volume_lookup_f(volume, s[0] + origin[0], s[1] + origin[1], s[2] + origin[2])
    if v > 0.0:
        cx = cells[first[0] + s[0]]
        cy = cells[first[1] + s[1]]
        cz = cells[first[2] + s[2]]
        for k in range(cz[0], cz[1] + 1):
            for j in range(cy[0], cy[1] + 1):
                for i in range(cx[0], cx[1] + 1):
                    wp.atomic_max(out, (k * res[1] + j) * res[0] + i, v)


@wp.kernel
def max_into(offset: int, src: wp.array(dtype=float), dst: wp.array(dtype=float)):
    """dst = max(dst, src) elementwise: folds a core's private copy of a majorant grid into it."""
    tid = wp.tid() + offset
    dst[tid] = wp.max(dst[tid], src[tid])


def volume_majorant_grid(volume: wp.Volume, origin, dims, outside: float = 0.0, res: int = MAJORANT_RES,
                         device=None) -> np.ndarray:
    """``majorant_grid`` of the samples of a float NanoVDB volume (voxel ``origin`` + (i, j, k)
    is sample (i, j, k) of a ``dims`` (x, y, z) grid), at least ``outside`` (what lookups return
    outside the leaves: tiles, background) everywhere. Visits the voxels of the active leaves
    only, so its cost follows what the grid stores, not its bounds; equal to ``majorant_grid``
    of the dense samples."""
    device = device or volume.device
    r = [min(n, res) for n in dims]
    cells, first = [], []
    for n, rr in zip(dims, r):  # invert the ranges: per sample, the coarse cells it reaches
        lo, hi = np.full(n, rr, np.int32), np.full(n, -1, np.int32)
        for a, (i0, i1) in enumerate(majorant_ranges(n, rr)):
            lo[i0 : i1 + 1] = np.minimum(lo[i0 : i1 + 1], a)
            hi[i0 : i1 + 1] = np.maximum(hi[i0 : i1 + 1], a)
        first.append(sum(len(c) for c in cells))
        cells.append(np.stack([lo, hi], 1))
    out = wp.zeros(r[0] * r[1] * r[2], dtype=float, device=device)
    leaves = wp.empty(volume.get_tile_count(), dtype=wp.vec3i, device=device)
    if leaves.shape[0]:
        volume.get_tiles(out=leaves)
        # each core into its own copy (Warp's CPU atomics are not atomic across threads: a
        # shared grid lost maxima, and the majorant fell below the density it bounds)
        dev.launch_private(leaf_majorant, leaves.shape[0] * 512,
                           [volume.id, leaves, wp.vec3i(*origin), wp.vec3i(*dims),
                            wp.array(np.concatenate(cells), dtype=wp.vec2i, device=device), wp.vec3i(*first),
                            wp.vec3i(*r)], out, max_into, device)
    return np.maximum(out.numpy().reshape(r[2], r[1], r[0]), np.float32(outside))


@wp.kernel
def store_samples(offset: int, volume: wp.uint64, values: wp.array(dtype=float), nx: int, ny: int, z0: int):
    """The non-zero samples of planes z0.. of a dense grid (x fastest) into the volume's voxels."""
    tid = wp.tid() + offset
    v = values[tid]
    if v != 0.0:
        wp.volume_store_f(volume, tid % nx, (tid / nx) % ny, z0 + tid / (nx * ny), v)


def save_volume(path, density, bounds_min, bounds_max, codec: str = "none") -> str:
    """Write a density grid as a NanoVDB file (.nvdb) that a ``type = "grid"`` medium reads
    with ``file`` and the same bounds.

    Parameters
    ----------
    path : str or path-like
        The file to write.
    density : array_like of shape (D, H, W)
        Cell-centred samples [z, y, x] (x fastest, the .npy layout), finite, >= 0.
    bounds_min, bounds_max : 3 numbers each
        The box the samples fill, in scene units: sample (i, j, k) sits at
        bounds_min + (i + 1/2, j + 1/2, k + 1/2) (bounds_max - bounds_min) / (W, H, D).
    codec : "none" or "zip"
        Compression of the file (Warp's ``save_to_nvdb``); zip files are smaller on disk
        and the same in memory.

    The grid is sparse: only the 8^3 leaves that hold a non-zero sample are stored, the
    background is 0. Voxel (i, j, k) is sample (i, j, k), centred as above (index-to-world:
    scale ``cell``, translation bounds_min + cell / 2; Warp's ``load_from_numpy`` would put
    voxel centres on bounds_min and store every leaf of the box). Returns ``path``.
    """
    path = str(path)
    a = np.asarray(density)
    if a.ndim != 3 or a.size == 0 or a.dtype.kind not in "biuf":
        raise ValueError(f"{path}: density of shape {a.shape} and type {a.dtype} "
                         "(allowed: a non-empty 3-D array (D, H, W) of numbers, x fastest)")
    lo, hi = float(a.min()), float(a.max())
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo < 0.0:
        raise ValueError(f"{path}: density has NaN, Inf or negative values (allowed: finite values >= 0)")
    bmin, bmax = np.asarray(bounds_min, np.float64), np.asarray(bounds_max, np.float64)
    if bmin.shape != (3,) or bmax.shape != (3,) or not np.all(np.isfinite(bmin) & np.isfinite(bmax) & (bmax > bmin)):
        raise ValueError(f"{path}: bounds {bmin.tolist()} to {bmax.tolist()} "
                         "(allowed: 3 finite numbers each, bounds_max > bounds_min on every axis)")
    if codec not in ("none", "zip"):
        raise ValueError(f"{path}: codec {codec!r} (allowed: none | zip)")
    nz, ny, nx = a.shape
    cell = (bmax - bmin) / (nx, ny, nz)
    tiles = []
    for z0 in range(0, nz, 8):  # the leaves that hold a non-zero sample, 8 planes at a time
        slab = np.zeros((8, -(-ny // 8) * 8, -(-nx // 8) * 8), bool)
        part = a[z0 : z0 + 8] != 0
        slab[: len(part), :ny, :nx] = part
        ty, tx = np.nonzero(slab.reshape(8, slab.shape[1] // 8, 8, slab.shape[2] // 8, 8).any(axis=(0, 2, 4)))
        tiles.append(np.stack([tx * 8, ty * 8, np.full_like(tx, z0)], 1))
    tiles = np.concatenate(tiles).astype(np.int32)
    if not len(tiles):  # an empty grid is still a grid: one leaf of zeros
        tiles = np.zeros((1, 3), np.int32)
    volume = wp.Volume.allocate_by_tiles(wp.array(tiles, dtype=wp.vec3i, device="cpu"), voxel_size=cell.tolist(),
                                         bg_value=0.0, translation=(bmin + 0.5 * cell).tolist(), device="cpu")
    for z0 in range(0, nz, 8):
        planes = np.ascontiguousarray(a[z0 : z0 + 8], np.float32).ravel()
        if np.any(planes):
            dev.launch(store_samples, planes.size, [volume.id, wp.array(planes, dtype=float, device="cpu"), nx, ny, z0],
                       "cpu")
    volume.save_to_nvdb(path, codec=codec)
    return path


@wp.func
def walk_start(lo: wp.vec3, h: wp.vec3, n: wp.vec3i, o: wp.vec3, d: wp.vec3, t: float):
    """A 3-D DDA (Amanatides & Woo 1987) over an n-cell grid of cell size h from lo, for the
    ray o + t d from t: (cell, step per axis, t of the next boundary per axis, t between
    boundaries per axis). ``walk_next`` advances it."""
    p = o + t * d
    cell = wp.vec3i(0)
    step = wp.vec3i(0)
    t_next = wp.vec3(INF)
    t_delta = wp.vec3(INF)
    for a in range(3):
        ci = wp.clamp(int(wp.floor((p[a] - lo[a]) / h[a])), 0, n[a] - 1)
        cell[a] = ci
        if d[a] > 0.0:
            step[a] = 1
            t_next[a] = (lo[a] + float(ci + 1) * h[a] - o[a]) / d[a]
            t_delta[a] = h[a] / d[a]
        elif d[a] < 0.0:
            step[a] = -1
            t_next[a] = (lo[a] + float(ci) * h[a] - o[a]) / d[a]
            t_delta[a] = -h[a] / d[a]
    return cell, step, t_next, t_delta


@wp.func
def walk_axis(t_next: wp.vec3) -> int:
    """The axis whose boundary the ray crosses next."""
    if t_next[0] <= t_next[1] and t_next[0] <= t_next[2]:
        return 0
    if t_next[1] <= t_next[2]:
        return 1
    return 2


@wp.func
def lattice_trilinear_vec3(values: wp.array(dtype=wp.vec3), base: int, stride: int, n: int, lo: wp.vec3,
                           hi: wp.vec3, x: wp.vec3) -> wp.vec3:
    """Trilinear lookup in an n^3 lattice of vec3 with nodes on the corners of [lo, hi]
    (node (i, j, k) at lo + (i, j, k) (hi - lo) / (n - 1), x fastest; node q's value at
    ``base + stride q``, so several lattices can be interleaved); points outside clamp to the
    boundary."""
    return lattice_at_vec3(values, base, stride, n, wp.cw_div(x - lo, hi - lo) * float(n - 1))


@wp.func
def lattice_cell(n: int, g: wp.vec3):
    """The cell of an n^3 lattice that holds lattice coordinates g (node (i, j, k) at g = (i, j, k);
    clamped to the lattice): its first node's index (z0 n + y0) n + x0, x fastest, and g's place
    in the cell, in [0, 1]^3."""
    fx = wp.clamp(g[0], 0.0, float(n - 1))
    fy = wp.clamp(g[1], 0.0, float(n - 1))
    fz = wp.clamp(g[2], 0.0, float(n - 1))
    x0 = wp.min(int(fx), n - 2)
    y0 = wp.min(int(fy), n - 2)
    z0 = wp.min(int(fz), n - 2)
    return (z0 * n + y0) * n + x0, wp.vec3(fx - float(x0), fy - float(y0), fz - float(z0))


@wp.func
def trilinear_weights(t: wp.vec3):
    """The weights of a cell's eight nodes at t in it: the nodes (0, 0), (1, 0), (0, 1), (1, 1) in
    (x, y) at z = 0, then the same four at z = 1."""
    tx = t[0]
    ty = t[1]
    tz = t[2]
    return (wp.vec4((1.0 - tx) * (1.0 - ty) * (1.0 - tz), tx * (1.0 - ty) * (1.0 - tz), (1.0 - tx) * ty * (1.0 - tz),
                    tx * ty * (1.0 - tz)),
            wp.vec4((1.0 - tx) * (1.0 - ty) * tz, tx * (1.0 - ty) * tz, (1.0 - tx) * ty * tz, tx * ty * tz))


@wp.func
def lattice_at_vec3(values: wp.array(dtype=wp.vec3), base: int, stride: int, n: int, g: wp.vec3) -> wp.vec3:
    """``lattice_trilinear_vec3`` at lattice coordinates g (node (i, j, k) at g = (i, j, k);
    clamped to the lattice), for lattices whose nodes are not evenly spaced."""
    q, t = lattice_cell(n, g)
    tx = t[0]
    ty = t[1]
    tz = t[2]
    i = base + q * stride
    sx = stride
    sy = n * stride
    sz = n * n * stride
    c00 = values[i] * (1.0 - tx) + values[i + sx] * tx
    c10 = values[i + sy] * (1.0 - tx) + values[i + sy + sx] * tx
    c01 = values[i + sz] * (1.0 - tx) + values[i + sz + sx] * tx
    c11 = values[i + sz + sy] * (1.0 - tx) + values[i + sz + sy + sx] * tx
    return (c00 * (1.0 - ty) + c10 * ty) * (1.0 - tz) + (c01 * (1.0 - ty) + c11 * ty) * tz


@wp.struct
class Grid:
    """A density grid as kernels read it (``GridBuffers`` builds it): its samples, dense or in a
    NanoVDB volume, and the bounds of the density per cell of its coarse majorant grid."""

    data: wp.array(dtype=float)  # dense samples, x fastest (unread when volume is set)
    volume: wp.uint64  # a NanoVDB wp.Volume holding the samples (0: data does)
    origin: wp.vec3i  # the volume's voxel that is sample (0, 0, 0)
    dims: wp.vec3i  # samples per axis (x, y, z)
    lo: wp.vec3  # bounds, scene units
    hi: wp.vec3
    majorant: wp.array(dtype=float)  # per coarse cell, x fastest
    majorant_dims: wp.vec3i  # coarse cells per axis (x, y, z)


@wp.func
def grid_density(G: Grid, x: wp.vec3) -> float:
    """The trilinear density factor at x (dense or NanoVDB: the same value); 0 outside the bounds."""
    if not inside_box(x, G.lo, G.hi):
        return 0.0
    if G.volume != wp.uint64(0):
        return volume_trilinear(G.volume, G.origin, G.dims, G.lo, G.hi, x)
    return grid_trilinear(G.data, 0, G.dims, G.lo, G.hi, x)


@wp.func
def grid_tracking(G: Grid, o: wp.vec3, d: wp.vec3, t0: float, t1: float, sig: float, ratio: bool, rng: wp.uint32):
    """Tracking through the grid on [t0, t1) against its majorant grid (times ``sig``, the
    channel's scale), walked cell by cell by a DDA (an exponential step that leaves a cell
    restarts at its boundary: memoryless).

    ``ratio`` False, delta tracking: (t of the first real collision, 1) or (t1, 0). ``ratio``
    True, ratio tracking (Novak et al. 2014): (t1, an unbiased estimate of the transmittance),
    with Russian roulette once the weight falls below 0.1."""
    a, b = ray_box(o, d, G.lo, G.hi)
    t = wp.max(a, t0)
    t_end = wp.min(b, t1)
    w = float(1.0)
    if t >= t_end:
        return t1, wp.where(ratio, 1.0, 0.0)
    n = G.majorant_dims
    cell, step, t_next, t_delta = walk_start(G.lo, wp.cw_div(G.hi - G.lo, wp.vec3(float(n[0]), float(n[1]), float(n[2]))),
                                             n, o, d, t)
    while t < t_end:
        seg_end = wp.min(wp.min(wp.min(t_next[0], t_next[1]), t_next[2]), t_end)
        mu = G.majorant[(cell[2] * n[1] + cell[1]) * n[0] + cell[0]] * sig
        while mu > 0.0:
            t = t + sample_exponential(wp.randf(rng), mu)
            if t >= seg_end:
                break
            real = grid_density(G, o + t * d) * sig / mu
            if not ratio:
                if wp.randf(rng) < real:
                    return t, 1.0
            else:
                w *= 1.0 - real
                if w < 0.1:  # Russian roulette keeps long thick segments short, unbiased
                    if wp.randf(rng) < 0.5:
                        return t1, 0.0
                    w *= 2.0
        t = seg_end
        ax = walk_axis(t_next)
        cell[ax] = cell[ax] + step[ax]
        t_next[ax] = t_next[ax] + t_delta[ax]
        if cell[ax] < 0 or cell[ax] >= n[ax]:
            break
    return t1, wp.where(ratio, w, 0.0)


@wp.func
def grid_extinction(G: Grid, sigma: wp.vec3, x: wp.vec3) -> wp.vec3:
    """sigma_t at x: the trilinear density times sigma (the medium interface, as ``shape_extinction``)."""
    return grid_density(G, x) * sigma


@wp.func
def grid_free_flight(G: Grid, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int,
                     rng: wp.uint32):
    """The first real collision on [t0, t1) in channel c by delta tracking (``grid_tracking``):
    (t, whether there is one, the generator after its draw). A grid has no closed-form optical
    depth: its transmittance is tracked too (``grid_transmittance``)."""
    t, w = grid_tracking(G, o, d, t0, t1, sigma[c], False, wp.rand_init(wp.randi(rng), STREAM))
    return t, w > 0.0, rng


@wp.func
def grid_transmittance(G: Grid, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int,
                       rng: wp.uint32):
    """An unbiased estimate of channel c's transmittance over [t0, t1] by ratio tracking
    (``grid_tracking``): (the estimate, the generator after its draw)."""
    t, w = grid_tracking(G, o, d, t0, t1, sigma[c], True, wp.rand_init(wp.randi(rng), STREAM))
    return w, rng


class GridBuffers:
    """Owns the device arrays behind a ``Grid`` struct: ``density`` (D, H, W) float samples
    [z, y, x], or ``volume`` (a ``wp.Volume`` whose voxel ``origin`` + (i, j, k) is sample
    (i, j, k)), of ``dims`` (x, y, z) samples over [lo, hi]; ``outside`` is what the volume
    returns outside its leaves. ``coarse`` is the majorant grid (host, [z, y, x]) and ``bound``
    its largest cell: the largest sample."""

    def __init__(self, density, volume, origin, dims, lo, hi, device, outside: float = 0.0):
        if volume is not None:
            self.coarse = volume_majorant_grid(volume, origin, dims, outside)
            data = np.zeros(1, np.float32)
        else:
            self.coarse = majorant_grid(density)
            data = np.asarray(density).ravel().astype(np.float32, copy=False)  # one copy only
        self.volume = volume  # kept alive while kernels read it
        self.bound = float(self.coarse.max())
        s = Grid()
        s.data = wp.array(data, dtype=float, device=device)
        s.volume = wp.uint64(volume.id if volume is not None else 0)
        s.origin = wp.vec3i(*(origin if volume is not None else (0, 0, 0)))
        s.dims = wp.vec3i(*dims)
        s.lo, s.hi = wp.vec3(*np.asarray(lo, np.float32)), wp.vec3(*np.asarray(hi, np.float32))
        mz, my, mx = self.coarse.shape
        s.majorant = wp.array(self.coarse.ravel().astype(np.float32), dtype=float, device=device)
        s.majorant_dims = wp.vec3i(mx, my, mz)
        self.struct = s
