"""Numerical constants shared by every kernel (``wp.constant``, one place)."""

import math

import warp as wp

PI = wp.constant(math.pi)
TWO_PI = wp.constant(2.0 * math.pi)
INV_PI = wp.constant(1.0 / math.pi)
INV_2PI = wp.constant(0.5 / math.pi)
INV_4PI = wp.constant(0.25 / math.pi)
SQRT2 = wp.constant(math.sqrt(2.0))
SQRT_HALF_PI = wp.constant(math.sqrt(0.5 * math.pi))
#: Stand-in for an infinite distance (a directional light, a ray that escapes).
INF = wp.constant(1.0e30)
#: Offset along the normal for rays leaving a surface, in scene units.
RAY_EPS = wp.constant(1.0e-4)
#: Offset that forks a random stream: ``wp.rand_init(wp.randi(rng), STREAM)``. Warp's
#: ``randi`` returns the new state and ``rand_init(seed)`` hashes it once more, so without an
#: offset the "fresh" stream replays its parent's next draws one step ahead: harmless for
#: estimates that are only summed, biased when the two feed one product (a collision depth
#: and the next scattering direction drawn from one number made the second bounce 12% dark).
STREAM = wp.constant(0x2545F491)
