"""Phase functions of water droplets, computed on the host (numpy) for the scene loader.

Two models of fog and cloud droplets; the kernels only read what these produce
(``warpvol.physics.phase``):

``mie_table``
    The phase function of a log-normal distribution of droplet diameters from Mie theory
    (miepython, Prahl), averaged over the distribution with weight number density x
    scattering cross-section, at three wavelengths, tabulated on the uniform cos grid of
    the ``tabulated`` phase kind. The kernels' tabulated phase is one scalar table per
    medium, so the scene gets the mean of the three wavelengths' phase functions.

``jendersie_deon``
    The fit of Jendersie & d'Eon, "An Approximate Mie Scattering Function for Fog and Cloud
    Rendering", SIGGRAPH 2023 Talks: p = (1 - w_d) HG(g_HG) + w_d Draine(g_d, alpha), each
    parameter a function of the droplet diameter d for 5 um <= d <= 50 um (their fit for
    the largest of their three ranges; the two for smaller droplets are not implemented).

Size distribution. Diameters d are log-normal: the number density per unit ln d is
n(d) ~ exp(-(ln d - ln d_m)^2 / (2 sigma^2)), d_m the median diameter, sigma the geometric
standard deviation in ln space (sigma = 0: one size). The averaged phase function is

    p(mu) = sum_k n(d_k) C_sca(d_k) p_k(mu) / sum_k n(d_k) C_sca(d_k),    C_sca = Q_sca pi d^2 / 4,

with p_k miepython's unpolarised phase function of the single size normalised to 1
(``norm="one"``), so p integrates to 1 whatever the nodes. Nodes are uniform in ln d over
+-``SPAN_SIGMA`` sigma about ln d_m + 2 sigma^2, the median of n(d) d^2 (where the weight
lies), spaced so the size parameter x = pi d / lambda steps by at most ``DX``: Mie resonances
are much narrower than any affordable step, so they are sampled rather than resolved
(``bench/mie_phase.py`` reports how far g and the table move when the step halves).

Table. The table is n values at cos = -1 + 2 i / (n - 1). Its n is a power of two plus one
chosen so 1 - cos(lambda / d) at the shortest wavelength (the diffraction peak's angular
half-width is ~ lambda / d) spans about 16 nodes, capped at ``MAX_ENTRIES``. Mie is evaluated
at a subset of the nodes, one per angular step of min(RELATIVE_STEP (theta + lambda / d),
COARSE_STEP) (every node near the peak, where the nodes are sparse in theta), and the nodes
between are interpolated linearly in (theta, ln p). Evaluated nodes are exact; the trapezoid
integral of the table minus 1 (``norm_error``) is what the piecewise-linear table loses at
the peak plus the interpolation error; ``tabulate`` rescales it away.

miepython runs its numba kernels (``MIEPYTHON_USE_JIT=1``, set by ``load_miepython`` unless the
caller set it): pure-Python Mie is ~60x slower for the large size parameters of fog.
"""

from __future__ import annotations

import functools
import math
import os
import warnings
from dataclasses import dataclass

import numpy as np

#: Wavelengths (um) of the R, G, B channels.
WAVELENGTHS_UM = (0.65, 0.55, 0.45)
#: Refractive index of water in the visible (real part; absorption is negligible there).
WATER_INDEX = 1.333
#: Largest step in size parameter between size nodes.
DX = 1.0
#: Size nodes span this many sigma either side of the cross-section weighted median.
SPAN_SIGMA = 3.5
#: Largest table (entries); a 50 um median with sigma = 0.3 needs it.
MAX_ENTRIES = 2**20 + 1
#: Angular steps of the Mie evaluations: relative to theta + lambda / d near the peak, in
#: radians away from it (the smaller of the two applies).
RELATIVE_STEP = 0.02
COARSE_STEP = 5.0e-3
#: Diameter range (um) of the Jendersie & d'Eon fit implemented here.
FIT_RANGE_UM = (5.0, 50.0)


def load_miepython():
    """miepython with its numba kernels: it reads MIEPYTHON_USE_JIT once, when first imported,
    so this sets it (unless the caller did) before that import, and warns if it came too late."""
    os.environ.setdefault("MIEPYTHON_USE_JIT", "1")
    try:
        import miepython
    except ImportError:
        raise ImportError("phase = {type = \"mie\"} needs miepython: pip install 'warpvol[mie]'") from None

    if not miepython.USE_JIT and os.environ["MIEPYTHON_USE_JIT"] == "1":
        warnings.warn("miepython was imported before warpvol.scene.mie set MIEPYTHON_USE_JIT=1: its pure-Python "
                      "Mie sums are ~60x slower", stacklevel=3)
    return miepython


def size_nodes(median_diameter_um: float, sigma: float, wavelength_um: float) -> tuple[np.ndarray, np.ndarray]:
    """Diameters (um) and normalised number-density weights of the log-normal quadrature."""
    if sigma == 0.0:
        return np.array([median_diameter_um]), np.ones(1)
    centre = math.log(median_diameter_um) + 2.0 * sigma * sigma
    span = SPAN_SIGMA * sigma
    x_range = math.pi * (math.exp(centre + span) - math.exp(centre - span)) / wavelength_um
    k = max(65, int(math.ceil(x_range / DX)) + 1)
    ln_d = np.linspace(centre - span, centre + span, k)
    w = np.exp(-((ln_d - math.log(median_diameter_um)) ** 2) / (2.0 * sigma * sigma))
    return np.exp(ln_d), w / w.sum()


def mie_phase(mu: np.ndarray, median_diameter_um: float, sigma: float, wavelength_um: float,
              refractive_index: float = WATER_INDEX) -> tuple[np.ndarray, float]:
    """The size-averaged Mie phase function p(mu) in 1/sr (float64) and its mean cosine g.

    Parameters
    ----------
    mu : ndarray of shape (M,)
        Cosines of the scattering angle.
    median_diameter_um, sigma : float
        Log-normal diameters: median in um, geometric standard deviation in ln space.
    wavelength_um : float
        Vacuum wavelength in um (the droplets are in air).
    refractive_index : float
        Real refractive index of the droplets.
    """
    mp = load_miepython()
    mu = np.ascontiguousarray(mu, dtype=np.float64)
    p = np.zeros_like(mu)
    total = g = 0.0
    for d, w in zip(*size_nodes(median_diameter_um, sigma, wavelength_um)):
        _, qsca, _, g_k = mp.efficiencies(refractive_index, d, wavelength_um)
        c = w * float(qsca) * d * d  # C_sca up to the constant pi / 4
        p += c * mp.i_unpolarized(refractive_index, math.pi * d / wavelength_um, mu, norm="one")
        total += c
        g += c * float(g_k)
    return p / total, g / total


@dataclass(frozen=True)
class MieTable:
    """A size-averaged Mie phase function on the uniform cos grid, per wavelength and mean.

    ``values`` (3, n) and ``mean`` (n,) are float64 in 1/sr, not renormalised; ``norm_error``
    (per wavelength, then the mean) is 2 pi times their trapezoid integral minus 1. ``g`` is
    each wavelength's exact mean cosine (miepython's g, averaged like p) and ``g_mean`` the
    mean's. ``evaluated`` marks the nodes where Mie was evaluated (the rest are interpolated).
    ``l1_to_mean`` is the integral over the sphere of |p_lambda - mean|."""

    median_diameter_um: float
    sigma: float
    refractive_index: float
    wavelengths_um: tuple
    mu: np.ndarray
    values: np.ndarray
    mean: np.ndarray
    evaluated: np.ndarray
    g: tuple
    g_mean: float
    norm_error: tuple
    l1_to_mean: tuple


def table_entries(median_diameter_um: float, sigma: float, wavelength_um: float) -> int:
    """Table size: the diffraction peak's 1 - cos(lambda / d) over about four nodes, d the
    median of the cross-section weighted diameters; a power of two plus one, at least 4097."""
    d = median_diameter_um * math.exp(2.0 * sigma * sigma)
    width = 1.0 - math.cos(min(wavelength_um / d, 1.0))
    n = 2 ** max(12, math.ceil(math.log2(32.0 / width))) + 1
    return min(n, MAX_ENTRIES)


def _evaluated_nodes(theta: np.ndarray, peak_width: float) -> np.ndarray:
    """Mask of the nodes to evaluate: the first node in each bin of the warped angle
    ln(1 + theta / w) / RELATIVE_STEP + theta / COARSE_STEP (bins about RELATIVE_STEP (theta + w)
    wide near the peak, COARSE_STEP away from it), and both ends."""
    warped = np.log1p(theta / peak_width) / RELATIVE_STEP + theta / COARSE_STEP
    _, first = np.unique(np.floor(warped).astype(np.int64), return_index=True)
    keep = np.zeros(theta.shape, bool)
    keep[first] = True
    keep[[0, -1]] = True
    return keep


@functools.lru_cache(maxsize=32)
def mie_table(median_diameter_um: float, sigma: float, refractive_index: float = WATER_INDEX,
              wavelengths_um: tuple = WAVELENGTHS_UM) -> MieTable:
    """The Mie phase function of log-normal droplets tabulated for the ``tabulated`` kind
    (cached on its arguments: a scene reload does not recompute it). Arrays are read-only."""
    lam_min = min(wavelengths_um)
    n = table_entries(median_diameter_um, sigma, lam_min)
    mu = np.linspace(-1.0, 1.0, n)
    theta = np.arccos(mu)
    evaluated = _evaluated_nodes(theta, lam_min / (median_diameter_um * math.exp(2.0 * sigma * sigma)))
    idx = np.flatnonzero(evaluated)
    order = idx[np.argsort(theta[idx])]
    h = 2.0 / (n - 1)
    rows, gs = [], []
    for lam in wavelengths_um:
        p_eval, g = mie_phase(mu[order], median_diameter_um, sigma, lam, refractive_index)
        row = np.exp(np.interp(theta, theta[order], np.log(np.maximum(p_eval, 1e-300))))
        row[order] = p_eval
        rows.append(row)
        gs.append(g)
    values = np.array(rows)
    mean = values.mean(axis=0)

    def integral(v):
        return 2.0 * np.pi * h * (v.sum(-1) - 0.5 * (v[..., 0] + v[..., -1]))

    norm_error = tuple(float(e) for e in np.append(integral(values), integral(mean)) - 1.0)
    l1 = tuple(float(integral(np.abs(v - mean))) for v in values)
    for a in (mu, values, mean, evaluated):
        a.setflags(write=False)
    return MieTable(float(median_diameter_um), float(sigma), float(refractive_index), tuple(wavelengths_um), mu,
                    values, mean, evaluated, tuple(gs), float(np.mean(gs)), norm_error, l1)


@dataclass(frozen=True)
class HGDraine:
    """Parameters of the HG + Draine blend (dimensionless)."""

    g_hg: float
    g_d: float
    alpha: float
    w_d: float


def jendersie_deon(diameter_um: float) -> HGDraine:
    """Jendersie & d'Eon 2023's fit for water droplets of diameter 5 um <= d <= 50 um."""
    d = float(diameter_um)
    if not FIT_RANGE_UM[0] <= d <= FIT_RANGE_UM[1]:
        raise ValueError(f"the Jendersie & d'Eon fit covers diameters {FIT_RANGE_UM[0]:g}-{FIT_RANGE_UM[1]:g} um, "
                         f"not {d:g}")
    return HGDraine(g_hg=math.exp(-0.0990567 / (d - 1.67154)),
                    g_d=math.exp(-2.20679 / (d + 3.91029) - 0.428934),
                    alpha=math.exp(3.62489 - 8.29288 / (d + 5.52825)),
                    w_d=math.exp(-0.599085 / (d - 0.641583) - 0.665888))


def hg_draine(mu: np.ndarray, f: HGDraine) -> np.ndarray:
    """The blend at cosines ``mu`` in 1/sr (float64): the host-side reference for tests and
    plots of the ``hg_draine`` kernel function."""
    mu = np.asarray(mu, np.float64)

    def hg(g):
        return (1.0 - g * g) / (4.0 * np.pi * (1.0 + g * g - 2.0 * g * mu) ** 1.5)

    draine = hg(f.g_d) * (1.0 + f.alpha * mu * mu) / (1.0 + f.alpha * (1.0 + 2.0 * f.g_d**2) / 3.0)
    return (1.0 - f.w_d) * hg(f.g_hg) + f.w_d * draine


def hg_draine_mean_cosine(f: HGDraine) -> float:
    """Mean cosine of the blend, closed form: Draine's is g (1 + alpha (3 + 2 g^2) / 5) /
    (1 + alpha (1 + 2 g^2) / 3) (Draine, ApJ 598, 2003)."""
    g = f.g_d
    draine = g * (1.0 + f.alpha * (3.0 + 2.0 * g * g) / 5.0) / (1.0 + f.alpha * (1.0 + 2.0 * g * g) / 3.0)
    return (1.0 - f.w_d) * f.g_hg + f.w_d * draine
