"""Point, spot and directional lights: what reaches a point x.

| kind        | strength  | units            | at x                                     |
|-------------|-----------|------------------|------------------------------------------|
| point       | intensity | W/sr (per RGB)   | irradiance I / d^2 from ``position``     |
| spot        | intensity | W/sr             | I / d^2 times a smoothstep cone falloff  |
| directional | irradiance| W/m^2            | E, arriving against ``direction``        |

``direction`` of a directional light is the way its light travels; of a spot light, the
axis of its cone. The spot falloff is smoothstep(cos_outer, cos_inner, cos(angle to axis)).
"""

import warp as wp

from .constants import INF

POINT = wp.constant(0)
SPOT = wp.constant(1)
DIRECTIONAL = wp.constant(2)

KINDS = {"point": 0, "spot": 1, "directional": 2}


@wp.struct
class Emitter:
    """A light as kernels read it (``upload.light_structs`` makes one of a scene ``Light``)."""

    kind: int
    position: wp.vec3
    direction: wp.vec3  # unit; travel direction (directional) or cone axis (spot)
    strength: wp.vec3  # intensity I (point, spot) or irradiance E (directional)
    cos_inner: float
    cos_outer: float


@wp.func
def spot_falloff(light: Emitter, cos_axis: float) -> float:
    if cos_axis >= light.cos_inner:
        return 1.0
    if cos_axis <= light.cos_outer:
        return 0.0
    t = (cos_axis - light.cos_outer) / (light.cos_inner - light.cos_outer)
    return t * t * (3.0 - 2.0 * t)


@wp.func
def light_incident(light: Emitter, x: wp.vec3):
    """Returns (wi, dist, E): unit direction from x to the light, distance to it
    (INF for directional), and the irradiance it delivers to a surface facing it."""
    if light.kind == DIRECTIONAL:
        return -light.direction, INF, light.strength
    to_light = light.position - x
    d2 = wp.dot(to_light, to_light)
    if d2 <= 0.0:
        return wp.vec3(0.0, 1.0, 0.0), 0.0, wp.vec3(0.0)
    dist = wp.sqrt(d2)
    wi = to_light / dist
    e = light.strength / d2
    if light.kind == SPOT:
        e = e * spot_falloff(light, wp.dot(-wi, light.direction))
    return wi, dist, e


@wp.func
def ball_mean_inverse_square(r: float, d: float) -> float:
    """Mean of 1/|x - s|^2 over a ball of radius r whose centre lies d from s: the mean
    irradiance per unit intensity that a point light at s delivers to a spherical particle.

    3/(4 r^3) [(r^2 - d^2)/d ln((r + d)/|r - d|) + 2 r], from shells around the centre
    (each averages ln((rho + d)/|rho - d|)/(2 rho d)). Bounded where 1/d^2 is not: 3/r^2 at
    the centre, 3/(2 r^2) on the surface, ~1/d^2 far away. The closed form cancels in
    float32 away from the surface, so with x = d/r the series
    3/r^2 (1 - sum_k x^2k/(4k^2 - 1)) (x < 1/2) and 3/r^2 sum_k x^-2k/(4k^2 - 1) (x > 2),
    k >= 1, summed to 12 terms (remainder < 4^-12), are used there."""
    if r <= 0.0:
        return 1.0 / wp.max(d * d, 1.0e-30)
    x = d / r
    if x < 0.5 or x > 2.0:
        y2 = wp.where(x < 0.5, x * x, 1.0 / (x * x))
        term = float(1.0)
        acc = float(0.0)
        for k in range(1, 13):
            term *= y2
            acc += term / float(4 * k * k - 1)
        return 3.0 / (r * r) * wp.where(x < 0.5, 1.0 - acc, acc)
    if wp.abs(x - 1.0) < 1.0e-6:
        return 1.5 / (r * r)
    return 0.75 / (r * r * r) * ((r * r - d * d) / d * wp.log((r + d) / wp.abs(r - d)) + 2.0 * r)


@wp.func
def particle_incident(light: Emitter, x: wp.vec3, r: float):
    """Returns (w, dist, E) for a spherical particle of radius r centred at x: the direction
    light travels on arrival (zero when a point light sits at the centre, where it arrives
    from every side), the distance to the light (INF for directional) and the irradiance
    averaged over the particle's volume (``ball_mean_inverse_square``), finite everywhere."""
    if light.kind == DIRECTIONAL:
        return light.direction, INF, light.strength
    to = x - light.position
    d = wp.length(to)
    w = wp.vec3(0.0)
    falloff = float(1.0)
    if d > 1.0e-6 * r:
        w = to / d
        if light.kind == SPOT:
            falloff = spot_falloff(light, wp.dot(w, light.direction))
    return w, d, light.strength * (ball_mean_inverse_square(r, d) * falloff)


#: float32's relative resolution (2^-23): a point light nearer a ray than this times its distance
#: from the ray's origin lies on the ray as far as float32 positions can tell.
POSITION_EPS = wp.constant(1.2e-7)


@wp.func
def segment_mean_inverse_square(o: wp.vec3, d: wp.vec3, t0: float, t1: float, p: wp.vec3) -> float:
    """Mean of 1 / |o + t d - p|^2 over t in [t0, t1] (d unit): (atan((t1 - tc) / h) -
    atan((t0 - tc) / h)) / (h (t1 - t0)), tc the closest approach to p and h its distance.
    A march step that takes it instead of 1/d^2 at its midpoint does not alias a point
    light's peak; h is kept above 1e-6 (t1 - t0) (the ray through the light itself) and above
    float32's resolution of |p - o| (``POSITION_EPS``): a step shorter than the resolution of t
    there (a medium 1e-6 thick seen from 3 away) has t1 - t0 = 0, and a ray through the light
    then had h = 0 and tm = 0, 1 / 0 = inf (NaN times a light of intensity 0)."""
    rel = p - o
    tc = wp.dot(rel, d)
    h2 = wp.max(wp.dot(rel, rel) - tc * tc, 0.0)
    dt = t1 - t0
    h = wp.max(wp.sqrt(h2), wp.max(1.0e-6 * dt, POSITION_EPS * wp.length(rel)))
    if dt <= 1.0e-4 * h:  # a step short beside the distance: the midpoint value
        tm = 0.5 * (t0 + t1) - tc
        return 1.0 / (h * h + tm * tm)
    return (wp.atan((t1 - tc) / h) - wp.atan((t0 - tc) / h)) / (h * dt)



@wp.func
def ball_window(r: float, radius: float) -> float:
    """(1 - (r / R)^2)^2 within ``radius`` R of a light, 0 beyond: the part of its 1/r^2 a
    march takes ray by ray at equiangular points. What it leaves, (1 - w) / r^2 =
    2 / R^2 - r^2 / R^4 inside the ball and 1/r^2 outside, is smooth and bounded (its integral
    along a ray: ``segment_mean_outside_window``), so neighbouring rays may share samples of it."""
    if r >= radius:
        return 0.0
    q = 1.0 - (r * r) / (radius * radius)
    return q * q


@wp.func
def inverse_square_integral(h: float, u0: float, u1: float) -> float:
    """int_u0^u1 du / (h^2 + u^2) for u0 <= u1 on one side of 0 (u0 u1 >= 0): atan of the
    difference by the subtraction rule, h (u1 - u0) / (h^2 + u0 u1), so a tiny h loses no digits."""
    return wp.atan(h * (u1 - u0) / (h * h + u0 * u1)) / h


@wp.func
def segment_mean_outside_window(o: wp.vec3, d: wp.vec3, t0: float, t1: float, p: wp.vec3, radius: float) -> float:
    """Mean over t in [t0, t1] (d unit) of (1 - ``ball_window``(r, radius)) / r^2, r = |o + t d - p|:
    1/r^2 outside the ball (``segment_mean_inverse_square``), 2 / R^2 - r^2 / R^4 inside, both in
    closed form. radius 0: the plain mean of 1/r^2."""
    rel = p - o
    tc = wp.dot(rel, d)
    h2 = wp.max(wp.dot(rel, rel) - tc * tc, 0.0)
    dt = t1 - t0
    if radius <= 0.0 or h2 >= radius * radius:
        return segment_mean_inverse_square(o, d, t0, t1, p)
    h = wp.max(wp.sqrt(h2), wp.max(1.0e-6 * dt, POSITION_EPS * wp.length(rel)))
    r2 = radius * radius
    if dt <= 1.0e-4 * radius:  # a step short beside the ball: the midpoint value
        tm = 0.5 * (t0 + t1) - tc
        q = h * h + tm * tm
        return wp.where(q >= r2, 1.0 / q, 2.0 / r2 - q / (r2 * r2))
    s = wp.sqrt(r2 - wp.min(h * h, r2))
    u0 = t0 - tc
    u1 = t1 - tc
    total = float(0.0)
    if u0 < -s:  # before the ball
        total += inverse_square_integral(h, u0, wp.min(u1, -s))
    if u1 > s:  # after it
        total += inverse_square_integral(h, wp.max(u0, s), u1)
    a = wp.max(u0, -s)
    b = wp.min(u1, s)
    if b > a:  # inside: (2 / R^2 - h^2 / R^4) - u^2 / R^4
        total += (2.0 / r2 - h * h / (r2 * r2)) * (b - a) - (b * b * b - a * a * a) / (3.0 * r2 * r2)
    return total / dt


@wp.func
def step_mean_outside_window(light: Emitter, e: wp.vec3, dist: float, o: wp.vec3, d: wp.vec3, t0: float, t1: float,
                             radius: float):
    """``step_mean_irradiance`` with a point or spot light's 1/d^2 replaced by its mean over the
    step of what its ball leaves (``segment_mean_outside_window``). Directional lights: ``e``."""
    if light.kind == DIRECTIONAL:
        return e
    e_d2 = wp.where(dist > 1.0e-10, e * (dist * dist), light.strength)  # I x falloff (x visibility)
    return e_d2 * segment_mean_outside_window(o, d, t0, t1, light.position, radius)


#: Beside a point or spot light a march step is split into equal angles at the light of at most
#: ANGLE_STEP radians (``step_angle``), up to MAX_ANGLE_SAMPLES of them.
ANGLE_STEP = wp.constant(0.1)
MAX_ANGLE_SAMPLES = wp.constant(32)


@wp.func
def step_angle(light: Emitter, o: wp.vec3, d: wp.vec3, t0: float, t1: float):
    """Returns (tc, h, phi): the closest approach tc of the ray o + t d (d unit) to a point or
    spot light, its distance h (kept above 1e-6 (t1 - t0) and float32's resolution of the
    distance to the light, as in ``segment_mean_inverse_square``), and the angle phi that the step
    [t0, t1] subtends at the light, atan2((t1 - t0) h, h^2 + (t0 - tc)(t1 - tc)) (the difference
    of the two atans without their cancellation). Directional lights: phi = 0."""
    if light.kind == DIRECTIONAL:
        return 0.0, 1.0, 0.0
    rel = light.position - o
    tc = wp.dot(rel, d)
    # h's floor as ``segment_mean_inverse_square``'s: the shares go as 1 / (h dt), and 1e-6 dt alone
    # took a ray through a light in a tiny medium (dt 1e-8) to 1e22 a unit intensity (inf times
    # sigma_s p for a dense, forward-scattering one)
    h = wp.max(wp.sqrt(wp.max(wp.dot(rel, rel) - tc * tc, 0.0)),
               wp.max(1.0e-6 * (t1 - t0), POSITION_EPS * wp.length(rel)))
    return tc, h, wp.atan2((t1 - t0) * h, h * h + (t0 - tc) * (t1 - tc))


@wp.func
def angle_samples(phi: float) -> int:
    """How many points a march step that subtends ``phi`` at a light is split into."""
    return wp.clamp(int(wp.ceil(phi / ANGLE_STEP)), 1, MAX_ANGLE_SAMPLES)


@wp.func
def angle_point(t0: float, tc: float, h: float, phi: float, j: int, n: int) -> float:
    """The ray parameter of the middle of the j-th of n equal angles into which the step from
    t0 (``step_angle``: tc, h, phi) is split at the light: tc + h tan(phi_0 + (j + 1/2) phi / n),
    by the tangent's addition rule (h tan phi_0 = t0 - tc). Along t, 1/d^2 dt = dphi / h, so
    the points are equiangular (Kulla & Fajardo 2012) and each carries an equal share of the
    light's 1/d^2 (``angle_share``): a step beside the light no longer takes the phase function,
    the shadow and the light's falloff at one point."""
    tau = wp.tan((float(j) + 0.5) * phi / float(n))
    a = t0 - tc
    return tc + h * (a + h * tau) / (h - a * tau)


@wp.func
def angle_share(light: Emitter, e: wp.vec3, dist: float, h: float, phi: float, n: int, dt: float) -> wp.vec3:
    """The irradiance ``e`` at one of n equiangular points (``angle_point``), distance ``dist``
    from the light, given its share of the step's mean: e d^2 (phi / n) / (h dt), so the n
    shares sum to the step mean of ``step_mean_irradiance`` where e d^2 is constant."""
    e_d2 = wp.where(dist > 1.0e-10, e * (dist * dist), light.strength)
    return e_d2 * (phi / (float(n) * h * dt))


@wp.func
def ball_chord(light: Emitter, o: wp.vec3, d: wp.vec3, radius: float) -> wp.vec2:
    """The ray parameters (a, b) where o + t d (d unit) enters and leaves the ball of ``radius``
    around a point or spot light; a >= b where it misses (and for directional lights)."""
    if light.kind == DIRECTIONAL:
        return wp.vec2(1.0, 0.0)
    rel = light.position - o
    tc = wp.dot(rel, d)
    h2 = wp.dot(rel, rel) - tc * tc
    if h2 >= radius * radius:
        return wp.vec2(1.0, 0.0)
    s = wp.sqrt(radius * radius - h2)
    return wp.vec2(tc - s, tc + s)


@wp.func
def step_mean_irradiance(light: Emitter, e: wp.vec3, dist: float, o: wp.vec3, d: wp.vec3, t0: float, t1: float):
    """The irradiance ``e`` that ``light`` delivers at a point of the march step o + t d,
    t in [t0, t1], at distance ``dist`` (``light_incident``, times any visibility), with a point
    or spot light's 1/d^2 replaced by its mean over the step (``segment_mean_inverse_square``):
    a step beside the light does not alias its peak. Directional lights: ``e`` as it is."""
    if light.kind == DIRECTIONAL:
        return e
    e_d2 = wp.where(dist > 1.0e-10, e * (dist * dist), light.strength)  # I x falloff (x visibility)
    return e_d2 * segment_mean_inverse_square(o, d, t0, t1, light.position)