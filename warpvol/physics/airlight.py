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

import numpy as np
import warp as wp

from .constants import PI

U_MAX = wp.constant(200.0)
TABLE_NU = 512
TABLE_NV = 512


def f_exact(u: np.ndarray, v: np.ndarray, n: int = 4096) -> np.ndarray:
    """F(u, v) by Gauss-Legendre quadrature in float64 (the ground truth for the table)."""
    u = np.asarray(u, dtype=np.float64)[..., None]
    v = np.asarray(v, dtype=np.float64)[..., None]
    x, w = np.polynomial.legendre.leggauss(n)
    xi = 0.5 * v * (x + 1.0)
    return np.sum(0.5 * v * w * np.exp(-u * np.tan(xi)), axis=-1)


def f_table() -> np.ndarray:
    """F on a (TABLE_NU, TABLE_NV) grid: u = expm1(i / (NU-1) * log1p(U_MAX)), v = j / (NV-1) * pi/2."""
    us = np.expm1(np.linspace(0.0, np.log1p(float(U_MAX)), TABLE_NU))
    vs = np.linspace(0.0, 0.5 * np.pi, TABLE_NV)
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
def f_lookup(table: wp.array2d(dtype=float), u: float, v: float) -> float:
    v = wp.clamp(v, 0.0, 0.5 * PI)
    if u > U_MAX:
        return (1.0 - wp.exp(-u * wp.tan(wp.min(v, 1.5707)))) / u
    nu = table.shape[0]
    nv = table.shape[1]
    x = wp.log(1.0 + wp.max(u, 0.0)) / wp.log(1.0 + U_MAX) * float(nu - 1)
    y = v / (0.5 * PI) * float(nv - 1)
    i = wp.min(int(x), nu - 2)
    j = wp.min(int(y), nv - 2)
    fx = x - float(i)
    fy = y - float(j)
    a = table[i, j] * (1.0 - fy) + table[i, j + 1] * fy
    b = table[i + 1, j] * (1.0 - fy) + table[i + 1, j + 1] * fy
    return a * (1.0 - fx) + b * fx


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
    x, w = np.polynomial.legendre.leggauss(n)
    length = np.asarray(length, dtype=np.float64)[..., None]
    t = 0.5 * length * (x + 1.0)
    p = origin[..., None, :] + t[..., None] * d[..., None, :]
    r2 = np.sum((light_pos - p) ** 2, axis=-1)
    f = np.exp(-sigma_t * (t + np.sqrt(r2))) / r2
    s = np.sum(0.5 * length * w * f, axis=-1)
    return (sigma_t * s / (4.0 * np.pi))[..., None] * np.asarray(albedo) * np.asarray(intensity)
