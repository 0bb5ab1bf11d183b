"""Closed-form single-scattering airlight of a point light in a homogeneous isotropic
medium (Sun, Ramamoorthi, Narasimhan & Nayar, "A Practical Analytic Single Scattering
Model for Real Time Rendering", SIGGRAPH 2005, equations 9-12).

For a ray from v along d of length D_vp, a light of intensity I0 at distance D_sv from v
at angle gamma to the ray, extinction beta (= sigma_t) and albedo a (Sun et al. take
a = 1; the in-scattered term scales with sigma_s = a beta):

    T_sv = beta D_sv,  T_vp = beta D_vp
    A0 = a beta^2 I0 exp(-T_sv cos gamma) / (2 pi T_sv sin gamma),  A1 = T_sv sin gamma
    L_a = A0 [F(A1, pi/4 + atan((T_vp - T_sv cos gamma) / (T_sv sin gamma)) / 2) - F(A1, gamma / 2)]
    F(u, v) = integral_0^v exp(-u tan xi) dxi

F is tabulated once (``f_table``) and read bilinearly by ``airlight``; the table's u axis
is spaced in log(1 + u) up to U_MAX, beyond which F(u, v) ~ (1 - exp(-u tan v)) / u
(relative error below 2 / U_MAX^2).
"""

import functools

import numpy as np
import warp as wp

from .constants import PI

U_MAX = wp.constant(200.0)
TABLE_NU = 512
TABLE_NV = 512


@functools.lru_cache(maxsize=8)
def _gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n Gauss-Legendre nodes and weights on [-1, 1]; past 256, equal panels of 32 nodes each
    (numpy's ``leggauss`` solves an n x n eigenproblem: 30 s at n = 8192)."""
    if n <= 256:
        return np.polynomial.legendre.leggauss(n)
    x, w = np.polynomial.legendre.leggauss(32)
    edges = np.linspace(-1.0, 1.0, -(-n // 32) + 1)
    half, mid = 0.5 * np.diff(edges), 0.5 * (edges[1:] + edges[:-1])
    return (mid[:, None] + half[:, None] * x).ravel(), (half[:, None] * w).ravel()


def f_exact(u: np.ndarray, v: np.ndarray, n: int = 4096) -> np.ndarray:
    """F(u, v) by Gauss-Legendre quadrature in float64 (the ground truth for the table)."""
    u = np.asarray(u, dtype=np.float64)[..., None]
    v = np.asarray(v, dtype=np.float64)[..., None]
    x, w = _gauss(n)
    xi = 0.5 * v * (x + 1.0)
    return np.sum(0.5 * v * w * np.exp(-u * np.tan(xi)), axis=-1)


def f_table() -> np.ndarray:
    """F on a (TABLE_NU, TABLE_NV) grid: u = expm1(i / (NU-1) * log1p(U_MAX)), v = j / (NV-1) * pi/2."""
    us = np.expm1(np.linspace(0.0, np.log1p(float(U_MAX)), TABLE_NU))
    # cumulative integral over v for every u, with 64 sub-steps per table cell (Simpson)
    sub = 64
    fine = np.linspace(0.0, 0.5 * np.pi, (TABLE_NV - 1) * sub + 1)
    vals = np.exp(-us[:, None] * np.tan(np.minimum(fine, 0.5 * np.pi - 1e-12))[None, :])
    vals[:, -1] = np.where(us == 0.0, 1.0, 0.0)
    h = fine[1] - fine[0]
    pairs = vals[:, :-1:2] + 4.0 * vals[:, 1::2] + vals[:, 2::2]
    cum = np.concatenate([np.zeros((TABLE_NU, 1)), np.cumsum(pairs * h / 3.0, axis=1)], axis=1)
    return cum[:, :: sub // 2].astype(np.float32)


@wp.func
def table_bilinear(table: wp.array2d(dtype=float), x: float, y: float) -> float:
    """``table`` read bilinearly at fractional indices (x, y), both >= 0 (the last cell
    extrapolates past the end)."""
    i = wp.min(int(x), table.shape[0] - 2)
    j = wp.min(int(y), table.shape[1] - 2)
    fx = x - float(i)
    fy = y - float(j)
    a = table[i, j] * (1.0 - fy) + table[i, j + 1] * fy
    b = table[i + 1, j] * (1.0 - fy) + table[i + 1, j + 1] * fy
    return a * (1.0 - fx) + b * fx


@wp.func
def f_lookup(table: wp.array2d(dtype=float), u: float, v: float) -> float:
    v = wp.clamp(v, 0.0, 0.5 * PI)
    if u > U_MAX:
        return (1.0 - wp.exp(-u * wp.tan(wp.min(v, 1.5707)))) / u
    x = wp.log(1.0 + wp.max(u, 0.0)) / wp.log(1.0 + U_MAX) * float(table.shape[0] - 1)
    y = v / (0.5 * PI) * float(table.shape[1] - 1)
    return table_bilinear(table, x, y)


@wp.func
def airlight(
    table: wp.array2d(dtype=float),
    origin: wp.vec3,
    d: wp.vec3,
    length: float,
    light_pos: wp.vec3,
    intensity: wp.vec3,
    sigma_t: float,
    albedo: wp.vec3,
) -> wp.vec3:
    """Single-scattered radiance along origin + t d, t in [0, length] (equation 12)."""
    to_light = light_pos - origin
    d_sv = wp.length(to_light)
    if sigma_t <= 0.0 or d_sv <= 0.0 or length <= 0.0:
        return wp.vec3(0.0)
    cos_g = wp.clamp(wp.dot(to_light, d) / d_sv, -1.0, 1.0)
    sin_g = wp.max(wp.sqrt(1.0 - cos_g * cos_g), 1.0e-6)
    t_sv = sigma_t * d_sv
    t_vp = sigma_t * length
    a0 = sigma_t * sigma_t * wp.exp(-t_sv * cos_g) / (2.0 * PI * t_sv * sin_g)
    a1 = t_sv * sin_g
    v_far = 0.25 * PI + 0.5 * wp.atan((t_vp - t_sv * cos_g) / (t_sv * sin_g))
    v_near = 0.5 * wp.acos(cos_g)
    f = f_lookup(table, a1, v_far) - f_lookup(table, a1, v_near)
    return a0 * f * wp.cw_mul(albedo, intensity)


def airlight_exact(origin, d, length, light_pos, intensity, sigma_t, albedo=1.0, n=4096):
    """The same integral by quadrature along the ray in float64, for checks (numpy, any shape)."""
    origin, d, light_pos = (np.asarray(a, dtype=np.float64) for a in (origin, d, light_pos))
    x, w = _gauss(n)
    length = np.asarray(length, dtype=np.float64)[..., None]
    t = 0.5 * length * (x + 1.0)
    p = origin[..., None, :] + t[..., None] * d[..., None, :]
    r2 = np.sum((light_pos - p) ** 2, axis=-1)
    f = np.exp(-sigma_t * (t + np.sqrt(r2))) / r2
    s = np.sum(0.5 * length * w * f, axis=-1)
    return (sigma_t * s / (4.0 * np.pi))[..., None] * np.asarray(albedo) * np.asarray(intensity)


# --- light scattered onto a surface: Sun et al. 2005's surface radiance (their section 5) ------
#
# A Lambertian patch (BRDF k_d) at distance D_sp from a point light I0, in the same medium:
#
#     L_p = I0 k_d [exp(-T_sp) cos(theta_s) / D_sp^2 + beta^2 G_0(T_sp, theta_s) / (2 pi T_sp)]
#
# with T_sp = beta D_sp and theta_s the angle between the normal and the light. The second
# term is the airlight arriving from every direction of the hemisphere, reflected. With
# gamma the angle between an incoming direction and the light, the airlight of the ray from
# the patch toward it (to infinity) is A0 [F(A1, pi/2) - F(A1, gamma/2)], A0 = beta^2 I0
# exp(-T cos gamma) / (2 pi T sin gamma), A1 = T sin gamma. Integrating in (gamma, phi)
# about the light's direction, d omega = sin gamma d gamma d phi cancels the 1/sin gamma:
#
#     G_n(T, theta) = int_0^pi exp(-T cos g) [F(T sin g, pi/2) - F(T sin g, g/2)] C_n(g, theta) dg
#     C_n(g, theta) = int_0^2pi max(cos g cos theta + sin g sin theta cos phi, 0)^n dphi
#
# (n = 1: the cosine over the hemisphere, closed form; n > 1: Sun et al.'s Phong lobe, theta
# then measured from the mirror direction). exp(-T cos g) F(...) <= exp(-T), since
# cos g + sin g tan(xi) >= 1 for xi >= g / 2, so G_n is tabulated as G_n e^T, over
# log(1 + T) up to G_T_MAX (beyond, G_n < e^-64 is 0 in float32 terms anyway).

G_T_MAX = wp.constant(64.0)
G_NT = 96
G_NTHETA = 64


def _cos_lobe(g: np.ndarray, theta: np.ndarray, n: int) -> np.ndarray:
    """C_n(g, theta) (broadcast): the phi integral, closed form for n = 1, else 256-point rule."""
    a = np.cos(g) * np.cos(theta)
    b = np.sin(g) * np.sin(theta)
    if n == 1:
        ratio = np.clip(-a / np.where(np.abs(b) > 1e-300, b, 1e-300), -1.0, 1.0)
        phi0 = np.arccos(ratio)
        part = 2.0 * (a * phi0 + np.abs(b) * np.sin(phi0))
        return np.where(a >= np.abs(b), 2.0 * np.pi * a, np.where(a <= -np.abs(b), 0.0, part))
    phi = (np.arange(256) + 0.5) * (2.0 * np.pi / 256)
    c = np.maximum(a[..., None] + b[..., None] * np.cos(phi), 0.0) ** n
    return c.sum(-1) * (2.0 * np.pi / 256)




def g_exact(T, theta, n: int = 1, n_gamma: int = 512, n_xi: int = 128) -> np.ndarray:
    """G_n(T, theta) e^T in float64 on the grid of 1-d ``T`` x ``theta`` (shape (len(T),
    len(theta))), by Gauss-Legendre quadrature in gamma and xi. The exponent is combined,
    exp(-T (cos g + sin g tan xi - 1)) <= 1, so nothing overflows."""
    T = np.atleast_1d(np.asarray(T, np.float64))
    theta = np.atleast_1d(np.asarray(theta, np.float64))
    x, w = _gauss(n_gamma)
    g = 0.5 * np.pi * (x + 1.0)
    wg = 0.5 * np.pi * w
    y, wy = _gauss(n_xi)
    lo = g / 2.0
    xi = lo[:, None] + (0.5 * np.pi - lo)[:, None] * 0.5 * (y + 1.0)  # (gamma, xi)
    wxi = (0.5 * np.pi - lo)[:, None] * 0.5 * wy
    expo = np.maximum(np.cos(g)[:, None] + np.sin(g)[:, None] * np.tan(np.minimum(xi, 0.5 * np.pi - 1e-12)) - 1.0,
                      0.0)
    inner = np.stack([np.sum(wxi * np.exp(-t * expo), axis=-1) for t in T])  # (T, gamma)
    c = _cos_lobe(g[:, None], theta[None, :], n)  # (gamma, theta)
    return inner @ (wg[:, None] * c)


@functools.lru_cache(maxsize=4)
def g_table(n: int = 1) -> np.ndarray:
    """G_n e^T on a (G_NT, G_NTHETA) grid: T = expm1(i / (NT-1) log1p(G_T_MAX)), cos theta =
    -1 + 2 j / (NTHETA-1) (uniform in the cosine: no arccos when reading)."""
    Ts = np.expm1(np.linspace(0.0, np.log1p(float(G_T_MAX)), G_NT))
    return g_exact(Ts, np.arccos(np.linspace(-1.0, 1.0, G_NTHETA)), n).astype(np.float32)


@wp.func
def g_lookup(table: wp.array2d(dtype=float), T: float, cos_theta: float) -> float:
    """G_n(T, theta) from ``g_table`` (bilinear in log(1 + T) and cos theta; T > G_T_MAX: 0)."""
    if T > G_T_MAX:
        return 0.0
    x = wp.log(1.0 + wp.max(T, 0.0)) / wp.log(1.0 + G_T_MAX) * float(table.shape[0] - 1)
    y = (wp.clamp(cos_theta, -1.0, 1.0) + 1.0) * 0.5 * float(table.shape[1] - 1)
    return table_bilinear(table, x, y) * wp.exp(-T)


@wp.func
def surface_radiance(table: wp.array2d(dtype=float), beta: float, dist: float, inv_d2: float, cos_s: float,
                     n: float) -> float:
    """Sun et al.'s surface radiance per unit I0 k: exp(-T) cos^n / D^2 + beta^2 G_n(T, theta) / (2 pi T),
    T = beta D, written as beta G / (2 pi D) so beta -> 0 stays finite. ``inv_d2``: the mean of
    1 / D^2 the caller wants (finite where D -> 0); D is kept above 1e-6 in the second term."""
    T = beta * dist
    c = wp.clamp(cos_s, -1.0, 1.0)
    lobe = wp.max(c, 0.0)
    if n != 1.0:
        lobe = wp.pow(lobe, n)
    return wp.exp(-T) * lobe * inv_d2 + beta * g_lookup(table, T, c) / (2.0 * PI * wp.max(dist, 1.0e-6))
