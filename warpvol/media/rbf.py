"""Gaussian RBF media: sigma_t(x) = peak sum_i a_i exp(-|x - c_i|^2 / (2 r_i^2)), each
Gaussian of its own standard deviation r_i and amplitude a_i.

Each Gaussian is cut off at CUTOFF r_i, where it has fallen to exp(-CUTOFF^2 / 2) = 3.7e-6
of its peak: the error this leaves is below 3.7e-6 a_i peak per overlapping RBF. Centres are
found through a ``wp.HashGrid`` queried at the largest cut-off radius.
"""

import numpy as np
import warp as wp

CUTOFF = wp.constant(5.0)


@wp.func
def rbf_density(grid: wp.uint64, points: wp.array(dtype=wp.vec3), radii: wp.array(dtype=float),
                amplitudes: wp.array(dtype=float), offset: int, largest: float, x: wp.vec3) -> float:
    """sum_i a_i exp(-|x - c_i|^2 / (2 r_i^2)) over the centres within their cut-off
    (``largest``: the largest r_i, the hash grid's query radius over CUTOFF)."""
    s = float(0.0)
    index = int(0)
    query = wp.hash_grid_query(grid, x, CUTOFF * largest)
    while wp.hash_grid_query_next(query, index):
        k = offset + index
        d = x - points[k]
        d2 = wp.dot(d, d)
        r = radii[k]
        if d2 < CUTOFF * CUTOFF * r * r:
            s += amplitudes[k] * wp.exp(-0.5 * d2 / (r * r))
    return s


def box_distance2(lo: np.ndarray, hi: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Squared distance from points p (N, 3) to each box [lo, hi] (C, 3): shape (C, N)."""
    d = np.maximum(lo[:, None, :] - p[None], 0.0) + np.maximum(p[None] - hi[:, None, :], 0.0)
    return np.sum(d * d, axis=-1)


def coarse_cells(bmin: np.ndarray, bmax: np.ndarray, n: int):
    edges = [np.linspace(bmin[a], bmax[a], n + 1) for a in range(3)]
    lo = np.stack(np.meshgrid(edges[0][:-1], edges[1][:-1], edges[2][:-1], indexing="ij"), -1).reshape(-1, 3)
    hi = np.stack(np.meshgrid(edges[0][1:], edges[1][1:], edges[2][1:], indexing="ij"), -1).reshape(-1, 3)
    return lo, hi


def rbf_majorant(centers: np.ndarray, radius, n: int = 12, amplitudes=None) -> float:
    """A rigorous bound of the density factor: over coarse cells, the sum of each Gaussian's
    maximum over the cell (its value at the closest point of the cell). ``radius``: one for
    all or one a centre; ``amplitudes``: one a centre (default 1)."""
    if len(centers) == 0:
        return 0.0
    radii = np.broadcast_to(np.asarray(radius, np.float64), (len(centers),))
    amps = np.ones(len(centers)) if amplitudes is None else np.asarray(amplitudes, np.float64)
    cut = float(CUTOFF) * radii.max()
    lo, hi = coarse_cells(centers.min(0) - cut, centers.max(0) + cut, n)
    total = np.zeros(len(lo))
    for s in range(0, len(centers), 2048):
        d2 = box_distance2(lo, hi, centers[s : s + 2048].astype(np.float64))
        r, a = radii[s : s + 2048], amps[s : s + 2048]
        cut_k = float(CUTOFF) * r
        total += np.sum(np.where(d2 < cut_k * cut_k, a * np.exp(-d2 / (2 * r * r)), 0.0), axis=1)
    return float(total.max())
