"""Sampling shared by every technique: exponential free flights, equiangular sampling toward a
point (Kulla & Fajardo 2012), the power heuristic (Veach 1997), an orthonormal frame
(Duff et al. 2017) and cosine-weighted directions about a normal."""

import warp as wp

from .constants import PI, TWO_PI


@wp.func
def sample_exponential(u: float, rate: float) -> float:
    """A distance with pdf rate e^(-rate t) from the uniform variate u: -ln(1 - u) / rate."""
    return -wp.log(1.0 - u) / rate


@wp.func
def exponential_pdf(rate: float, t: float) -> float:
    """rate e^(-rate t): the pdf of ``sample_exponential`` at t >= 0."""
    return rate * wp.exp(-rate * t)


@wp.func
def equiangular_sample(h: float, delta: float, th_a: float, th_b: float, u: float) -> float:
    """The distance along a ray whose closest point to the light is at delta, h from it, with
    the segment subtending the angles th_a .. th_b seen from the light: delta + h tan(theta),
    theta uniform in [th_a, th_b]; its pdf is ``equiangular_pdf``."""
    return delta + h * wp.tan(th_a + (th_b - th_a) * u)


@wp.func
def equiangular_pdf(h: float, delta: float, th_a: float, th_b: float, t: float) -> float:
    """h / ((th_b - th_a) (h^2 + (t - delta)^2)): the pdf of ``equiangular_sample`` at t."""
    return h / ((th_b - th_a) * (h * h + (t - delta) * (t - delta)))


@wp.func
def power_heuristic(pdf_a: float, pdf_b: float) -> float:
    """The weight of strategy a against b, pdf_a^2 / (pdf_a^2 + pdf_b^2): 0 where pdf_a is 0
    (both 0: a sample neither strategy draws), and the same ratio without overflow where the
    squares pass the float range."""
    a2 = pdf_a * pdf_a
    s = a2 + pdf_b * pdf_b
    w = float(0.0)
    if s > 0.0 and s < 3.0e38:
        w = a2 / s
    elif pdf_a > 0.0:
        r = pdf_b / pdf_a
        w = 1.0 / (1.0 + r * r)
    return w


@wp.func
def orthonormal_basis(n: wp.vec3):
    """Two unit vectors completing the unit vector n to a right-handed frame (Duff et al. 2017)."""
    sign = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = wp.vec3(1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    s = wp.vec3(b, sign + n[1] * n[1] * a, -n[1])
    return t, s


@wp.func
def cosine_direction(n: wp.vec3, u1: float, u2: float) -> wp.vec3:
    """A direction about the unit normal n with pdf cos / pi, from two uniform numbers."""
    r = wp.sqrt(u1)
    phi = TWO_PI * u2
    tx, ty = orthonormal_basis(n)
    return wp.normalize(r * wp.cos(phi) * tx + r * wp.sin(phi) * ty + wp.sqrt(wp.max(0.0, 1.0 - r * r)) * n)


@wp.func
def angle_uniform_direction(axis: wp.vec3, u1: float, u2: float) -> wp.vec3:
    """A direction at an angle alpha = pi u1 from the unit ``axis``, azimuth 2 pi u2: uniform in
    the angle, so its density on the sphere, 1 / (2 pi^2 sin alpha), grows like 1/alpha toward
    the axis (``angle_uniform_pdf``). Aimed at a point light, it samples the light's glow seen
    from afar, whose radiance grows like 1/alpha toward the light, with a bounded ratio."""
    alpha = PI * u1
    phi = TWO_PI * u2
    tx, ty = orthonormal_basis(axis)
    sa = wp.sin(alpha)
    return wp.normalize(sa * wp.cos(phi) * tx + sa * wp.sin(phi) * ty + wp.cos(alpha) * axis)


@wp.func
def angle_uniform_pdf(axis: wp.vec3, w: wp.vec3) -> float:
    """The density on the sphere of ``angle_uniform_direction`` about ``axis`` at the unit w:
    1 / (2 pi^2 sin alpha), held finite on the axis itself (sin alpha at least 1e-7)."""
    c = wp.clamp(wp.dot(axis, w), -1.0, 1.0)
    return 1.0 / (2.0 * PI * PI * wp.max(wp.sqrt(wp.max(1.0 - c * c, 0.0)), 1.0e-7))
