"""Rays against boxes and spheres, and points in boxes: the one definition every medium,
technique and shading routine uses.

A ray is o + t d; ``ray_box`` takes any d (axis-parallel d included), the sphere tests a
unit d. Results are parameters t along the ray (scene units for a unit d).
"""

import warp as wp

from ..physics.constants import INF


@wp.func
def inside_box(x: wp.vec3, lo: wp.vec3, hi: wp.vec3) -> bool:
    """Whether x lies in the closed box [lo, hi]."""
    return x[0] >= lo[0] and x[1] >= lo[1] and x[2] >= lo[2] and x[0] <= hi[0] and x[1] <= hi[1] and x[2] <= hi[2]


@wp.func
def ray_box(o: wp.vec3, d: wp.vec3, bmin: wp.vec3, bmax: wp.vec3):
    """Slab test: (t_near, t_far); t_near > t_far when the ray misses."""
    t0 = float(-INF)
    t1 = float(INF)
    for a in range(3):
        if wp.abs(d[a]) < 1.0e-20:
            if o[a] < bmin[a] or o[a] > bmax[a]:
                return INF, -INF
        else:
            inv = 1.0 / d[a]
            ta = (bmin[a] - o[a]) * inv
            tb = (bmax[a] - o[a]) * inv
            t0 = wp.max(t0, wp.min(ta, tb))
            t1 = wp.min(t1, wp.max(ta, tb))
    return t0, t1


@wp.func
def ray_sphere(o: wp.vec3, d: wp.vec3, c: wp.vec3, r: float):
    """(t_near, t_far) of a unit-direction ray and the sphere (c, r); t_near > t_far when it misses."""
    oc = o - c
    b = wp.dot(oc, d)
    h = b * b - (wp.dot(oc, oc) - r * r)
    if h < 0.0:
        return INF, -INF
    s = wp.sqrt(h)
    return -b - s, -b + s


@wp.func
def sphere_chord(o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: wp.vec3, r: float) -> float:
    """Length of the part of the segment o + t d (unit d, t0 <= t <= t1) inside the sphere
    (c, r): the sphere's share of the optical depth is sigma_t times this."""
    oc = c - o
    b = wp.dot(oc, d)
    h2 = r * r - (wp.dot(oc, oc) - b * b)
    if h2 <= 0.0:
        return 0.0
    h = wp.sqrt(h2)
    return wp.max(wp.min(b + h, t1) - wp.max(b - h, t0), 0.0)
