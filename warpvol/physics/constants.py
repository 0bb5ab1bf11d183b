"""Numerical constants shared by every kernel (``wp.constant``, one place)."""

import math

import warp as wp

PI = wp.constant(math.pi)
TWO_PI = wp.constant(2.0 * math.pi)
INV_PI = wp.constant(1.0 / math.pi)
INV_2PI = wp.constant(0.5 / math.pi)
INV_4PI = wp.constant(0.25 / math.pi)
#: Stand-in for an infinite distance (a directional light, a ray that escapes).
INF = wp.constant(1.0e30)
#: Offset along the normal for rays leaving a surface, in scene units.
RAY_EPS = wp.constant(1.0e-4)
