"""Phase functions: evaluation and importance sampling, each normalised over the sphere.

Convention (DESIGN.md): ``cos_theta`` is the cosine of the angle between the direction
light travels before and after scattering, so g > 0 scatters forward. In a path tracer
that follows a ray ``d`` backwards and continues along ``d'``, cos_theta = dot(d, d').

| kind             | parameters | p(cos_theta)                                            |
|------------------|------------|---------------------------------------------------------|
| isotropic        |            | 1 / (4 pi)                                              |
| hg               | g in (-1,1)| (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^(3/2))            |
| cornette_shanks  | g in (-1,1)| 3 (1 - g^2)(1 + cos^2) / (8 pi (2 + g^2)(1 + g^2 - 2 g cos)^(3/2)) |
| rayleigh         |            | 3 (1 + cos^2) / (16 pi)                                 |
| tabulated        | table      | piecewise-linear in cos_theta on a uniform grid over [-1, 1] |

References: Henyey & Greenstein, ApJ 1941; Cornette & Shanks, Applied Optics 1992;
pbrt-v4 ``util/scattering.h`` for the sampling routine. In float32 the HG lobe for
g = 0.999 is narrower than the spacing of representable cosines near 1, so normalisation
is tested up to |g| = 0.99 by quadrature and beyond by sampling (mean cosine = g).
"""

import numpy as np
import warp as wp

from .constants import INV_4PI, PI, TWO_PI

ISOTROPIC = wp.constant(0)
HG = wp.constant(1)
CORNETTE_SHANKS = wp.constant(2)
RAYLEIGH = wp.constant(3)
TABULATED = wp.constant(4)

#: Scene-file name -> kind id.
KINDS = {"isotropic": 0, "hg": 1, "cornette_shanks": 2, "rayleigh": 3, "tabulated": 4}


@wp.struct
class Phase:
    """A phase function: its kind, asymmetry g, and (tabulated) where its table lies."""

    kind: int
    g: float
    offset: int  # first entry of the table in the shared table array
    n: int  # entries: values at cos = -1 + 2 i / (n - 1)


@wp.func
def hg_denominator(g: float, cos_theta: float) -> float:
    """1 + g^2 - 2 g cos, written as a sum of non-negative terms (no cancellation as |g| -> 1).

    cos_theta is clamped to [-1, 1]: a float32 dot of two unit vectors can exceed 1 by an
    ulp or two, which for |g| -> 1 made the denominator negative (and p NaN). The result is
    at least 1e-20, below (1 - |g|)^2 >= 3.5e-15 for every float32 |g| < 1, so it changes
    nothing there and keeps |g| = 1 finite (its numerator is zero)."""
    c = wp.clamp(cos_theta, -1.0, 1.0)
    d = float(0.0)
    if g >= 0.0:
        d = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - c)
    else:
        d = (1.0 + g) * (1.0 + g) - 2.0 * g * (1.0 + c)
    return wp.max(d, 1.0e-20)


@wp.func
def henyey_greenstein(g: float, cos_theta: float) -> float:
    denom = hg_denominator(g, cos_theta)
    return INV_4PI * (1.0 - g) * (1.0 + g) / (denom * wp.sqrt(denom))


@wp.func
def cornette_shanks(g: float, cos_theta: float) -> float:
    denom = hg_denominator(g, cos_theta)
    c = wp.clamp(cos_theta, -1.0, 1.0)
    return (3.0 / (8.0 * PI)) * (1.0 - g) * (1.0 + g) * (1.0 + c * c) / (
        (2.0 + g * g) * denom * wp.sqrt(denom)
    )


@wp.func
def rayleigh(cos_theta: float) -> float:
    return (3.0 / (16.0 * PI)) * (1.0 + cos_theta * cos_theta)


@wp.func
def tabulated(table: wp.array(dtype=float), offset: int, n: int, cos_theta: float) -> float:
    x = wp.clamp((cos_theta + 1.0) * 0.5 * float(n - 1), 0.0, float(n - 1))
    i = wp.min(int(x), n - 2)
    f = x - float(i)
    return table[offset + i] * (1.0 - f) + table[offset + i + 1] * f


@wp.func
def phase_eval(ph: Phase, table: wp.array(dtype=float), cos_theta: float) -> float:
    """p(cos_theta) in 1/sr for any kind."""
    if ph.kind == HG:
        return henyey_greenstein(ph.g, cos_theta)
    if ph.kind == CORNETTE_SHANKS:
        return cornette_shanks(ph.g, cos_theta)
    if ph.kind == RAYLEIGH:
        return rayleigh(cos_theta)
    if ph.kind == TABULATED:
        return tabulated(table, ph.offset, ph.n, cos_theta)
    return INV_4PI


@wp.func
def phase_toward(ph: Phase, table: wp.array(dtype=float), w_in: wp.vec3, w_out: wp.vec3) -> float:
    """p(w_in . w_out); isotropic for light that arrives from every side (w_in = 0)."""
    if wp.length_sq(w_in) == 0.0:
        return INV_4PI
    return phase_eval(ph, table, wp.dot(w_in, w_out))


@wp.func
def sample_hg_cos(g: float, u: float) -> float:
    """Inverse CDF of the HG distribution of cos_theta (forward for g > 0)."""
    if wp.abs(g) < 1.0e-3:
        return 1.0 - 2.0 * u
    s = (1.0 - g) * (1.0 + g) / (1.0 - g + 2.0 * g * u)
    return wp.clamp((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0)


@wp.func
def sample_tabulated_cos(table: wp.array(dtype=float), offset: int, n: int, u: float) -> float:
    """Exact inverse CDF of the piecewise-linear table (bins by area, then the linear piece)."""
    h = 2.0 / float(n - 1)
    total = float(0.0)
    for i in range(n - 1):
        total += 0.5 * (table[offset + i] + table[offset + i + 1]) * h
    target = u * total
    acc = float(0.0)
    for i in range(n - 1):
        a = table[offset + i]
        b = table[offset + i + 1]
        area = 0.5 * (a + b) * h
        if acc + area >= target or i == n - 2:
            r = wp.clamp((target - acc) / h, 0.0, 0.5 * (a + b))  # solve a s + (b - a) s^2 / 2 = r
            s = float(0.0)
            if wp.abs(b - a) < 1.0e-6 * (a + b):
                s = r / wp.max(a, 1.0e-30)
            else:
                s = (-a + wp.sqrt(wp.max(a * a + 2.0 * (b - a) * r, 0.0))) / (b - a)
            return wp.clamp(-1.0 + (float(i) + wp.clamp(s, 0.0, 1.0)) * h, -1.0, 1.0)
        acc += area
    return 1.0


@wp.func
def orthonormal_basis(n: wp.vec3):
    """Two unit vectors completing n to a right-handed frame (Duff et al. 2017)."""
    sign = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = wp.vec3(1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    s = wp.vec3(b, sign + n[1] * n[1] * a, -n[1])
    return t, s


@wp.func
def direction_from_cos(d: wp.vec3, cos_theta: float, u: float) -> wp.vec3:
    """The unit vector at angle acos(cos_theta) from d, azimuth 2 pi u."""
    t, s = orthonormal_basis(d)
    sin_theta = wp.sqrt(wp.max(0.0, 1.0 - cos_theta * cos_theta))
    phi = TWO_PI * u
    return wp.normalize(sin_theta * wp.cos(phi) * t + sin_theta * wp.sin(phi) * s + cos_theta * d)


@wp.func
def phase_sample(ph: Phase, table: wp.array(dtype=float), d: wp.vec3, u1: float, u2: float):
    """Sample d' given the travel direction d. Returns (d', weight = p / pdf, pdf).

    HG, isotropic and tabulated are sampled exactly (weight 1). Cornette-Shanks is sampled
    with HG of the same g, Rayleigh uniformly: their weights are bounded by 3/2.
    """
    cos_theta = float(0.0)
    if ph.kind == HG or ph.kind == CORNETTE_SHANKS:
        cos_theta = sample_hg_cos(ph.g, u1)
    elif ph.kind == TABULATED:
        cos_theta = sample_tabulated_cos(table, ph.offset, ph.n, u1)
    else:
        cos_theta = 1.0 - 2.0 * u1
    wi = direction_from_cos(d, cos_theta, u2)
    pdf = INV_4PI
    if ph.kind == HG or ph.kind == CORNETTE_SHANKS:
        pdf = henyey_greenstein(ph.g, cos_theta)
    elif ph.kind == TABULATED:
        pdf = tabulated(table, ph.offset, ph.n, cos_theta)
    p = phase_eval(ph, table, cos_theta)
    return wi, p / pdf, pdf


def tabulate(values: np.ndarray) -> np.ndarray:
    """Normalise samples of p on a uniform cos grid over [-1, 1] so 2 pi * integral = 1.

    The trapezoid rule is exact for the piecewise-linear interpolant the kernels use.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 1 or v.size < 2 or np.any(v < 0) or not np.all(np.isfinite(v)) or v.sum() <= 0:
        raise ValueError("tabulated phase needs >= 2 finite, non-negative values, not all zero")
    h = 2.0 / (v.size - 1)
    integral = 2.0 * np.pi * h * (v.sum() - 0.5 * (v[0] + v[-1]))
    return (v / integral).astype(np.float32)


def phase_struct(phase, offset: int = 0) -> tuple[Phase, np.ndarray]:
    """A scene ``Phase`` as the kernel struct and its table (empty unless tabulated), the
    table placed at ``offset`` of a shared table array."""
    ph = Phase()
    ph.kind, ph.g, ph.offset, ph.n = KINDS[phase.type], float(phase.g), offset, 0
    table = np.zeros(0, np.float32)
    if phase.values is not None:
        table = tabulate(phase.values)
        ph.n = len(table)
    return ph, table
