"""Gaussian RBF media: sigma_t(x) = peak sum_i a_i exp(-|x - c_i|^2 / (2 r_i^2)), each
Gaussian of its own standard deviation r_i and amplitude a_i.

Each Gaussian is cut off at CUTOFF r_i, where it has fallen to exp(-CUTOFF^2 / 2) = 3.7e-6
of its peak: the error this leaves is below 3.7e-6 a_i peak per overlapping RBF. Kernels read
a medium as a ``Gaussians`` struct (``GaussianBuffers`` builds it): points find their centres
through a ``wp.HashGrid`` queried at the largest cut-off radius, rays the Gaussians they cross
through a ``wp.Bvh`` over the cut-off spheres' boxes. Along a ray o + t d (unit d) a Gaussian
is g exp(-(t - tc)^2 / 2 r^2), g = a exp(-h^2 / 2 r^2) at the distance h of its centre, so its
optical depth over [a, b] is g r sqrt(pi / 2) (erf((b - tc) / sqrt(2) r) - erf((a - tc) / sqrt(2) r)).
"""

import numpy as np
import warp as wp

from ..physics.constants import SQRT2, SQRT_HALF_PI
from ..physics.sampling import sample_exponential

CUTOFF = wp.constant(5.0)


@wp.struct
class Gaussians:
    """An RBF medium's Gaussians, as kernels read them (density factors: times the peak)."""

    centres: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=float)  # each Gaussian's standard deviation, scene units
    amplitude: wp.array(dtype=float)
    largest: float  # the largest radius: the hash grid's query radius over CUTOFF
    grid: wp.uint64  # wp.HashGrid over the centres (0: no centres)
    bvh: wp.uint64  # wp.Bvh over the cut-off spheres' boxes (0: no centres)


@wp.func
def rbf_density(R: Gaussians, x: wp.vec3) -> float:
    """sum_i a_i exp(-|x - c_i|^2 / (2 r_i^2)) over the centres within their cut-off."""
    s = float(0.0)
    k = int(0)
    query = wp.hash_grid_query(R.grid, x, CUTOFF * R.largest)
    while wp.hash_grid_query_next(query, k):
        d = x - R.centres[k]
        d2 = wp.dot(d, d)
        r = R.radius[k]
        if d2 < CUTOFF * CUTOFF * r * r:
            s += R.amplitude[k] * wp.exp(-0.5 * d2 / (r * r))
    return s


@wp.func
def gaussian_on_ray(R: Gaussians, k: int, o: wp.vec3, d: wp.vec3):
    """Gaussian k on the ray o + t d (unit d): (t at its closest point tc, its density factor g
    there, the half chord s of its cut-off sphere, its radius r); g = s = 0 when the ray misses."""
    r = R.radius[k]
    oc = R.centres[k] - o
    tc = wp.dot(oc, d)
    h2 = wp.max(wp.dot(oc, oc) - tc * tc, 0.0)
    r_cut = CUTOFF * r
    s2 = r_cut * r_cut - h2
    if s2 <= 0.0:
        return tc, 0.0, 0.0, r
    return tc, wp.exp(-0.5 * h2 / (r * r)) * R.amplitude[k], wp.sqrt(s2), r


@wp.func
def gaussian_chord(R: Gaussians, k: int, o: wp.vec3, d: wp.vec3, t0: float, t1: float):
    """``gaussian_on_ray`` with its cut-off chord clipped to [t0, t1]: (tc, g, s, r, a, b);
    a >= b: the ray's [t0, t1] misses it."""
    tc, g, s, r = gaussian_on_ray(R, k, o, d)
    return tc, g, s, r, wp.max(tc - s, t0), wp.min(tc + s, t1)


@wp.func
def gaussian_erf(t: float, tc: float, radius: float) -> wp.float64:
    """erf((t - tc) / (sqrt(2) radius)) in float64: differences of it lose nothing in the tails."""
    return wp.erf(wp.float64(t - tc) / (wp.float64(SQRT2) * wp.float64(radius)))


@wp.func
def erf_between(a: float, b: float, tc: float, s: float, r: float) -> float:
    """erf((b - tc) / sqrt(2) r) - erf((a - tc) / sqrt(2) r) for a chord [a, b] of the cut-off
    [tc - s, tc + s]: one erf when the chord is whole (erf is odd), as it is for most of the
    Gaussians a long ray crosses."""
    s2r = SQRT2 * r
    if a == tc - s and b == tc + s:
        return 2.0 * wp.erf(s / s2r)
    return wp.erf((b - tc) / s2r) - wp.erf((a - tc) / s2r)


@wp.func
def rbf_optical_depth(R: Gaussians, o: wp.vec3, d: wp.vec3, t0: float, t1: float) -> float:
    """The density factor's integral over [t0, t1] along o + t d (unit d): the optical depth
    per unit peak. Float32 erf: its absolute error (6e-8 of a Gaussian's mass) is harmless here."""
    acc = float(0.0)
    query = wp.bvh_query_ray(R.bvh, o, d)
    k = int(0)
    while wp.bvh_query_next(query, k, t1):
        tc, g, s, r, a, b = gaussian_chord(R, k, o, d, t0, t1)
        if a < b:
            acc += g * r * SQRT_HALF_PI * erf_between(a, b, tc, s, r)
    return acc


@wp.func
def rbf_depths_and_density(R: Gaussians, o: wp.vec3, d: wp.vec3, t0: float, t1: float, t2: float):
    """In one walk through the Gaussians along o + t d (unit d): the density factor's integral
    over [t0, t1] and over [t0, t2], and the density factor at t1 and at t2."""
    acc1 = float(0.0)
    acc2 = float(0.0)
    dens1 = float(0.0)
    dens2 = float(0.0)
    query = wp.bvh_query_ray(R.bvh, o, d)
    k = int(0)
    while wp.bvh_query_next(query, k, wp.max(t1, t2)):
        tc, g, h, r = gaussian_on_ray(R, k, o, d)
        s2r = SQRT2 * r
        inv = 0.5 / (r * r)
        a = wp.max(tc - h, t0)
        b = tc + h
        if a < wp.min(b, wp.max(t1, t2)):
            mass = g * r * SQRT_HALF_PI
            if b <= wp.min(t1, t2):  # the same chord [a, b] on both
                both = mass * erf_between(a, b, tc, h, r)
                acc1 += both
                acc2 += both
            else:
                ea = wp.erf((a - tc) / s2r)
                if a < wp.min(b, t1):
                    acc1 += mass * (wp.erf((wp.min(b, t1) - tc) / s2r) - ea)
                if a < wp.min(b, t2):
                    acc2 += mass * (wp.erf((wp.min(b, t2) - tc) / s2r) - ea)
        if wp.abs(t1 - tc) < h:
            dens1 += g * wp.exp(-(t1 - tc) * (t1 - tc) * inv)
        if wp.abs(t2 - tc) < h:
            dens2 += g * wp.exp(-(t2 - tc) * (t2 - tc) * inv)
    return acc1, acc2, dens1, dens2


@wp.func
def rbf_free_flight(R: Gaussians, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int,
                    rng: wp.uint32):
    """The first collision on [t0, t1) along o + t d (unit d) in channel c (peak sigma[c]): the
    earliest of the Gaussians' own first collisions, each sampled exactly by inverting its erf.
    Returns (t, whether there is one, the generator after its draws); t = t1 when there is none."""
    sig = sigma[c]
    best = float(t1)
    hit = bool(False)
    query = wp.bvh_query_ray(R.bvh, o, d)
    k = int(0)
    while wp.bvh_query_next(query, k, best):
        tc, g, s, r, a, b = gaussian_chord(R, k, o, d, t0, best)
        if a < b:
            # optical depth from a to t: K (erf(z_t) - erf(z_a)), K = sig g r sqrt(pi / 2);
            # at most 2K, so an exponential variate above that needs no erf at all
            K = wp.float64(sig * g * r * SQRT_HALF_PI)
            e = wp.float64(sample_exponential(wp.randf(rng), 1.0))
            if e < wp.float64(2.0) * K:
                ea = gaussian_erf(a, tc, r)
                if e < K * (gaussian_erf(b, tc, r) - ea):
                    z = wp.erfinv(ea + e / K)
                    best = wp.clamp(tc + SQRT2 * r * wp.float32(z), a, b)
                    hit = True
    return best, hit, rng


@wp.func
def rbf_extinction(R: Gaussians, sigma: wp.vec3, x: wp.vec3) -> wp.vec3:
    """sigma_t at x: the Gaussians' sum times sigma (the medium interface, as ``shape_extinction``)."""
    return rbf_density(R, x) * sigma


@wp.func
def rbf_tau(R: Gaussians, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, t0: float, t1: float) -> wp.vec3:
    """The optical depth over [t0, t1] along o + t d (unit d): an erf difference per Gaussian, times sigma."""
    return rbf_optical_depth(R, o, d, t0, t1) * sigma


class GaussianBuffers:
    """Owns the device arrays, hash grid and BVH behind a ``Gaussians`` struct.

    ``centres`` (N, 3), ``radii`` and ``amplitudes`` (N,) in scene units; ``largest`` is the
    hash grid's query radius over CUTOFF (at least the largest of ``radii``)."""

    def __init__(self, centres: np.ndarray, radii: np.ndarray, amplitudes: np.ndarray, largest: float, device):
        centres = np.asarray(centres, np.float32).reshape(-1, 3)
        radii = np.asarray(radii, np.float32).reshape(-1)
        s = Gaussians()
        s.centres = wp.array(centres if len(centres) else np.zeros((1, 3), np.float32), dtype=wp.vec3, device=device)
        s.radius = wp.array(radii if len(radii) else np.ones(1, np.float32), dtype=float, device=device)
        s.amplitude = wp.array(np.asarray(amplitudes, np.float32).reshape(-1) if len(centres) else np.ones(1, np.float32),
                               dtype=float, device=device)
        s.largest = float(largest)
        s.grid = s.bvh = wp.uint64(0)
        self.hash_grid = self.bvh = None
        if len(centres):
            self.hash_grid = wp.HashGrid(64, 64, 64, device=device)
            self.hash_grid.build(s.centres, float(CUTOFF) * float(largest))
            own = (float(CUTOFF) * radii)[:, None]  # each Gaussian's own cut-off
            self.bvh = wp.Bvh(wp.array(centres - own, dtype=wp.vec3, device=device),
                              wp.array(centres + own, dtype=wp.vec3, device=device))
            s.grid, s.bvh = self.hash_grid.id, self.bvh.id
        self.struct = s


def box_distance2(lo: np.ndarray, hi: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Squared distance from points p (N, 3) to each box [lo, hi] (C, 3): shape (C, N)."""
    d = np.maximum(lo[:, None, :] - p[None], 0.0) + np.maximum(p[None] - hi[:, None, :], 0.0)
    return np.sum(d * d, axis=-1)


def coarse_cells(bmin: np.ndarray, bmax: np.ndarray, n: int):
    edges = [np.linspace(bmin[a], bmax[a], n + 1) for a in range(3)]
    lo = np.stack(np.meshgrid(edges[0][:-1], edges[1][:-1], edges[2][:-1], indexing="ij"), -1).reshape(-1, 3)
    hi = np.stack(np.meshgrid(edges[0][1:], edges[1][1:], edges[2][1:], indexing="ij"), -1).reshape(-1, 3)
    return lo, hi


def rbf_majorant(centers: np.ndarray, radius, n: int = 12, amplitudes=None) -> float:
    """A rigorous bound of the density factor: over coarse cells, the sum of each Gaussian's
    maximum over the cell (its value at the closest point of the cell). ``radius``: one for
    all or one a centre; ``amplitudes``: one a centre (default 1)."""
    if len(centers) == 0:
        return 0.0
    radii = np.broadcast_to(np.asarray(radius, np.float64), (len(centers),))
    amps = np.ones(len(centers)) if amplitudes is None else np.asarray(amplitudes, np.float64)
    cut = float(CUTOFF) * radii.max()
    lo, hi = coarse_cells(centers.min(0) - cut, centers.max(0) + cut, n)
    total = np.zeros(len(lo))
    for s in range(0, len(centers), 2048):
        d2 = box_distance2(lo, hi, centers[s : s + 2048].astype(np.float64))
        r, a = radii[s : s + 2048], amps[s : s + 2048]
        cut_k = float(CUTOFF) * r
        total += np.sum(np.where(d2 < cut_k * cut_k, a * np.exp(-d2 / (2 * r * r)), 0.0), axis=1)
    return float(total.max())
