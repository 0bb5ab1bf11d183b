"""Scene to device: the one place where scene dataclasses become the ``@wp.struct``s and
arrays that kernels read. ``media``, ``geometry`` and ``physics`` take structs and arrays
and know nothing of scenes; everything that reads a ``Scene`` to build them is here.

``pinhole`` (Camera -> PinholeCamera), ``light_array`` (lights -> Emitter array),
``SurfaceBuffers`` (surfaces -> one wp.Mesh and materials), ``MediaBuffers`` (media ->
the Media struct, from each kind's own buffers: ``grid_buffers``, ``gaussian_buffers``,
``particle_buffers``), ``medium_bounds`` / ``scene_bounds``, and
``extinction_volume`` (the public sampler of a scene's sigma_t).

``SceneUploads`` owns the ``Media``, ``Surfaces`` and ``Emitter`` buffers and declares one
stage per part, so a change to the lights re-uploads the lights and nothing else, and a
scene without surfaces skips building a BVH.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from . import device as dev
from .geometry.camera import PinholeCamera
from .geometry.mesh import Surfaces
from .geometry.shadowmap import ShadowedLights, ShadowMap, shadow_map_depths, shadow_map_for, texels
from .media.grid import Grid, GridBuffers
from .media.particles import ParticleBuffers, Particles, ball_around, particle_majorant
from .media.rbf import CUTOFF, GaussianBuffers, Gaussians, rbf_majorant
from .media.volume import BOX, GRID, PARTICLES, RBF, SPHERE, Media, sample_extinction, sample_rbf_density
from .physics.brdf import Material
from .physics.lights import KINDS, Emitter
from .physics.phase import PhaseParams, phase_struct
from .physics.sphere import fibonacci_directions
from .physics.constants import INF
from .pipeline import Bias, Setting, SettingsError, Stage, Technique
from .scene import SceneError, load_scene
from .scene.model import Camera, GridMedium, HomogeneousMedium, MediumKind, ParticleMedium, RBFMedium, Scene


def pinhole(camera: Camera) -> PinholeCamera:
    o = np.asarray(camera.origin, np.float64)
    f = np.asarray(camera.target, np.float64) - o
    f /= np.linalg.norm(f)
    r = np.cross(f, np.asarray(camera.up, np.float64))
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    th = math.tan(math.radians(camera.fov_y) / 2.0)
    cam = PinholeCamera()
    cam.origin = wp.vec3(*o)
    cam.forward = wp.vec3(*f)
    cam.right = wp.vec3(*(r * th * camera.width / camera.height))
    cam.up = wp.vec3(*(u * th))
    cam.width, cam.height = camera.width, camera.height
    return cam


def light_array(scene, device) -> wp.array:
    """The scene's lights as an array of ``Emitter`` structs."""
    return lights_array(light_structs(scene), device)


def lights_array(structs: list, device) -> wp.array:
    """Host-side ``Emitter`` structs as a device array (empty for none)."""
    return wp.array(structs, dtype=Emitter, device=device) if structs else wp.empty(0, dtype=Emitter, device=device)


def light_structs(scene) -> list:
    """The scene's lights as ``Emitter`` structs (host side)."""
    out = []
    for light in scene.lights:
        s = Emitter()
        s.kind = KINDS[light.type]
        s.position = wp.vec3(*light.position)
        s.direction = wp.vec3(*light.direction)
        s.strength = wp.vec3(*light.strength)
        s.cos_inner = math.cos(math.radians(light.inner_angle))
        s.cos_outer = math.cos(math.radians(light.outer_angle))
        out.append(s)
    return out


def sky_lights(background, count: int, device) -> wp.array:
    """A constant sky of radiance ``background`` as ``count`` directional lights from a
    Fibonacci set of directions over the whole sphere (``physics.sphere.fibonacci_directions``),
    each of strength ``background``: a technique sums p_k E_k T_k over them and divides by sum p_k
    (or by sum cos_k at a surface), which is exact for an unoccluded point. None when the sky
    is black or ``count`` is 0."""
    out = sky_light_structs(background, count)
    return lights_array(out, device) if out else None


def sky_light_structs(background, count: int) -> list:
    """``sky_lights`` as host-side ``Emitter`` structs ([] for a black sky or count 0)."""
    sky = np.asarray(background, np.float64)
    if count <= 0 or not np.any(sky > 0.0):
        return []
    out = []
    for w in fibonacci_directions(count):  # w: toward the sky
        light = Emitter()
        light.kind = KINDS["directional"]
        light.position = wp.vec3(0.0)
        light.direction = wp.vec3(*(-w))
        light.strength = wp.vec3(*sky)
        light.cos_inner = light.cos_outer = 1.0
        out.append(light)
    return out


def shadow_map_structs(scene: Scene, res: int, bias: float, occluders: bool) -> list:
    """One ``ShadowMap`` per scene light (kind NONE without occluders), laid end to end in
    one texel array: the maps of the scene's bounds (``shadow_map_for``)."""
    bounds = scene_bounds(scene)
    out, offset = [], 0
    for light in scene.lights:
        sm = shadow_map_for(light, res, bias, bounds, offset, occluders)
        out.append(sm)
        offset += texels(sm.kind, res)
    return out


def shadowed_lights(scene: Scene, lights: wp.array, surfaces: Surfaces, res: int, bias: float,
                    device) -> ShadowedLights:
    """The scene's lights with their shadow maps, made by casting one ray per texel through the
    surfaces' BVH; without surfaces (or lights) every map says "lit" and nothing is cast."""
    occluders = bool(scene.surfaces) and bool(scene.lights)
    structs = shadow_map_structs(scene, res, bias, occluders)
    sl = ShadowedLights()
    sl.lights = lights
    sl.maps = wp.array(structs or [ShadowMap()], dtype=ShadowMap, device=device)
    sl.depth = (shadow_map_depths(structs, device, surfaces=surfaces) if occluders
                else wp.full(1, INF, dtype=float, device=device))
    sl.baked_n, sl.baked = 0, wp.zeros(1, dtype=wp.vec3, device=device)  # marched (shading.LightDepthVolume.attach)
    return sl


#: The light volume a marcher may read instead of marching to the lights (``shading.bake_light_depth``).
LIGHT_VOLUME_SETTINGS = {
    "shadow_grid": Setting(32, 0, 512, "nodes per axis of the lattice the media's optical depth toward each light is "
                                       "baked on, over heterogeneous media (a lookup a step instead of a march; shadow "
                                       "edges blurred to a cell); 0 = marched at every step"),
}
LIGHT_VOLUME_BIAS = Bias("shadow_grid", exact=0, when="heterogeneous")


def check_particle_scene(technique: str, scene: Scene) -> None:
    """Raise ``SettingsError`` unless the scene's media are all particle clouds (at least one)
    sharing one phase function: what the particle techniques render."""
    bad = [f"media[{k}] of type {m.type}" for k, m in enumerate(scene.media) if m.type != MediumKind.PARTICLES]
    if bad or not scene.media:
        raise SettingsError(f"{technique}: renders particle media only (scene {scene.name!r} has "
                            f"{', '.join(bad) if bad else 'no media'}; allowed: type = \"particles\")")
    phases = {(m.phase.type, m.phase.g, m.phase.g_d, m.phase.alpha, m.phase.w_d,
               None if m.phase.values is None else m.phase.values.tobytes()) for m in scene.media}
    if len(phases) > 1:
        raise SettingsError(f"{technique}: the particle media must share one phase function (found {len(phases)})")


def particle_buffers(media: list, device, **options) -> ParticleBuffers:
    """Particle media (a scene's, or one) as one cloud on the device (per particle: centre,
    radius, sigma_t, albedo; media in order); ``options`` go to ``ParticleBuffers``."""
    pos = np.concatenate([np.asarray(m.positions, np.float32).reshape(-1, 3) for m in media])
    counts = [len(m.positions) for m in media]
    rep = lambda values: np.repeat(np.asarray(values, np.float32), counts, axis=0)  # noqa: E731
    return ParticleBuffers(pos, rep([m.radius for m in media]), rep([m.sigma_t for m in media]),
                           rep([m.albedo for m in media]), device, **options)


class SurfaceBuffers:
    """Owns the ``wp.Mesh`` and material array behind a ``Surfaces`` struct."""

    def __init__(self, scene: Scene, device):
        s = Surfaces()
        verts, faces, mats = [], [], []
        base = 0
        for surf in scene.surfaces:
            verts.append(surf.vertices)
            faces.append(surf.faces + base)
            base += len(surf.vertices)
            for colour in surf.diffuse:
                m = Material()
                m.diffuse = wp.vec3(*colour)
                m.specular = surf.specular
                m.shininess = surf.shininess
                mats.append(m)
        self.mesh = None
        if faces:
            self.mesh = wp.Mesh(
                points=wp.array(np.concatenate(verts).astype(np.float32), dtype=wp.vec3, device=device),
                indices=wp.array(np.concatenate(faces).astype(np.int32).ravel(), dtype=int, device=device),
            )
            s.mesh, s.present = self.mesh.id, 1
        else:
            s.mesh, s.present = wp.uint64(0), 0
            mats = [Material()]
        s.material = wp.array(mats, dtype=Material, device=device)
        self.struct = s


def medium_bounds(m) -> tuple[np.ndarray, np.ndarray] | None:
    """Axis-aligned bounds (lo, hi) of a scene medium: RBFs reach CUTOFF radii past their
    centres, particles one radius; None for an empty RBF or particle cloud."""
    if isinstance(m, HomogeneousMedium):
        half = 0.5 * np.asarray(m.size) if m.shape == "box" else np.full(3, m.radius)
        return np.asarray(m.center) - half, np.asarray(m.center) + half
    if isinstance(m, GridMedium):
        return np.asarray(m.bounds_min), np.asarray(m.bounds_max)
    pts, reach = cloud_points(m)
    if not len(pts):
        return None
    return pts.min(0) - reach, pts.max(0) + reach


def cloud_points(m) -> tuple[np.ndarray, float]:
    """An RBF or particle medium's centres and how far its components reach past them: RBFs
    CUTOFF radii (their cut-off spheres), particles one radius."""
    if isinstance(m, RBFMedium):
        return m.centers, float(CUTOFF) * m.radius
    return m.positions, m.radius


def medium_ball(m, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """(centre, radius) of a ball holding all of a scene medium with bounds (lo, hi): a
    sphere itself; around the centres of an RBF or particle cloud, their farthest reach; else
    the box's circumsphere. Padded by 1e-5 of its size, so that float32 rays stay inside it."""
    if isinstance(m, HomogeneousMedium) and m.shape == "sphere":
        c, r = np.asarray(m.center, np.float64), float(m.radius)
    elif isinstance(m, (RBFMedium, ParticleMedium)) and len(cloud_points(m)[0]):
        pts, reach = cloud_points(m)
        c, r = ball_around(np.asarray(pts, np.float64), reach)
    else:
        c, r = 0.5 * (np.asarray(lo, np.float64) + hi), 0.5 * float(np.linalg.norm(np.asarray(hi, np.float64) - lo))
    return c, max(r, 0.0) * (1.0 + 1e-5) + 1e-6


def scene_bounds(scene: Scene, media: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (lo, hi) of the scene's surfaces and, with ``media``, its media; [-1, 1]^3 if empty."""
    boxes = [(s.vertices.min(0), s.vertices.max(0)) for s in scene.surfaces]
    if media:
        boxes += [b for b in map(medium_bounds, scene.media) if b is not None]
    if not boxes:
        return np.full(3, -1.0), np.full(3, 1.0)
    return np.min([b[0] for b in boxes], 0).astype(np.float64), np.max([b[1] for b in boxes], 0).astype(np.float64)


def load_volume(path: str, device) -> wp.Volume:
    """A NanoVDB file on the device (``wp.Volume.load_from_nvdb``); the scene loader has checked
    it (``warpvol.scene.nanovdb``), so a failure here means the file changed since. The file is
    memory-mapped, not read: Warp slices its buffer without copying a mapping (a bytes object's
    slices are copies), which saves two copies of the grid at the peak."""
    try:
        return wp.Volume.load_from_nvdb(np.memmap(path, np.uint8, "r"), device=device)
    except (OSError, RuntimeError, ValueError) as exc:
        raise SceneError(f"{path}: cannot load the NanoVDB grid: {exc} (allowed: the file as the scene loaded it)") from None


def grid_buffers(m: GridMedium, device) -> GridBuffers:
    """A grid medium's samples on the device: its NanoVDB file, or its dense array."""
    if m.volume is not None:
        return GridBuffers(None, load_volume(m.volume.path, device), m.volume_index_min, m.dims, m.bounds_min,
                           m.bounds_max, device, m.volume.outside_leaves)
    return GridBuffers(m.density, None, None, m.dims, m.bounds_min, m.bounds_max, device)


def gaussian_buffers(m: RBFMedium, device) -> tuple[GaussianBuffers, float]:
    """An RBF medium's Gaussians on the device, and the bound of its density factor."""
    radii, amps = m.gaussians()
    # one radius for all: the scalar, so the bound is the one a uniform medium always had
    same = len(radii) == 0 or bool(np.all(radii == radii[0]))
    return (GaussianBuffers(m.centers, radii, amps, m.radius, device),
            rbf_majorant(m.centers, m.radius if same else radii, amplitudes=amps))


#: The marchers' setting for media whose lookup sums what is in reach (RBFs), and its bias.
EXTINCTION_SETTINGS = {
    "extinction_grid": Setting(-1, -1, 512, "cells along the longest side of the grid an RBF medium's extinction is "
                                             "baked into, so a march reads 8 samples where it would sum every Gaussian "
                                             "in reach; 0: the Gaussians summed at every lookup (exact); -1: chosen from "
                                             "the medium (a cell a quarter of the smallest radius where that grid is at "
                                             "most 64 cells a side; else half a radius where more than 8 Gaussians "
                                             "overlap; else not baked)"),
}
EXTINCTION_BIAS = Bias("extinction_grid", exact=0, when="rbf")
#: A cell of the baked grid, in radii of the smallest Gaussian: the trilinear error goes as its
#: square (tests/test_extinction_grid.py). Even one Gaussian costs a march more than the grid's 8
#: samples do (its hash-grid cell and its exp at each of three lookups a step), so a medium whose
#: grid of such cells is small (BAKE_SMALL cells a side at most) is baked whatever its Gaussians
#: (rbf-single and rbf-cornell in results/defaults). A larger grid (small Gaussians spread over a
#: wide box) costs its cells in time and memory: it is baked only where more than BAKE_OVERLAP
#: Gaussians reach a point on average, a cell half the smallest radius, at most BAKE_MAX a side.
BAKE_CELL = 0.25
BAKE_SMALL = 64
BAKE_OVERLAP = 8
BAKE_MAX = 256


def extinction_cells(m, setting: int) -> int:
    """Cells along the longest side of the grid a march reads medium ``m`` from (0: the medium
    itself): ``setting`` for an RBF medium, or with -1 the choice from the medium (a cell BAKE_CELL
    of its smallest radius where that grid has at most BAKE_SMALL cells a side; else, where more
    than BAKE_OVERLAP Gaussians reach a point, a cell half that radius, at most BAKE_MAX; else 0);
    0 for every other kind."""
    if not isinstance(m, RBFMedium) or not len(m.centers) or setting == 0:
        return 0
    if setting > 0:
        return setting
    lo, hi = medium_bounds(m)
    extent, radius = float(np.max(hi - lo)), float(m.gaussians()[0].min())
    fine = math.ceil(extent / (BAKE_CELL * radius))
    if fine <= BAKE_SMALL:
        return fine
    if gaussians_in_reach(m) <= BAKE_OVERLAP:
        return 0
    return int(min(BAKE_MAX, math.ceil(extent / (0.5 * radius))))


def gaussians_in_reach(m: RBFMedium) -> float:
    """How many of an RBF medium's Gaussians reach a point of its bounds on average: the sum of
    their cut-off balls' volumes over the bounds' volume (what a density lookup sums)."""
    radii, _ = m.gaussians()
    lo, hi = medium_bounds(m) or (np.zeros(3), np.zeros(3))
    volume = float(np.prod(np.maximum(hi - lo, 1e-9)))
    return float(np.sum(4.0 / 3.0 * np.pi * (float(CUTOFF) * radii.astype(np.float64)) ** 3)) / volume


def baked_rbf_grid(m: RBFMedium, lo: np.ndarray, hi: np.ndarray, cells: int, device) -> GridBuffers:
    """An RBF medium's density factor sampled at the cell centres of a grid over its bounds
    [lo, hi], ``cells`` along the longest side (at least 2 on each): a grid medium of the same
    extinction up to trilinear interpolation (error ~ (cell / radius)^2). Its Gaussians are
    uploaded for the sampling only; their majorant, which the grid's replaces, is not computed."""
    gaussians = GaussianBuffers(m.centers, *m.gaussians(), m.radius, device)
    extent = np.maximum(hi - lo, 1e-9)
    dims = np.maximum(2, np.ceil(cells * extent / extent.max() - 1e-9)).astype(int)
    out = wp.empty(int(np.prod(dims)), dtype=float, device=device)
    dev.launch(sample_rbf_density, out.shape[0], [gaussians.struct, wp.vec3(*lo.astype(np.float32)),
                                                   wp.vec3(*hi.astype(np.float32)), wp.vec3i(*dims), out], device)
    return GridBuffers(out.numpy().reshape(dims[2], dims[1], dims[0]), None, None, tuple(int(d) for d in dims), lo, hi,
                       device)


class MediaBuffers:
    """Owns the device buffers behind a ``Media`` struct: each medium's own (``grids``,
    ``gaussians``, ``clouds``: the kinds' buffers, in the order of the scene's media)."""

    def __init__(self, scene: Scene, device, extinction_grid: int = 0):
        """Every medium of ``scene`` on ``device``: per medium its kind, box and bounding ball,
        extinction, albedo and phase (its table in one shared array), and its kind's buffers
        (a grid's dense or NanoVDB values and majorant grid; an RBF medium's Gaussians with their
        hash grid and BVH; a particle cloud's spheres), with the ``Media`` struct kernels read.
        ``extinction_grid`` (``extinction_cells``): RBF media baked into grids for a march;
        ``baked`` lists the cells along the longest side of each medium's (0: not baked)."""
        kinds, bmin, bmax, center, radius, sigma, albedo, phases, index, reach = ([] for _ in range(10))
        majorants, tables = [], []
        n_table = 0
        self.grids, self.gaussians, self.clouds = [], [], []
        self.baked = []
        for m in scene.media:
            self.baked.append(extinction_cells(m, extinction_grid))
            ph, values = phase_struct(m.phase, n_table)
            if len(values):
                tables.append(values)
                n_table += len(values)
            phases.append(ph)
            albedo.append(m.albedo)
            homogeneous = isinstance(m, HomogeneousMedium)
            center.append(m.center if homogeneous else (0.0, 0.0, 0.0))
            radius.append(m.radius if homogeneous else 0.0)
            lo, hi = medium_bounds(m) or (np.full(3, 1.0), np.full(3, -1.0))  # empty cloud: nothing hits it
            bmin.append(lo)
            bmax.append(hi)
            reach.append(medium_ball(m, lo, hi))
            kind, i, sig, majorant = self._kind_buffers(m, lo, hi, self.baked[-1], device)
            kinds.append(kind)
            index.append(i)
            sigma.append(sig)
            majorants.append(majorant)
        count = len(kinds)
        self.device = device
        f3 = lambda rows: wp.array(np.asarray(rows, np.float32).reshape(-1, 3) if rows else np.zeros((1, 3), np.float32), dtype=wp.vec3, device=device)  # noqa: E731
        s = Media()
        s.count = count
        s.kind = wp.array(np.asarray(kinds or [0], np.int32), dtype=int, device=device)
        s.bmin, s.bmax, s.center = f3(bmin), f3(bmax), f3(center)
        s.reach_centre = f3([c for c, _ in reach])
        s.reach = wp.array(np.asarray([r for _, r in reach] or [0.0], np.float32), dtype=float, device=device)
        s.radius = wp.array(np.asarray(radius or [0.0], np.float32), dtype=float, device=device)
        s.sigma, s.albedo = f3(sigma), f3(albedo)
        s.phase = wp.array(phases or [PhaseParams()], dtype=PhaseParams, device=device)
        s.phase_table = wp.array(np.concatenate(tables) if tables else np.zeros(1, np.float32), dtype=float, device=device)
        s.index = wp.array(np.asarray(index or [0], np.int32), dtype=int, device=device)
        s.grids = wp.array([g.struct for g in self.grids] or [Grid()], dtype=Grid, device=device)
        s.gaussians = wp.array([g.struct for g in self.gaussians] or [Gaussians()], dtype=Gaussians, device=device)
        s.particles = wp.array([c.struct for c in self.clouds] or [Particles()], dtype=Particles, device=device)
        het = [k >= int(GRID) for k in kinds]
        s.all_min, s.all_max = _union(bmin, bmax, [True] * count)
        s.het_min, s.het_max = _union(bmin, bmax, het)
        s.majorant = wp.vec3(*np.sum(majorants, axis=0)) if count else wp.vec3(0.0)
        het_maj = [mj for mj, h in zip(majorants, het) if h]
        s.het_majorant = wp.vec3(*np.sum(het_maj, axis=0)) if het_maj else wp.vec3(0.0)
        self.struct = s
        #: Extinction is the same in R, G and B everywhere: one distance sampling serves all three.
        self.grey = all(abs(v[0] - v[1]) < 1e-12 and abs(v[0] - v[2]) < 1e-12 for v in sigma)

    def _kind_buffers(self, m, lo: np.ndarray, hi: np.ndarray, baked: int, device):
        """Medium ``m``'s kind and its kind's buffers, appended to ``grids`` (a grid, or an RBF
        medium baked to ``baked`` cells), ``gaussians`` or ``clouds``: (kind, its index in that
        list, its extinction scale, its majorant)."""
        if isinstance(m, HomogeneousMedium):
            return int(BOX) if m.shape == "box" else int(SPHERE), 0, m.sigma_t, np.asarray(m.sigma_t)
        if isinstance(m, GridMedium):
            self.grids.append(grid_buffers(m, device))
            return int(GRID), len(self.grids) - 1, m.sigma_t_scale, self.grids[-1].bound * np.asarray(m.sigma_t_scale)
        if isinstance(m, RBFMedium) and baked:
            self.grids.append(baked_rbf_grid(m, lo, hi, baked, device))
            return int(GRID), len(self.grids) - 1, tuple(m.peak), self.grids[-1].bound * np.asarray(m.peak)
        if isinstance(m, RBFMedium):
            buffers, bound = gaussian_buffers(m, device)
            self.gaussians.append(buffers)
            return int(RBF), len(self.gaussians) - 1, tuple(m.peak), bound * np.asarray(m.peak)
        self.clouds.append(particle_buffers([m], device))  # a cloud of its own
        return (int(PARTICLES), len(self.clouds) - 1, tuple(m.sigma_t),
                particle_majorant(m.positions, m.radius) * np.asarray(m.sigma_t))


def _union(bmin, bmax, mask):
    lo = [b for b, k in zip(bmin, mask) if k]
    hi = [b for b, k in zip(bmax, mask) if k]
    if not lo:
        return wp.vec3(1.0), wp.vec3(-1.0)
    return wp.vec3(*np.min(lo, 0).astype(np.float32)), wp.vec3(*np.max(hi, 0).astype(np.float32))


def extinction_volume(scene, resolution: int = 64, device: str | None = None):
    """The scene's extinction sampled at cell centres over the union of its media's bounds.

    Returns (sigma_t, bounds_min, bounds_max): sigma_t of shape (D, H, W, 3) in inverse
    scene units, [z, y, x] like a grid medium's density, with ``resolution`` cells along
    the longest side. For looking inside volumes (pyvista) and checking techniques' grids.
    """
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


class SceneUploads:
    """Device copies of a technique's scene: ``media``, ``surfaces`` and ``lights``."""

    def __init__(self, technique: Technique, medium: bool = True):
        self.t = technique
        self._medium = medium  # False: the technique builds its own view of the media
        self.media: MediaBuffers | None = None
        self.lights = None
        self._surfaces: SurfaceBuffers | None = None
        self._no_surfaces: SurfaceBuffers | None = None

    def stages(self) -> list[Stage]:
        baking = ("extinction_grid",) if "extinction_grid" in self.t.settings else ()
        return [Stage("medium", self._upload_medium, reads=("medium",), settings=baking)] * self._medium + [
            Stage("surfaces", self._upload_surfaces, reads=("surfaces",), needed=bool(self.t.scene.surfaces)),
            Stage("lights", self._upload_lights, reads=("lights",)),
        ]

    @property
    def surfaces(self):
        """The ``Surfaces`` struct; an empty one when the scene has no surfaces."""
        if self.t.scene.surfaces:
            return self._surfaces.struct
        if self._no_surfaces is None:
            self._no_surfaces = SurfaceBuffers(self.t.scene, self.t.device)
        return self._no_surfaces.struct

    def _upload_medium(self):
        self.media = MediaBuffers(self.t.scene, self.t.device, self.t.settings.get("extinction_grid", 0))

    def diagnostics(self) -> dict:
        """``extinction_grid``: per medium, the cells along the longest side of the grid the march
        read it from (0: the medium itself), as chosen from the scene or set."""
        return {"extinction_grid": list(self.media.baked)} if self.media is not None else {}

    def _upload_surfaces(self):
        self._surfaces = SurfaceBuffers(self.t.scene, self.t.device)

    def _upload_lights(self):
        self.lights = light_array(self.t.scene, self.t.device)
