"""Optical depth and Beer-Lambert transmittance that stay finite for any input.

``tau`` is optical depth (dimensionless), ``sigma_t`` extinction in 1/unit. For tau
from 0 to 1e6 (and +inf) the transmittance is a finite number in [0, 1]; NaN never
comes out unless NaN goes in.
"""

import warp as wp


@wp.func
def transmittance(tau: float) -> float:
    """exp(-tau), exactly 0 past float32's range instead of a denormal or NaN."""
    if tau <= 0.0:
        return 1.0
    if tau > 104.0:  # expf(-104) is below the smallest float32 denormal
        return 0.0
    return wp.exp(-tau)


@wp.func
def transmittance_rgb(tau: wp.vec3) -> wp.vec3:
    """``transmittance`` per channel; one exp where the three are equal (a grey medium, the
    common case), the same numbers at a third of the exps."""
    if tau[0] == tau[1] and tau[1] == tau[2]:
        return wp.vec3(transmittance(tau[0]))
    return wp.vec3(transmittance(tau[0]), transmittance(tau[1]), transmittance(tau[2]))


@wp.func
def step_integral(sigma_t: float, dt: float) -> float:
    """integral_0^dt exp(-sigma_t s) ds = (1 - exp(-sigma_t dt)) / sigma_t: how much of a
    constant source over a step of constant extinction leaves it; stable as sigma_t -> 0."""
    tau = sigma_t * dt
    if tau < 1.0e-4:
        return dt * (1.0 - 0.5 * tau)
    return (1.0 - wp.exp(-tau)) / sigma_t


@wp.func
def step_integral_rgb(sigma_t: wp.vec3, dt: float) -> wp.vec3:
    """``step_integral`` per channel; one exp where the three are equal (a grey medium)."""
    if sigma_t[0] == sigma_t[1] and sigma_t[1] == sigma_t[2]:
        return wp.vec3(step_integral(sigma_t[0], dt))
    return wp.vec3(step_integral(sigma_t[0], dt), step_integral(sigma_t[1], dt), step_integral(sigma_t[2], dt))


@wp.func
def sphere_escape(tau: float) -> float:
    """Mean transmittance from a uniformly distributed point of a homogeneous sphere of
    optical radius tau = sigma_t r to its surface along one direction: the escape
    probability 3/(8 tau^3) [2 tau^2 - 1 + (1 + 2 tau) e^(-2 tau)] (1 - 3 tau / 4 when thin,
    3 / (4 tau) when thick). By symmetry it is also the mean over the sphere of the
    transmittance from outside along one direction. Below tau = 0.1 the series
    1 - 3/4 tau + 2/5 tau^2 - 1/6 tau^3 + 2/35 tau^4 avoids the cancellation."""
    if tau < 0.1:
        return 1.0 - tau * (0.75 - tau * (0.4 - tau * (1.0 / 6.0 - tau * (2.0 / 35.0))))
    return 0.375 / (tau * tau * tau) * (2.0 * tau * tau - 1.0 + (1.0 + 2.0 * tau) * wp.exp(-2.0 * tau))
