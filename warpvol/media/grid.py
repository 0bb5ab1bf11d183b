"""Dense extinction grids: cell-centred samples, trilinear lookup, zero outside the bounds.

``data`` holds grids flattened with x fastest (the .npy layout [z, y, x]); sample (i, j, k)
sits at bounds_min + (i + 0.5, j + 0.5, k + 0.5) * cell. Inside the half-cell border the
lookup clamps to the outermost samples.
"""

from typing import Any

import numpy as np
import warp as wp

from ..geometry.intersect import inside_box
from ..physics.constants import INF


@wp.func
def grid_value(data: wp.array(dtype=Any), offset: int, dims: wp.vec3i, ix: int, iy: int, iz: int):
    return data[offset + (iz * dims[1] + iy) * dims[0] + ix]


@wp.func
def grid_trilinear(data: wp.array(dtype=Any), offset: int, dims: wp.vec3i, bmin: wp.vec3, bmax: wp.vec3, x: wp.vec3):
    """Trilinear between cell centres of a float or vec3 grid; zero outside [bmin, bmax]."""
    if not inside_box(x, bmin, bmax):
        return grid_value(data, offset, dims, 0, 0, 0) * 0.0  # the grid's own zero, float or vec3 (data are finite)
    g = wp.cw_div(x - bmin, bmax - bmin)
    fx = wp.clamp(g[0] * float(dims[0]) - 0.5, 0.0, float(dims[0] - 1))
    fy = wp.clamp(g[1] * float(dims[1]) - 0.5, 0.0, float(dims[1] - 1))
    fz = wp.clamp(g[2] * float(dims[2]) - 0.5, 0.0, float(dims[2] - 1))
    x0 = wp.min(int(fx), wp.max(dims[0] - 2, 0))
    y0 = wp.min(int(fy), wp.max(dims[1] - 2, 0))
    z0 = wp.min(int(fz), wp.max(dims[2] - 2, 0))
    x1 = wp.min(x0 + 1, dims[0] - 1)
    y1 = wp.min(y0 + 1, dims[1] - 1)
    z1 = wp.min(z0 + 1, dims[2] - 1)
    tx = fx - float(x0)
    ty = fy - float(y0)
    tz = fz - float(z0)
    c00 = grid_value(data, offset, dims, x0, y0, z0) * (1.0 - tx) + grid_value(data, offset, dims, x1, y0, z0) * tx
    c10 = grid_value(data, offset, dims, x0, y1, z0) * (1.0 - tx) + grid_value(data, offset, dims, x1, y1, z0) * tx
    c01 = grid_value(data, offset, dims, x0, y0, z1) * (1.0 - tx) + grid_value(data, offset, dims, x1, y0, z1) * tx
    c11 = grid_value(data, offset, dims, x0, y1, z1) * (1.0 - tx) + grid_value(data, offset, dims, x1, y1, z1) * tx
    return (c00 * (1.0 - ty) + c10 * ty) * (1.0 - tz) + (c01 * (1.0 - ty) + c11 * ty) * tz


def grid_majorant(density: np.ndarray) -> float:
    """Trilinear interpolation never exceeds the largest sample."""
    return float(np.max(density))


#: Majorant cells per axis at most (fewer where the grid has fewer samples).
MAJORANT_RES = 32


def majorant_grid(density: np.ndarray, res: int = MAJORANT_RES) -> np.ndarray:
    """A rigorous bound of the trilinear density over each cell of a coarse grid over the same
    bounds: (rz, ry, rx) float32, r = min(samples, ``res``) per axis, [z, y, x] like ``density``.
    The lookup at a point blends the samples of the cell-centre lattice around it, so a coarse
    cell's bound is the largest sample whose blending support reaches into the cell."""
    out = np.asarray(density, np.float32)
    for axis in range(3):
        n = out.shape[axis]
        r = min(n, res)
        pieces = []
        for a in range(r):
            # samples blended somewhere in [a, a + 1) / r of the axis: fractional index f = x n - 0.5
            i0 = max(int(np.floor(a * n / r - 0.5)), 0)
            i1 = min(int(np.floor((a + 1) * n / r - 0.5)) + 1, n - 1)
            pieces.append(np.take(out, np.arange(i0, i1 + 1), axis=axis).max(axis=axis, keepdims=True))
        out = np.concatenate(pieces, axis=axis)
    return out


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
def lattice_trilinear_vec3(values: wp.array(dtype=wp.vec3), base: int, n: int, lo: wp.vec3, hi: wp.vec3,
                           x: wp.vec3) -> wp.vec3:
    """Trilinear lookup in an n^3 lattice of vec3 with nodes on the corners of [lo, hi]
    (node (i, j, k) at lo + (i, j, k) (hi - lo) / (n - 1), x fastest, from ``base``);
    points outside clamp to the boundary."""
    g = wp.cw_div(x - lo, hi - lo) * float(n - 1)
    fx = wp.clamp(g[0], 0.0, float(n - 1))
    fy = wp.clamp(g[1], 0.0, float(n - 1))
    fz = wp.clamp(g[2], 0.0, float(n - 1))
    x0 = wp.min(int(fx), n - 2)
    y0 = wp.min(int(fy), n - 2)
    z0 = wp.min(int(fz), n - 2)
    tx = fx - float(x0)
    ty = fy - float(y0)
    tz = fz - float(z0)
    i = base + (z0 * n + y0) * n + x0
    c00 = values[i] * (1.0 - tx) + values[i + 1] * tx
    c10 = values[i + n] * (1.0 - tx) + values[i + n + 1] * tx
    c01 = values[i + n * n] * (1.0 - tx) + values[i + n * n + 1] * tx
    c11 = values[i + n * n + n] * (1.0 - tx) + values[i + n * n + n + 1] * tx
    return (c00 * (1.0 - ty) + c10 * ty) * (1.0 - tz) + (c01 * (1.0 - ty) + c11 * ty) * tz
