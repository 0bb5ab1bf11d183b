"""All of a scene's media as one struct that kernels read, and the lookups on it.

sigma_t(x) = sum_m density_m(x) * sigma_m, where density_m is 1 inside a homogeneous
shape, the trilinear grid value (a dense array or a NanoVDB ``wp.Volume``, grid.py), the RBF
sum, or the particle overlap count, and sigma_m
is the medium's RGB scale (sigma_t, sigma_t_scale, peak). Majorants are rigorous bounds
(see grid.py, rbf.py, particles.py), per medium and summed over media.

Free flight and transmittance treat sigma_t as the sum it is. Each homogeneous shape, each
particle sphere and each RBF Gaussian is a component whose optical depth along a ray has a
closed form (a chord length; an erf), and collisions of a sum of media are the union of
independent Poisson processes: the first collision is the earliest of the components' own
first collisions (``free_flight``), and the transmittance is the product of theirs
(``transmittance_estimate``). Spheres and Gaussians on a ray are found through a ``wp.Bvh``
over their boxes. Only grids are tracked (delta / ratio tracking against a majorant grid
of up to 32^3 cells, walked by a DDA, so empty regions of a grid cost a step per cell). A dense medium therefore costs what its surface costs:
with sigma_t = 1e6 a path stops at the first sphere it enters, not after 1e6 null
collisions per unit.
"""

from __future__ import annotations

import warp as wp

from ..geometry.intersect import inside_box, ray_box, ray_sphere
from ..physics.constants import INF, SQRT2, SQRT_HALF_PI, STREAM
from ..physics.phase import Phase, phase_eval
from ..physics.sampling import sample_exponential
from ..physics.transmittance import transmittance_rgb
from .grid import grid_trilinear, volume_trilinear, walk_axis, walk_start
from .particles import Particles, particle_optical_depth, particle_sigma_t
from .rbf import CUTOFF, rbf_density

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
    radius: wp.array(dtype=float)  # sphere / the largest RBF sigma / particle radius
    sigma: wp.array(dtype=wp.vec3)  # RGB scale of the density factor, 1/unit
    albedo: wp.array(dtype=wp.vec3)
    phase: wp.array(dtype=Phase)
    dims: wp.array(dtype=wp.vec3i)  # grid resolution (x, y, z)
    offset: wp.array(dtype=int)  # first entry in grid_data or points; a particle medium's entry in particles
    volume: wp.array(dtype=wp.uint64)  # grid media: a NanoVDB wp.Volume holding the samples (0: grid_data does)
    volume_origin: wp.array(dtype=wp.vec3i)  # its voxel that is sample (0, 0, 0)
    hash_grid: wp.array(dtype=wp.uint64)  # RBF media: a wp.HashGrid over their centres
    grid_data: wp.array(dtype=float)
    points: wp.array(dtype=wp.vec3)  # RBF centres
    point_radius: wp.array(dtype=float)  # each RBF Gaussian's standard deviation
    point_amplitude: wp.array(dtype=float)  # and its amplitude
    particles: wp.array(dtype=Particles)  # particle media: each one's cloud (media/particles.py)
    phase_table: wp.array(dtype=float)
    all_min: wp.vec3  # union bounds of every medium
    all_max: wp.vec3
    het_min: wp.vec3  # union bounds of the heterogeneous media
    het_max: wp.vec3
    majorant: wp.vec3  # bound of sigma_t over all media
    het_majorant: wp.vec3  # bound of sigma_t over heterogeneous media
    majorant_data: wp.array(dtype=float)  # grid media: bounds of the density per coarse cell (media/grid.py)
    majorant_dims: wp.array(dtype=wp.vec3i)  # coarse cells per axis (x, y, z)
    majorant_offset: wp.array(dtype=int)  # first entry of a grid's coarse cells in majorant_data
    bvh: wp.array(dtype=wp.uint64)  # RBF media: a BVH over the cut-off spheres' boxes (0: none)


@wp.func
def medium_density(m: Media, i: int, x: wp.vec3) -> float:
    """The density factor of a homogeneous, grid or RBF medium i at x (sigma_t = it times
    m.sigma[i]); particle media have per-sphere sigma_t (``medium_sigma_t``)."""
    kind = m.kind[i]
    if kind == SPHERE:
        d = x - m.center[i]
        return wp.where(wp.dot(d, d) <= m.radius[i] * m.radius[i], 1.0, 0.0)
    lo = m.bmin[i]
    hi = m.bmax[i]
    if not inside_box(x, lo, hi):
        return 0.0
    if kind == BOX:
        return 1.0
    if kind == GRID:
        if m.volume[i] != wp.uint64(0):
            return volume_trilinear(m.volume[i], m.volume_origin[i], m.dims[i], lo, hi, x)
        return grid_trilinear(m.grid_data, m.offset[i], m.dims[i], lo, hi, x)
    return rbf_density(m.hash_grid[i], m.points, m.point_radius, m.point_amplitude, m.offset[i], m.radius[i], x)


@wp.func
def medium_sigma_t(m: Media, i: int, x: wp.vec3) -> wp.vec3:
    """sigma_t of medium i at x (RGB, 1/unit)."""
    if m.kind[i] == PARTICLES:
        if not inside_box(x, m.bmin[i], m.bmax[i]):
            return wp.vec3(0.0)
        return particle_sigma_t(m.particles[m.offset[i]], x)
    return medium_density(m, i, x) * m.sigma[i]


@wp.func
def is_heterogeneous(m: Media, i: int) -> bool:
    return m.kind[i] >= GRID


@wp.func
def sigma_t_at(m: Media, x: wp.vec3, hetero_only: bool) -> wp.vec3:
    s = wp.vec3(0.0)
    for i in range(m.count):
        if is_heterogeneous(m, i) or not hetero_only:
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
def inside_convex(m: Media, i: int, x: wp.vec3) -> bool:
    """Whether x lies in homogeneous medium i (a box or a sphere)."""
    if m.kind[i] == SPHERE:
        r = x - m.center[i]
        return wp.dot(r, r) <= m.radius[i] * m.radius[i]
    return inside_box(x, m.bmin[i], m.bmax[i])


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
    p0 = o + t0 * d
    p1 = o + t1 * d
    for i in range(m.count):
        kind = m.kind[i]
        if kind == BOX or kind == SPHERE:
            a = float(0.0)
            b = float(0.0)
            if inside_convex(m, i, p0) and t1 < INF and inside_convex(m, i, p1):
                a = t0  # both ends inside a convex medium: all of it is (no slab test)
                b = t1
            elif kind == BOX:
                a, b = ray_box(o, d, m.bmin[i], m.bmax[i])
            else:
                a, b = ray_sphere(o, d, m.center[i], m.radius[i])
            overlap = wp.min(b, t1) - wp.max(a, t0)
            if overlap > 0.0:
                tau += overlap * m.sigma[i]
    return tau


@wp.func
def grid_tracking(m: Media, i: int, o: wp.vec3, d: wp.vec3, t0: float, t1: float, sig: float, ratio: bool,
                  rng: wp.uint32):
    """Tracking through grid medium i on [t0, t1) against its majorant grid, walked cell by cell
    by a DDA (an exponential step that leaves a cell restarts at its boundary: memoryless).

    ``ratio`` False, delta tracking: (t of the first real collision, 1) or (t1, 0). ``ratio``
    True, ratio tracking (Novak et al. 2014): (t1, an unbiased estimate of the transmittance),
    with Russian roulette once the weight falls below 0.1."""
    lo = m.bmin[i]
    hi = m.bmax[i]
    a, b = ray_box(o, d, lo, hi)
    t = wp.max(a, t0)
    t_end = wp.min(b, t1)
    w = float(1.0)
    if t >= t_end:
        return t1, wp.where(ratio, 1.0, 0.0)
    n = m.majorant_dims[i]
    base = m.majorant_offset[i]
    cell, step, t_next, t_delta = walk_start(lo, wp.cw_div(hi - lo, wp.vec3(float(n[0]), float(n[1]), float(n[2]))),
                                             n, o, d, t)
    while t < t_end:
        seg_end = wp.min(wp.min(wp.min(t_next[0], t_next[1]), t_next[2]), t_end)
        mu = m.majorant_data[base + (cell[2] * n[1] + cell[1]) * n[0] + cell[0]] * sig
        while mu > 0.0:
            t = t + sample_exponential(wp.randf(rng), mu)
            if t >= seg_end:
                break
            real = medium_density(m, i, o + t * d) * sig / mu
            if not ratio:
                if wp.randf(rng) < real:
                    return t, 1.0
            else:
                w *= 1.0 - real
                if w < 0.1:  # Russian roulette keeps long thick segments short, unbiased
                    if wp.randf(rng) < 0.5:
                        return t1, 0.0
                    w *= 2.0
        t = seg_end
        ax = walk_axis(t_next)
        cell[ax] = cell[ax] + step[ax]
        t_next[ax] = t_next[ax] + t_delta[ax]
        if cell[ax] < 0 or cell[ax] >= n[ax]:
            break
    return t1, wp.where(ratio, w, 0.0)


@wp.func
def transmittance_estimate(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int, rng: wp.uint32) -> wp.vec3:
    """Unbiased estimate of exp(-integral sigma_t) over [t0, t1] (d unit): exact for every
    medium with a closed form (``exact_optical_depth``), times ratio tracking (Novak et al.
    2014) with Russian roulette through each grid against its majorant grid."""
    tr = transmittance_rgb(exact_optical_depth(m, o, d, t0, t1))
    w = float(1.0)
    for i in range(m.count):
        if m.kind[i] == GRID and w > 0.0:
            t_end, wi = grid_tracking(m, i, o, d, t0, t1, m.sigma[i][c], True, wp.rand_init(wp.randi(rng), STREAM))
            w *= wi
    return tr * w


@wp.func
def gaussian_on_ray(o: wp.vec3, d: wp.vec3, c: wp.vec3, radius: float):
    """A cut-off Gaussian RBF on the ray o + t d (unit d): (t at its closest point, its
    density factor there, the half chord of its cut-off sphere; 0 when the ray misses)."""
    oc = c - o
    tc = wp.dot(oc, d)
    h2 = wp.max(wp.dot(oc, oc) - tc * tc, 0.0)
    r_cut = CUTOFF * radius
    s2 = r_cut * r_cut - h2
    if s2 <= 0.0:
        return tc, 0.0, 0.0
    return tc, wp.exp(-0.5 * h2 / (radius * radius)), wp.sqrt(s2)


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
def exact_optical_depth(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float) -> wp.vec3:
    """Optical depth over [t0, t1] (d unit) of every medium with a closed form: homogeneous
    shapes (slab / sphere), particles (sigma_t times chord lengths; overlaps add) and RBFs
    (peak exp(-h^2 / 2r^2) r sqrt(pi / 2) times an erf difference per Gaussian)."""
    tau = homogeneous_optical_depth(m, o, d, t0, t1)
    for i in range(m.count):
        kind = m.kind[i]
        if kind == PARTICLES:
            tau += particle_optical_depth(m.particles[m.offset[i]], -1, o, d, t0, t1)
        elif kind == RBF:
            acc = float(0.0)
            query = wp.bvh_query_ray(m.bvh[i], o, d)
            k = int(0)
            while wp.bvh_query_next(query, k, t1):
                r = m.point_radius[m.offset[i] + k]
                tc, g, s = gaussian_on_ray(o, d, m.points[m.offset[i] + k], r)
                g *= m.point_amplitude[m.offset[i] + k]
                a = wp.max(tc - s, t0)
                b = wp.min(tc + s, t1)
                if a < b:  # float32 erf: its absolute error (6e-8 of the Gaussian's mass) is harmless here
                    acc += g * r * SQRT_HALF_PI * erf_between(a, b, tc, s, r)
            tau += acc * m.sigma[i]
    return tau


@wp.func
def depths_and_extinction(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float, t2: float, cos1: float):
    """For media that are all exact (``exact_media``), along o + t d (d unit): the optical depths
    over [t0, t1] and [t0, t2], ``in_scatter_at`` at t1 for the angle cos1, and sigma_t at t1 and
    t2, with one walk through each RBF's Gaussians instead of two walks and two hash-grid lookups
    (a Gaussian's density on the ray is g exp(-(t - tc)^2 / 2 r^2) inside its cut-off chord)."""
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
            acc1 = float(0.0)
            acc2 = float(0.0)
            dens1 = float(0.0)
            dens2 = float(0.0)
            query = wp.bvh_query_ray(m.bvh[i], o, d)
            k = int(0)
            while wp.bvh_query_next(query, k, wp.max(t1, t2)):
                r = m.point_radius[m.offset[i] + k]
                s2r = SQRT2 * r
                inv = 0.5 / (r * r)
                tc, g, h = gaussian_on_ray(o, d, m.points[m.offset[i] + k], r)
                g *= m.point_amplitude[m.offset[i] + k]
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
            tau1 += acc1 * m.sigma[i]
            tau2 += acc2 * m.sigma[i]
            s1 = dens1 * m.sigma[i]
            sig2 += dens2 * m.sigma[i]
        else:
            if kind == PARTICLES:
                P = m.particles[m.offset[i]]
                tau1 += particle_optical_depth(P, -1, o, d, t0, t1)
                tau2 += particle_optical_depth(P, -1, o, d, t0, t2)
            s1 = medium_sigma_t(m, i, x1)
            sig2 += medium_sigma_t(m, i, x2)
        if wp.max(s1) > 0.0:
            fs1 += phase_eval(m.phase[i], m.phase_table, cos1) * wp.cw_mul(s1, m.albedo[i])
            sig1 += s1
    return tau1, tau2, fs1, sig1, sig2


@wp.func
def uniform_collision(a: float, b: float, sig: float, u: float) -> float:
    """The first collision in a uniform medium of extinction sig on [a, b), from the uniform
    variate u: a + E / sig with E exponential, or INF when it falls past b (or a >= b)."""
    if a >= b:
        return INF
    t = a + sample_exponential(u, sig)
    return wp.where(t < b, t, INF)


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
        sig = m.sigma[i][c]
        if sig > 0.0:
            if kind == BOX or kind == SPHERE:
                a = float(0.0)
                b = float(0.0)
                if kind == BOX:
                    a, b = ray_box(o, d, m.bmin[i], m.bmax[i])
                else:
                    a, b = ray_sphere(o, d, m.center[i], m.radius[i])
                t = uniform_collision(wp.max(a, t0), wp.min(b, best), sig, wp.randf(rng))
                if t < best:
                    best = t
                    who = i
            elif kind == GRID:
                t, hit = grid_tracking(m, i, o, d, t0, best, sig, False, wp.rand_init(wp.randi(rng), STREAM))
                if hit > 0.0:
                    best = t
                    who = i
            elif kind == PARTICLES:
                P = m.particles[m.offset[i]]
                if P.bvh != wp.uint64(0):
                    query = wp.bvh_query_ray(P.bvh, o, d)
                    k = int(0)
                    while wp.bvh_query_next(query, k, best):
                        a, b = ray_sphere(o, d, P.centres[k], P.radius[k])
                        t = uniform_collision(wp.max(a, t0), wp.min(b, best), P.sigma_t[k][c], wp.randf(rng))
                        if t < best:
                            best = t
                            who = i
            else:
                query = wp.bvh_query_ray(m.bvh[i], o, d)
                k = int(0)
                while wp.bvh_query_next(query, k, best):
                    r = m.point_radius[m.offset[i] + k]
                    tc, g, s = gaussian_on_ray(o, d, m.points[m.offset[i] + k], r)
                    g *= m.point_amplitude[m.offset[i] + k]
                    a = wp.max(tc - s, t0)
                    b = wp.min(tc + s, best)
                    if a < b:
                        # optical depth from a to t: K (erf(z_t) - erf(z_a)), K = sig g r sqrt(pi / 2);
                        # at most 2K, so an exponential variate above that needs no erf at all
                        K = wp.float64(sig * g * r * SQRT_HALF_PI)
                        e = wp.float64(sample_exponential(wp.randf(rng), 1.0))
                        if e < wp.float64(2.0) * K:
                            ea = gaussian_erf(a, tc, r)
                            if e < K * (gaussian_erf(b, tc, r) - ea):
                                z = wp.erfinv(ea + e / K)
                                t = tc + SQRT2 * r * wp.float32(z)
                                best = wp.clamp(t, a, b)
                                who = i
    return best, who


@wp.kernel
def sample_extinction(offset: int, m: Media, lo: wp.vec3, hi: wp.vec3, n: wp.vec3i, out: wp.array(dtype=wp.vec3)):
    """sigma_t at the cell centres of an n[0] x n[1] x n[2] lattice over [lo, hi], x fastest."""
    tid = wp.tid() + offset
    ix = tid % n[0]
    iy = (tid / n[0]) % n[1]
    iz = tid / (n[0] * n[1])
    f = wp.vec3((float(ix) + 0.5) / float(n[0]), (float(iy) + 0.5) / float(n[1]), (float(iz) + 0.5) / float(n[2]))
    out[tid] = sigma_t_at(m, lo + wp.cw_mul(hi - lo, f), False)
