"""All of a scene's media as one struct that kernels read, and the lookups on it.

sigma_t(x) = sum_m density_m(x) * sigma_m, where density_m is 1 inside a homogeneous
shape, the trilinear grid value, the RBF sum, or the particle overlap count, and sigma_m
is the medium's RGB scale (sigma_t, sigma_t_scale, peak). Majorants are rigorous bounds
(see grid.py, rbf.py, particles.py), summed over media.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..physics.constants import INF
from ..physics.phase import Phase, phase_eval, phase_struct
from ..physics.transmittance import transmittance_rgb
from ..scene.model import GridMedium, HomogeneousMedium, ParticleMedium, RBFMedium, Scene
from .grid import grid_majorant, grid_trilinear
from .particles import particle_count, particle_majorant
from .rbf import CUTOFF, rbf_density, rbf_majorant

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
    center: wp.array(dtype=wp.vec3)  # homogeneous sphere centre
    radius: wp.array(dtype=float)  # sphere / RBF sigma / particle radius
    sigma: wp.array(dtype=wp.vec3)  # RGB scale of the density factor, 1/unit
    albedo: wp.array(dtype=wp.vec3)
    phase: wp.array(dtype=Phase)
    dims: wp.array(dtype=wp.vec3i)  # grid resolution (x, y, z)
    offset: wp.array(dtype=int)  # first entry in grid_data or points
    hash_grid: wp.array(dtype=wp.uint64)
    grid_data: wp.array(dtype=float)
    points: wp.array(dtype=wp.vec3)
    phase_table: wp.array(dtype=float)
    all_min: wp.vec3  # union bounds of every medium
    all_max: wp.vec3
    het_min: wp.vec3  # union bounds of the heterogeneous media
    het_max: wp.vec3
    majorant: wp.vec3  # bound of sigma_t over all media
    het_majorant: wp.vec3  # bound of sigma_t over heterogeneous media


@wp.func
def ray_box(o: wp.vec3, d: wp.vec3, bmin: wp.vec3, bmax: wp.vec3):
    """Slab test: (t_near, t_far); t_near > t_far when the ray misses."""
    t0 = float(-INF)
    t1 = float(INF)
    for a in range(3):
        if wp.abs(d[a]) < 1.0e-20:
            if o[a] < bmin[a] or o[a] > bmax[a]:
                return INF, -INF
        else:
            inv = 1.0 / d[a]
            ta = (bmin[a] - o[a]) * inv
            tb = (bmax[a] - o[a]) * inv
            t0 = wp.max(t0, wp.min(ta, tb))
            t1 = wp.min(t1, wp.max(ta, tb))
    return t0, t1


@wp.func
def ray_sphere(o: wp.vec3, d: wp.vec3, c: wp.vec3, r: float):
    """(t_near, t_far) of a unit-direction ray and a sphere; t_near > t_far when it misses."""
    oc = o - c
    b = wp.dot(oc, d)
    h = b * b - (wp.dot(oc, oc) - r * r)
    if h < 0.0:
        return INF, -INF
    s = wp.sqrt(h)
    return -b - s, -b + s


@wp.func
def medium_density(m: Media, i: int, x: wp.vec3) -> float:
    kind = m.kind[i]
    if kind == SPHERE:
        d = x - m.center[i]
        return wp.where(wp.dot(d, d) <= m.radius[i] * m.radius[i], 1.0, 0.0)
    lo = m.bmin[i]
    hi = m.bmax[i]
    if x[0] < lo[0] or x[1] < lo[1] or x[2] < lo[2] or x[0] > hi[0] or x[1] > hi[1] or x[2] > hi[2]:
        return 0.0
    if kind == BOX:
        return 1.0
    if kind == GRID:
        return grid_trilinear(m.grid_data, m.offset[i], m.dims[i], lo, hi, x)
    if kind == RBF:
        return rbf_density(m.hash_grid[i], m.points, m.offset[i], m.radius[i], x)
    return particle_count(m.hash_grid[i], m.points, m.offset[i], m.radius[i], x)


@wp.func
def is_heterogeneous(m: Media, i: int) -> bool:
    return m.kind[i] >= GRID


@wp.func
def sigma_t_at(m: Media, x: wp.vec3, hetero_only: bool) -> wp.vec3:
    s = wp.vec3(0.0)
    for i in range(m.count):
        if is_heterogeneous(m, i) or not hetero_only:
            s += medium_density(m, i, x) * m.sigma[i]
    return s


@wp.func
def in_scatter_at(m: Media, x: wp.vec3, cos_theta: float) -> wp.vec3:
    """sum_m sigma_s,m(x) p_m(cos_theta): what scatters from a unit beam into a unit solid angle."""
    s = wp.vec3(0.0)
    for i in range(m.count):
        dens = medium_density(m, i, x)
        if dens > 0.0:
            s += dens * phase_eval(m.phase[i], m.phase_table, cos_theta) * wp.cw_mul(m.sigma[i], m.albedo[i])
    return s


@wp.func
def choose_medium(m: Media, x: wp.vec3, c: int, u: float) -> int:
    """Pick the medium that caused a collision at x, in proportion to its sigma_t in channel c."""
    total = float(0.0)
    for i in range(m.count):
        total += medium_density(m, i, x) * m.sigma[i][c]
    target = u * total
    acc = float(0.0)
    last = int(0)
    for i in range(m.count):
        w = medium_density(m, i, x) * m.sigma[i][c]
        if w > 0.0:
            last = i
            acc += w
            if acc >= target:
                return i
    return last


@wp.func
def inside_convex(m: Media, i: int, x: wp.vec3) -> bool:
    """Whether x lies in homogeneous medium i (a box or a sphere)."""
    if m.kind[i] == SPHERE:
        r = x - m.center[i]
        return wp.dot(r, r) <= m.radius[i] * m.radius[i]
    lo = m.bmin[i]
    hi = m.bmax[i]
    return x[0] >= lo[0] and x[1] >= lo[1] and x[2] >= lo[2] and x[0] <= hi[0] and x[1] <= hi[1] and x[2] <= hi[2]


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
def transmittance_estimate(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int, rng: wp.uint32) -> wp.vec3:
    """Unbiased estimate of exp(-integral sigma_t) over [t0, t1]: exact for homogeneous media,
    ratio tracking (Novak et al. 2014) with Russian roulette for heterogeneous ones."""
    tr = transmittance_rgb(homogeneous_optical_depth(m, o, d, t0, t1))
    mu = m.het_majorant[c]
    if mu <= 0.0:
        return tr
    a, b = ray_box(o, d, m.het_min, m.het_max)
    t = wp.max(a, t0)
    t_end = wp.min(b, t1)
    w = float(1.0)
    while t < t_end:
        t = t - wp.log(1.0 - wp.randf(rng)) / mu
        if t >= t_end:
            break
        w *= 1.0 - sigma_t_at(m, o + t * d, True)[c] / mu
        if w < 0.1:  # Russian roulette keeps long thick segments short, unbiased
            if wp.randf(rng) < 0.5:
                return wp.vec3(0.0)
            w *= 2.0
    return tr * w


def medium_bounds(m) -> tuple[np.ndarray, np.ndarray] | None:
    """Axis-aligned bounds (lo, hi) of a scene medium: RBFs reach CUTOFF radii past their
    centres, particles one radius; None for an empty RBF or particle cloud."""
    if isinstance(m, HomogeneousMedium):
        half = 0.5 * np.asarray(m.size) if m.shape == "box" else np.full(3, m.radius)
        return np.asarray(m.center) - half, np.asarray(m.center) + half
    if isinstance(m, GridMedium):
        return np.asarray(m.bounds_min), np.asarray(m.bounds_max)
    pts = m.centers if isinstance(m, RBFMedium) else m.positions
    if not len(pts):
        return None
    reach = float(CUTOFF) * m.radius if isinstance(m, RBFMedium) else m.radius
    return pts.min(0) - reach, pts.max(0) + reach


def scene_bounds(scene: Scene, media: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (lo, hi) of the scene's surfaces and, with ``media``, its media; [-1, 1]^3 if empty."""
    boxes = [(s.vertices.min(0), s.vertices.max(0)) for s in scene.surfaces]
    if media:
        boxes += [b for b in map(medium_bounds, scene.media) if b is not None]
    if not boxes:
        return np.full(3, -1.0), np.full(3, 1.0)
    return np.min([b[0] for b in boxes], 0).astype(np.float64), np.max([b[1] for b in boxes], 0).astype(np.float64)


class MediaBuffers:
    """Owns the device arrays (and hash grids) behind a ``Media`` struct."""

    def __init__(self, scene: Scene, device):
        kinds, bmin, bmax, center, radius, sigma, albedo, phases, dims, offset = ([] for _ in range(10))
        majorants, grid_chunks, point_chunks, tables = [], [], [], []
        n_grid = n_points = n_table = 0
        point_media = []
        for m in scene.media:
            ph, values = phase_struct(m.phase, n_table)
            if len(values):
                tables.append(values)
                n_table += len(values)
            phases.append(ph)
            albedo.append(m.albedo)
            dims.append((1, 1, 1))
            offset.append(0)
            center.append((0.0, 0.0, 0.0))
            radius.append(0.0)
            lo, hi = medium_bounds(m) or (np.full(3, 1.0), np.full(3, -1.0))  # empty cloud: nothing hits it
            bmin.append(lo)
            bmax.append(hi)
            if isinstance(m, HomogeneousMedium):
                kinds.append(int(BOX) if m.shape == "box" else int(SPHERE))
                center[-1], radius[-1] = m.center, m.radius
                sigma.append(m.sigma_t)
                majorants.append(np.asarray(m.sigma_t))
            elif isinstance(m, GridMedium):
                kinds.append(int(GRID))
                dz, dy, dx = m.density.shape
                dims[-1], offset[-1] = (dx, dy, dz), n_grid
                grid_chunks.append(m.density.ravel())
                n_grid += m.density.size
                sigma.append(m.sigma_t_scale)
                majorants.append(grid_majorant(m.density) * np.asarray(m.sigma_t_scale))
            else:
                pts = m.centers if isinstance(m, RBFMedium) else m.positions
                reach = float(CUTOFF) * m.radius if isinstance(m, RBFMedium) else m.radius
                kinds.append(int(RBF) if isinstance(m, RBFMedium) else int(PARTICLES))
                radius[-1], offset[-1] = m.radius, n_points
                point_chunks.append(pts)
                point_media.append((len(kinds) - 1, n_points, len(pts), reach))
                n_points += len(pts)
                scale = np.asarray(m.peak if isinstance(m, RBFMedium) else m.sigma_t)
                sigma.append(tuple(scale))
                bound = rbf_majorant(pts, m.radius) if isinstance(m, RBFMedium) else particle_majorant(pts, m.radius)
                majorants.append(bound * scale)
        count = len(kinds)
        self.device = device
        f3 = lambda rows: wp.array(np.asarray(rows, np.float32).reshape(-1, 3) if rows else np.zeros((1, 3), np.float32), dtype=wp.vec3, device=device)  # noqa: E731
        s = Media()
        s.count = count
        s.kind = wp.array(np.asarray(kinds or [0], np.int32), dtype=int, device=device)
        s.bmin, s.bmax, s.center = f3(bmin), f3(bmax), f3(center)
        s.radius = wp.array(np.asarray(radius or [0.0], np.float32), dtype=float, device=device)
        s.sigma, s.albedo = f3(sigma), f3(albedo)
        s.phase = wp.array(phases or [Phase()], dtype=Phase, device=device)
        s.dims = wp.array(np.asarray(dims or [(1, 1, 1)], np.int32), dtype=wp.vec3i, device=device)
        s.offset = wp.array(np.asarray(offset or [0], np.int32), dtype=int, device=device)
        s.grid_data = wp.array(np.concatenate(grid_chunks).astype(np.float32) if grid_chunks else np.zeros(1, np.float32), dtype=float, device=device)
        pts_all = np.concatenate(point_chunks).astype(np.float32) if n_points else np.zeros((1, 3), np.float32)
        s.points = wp.array(pts_all, dtype=wp.vec3, device=device)
        s.phase_table = wp.array(np.concatenate(tables) if tables else np.zeros(1, np.float32), dtype=float, device=device)
        self.hash_grids = []
        ids = np.zeros(max(count, 1), np.uint64)
        for i, first, n, reach in point_media:
            if n == 0:
                continue
            hg = wp.HashGrid(64, 64, 64, device=device)
            hg.build(s.points[first : first + n], reach)
            self.hash_grids.append(hg)
            ids[i] = hg.id
        s.hash_grid = wp.array(ids, dtype=wp.uint64, device=device)
        het = [k >= int(GRID) for k in kinds]
        s.all_min, s.all_max = _union(bmin, bmax, [True] * count)
        s.het_min, s.het_max = _union(bmin, bmax, het)
        s.majorant = wp.vec3(*np.sum(majorants, axis=0)) if count else wp.vec3(0.0)
        het_maj = [mj for mj, h in zip(majorants, het) if h]
        s.het_majorant = wp.vec3(*np.sum(het_maj, axis=0)) if het_maj else wp.vec3(0.0)
        self.struct = s
        #: Extinction is the same in R, G and B everywhere: one distance sampling serves all three.
        self.grey = all(abs(v[0] - v[1]) < 1e-12 and abs(v[0] - v[2]) < 1e-12 for v in sigma)


def _union(bmin, bmax, mask):
    lo = [b for b, k in zip(bmin, mask) if k]
    hi = [b for b, k in zip(bmax, mask) if k]
    if not lo:
        return wp.vec3(1.0), wp.vec3(-1.0)
    return wp.vec3(*np.min(lo, 0).astype(np.float32)), wp.vec3(*np.max(hi, 0).astype(np.float32))


@wp.kernel
def sample_extinction(offset: int, m: Media, lo: wp.vec3, hi: wp.vec3, n: wp.vec3i, out: wp.array(dtype=wp.vec3)):
    """sigma_t at the cell centres of an n[0] x n[1] x n[2] lattice over [lo, hi], x fastest."""
    tid = wp.tid() + offset
    ix = tid % n[0]
    iy = (tid / n[0]) % n[1]
    iz = tid / (n[0] * n[1])
    f = wp.vec3((float(ix) + 0.5) / float(n[0]), (float(iy) + 0.5) / float(n[1]), (float(iz) + 0.5) / float(n[2]))
    out[tid] = sigma_t_at(m, lo + wp.cw_mul(hi - lo, f), False)


def extinction_volume(scene, resolution: int = 64, device: str | None = None):
    """The scene's extinction sampled at cell centres over the union of its media's bounds.

    Returns (sigma_t, bounds_min, bounds_max): sigma_t of shape (D, H, W, 3) in inverse
    scene units, [z, y, x] like a grid medium's density, with ``resolution`` cells along
    the longest side. For looking inside volumes (pyvista) and checking techniques' grids.
    """
    from .. import device as dev
    from ..scene import load_scene

    scene = load_scene(scene)
    device = dev.pick(device)
    if not scene.media:
        raise ValueError(f"{scene.source}: the scene has no media (allowed: a scene with at least one medium)")
    buffers = MediaBuffers(scene, device)
    lo, hi = np.asarray(buffers.struct.all_min, np.float64), np.asarray(buffers.struct.all_max, np.float64)
    extent = hi - lo
    dims = np.maximum(1, np.round(resolution * extent / extent.max())).astype(int)
    out = wp.empty(int(np.prod(dims)), dtype=wp.vec3, device=device)
    dev.launch(sample_extinction, out.shape[0], [buffers.struct, wp.vec3(*lo), wp.vec3(*hi), wp.vec3i(*dims), out], device)
    return out.numpy().reshape(dims[2], dims[1], dims[0], 3), tuple(lo), tuple(hi)
