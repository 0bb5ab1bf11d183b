"""All of a scene's media as one struct that kernels read, and the lookups on it: a
dispatch over the media, each kind's mathematics in its own module.

sigma_t(x) = sum_m density_m(x) * sigma_m, where density_m is 1 inside a homogeneous shape
(homogeneous.py), the trilinear grid value (a dense array or a NanoVDB ``wp.Volume``,
grid.py), the RBF sum (rbf.py) or the particle overlap count (particles.py), and sigma_m is
the medium's RGB scale (sigma_t, sigma_t_scale, peak). Majorants are rigorous bounds, per
medium and summed over media.

Free flight and transmittance treat sigma_t as the sum it is. Each homogeneous shape, each
particle sphere and each RBF Gaussian is a component whose optical depth along a ray has a
closed form (a chord length; an erf), and collisions of a sum of media are the union of
independent Poisson processes: the first collision is the earliest of the components' own
first collisions (``free_flight``), and the transmittance is the product of theirs
(``transmittance_estimate``). Only grids are tracked, against their majorant grids. A dense
medium therefore costs what its surface costs: with sigma_t = 1e6 a path stops at the first
sphere it enters, not after 1e6 null collisions per unit.

Each kind's module exposes the same medium interface, so the dispatch here is one line a kind:
``<kind>_extinction(S, sigma, x)`` (sigma_t at x), ``<kind>_tau(S, sigma, o, d, t0, t1)`` (the
optical depth in closed form; a grid has none and gives ``grid_transmittance`` by ratio
tracking instead) and ``<kind>_free_flight(S, sigma, o, d, t0, t1, c, rng)`` -> (t, hit, rng),
with S the kind's struct (``Shape``, ``Grid``, ``Gaussians``, ``Particles``) and sigma the
medium's RGB scale; the majorants are the modules' host functions (``majorant_grid``,
``rbf_majorant``, ``particle_majorant``; a shape's is its sigma_t).
"""

from __future__ import annotations

import warp as wp

from .. import device as dev
from ..geometry.intersect import inside_box, ray_box, ray_sphere
from ..physics.constants import INF
from ..physics.phase import PhaseParams, phase_eval
from ..physics.transmittance import transmittance_rgb
from .grid import Grid, grid_extinction, grid_free_flight, grid_transmittance
from .homogeneous import Shape, shape_extinction, shape_free_flight, shape_tau
from .particles import Particles, particle_extinction, particle_free_flight, particle_optical_depth, particle_tau
from .rbf import Gaussians, rbf_density, rbf_depths_and_density, rbf_extinction, rbf_free_flight, rbf_tau

dev.kernel_module(__name__)

BOX = wp.constant(0)
SPHERE = wp.constant(1)
GRID = wp.constant(2)
RBF = wp.constant(3)
PARTICLES = wp.constant(4)


@wp.struct
class Media:
    count: int
    kind: wp.array(dtype=int)
    bmin: wp.array(dtype=wp.vec3)  # bounds of each medium
    bmax: wp.array(dtype=wp.vec3)
    reach_centre: wp.array(dtype=wp.vec3)  # a ball around each medium (a sphere, a cloud of spheres)
    reach: wp.array(dtype=float)  # its radius (the box's circumsphere where nothing tighter is known)
    center: wp.array(dtype=wp.vec3)  # homogeneous sphere centre
    radius: wp.array(dtype=float)  # its radius
    sigma: wp.array(dtype=wp.vec3)  # RGB scale of the density factor, 1/unit
    albedo: wp.array(dtype=wp.vec3)
    phase: wp.array(dtype=PhaseParams)
    phase_table: wp.array(dtype=float)
    index: wp.array(dtype=int)  # a grid's, RBF medium's or particle medium's entry in grids, gaussians, particles
    grids: wp.array(dtype=Grid)  # grid.py
    gaussians: wp.array(dtype=Gaussians)  # rbf.py
    particles: wp.array(dtype=Particles)  # particles.py
    all_min: wp.vec3  # union bounds of every medium
    all_max: wp.vec3
    het_min: wp.vec3  # union bounds of the heterogeneous media
    het_max: wp.vec3
    majorant: wp.vec3  # bound of sigma_t over all media
    het_majorant: wp.vec3  # bound of sigma_t over heterogeneous media


@wp.func
def shape_of(m: Media, i: int) -> Shape:
    """Homogeneous medium i's shape."""
    S = Shape()
    S.box = wp.where(m.kind[i] == BOX, 1, 0)
    S.lo = m.bmin[i]
    S.hi = m.bmax[i]
    S.centre = m.center[i]
    S.radius = m.radius[i]
    return S


@wp.func
def medium_sigma_t(m: Media, i: int, x: wp.vec3) -> wp.vec3:
    """sigma_t of medium i at x (RGB, 1/unit): its kind's ``*_extinction``. An RBF or particle
    medium is first tested against its bounds (its own lookup walks a hash grid)."""
    kind = m.kind[i]
    if kind == BOX or kind == SPHERE:
        return shape_extinction(shape_of(m, i), m.sigma[i], x)
    if kind == GRID:
        return grid_extinction(m.grids[m.index[i]], m.sigma[i], x)
    if not inside_box(x, m.bmin[i], m.bmax[i]):
        return wp.vec3(0.0)
    if kind == RBF:
        return rbf_extinction(m.gaussians[m.index[i]], m.sigma[i], x)
    return particle_extinction(m.particles[m.index[i]], m.sigma[i], x)


@wp.func
def is_heterogeneous(m: Media, i: int) -> bool:
    """Whether medium i varies in space (a grid, RBFs, particles): not a homogeneous shape."""
    return m.kind[i] != BOX and m.kind[i] != SPHERE


@wp.func
def sigma_t_at(m: Media, x: wp.vec3, hetero_only: bool) -> wp.vec3:
    s = wp.vec3(0.0)
    for i in range(m.count):
        if is_heterogeneous(m, i) or not hetero_only:
            s += medium_sigma_t(m, i, x)
    return s


@wp.func
def grid_sigma_t_at(m: Media, x: wp.vec3) -> wp.vec3:
    """sigma_t of the grid media alone at x: what a march samples where no closed form exists."""
    s = wp.vec3(0.0)
    for i in range(m.count):
        if m.kind[i] == GRID:
            s += medium_sigma_t(m, i, x)
    return s


@wp.func
def in_scatter_at(m: Media, x: wp.vec3, cos_theta: float) -> wp.vec3:
    """sum_m sigma_s,m(x) p_m(cos_theta): what scatters from a unit beam into a unit solid angle."""
    s = wp.vec3(0.0)
    for i in range(m.count):
        sig = medium_sigma_t(m, i, x)
        if wp.max(sig) > 0.0:
            s += phase_eval(m.phase[i], m.phase_table, cos_theta) * wp.cw_mul(sig, m.albedo[i])
    return s


@wp.func
def in_scatter_from(m: Media, x: wp.vec3, sigma_s: wp.vec3, cos_theta: float) -> wp.vec3:
    """``in_scatter_at`` where the caller holds sigma_s at x (``coefficients_at``): with one
    medium it is sigma_s p(cos_theta), no lookup; with several each medium is looked up again."""
    if m.count == 1:
        return phase_eval(m.phase[0], m.phase_table, cos_theta) * sigma_s
    return in_scatter_at(m, x, cos_theta)


@wp.func
def in_scatter_sample(m: Media, x: wp.vec3, sigma_s: wp.vec3, looked_up: bool, cos_theta: float) -> wp.vec3:
    """The in-scattering at a march sample x: ``in_scatter_from`` where x is the point whose
    sigma_s the caller looked up (``looked_up``: the step's midpoint), else ``in_scatter_at`` (a
    point of its own, such as an equiangular point beside a light)."""
    if looked_up:
        return in_scatter_from(m, x, sigma_s, cos_theta)
    return in_scatter_at(m, x, cos_theta)


@wp.func
def exact_media(m: Media) -> bool:
    """Whether every medium has a closed-form optical depth (no grid is tracked): then
    ``transmittance_estimate`` is exact and a free flight's pdf sigma_t T is known."""
    for i in range(m.count):
        if m.kind[i] == GRID:
            return False
    return True


@wp.func
def scattering_at(m: Media, x: wp.vec3) -> wp.vec3:
    """sum_m sigma_s,m(x): the scattering coefficient (in_scatter_at without the phase function)."""
    s = wp.vec3(0.0)
    for i in range(m.count):
        s += wp.cw_mul(medium_sigma_t(m, i, x), m.albedo[i])
    return s


@wp.func
def coefficients_at(m: Media, x: wp.vec3):
    """(sigma_t, sigma_s) of all the media at x: ``sigma_t_at`` and ``scattering_at`` with each
    medium looked up once."""
    st = wp.vec3(0.0)
    ss = wp.vec3(0.0)
    for i in range(m.count):
        sig = medium_sigma_t(m, i, x)
        st += sig
        ss += wp.cw_mul(sig, m.albedo[i])
    return st, ss


@wp.func
def media_span(m: Media, o: wp.vec3, d: wp.vec3):
    """(t_near, t_far) of the part of the ray o + t d (unit d) that can meet a medium: the
    hull of each medium's box met with its ball; t_near > t_far when the ray misses them all.
    Outside it sigma_t is 0, so a path's segment (its next-event estimate, its free flight)
    starts and ends there: a ray past a round cloud's corners costs nothing."""
    lo = float(INF)
    hi = float(-INF)
    for i in range(m.count):
        a, b = ray_box(o, d, m.bmin[i], m.bmax[i])
        a2, b2 = ray_sphere(o, d, m.reach_centre[i], m.reach[i])
        a = wp.max(a, a2)
        b = wp.min(b, b2)
        if a < b:
            lo = wp.min(lo, a)
            hi = wp.max(hi, b)
    return lo, hi


@wp.func
def homogeneous_optical_depth(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float) -> wp.vec3:
    """Exact optical depth of the homogeneous media over [t0, t1] along o + t d (d unit)."""
    tau = wp.vec3(0.0)
    for i in range(m.count):
        kind = m.kind[i]
        if kind == BOX or kind == SPHERE:
            tau += shape_tau(shape_of(m, i), m.sigma[i], o, d, t0, t1)
    return tau


@wp.func
def transmittance_estimate(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int, rng: wp.uint32) -> wp.vec3:
    """Unbiased estimate of exp(-integral sigma_t) over [t0, t1] (d unit): exact for every
    medium with a closed form (``exact_optical_depth``), times ratio tracking (Novak et al.
    2014) with Russian roulette through each grid against its majorant grid."""
    tr = transmittance_rgb(exact_optical_depth(m, o, d, t0, t1))
    w = float(1.0)
    for i in range(m.count):
        if m.kind[i] == GRID and w > 0.0:
            wi, rng = grid_transmittance(m.grids[m.index[i]], m.sigma[i], o, d, t0, t1, c, rng)
            w *= wi
    return tr * w


@wp.func
def exact_optical_depth(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float) -> wp.vec3:
    """Optical depth over [t0, t1] (d unit) of every medium with a closed form: homogeneous
    shapes (slab / sphere), particles (sigma_t times chord lengths; overlaps add) and RBFs
    (an erf difference per Gaussian)."""
    tau = homogeneous_optical_depth(m, o, d, t0, t1)
    for i in range(m.count):
        kind = m.kind[i]
        if kind == PARTICLES:
            tau += particle_tau(m.particles[m.index[i]], m.sigma[i], o, d, t0, t1)
        elif kind == RBF:
            tau += rbf_tau(m.gaussians[m.index[i]], m.sigma[i], o, d, t0, t1)
    return tau


@wp.func
def depths_and_extinction(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float, t2: float, cos1: float):
    """For media that are all exact (``exact_media``), along o + t d (d unit): the optical depths
    over [t0, t1] and [t0, t2], ``in_scatter_at`` at t1 for the angle cos1, and sigma_t at t1 and
    t2, with one walk through each RBF's Gaussians instead of two walks and two hash-grid lookups."""
    x1 = o + t1 * d
    x2 = o + t2 * d
    tau1 = homogeneous_optical_depth(m, o, d, t0, t1)
    tau2 = homogeneous_optical_depth(m, o, d, t0, t2)
    fs1 = wp.vec3(0.0)
    sig1 = wp.vec3(0.0)
    sig2 = wp.vec3(0.0)
    for i in range(m.count):
        kind = m.kind[i]
        s1 = wp.vec3(0.0)
        if kind == RBF:
            acc1, acc2, dens1, dens2 = rbf_depths_and_density(m.gaussians[m.index[i]], o, d, t0, t1, t2)
            tau1 += acc1 * m.sigma[i]
            tau2 += acc2 * m.sigma[i]
            s1 = dens1 * m.sigma[i]
            sig2 += dens2 * m.sigma[i]
        else:
            if kind == PARTICLES:
                P = m.particles[m.index[i]]
                tau1 += particle_optical_depth(P, -1, o, d, t0, t1)
                tau2 += particle_optical_depth(P, -1, o, d, t0, t2)
            s1 = medium_sigma_t(m, i, x1)
            sig2 += medium_sigma_t(m, i, x2)
        if wp.max(s1) > 0.0:
            fs1 += phase_eval(m.phase[i], m.phase_table, cos1) * wp.cw_mul(s1, m.albedo[i])
            sig1 += s1
    return tau1, tau2, fs1, sig1, sig2


@wp.func
def free_flight(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int, rng: wp.uint32):
    """The first real collision on [t0, t1) along o + t d (d unit) in channel c: (t, medium),
    or (t1, -1) when there is none. The earliest of the components' own first collisions,
    each sampled exactly (homogeneous shapes, particle spheres, RBF Gaussians by inverting
    the erf) or by delta tracking (grids); the medium returned is the component's, which is
    the one a collision at t belongs to with probability sigma_i(t) / sigma_t(t)."""
    best = float(t1)
    who = int(-1)
    for i in range(m.count):
        kind = m.kind[i]
        sigma = m.sigma[i]
        if sigma[c] > 0.0:
            t = float(INF)
            hit = bool(False)
            if kind == BOX or kind == SPHERE:
                t, hit, rng = shape_free_flight(shape_of(m, i), sigma, o, d, t0, best, c, rng)
            elif kind == GRID:
                t, hit, rng = grid_free_flight(m.grids[m.index[i]], sigma, o, d, t0, best, c, rng)
            elif kind == PARTICLES:
                t, hit, rng = particle_free_flight(m.particles[m.index[i]], sigma, o, d, t0, best, c, rng)
            else:
                t, hit, rng = rbf_free_flight(m.gaussians[m.index[i]], sigma, o, d, t0, best, c, rng)
            if hit:
                best = t
                who = i
    return best, who


@wp.func
def cell_centre(tid: int, lo: wp.vec3, hi: wp.vec3, n: wp.vec3i) -> wp.vec3:
    """The centre of cell ``tid`` (x fastest) of an n[0] x n[1] x n[2] lattice over [lo, hi]."""
    ix = tid % n[0]
    iy = (tid / n[0]) % n[1]
    iz = tid / (n[0] * n[1])
    f = wp.vec3((float(ix) + 0.5) / float(n[0]), (float(iy) + 0.5) / float(n[1]), (float(iz) + 0.5) / float(n[2]))
    return lo + wp.cw_mul(hi - lo, f)


@wp.kernel
def sample_rbf_density(offset: int, R: Gaussians, lo: wp.vec3, hi: wp.vec3, n: wp.vec3i, out: wp.array(dtype=float)):
    """An RBF medium's density factor at the cell centres of an n[0] x n[1] x n[2] lattice over
    [lo, hi], x fastest: its Gaussians summed once, for a march to read as a grid."""
    tid = wp.tid() + offset
    out[tid] = rbf_density(R, cell_centre(tid, lo, hi, n))


@wp.kernel
def sample_extinction(offset: int, m: Media, lo: wp.vec3, hi: wp.vec3, n: wp.vec3i, out: wp.array(dtype=wp.vec3)):
    """sigma_t at the cell centres of an n[0] x n[1] x n[2] lattice over [lo, hi], x fastest."""
    tid = wp.tid() + offset
    out[tid] = sigma_t_at(m, cell_centre(tid, lo, hi, n), False)
