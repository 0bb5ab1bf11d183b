"""Phase functions: evaluation and importance sampling, each normalised over the sphere.

Convention: ``cos_theta`` is the cosine of the angle between the direction
light travels before and after scattering, so g > 0 scatters forward. In a path tracer
that follows a ray ``d`` backwards and continues along ``d'``, cos_theta = dot(d, d').

| kind             | parameters | p(cos_theta)                                            |
|------------------|------------|---------------------------------------------------------|
| isotropic        |            | 1 / (4 pi)                                              |
| hg               | g in (-1,1)| (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^(3/2))            |
| cornette_shanks  | g in (-1,1)| 3 (1 - g^2)(1 + cos^2) / (8 pi (2 + g^2)(1 + g^2 - 2 g cos)^(3/2)) |
| rayleigh         |            | 3 (1 + cos^2) / (16 pi)                                 |
| tabulated        | table      | piecewise-linear in cos_theta on a uniform grid over [-1, 1] |
| hg_draine        | g (= g_HG), g_d in (0, 1), alpha > 0, w_d in [0, 1] | (1 - w_d) HG(g_HG) + w_d Draine(g_d, alpha) |

Draine(g, alpha) = (1 - g^2)(1 + alpha cos^2) / (4 pi (1 + alpha (1 + 2 g^2) / 3)(1 + g^2 - 2 g cos)^(3/2))
(Draine, ApJ 598, 2003). The HG + Draine blend is Jendersie & d'Eon, "An Approximate Mie
Scattering Function for Fog and Cloud Rendering", SIGGRAPH 2023 Talks: their fit of the four
parameters to water droplets of diameter 5-50 um lives with the scene loader
(``warpvol.scene.mie.jendersie_deon``), which fills this struct. Mie phase functions of a droplet
size distribution (``warpvol.scene.mie.mie_table``) arrive here as a ``tabulated`` kind.

A tabulated phase occupies 2 n entries of the shared table array: its n values, then their CDF
(trapezoid, 0 at cos = -1, 1 at cos = 1), so sampling is a binary search; a forward peak needs
tens of thousands of entries on the uniform cos grid, which a linear scan would walk per sample.

References: Henyey & Greenstein, ApJ 1941; Cornette & Shanks, Applied Optics 1992;
pbrt-v4 ``util/scattering.h`` for the sampling routine. In float32 the HG lobe for
g = 0.999 is narrower than the spacing of representable cosines near 1, so normalisation
is tested up to |g| = 0.99 by quadrature and beyond by sampling (mean cosine = g).
"""

import numpy as np
import warp as wp

from .constants import INV_4PI, PI, TWO_PI
from .sampling import orthonormal_basis

ISOTROPIC = wp.constant(0)
HG = wp.constant(1)
CORNETTE_SHANKS = wp.constant(2)
RAYLEIGH = wp.constant(3)
TABULATED = wp.constant(4)
HG_DRAINE = wp.constant(5)

#: Scene-file name -> kind id.
KINDS = {"isotropic": int(ISOTROPIC), "hg": int(HG), "cornette_shanks": int(CORNETTE_SHANKS), "rayleigh": int(RAYLEIGH),
         "tabulated": int(TABULATED), "hg_draine": int(HG_DRAINE)}


@wp.struct
class PhaseParams:
    """A phase function as kernels read it (``phase_struct`` makes one of a scene ``Phase``;
    ``PhaseFn`` carries it with its table): its kind, asymmetry g, (tabulated) where its
    table lies, and (hg_draine) the Draine lobe's g_d, alpha and weight w_d; g is then the
    HG lobe's g."""

    kind: int
    g: float
    offset: int  # first entry of the table in the shared table array
    n: int  # values at cos = -1 + 2 i / (n - 1), then their CDF at the same cosines
    g_d: float
    alpha: float
    w_d: float


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
def draine(g: float, alpha: float, cos_theta: float) -> float:
    """Draine's phase function: HG times (1 + alpha cos^2), renormalised (Draine 2003)."""
    c = wp.clamp(cos_theta, -1.0, 1.0)
    return henyey_greenstein(g, c) * (1.0 + alpha * c * c) / (1.0 + alpha * (1.0 + 2.0 * g * g) / 3.0)


@wp.func
def hg_draine(ph: PhaseParams, cos_theta: float) -> float:
    """Jendersie & d'Eon 2023: (1 - w_d) HG(g) + w_d Draine(g_d, alpha)."""
    return (1.0 - ph.w_d) * henyey_greenstein(ph.g, cos_theta) + ph.w_d * draine(ph.g_d, ph.alpha, cos_theta)


@wp.func
def tabulated(table: wp.array(dtype=float), offset: int, n: int, cos_theta: float) -> float:
    x = wp.clamp((cos_theta + 1.0) * 0.5 * float(n - 1), 0.0, float(n - 1))
    i = wp.min(int(x), n - 2)
    f = x - float(i)
    return table[offset + i] * (1.0 - f) + table[offset + i + 1] * f


@wp.func
def phase_eval(ph: PhaseParams, table: wp.array(dtype=float), cos_theta: float) -> float:
    """p(cos_theta) in 1/sr for any kind."""
    if ph.kind == HG:
        return henyey_greenstein(ph.g, cos_theta)
    if ph.kind == CORNETTE_SHANKS:
        return cornette_shanks(ph.g, cos_theta)
    if ph.kind == RAYLEIGH:
        return rayleigh(cos_theta)
    if ph.kind == TABULATED:
        return tabulated(table, ph.offset, ph.n, cos_theta)
    if ph.kind == HG_DRAINE:
        return hg_draine(ph, cos_theta)
    return INV_4PI


@wp.func
def phase_toward(ph: PhaseParams, table: wp.array(dtype=float), w_in: wp.vec3, w_out: wp.vec3) -> float:
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
def sample_draine_cos(g: float, alpha: float, u: float) -> float:
    """Exact inverse CDF of Draine's distribution of cos_theta, for 0 < g < 1 and alpha > 0.

    The CDF, written in t = sqrt(1 + g^2 - 2 g cos), is a depressed quartic in t; this is its
    closed-form root as given by Jendersie & d'Eon 2023 (supplemental code, ``sampleDraineCos``).
    The root cancels heavily: in float32 it is off by up to 4e-3 in cos at alpha = 100 (1e-4 at
    the fit's alpha ~ 27), so it is evaluated in float64 (a few dozen operations per sample)."""
    x = wp.float64(u)
    gg = wp.float64(g)
    a = wp.float64(alpha)
    one = wp.float64(1.0)
    g2 = gg * gg
    g4 = g2 * g2
    t1a = a * (g4 - one)
    a1mg2 = a * (one - g2)
    t2 = wp.float64(1296.0) * (one - g2) * a1mg2 * t1a * (wp.float64(4.0) * g2 + a * (one + g2) * (one + g2))
    t3 = wp.float64(3.0) * g2 * (one + gg * (wp.float64(2.0) * x - one)) + a * (
        wp.float64(2.0) + g2 + g2 * gg * (one + wp.float64(2.0) * g2) * (wp.float64(2.0) * x - one))
    t4a = wp.float64(432.0) * t1a * t1a * t1a + t2 + wp.float64(432.0) * a1mg2 * t3 * t3
    t4b = wp.float64(-144.0) * a * g2 * (one - g2) * (one - g2)
    t4 = t4a + wp.sqrt(wp.max(t4a * t4a - wp.float64(4.0) * t4b * t4b * t4b, wp.float64(0.0)))
    t4p3 = wp.pow(wp.max(t4, wp.float64(1.0e-300)), wp.float64(1.0 / 3.0))
    cbrt2 = wp.float64(1.2599210498948732)
    t6 = (wp.float64(2.0) * t1a + wp.float64(48.0) * cbrt2 * t4b / wp.float64(144.0) / t4p3
          + t4p3 / (wp.float64(3.0) * cbrt2)) / a1mg2
    t5 = wp.float64(6.0) * (one + g2) + t6
    sq5 = wp.sqrt(wp.max(t5, wp.float64(0.0)))
    inner = wp.float64(6.0) * (one + g2) + wp.float64(8.0) * t3 / (a1mg2 * sq5) - t6
    t = wp.float64(0.5) * (-sq5 + wp.sqrt(wp.max(inner, wp.float64(0.0))))
    return wp.clamp(float((one + g2 - t * t) / (wp.float64(2.0) * gg)), -1.0, 1.0)


@wp.func
def sample_tabulated_cos(table: wp.array(dtype=float), offset: int, n: int, u: float) -> float:
    """Exact inverse CDF of the piecewise-linear table: binary search of the stored CDF for the
    bin, then the root of the linear piece within it."""
    cdf = offset + n
    lo = int(0)
    hi = n - 1
    while hi - lo > 1:  # invariant: cdf[lo] <= u < cdf[hi] (or u past the last value)
        mid = (lo + hi) // 2
        if table[cdf + mid] <= u:
            lo = mid
        else:
            hi = mid
    h = 2.0 / float(n - 1)
    a = table[offset + lo]
    b = table[offset + lo + 1]
    r = wp.clamp((u - table[cdf + lo]) / (TWO_PI * h), 0.0, 0.5 * (a + b))  # solve a s + (b - a) s^2 / 2 = r
    s = float(0.0)
    if wp.abs(b - a) < 1.0e-6 * (a + b):
        s = r / wp.max(a, 1.0e-30)
    else:
        s = 2.0 * r / (a + wp.sqrt(wp.max(a * a + 2.0 * (b - a) * r, 0.0)))  # the root without cancellation
    return wp.clamp(-1.0 + (float(lo) + wp.clamp(s, 0.0, 1.0)) * h, -1.0, 1.0)


@wp.struct
class PhaseFn:
    """A phase function and the table it reads (``phase_struct``'s two parts), as one argument."""

    phase: PhaseParams
    table: wp.array(dtype=float)


def phase_fn(phase: PhaseParams, table: wp.array) -> PhaseFn:
    """``phase`` and its device ``table`` as one ``PhaseFn``."""
    pf = PhaseFn()
    pf.phase, pf.table = phase, table
    return pf


@wp.func
def direction_from_cos(d: wp.vec3, cos_theta: float, u: float) -> wp.vec3:
    """The unit vector at angle acos(cos_theta) from d, azimuth 2 pi u."""
    t, s = orthonormal_basis(d)
    sin_theta = wp.sqrt(wp.max(0.0, 1.0 - cos_theta * cos_theta))
    phi = TWO_PI * u
    return wp.normalize(sin_theta * wp.cos(phi) * t + sin_theta * wp.sin(phi) * s + cos_theta * d)


@wp.func
def phase_sample(ph: PhaseParams, table: wp.array(dtype=float), d: wp.vec3, u1: float, u2: float):
    """Sample d' given the travel direction d. Returns (d', weight = p / pdf, pdf).

    HG, isotropic, tabulated and hg_draine are sampled exactly (weight 1; hg_draine picks its
    HG lobe with probability 1 - w_d, else its Draine lobe, reusing u1). Cornette-Shanks is
    sampled with HG of the same g, Rayleigh uniformly: their weights are bounded by 3/2.
    """
    cos_theta = float(0.0)
    if ph.kind == HG or ph.kind == CORNETTE_SHANKS:
        cos_theta = sample_hg_cos(ph.g, u1)
    elif ph.kind == TABULATED:
        cos_theta = sample_tabulated_cos(table, ph.offset, ph.n, u1)
    elif ph.kind == HG_DRAINE:
        if u1 < ph.w_d:
            cos_theta = sample_draine_cos(ph.g_d, ph.alpha, u1 / ph.w_d)
        else:
            cos_theta = sample_hg_cos(ph.g, (u1 - ph.w_d) / (1.0 - ph.w_d))
    else:
        cos_theta = 1.0 - 2.0 * u1
    wi = direction_from_cos(d, cos_theta, u2)
    pdf = phase_sample_pdf(ph, table, cos_theta)
    p = phase_eval(ph, table, cos_theta)
    return wi, p / pdf, pdf


@wp.func
def phase_sample_pdf(ph: PhaseParams, table: wp.array(dtype=float), cos_theta: float) -> float:
    """The density (1/sr) with which ``phase_sample`` draws a direction at ``cos_theta`` to the
    travel direction: p itself where it is sampled exactly, HG of the same g for
    Cornette-Shanks, uniform for Rayleigh."""
    if ph.kind == HG or ph.kind == CORNETTE_SHANKS:
        return henyey_greenstein(ph.g, cos_theta)
    if ph.kind == TABULATED:
        return tabulated(table, ph.offset, ph.n, cos_theta)
    if ph.kind == HG_DRAINE:
        return hg_draine(ph, cos_theta)
    return INV_4PI


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


def tabulated_cdf(values: np.ndarray) -> np.ndarray:
    """The CDF that ``sample_tabulated_cos`` searches: 2 pi times the trapezoid integral of the
    normalised ``values`` from cos = -1 to each node, accumulated in float64."""
    v = np.asarray(values, np.float64)
    h = 2.0 / (v.size - 1)
    cdf = np.concatenate([[0.0], np.cumsum(np.pi * h * (v[1:] + v[:-1]))])
    return (cdf / cdf[-1]).astype(np.float32)


def phase_struct(phase, offset: int = 0) -> tuple[PhaseParams, np.ndarray]:
    """A scene ``Phase`` as the kernel struct (``PhaseParams``) and its table (empty unless tabulated: the n
    normalised values, then their CDF), the table placed at ``offset`` of a shared table array."""
    ph = PhaseParams()
    ph.kind, ph.g, ph.offset, ph.n = KINDS[phase.type], float(phase.g), offset, 0
    ph.g_d, ph.alpha, ph.w_d = float(phase.g_d), float(phase.alpha), float(phase.w_d)
    table = np.zeros(0, np.float32)
    if phase.values is not None:
        values = tabulate(phase.values)
        table = np.concatenate([values, tabulated_cdf(values)])
        ph.n = len(values)
    return ph, table
