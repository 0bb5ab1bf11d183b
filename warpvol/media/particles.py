"""Particle media: N spheres of one radius, each of uniform extinction; overlaps add.

The density factor at x is the number of spheres that contain x, found through a
``wp.HashGrid`` with cells of the particle radius.
"""

import numpy as np
import warp as wp

from .rbf import box_distance2, coarse_cells


@wp.func
def particle_count(grid: wp.uint64, points: wp.array(dtype=wp.vec3), offset: int, radius: float, x: wp.vec3) -> float:
    n = float(0.0)
    index = int(0)
    query = wp.hash_grid_query(grid, x, radius)
    while wp.hash_grid_query_next(query, index):
        d = x - points[offset + index]
        if wp.dot(d, d) <= radius * radius:
            n += 1.0
    return n


def particle_majorant(positions: np.ndarray, radius: float, n: int = 12) -> float:
    """Largest number of spheres touching one coarse cell: a bound of the overlap count."""
    if len(positions) == 0:
        return 0.0
    lo, hi = coarse_cells(positions.min(0) - radius, positions.max(0) + radius, n)
    count = np.zeros(len(lo))
    for s in range(0, len(positions), 2048):
        count += np.sum(box_distance2(lo, hi, positions[s : s + 2048].astype(np.float64)) <= radius * radius, axis=1)
    return float(count.max())


@wp.func
def sphere_chord(o: wp.vec3, d: wp.vec3, t1: float, c: wp.vec3, r: float) -> float:
    """Length of the part of the segment o + t d (unit d, 0 <= t <= t1) inside the sphere
    (c, r): the sphere's share of the optical depth is sigma_t times this."""
    oc = c - o
    b = wp.dot(oc, d)
    h2 = r * r - (wp.dot(oc, oc) - b * b)
    if h2 <= 0.0:
        return 0.0
    h = wp.sqrt(h2)
    return wp.max(wp.min(b + h, t1) - wp.max(b - h, 0.0), 0.0)
