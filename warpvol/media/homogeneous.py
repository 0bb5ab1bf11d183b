"""Homogeneous media: a box or a sphere of uniform extinction sigma_t (density factor 1 inside).

Along a ray each is one chord [a, b] (a slab or a sphere test), so its optical depth over
[t0, t1] is sigma_t times the overlap of the two and its first collision one exponential
variate: t0' + E / sigma_t, E ~ Exp(1), when that falls inside the chord.

The medium interface every kind module exposes, with the same arguments (the kind's struct,
the medium's RGB scale sigma, then the point or the ray): ``shape_extinction`` (sigma_t at x),
``shape_tau`` (the optical depth over [t0, t1], in closed form) and ``shape_free_flight`` (the
first collision in channel c: t, whether there is one, the generator after its draws).
"""

import warp as wp

from ..geometry.intersect import inside_box, ray_box, ray_sphere
from ..physics.constants import INF
from ..physics.sampling import sample_exponential


@wp.struct
class Shape:
    """A homogeneous medium's shape: the box [lo, hi] (box = 1) or the ball (centre, radius)."""

    box: int
    lo: wp.vec3
    hi: wp.vec3
    centre: wp.vec3
    radius: float


@wp.func
def shape_inside(box: bool, lo: wp.vec3, hi: wp.vec3, centre: wp.vec3, radius: float, x: wp.vec3) -> bool:
    """Whether x lies in the box [lo, hi] (``box``) or in the ball (centre, radius)."""
    if not box:
        r = x - centre
        return wp.dot(r, r) <= radius * radius
    return inside_box(x, lo, hi)


@wp.func
def shape_chord(box: bool, lo: wp.vec3, hi: wp.vec3, centre: wp.vec3, radius: float, o: wp.vec3, d: wp.vec3):
    """(a, b): the chord of the ray o + t d (unit d) through the box or the ball; a >= b: a miss."""
    if box:
        return ray_box(o, d, lo, hi)
    return ray_sphere(o, d, centre, radius)


@wp.func
def shape_length(box: bool, lo: wp.vec3, hi: wp.vec3, centre: wp.vec3, radius: float, o: wp.vec3, d: wp.vec3,
                 t0: float, t1: float) -> float:
    """The length of [t0, t1] along o + t d (unit d) inside the box or the ball. Both ends
    inside (t1 finite) is all of it, with no slab test: the shape is convex."""
    a = float(0.0)
    b = float(0.0)
    if shape_inside(box, lo, hi, centre, radius, o + t0 * d) and t1 < INF and \
            shape_inside(box, lo, hi, centre, radius, o + t1 * d):
        a = t0
        b = t1
    else:
        a, b = shape_chord(box, lo, hi, centre, radius, o, d)
    return wp.max(wp.min(b, t1) - wp.max(a, t0), 0.0)


@wp.func
def uniform_collision(a: float, b: float, sig: float, u: float) -> float:
    """The first collision in a uniform medium of extinction sig on [a, b), from the uniform
    variate u: a + E / sig with E exponential, or INF when it falls past b (or a >= b)."""
    if a >= b:
        return INF
    t = a + sample_exponential(u, sig)
    return wp.where(t < b, t, INF)


@wp.func
def shape_extinction(S: Shape, sigma: wp.vec3, x: wp.vec3) -> wp.vec3:
    """sigma_t at x: sigma inside the shape, 0 outside."""
    return wp.where(shape_inside(S.box != 0, S.lo, S.hi, S.centre, S.radius, x), 1.0, 0.0) * sigma


@wp.func
def shape_tau(S: Shape, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, t0: float, t1: float) -> wp.vec3:
    """The optical depth over [t0, t1] along o + t d (unit d): sigma times the chord's overlap."""
    return shape_length(S.box != 0, S.lo, S.hi, S.centre, S.radius, o, d, t0, t1) * sigma


@wp.func
def shape_free_flight(S: Shape, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int,
                      rng: wp.uint32):
    """The first collision on [t0, t1) along o + t d (unit d) in channel c: (t, whether there is
    one, the generator after its draw); one exponential variate in the chord."""
    a, b = shape_chord(S.box != 0, S.lo, S.hi, S.centre, S.radius, o, d)
    t = uniform_collision(wp.max(a, t0), wp.min(b, t1), sigma[c], wp.randf(rng))
    return t, t < t1, rng
