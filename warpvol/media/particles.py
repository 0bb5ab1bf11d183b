"""Particle media: N spheres, each of uniform extinction; overlaps add.

Every kernel reads a cloud as a ``Particles`` struct (per-sphere radius, sigma_t and albedo;
``ParticleBuffers`` builds it): the reference's ``Media`` holds one per particle medium
(media/volume.py), a particle technique one for the scene's whole cloud. On it: sigma_t at a
point through its hash grid (``particle_sigma_t``), exact optical depth along a segment
through the union of spheres (``particle_optical_depth``, through a ``wp.Bvh`` over the
spheres' boxes), and free flight, the earliest of the spheres' own first collisions
(``particle_free_flight``).
"""

import numpy as np
import warp as wp

from ..geometry.intersect import ray_sphere, sphere_chord
from .homogeneous import uniform_collision
from .rbf import box_distance2, coarse_cells


def ball_around(centres: np.ndarray, reach: float) -> tuple[np.ndarray, float]:
    """(centre, radius) of a ball holding spheres of radius at most ``reach`` about ``centres``
    (N, 3), N >= 1: about the centres' box centre, out to the farthest centre plus ``reach``."""
    centre = 0.5 * (centres.min(0) + centres.max(0))
    return centre, float(np.sqrt(((centres - centre) ** 2).sum(1)).max()) + reach


def particle_majorant(positions: np.ndarray, radius: float, n: int = 12) -> float:
    """Largest number of spheres touching one coarse cell: a bound of the overlap count."""
    if len(positions) == 0:
        return 0.0
    lo, hi = coarse_cells(positions.min(0) - radius, positions.max(0) + radius, n)
    count = np.zeros(len(lo))
    for s in range(0, len(positions), 2048):
        count += np.sum(box_distance2(lo, hi, positions[s : s + 2048].astype(np.float64)) <= radius * radius, axis=1)
    return float(count.max())


@wp.struct
class Particles:
    """A cloud of spheres, each of uniform extinction (overlaps add), as kernels read it."""

    centres: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=float)  # scene units
    sigma_t: wp.array(dtype=wp.vec3)  # RGB extinction inside the sphere, 1/unit
    albedo: wp.array(dtype=wp.vec3)
    grid: wp.uint64  # wp.HashGrid over the centres, queried with r_max
    r_max: float  # the largest radius
    bvh: wp.uint64  # wp.Bvh over the spheres' boxes: rays find the spheres they cross


@wp.func
def particle_sigma_t(P: Particles, x: wp.vec3) -> wp.vec3:
    """sigma_t(x): the sum of sigma_t over the spheres that contain x (through the hash grid)."""
    acc = wp.vec3(0.0)
    q = int(0)
    query = wp.hash_grid_query(P.grid, x, P.r_max)
    while wp.hash_grid_query_next(query, q):
        d = x - P.centres[q]
        if wp.dot(d, d) <= P.radius[q] * P.radius[q]:
            acc += P.sigma_t[q]
    return acc


@wp.func
def particle_extinction(P: Particles, sigma: wp.vec3, x: wp.vec3) -> wp.vec3:
    """sigma_t at x (``particle_sigma_t``; the medium interface, as ``shape_extinction``: ``sigma`` is
    unread, each sphere carries its own sigma_t)."""
    return particle_sigma_t(P, x)


@wp.func
def particle_tau(P: Particles, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, t0: float, t1: float) -> wp.vec3:
    """The optical depth over [t0, t1] along o + t d (unit d) through every sphere
    (``particle_optical_depth``; ``sigma`` unread)."""
    return particle_optical_depth(P, -1, o, d, t0, t1)


@wp.func
def particle_optical_depth(P: Particles, skip: int, x: wp.vec3, w: wp.vec3, t0: float, t1: float) -> wp.vec3:
    """Optical depth along x + t w (unit w), t0 <= t <= t1, through the union of the spheres
    other than ``skip`` (-1: all): exact, chord lengths times sigma_t, the spheres found by a
    BVH ray query (O(log N + the spheres crossed))."""
    tau = wp.vec3(0.0)
    if P.bvh == wp.uint64(0):
        return tau
    q = int(0)
    query = wp.bvh_query_ray(P.bvh, x, w)
    while wp.bvh_query_next(query, q, t1):
        if q != skip:
            c = sphere_chord(x, w, t0, t1, P.centres[q], P.radius[q])
            if c > 0.0:
                tau += c * P.sigma_t[q]
    return tau


@wp.func
def particle_free_flight(P: Particles, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, t0: float, t1: float, c: int,
                         rng: wp.uint32):
    """The first collision on [t0, t1) along o + t d (unit d) in channel c: the earliest of the
    spheres' own first collisions, each in a uniform medium (``uniform_collision``). Returns
    (t, whether there is one, the generator after its draws); t = t1 when there is none.
    ``sigma`` is unread: each sphere carries its own sigma_t (the medium interface's arguments)."""
    best = float(t1)
    hit = bool(False)
    if P.bvh != wp.uint64(0):
        query = wp.bvh_query_ray(P.bvh, o, d)
        k = int(0)
        while wp.bvh_query_next(query, k, best):
            a, b = ray_sphere(o, d, P.centres[k], P.radius[k])
            t = uniform_collision(wp.max(a, t0), wp.min(b, best), P.sigma_t[k][c], wp.randf(rng))
            if t < best:
                best = t
                hit = True
    return best, hit, rng


@wp.struct
class Blocks:
    """A cloud built of blocks (Umenhoffer & Szirmay-Kalos 2005): K instances of templates,
    a template's particles offsets from its centre, all of one radius and medium."""
    centre: wp.array(dtype=wp.vec3)  # per instance
    tpl: wp.array(dtype=int)  # per instance: its template
    reach: wp.array(dtype=float)  # per instance: the template's bounding radius
    first: wp.array(dtype=int)  # per template: its first particle offset
    count: wp.array(dtype=int)  # per template: b
    offsets: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=float)  # per template (one medium each)
    sigma_t: wp.array(dtype=wp.vec3)
    albedo: wp.array(dtype=wp.vec3)
    texel0: wp.array(dtype=int)  # per template: its first impostor texel (-1: one particle, no texture)
    res: int  # T


class BlockCloud:
    """A ``Blocks`` struct with what the host needs of it: ``reach`` (per template, device),
    its largest value ``reach_max``, ``owner`` (per template particle: its template), and
    the counts of instances, templates and template particles."""

    def __init__(self, struct: Blocks, reach: wp.array, n_instances: int):
        self.struct, self.reach, self.n_instances = struct, reach, int(n_instances)
        counts = struct.count.numpy()
        self.n_templates, self.n_offsets = len(counts), int(counts.sum())
        self.reach_max = float(reach.numpy().max()) if reach.shape[0] else 0.0
        self.owner = wp.array(np.repeat(np.arange(len(counts), dtype=np.int32), counts), dtype=int,
                              device=reach.device)


class ParticleBuffers:
    """Owns the device arrays and hash grid behind a ``Particles`` struct.

    Parameters: ``centres`` (N, 3), ``radius`` (N,), ``sigma_t`` and ``albedo`` (N, 3),
    float32 arrays in scene units (kept as host copies under the same names). ``centre`` and ``R`` are the cloud's bounding ball (the
    centres' box centre; the farthest sphere's reach), R = 1 for an empty cloud.
    ``hash_grid`` / ``bvh`` = False skip building those (a user that never looks a point or a
    ray up saves the build).
    """

    def __init__(self, centres: np.ndarray, radius: np.ndarray, sigma_t: np.ndarray, albedo: np.ndarray, device,
                 hash_grid: bool = True, bvh: bool = True):
        centres = np.asarray(centres, np.float32).reshape(-1, 3)
        radius = np.asarray(radius, np.float32).reshape(-1)
        sigma_t = np.asarray(sigma_t, np.float32).reshape(-1, 3)
        albedo = np.asarray(albedo, np.float32).reshape(-1, 3)
        self.centres, self.radius, self.sigma_t, self.albedo = centres, radius, sigma_t, albedo  # host copies
        n = len(centres)
        r_max = float(np.max(radius)) if n else 0.0
        self.centre, self.R = ball_around(centres, r_max) if n else (np.zeros(3), 1.0)
        s = Particles()
        s.centres = wp.array(centres, dtype=wp.vec3, device=device)
        s.radius = wp.array(radius, dtype=float, device=device)
        s.sigma_t = wp.array(sigma_t, dtype=wp.vec3, device=device)
        s.albedo = wp.array(albedo, dtype=wp.vec3, device=device)
        s.r_max = r_max
        self.hash_grid = self.bvh = None
        s.grid = s.bvh = wp.uint64(0)
        if n and bvh:
            reach = radius.reshape(-1, 1)
            self.bvh = wp.Bvh(wp.array(centres - reach, dtype=wp.vec3, device=device),
                              wp.array(centres + reach, dtype=wp.vec3, device=device))
            s.bvh = self.bvh.id
        if n and hash_grid:
            cells = max(1, min(128, int(np.ceil(self.R / max(r_max, 1e-6)))))
            self.hash_grid = wp.HashGrid(cells, cells, cells, device=device)
            self.hash_grid.build(s.centres, r_max)
            s.grid = self.hash_grid.id
        self.struct = s
