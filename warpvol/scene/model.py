"""What is rendered, as plain dataclasses (no Warp here).

Vectors are 3-tuples of floats; RGB quantities are 3-tuples even when the file gave a
scalar. Arrays (grid densities, RBF centres, particle positions, mesh triangles) are
numpy arrays. ``warpvol.scene.load`` builds these from TOML or a dict and validates them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

Vec3 = tuple[float, float, float]


class Kind(str, Enum):
    """A kind named in a scene file, past the loader: a member, equal to (and formatted as) its name."""

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)


class LightKind(Kind):
    POINT = "point"
    SPOT = "spot"
    DIRECTIONAL = "directional"


class MediumKind(Kind):
    HOMOGENEOUS = "homogeneous"
    GRID = "grid"
    RBF = "rbf"
    PARTICLES = "particles"


@dataclass
class Camera:
    origin: Vec3
    target: Vec3
    up: Vec3 = (0.0, 1.0, 0.0)
    fov_y: float = 40.0  # vertical field of view, degrees
    width: int = 128
    height: int = 96
    static: bool = True


@dataclass
class Light:
    type: LightKind  # point | spot | directional (the loader gives a LightKind; a name is taken too)
    strength: Vec3  # intensity (W/sr) for point and spot; irradiance for directional
    position: Vec3 = (0.0, 0.0, 0.0)
    direction: Vec3 = (0.0, -1.0, 0.0)  # travel direction (directional), cone axis (spot)
    inner_angle: float = 20.0  # spot: full strength inside this half-angle, degrees
    outer_angle: float = 30.0  # spot: zero outside this half-angle, degrees
    static: bool = True

    def __post_init__(self):
        self.type = LightKind(self.type)


@dataclass
class Phase:
    type: str = "isotropic"  # isotropic | hg | cornette_shanks | rayleigh | tabulated | hg_draine
    g: float = 0.0  # hg_draine: g of the HG lobe
    values: np.ndarray | None = None  # tabulated: p on a uniform cos grid over [-1, 1]
    g_d: float = 0.0  # hg_draine: the Draine lobe's g, alpha and weight (Jendersie & d'Eon 2023)
    alpha: float = 0.0
    w_d: float = 0.0


@dataclass
class Medium:
    """Common part of every medium: single-scattering albedo and phase function."""

    albedo: Vec3
    phase: Phase
    static: bool = True

    @property
    def type(self) -> MediumKind:
        raise NotImplementedError


@dataclass
class HomogeneousMedium(Medium):
    shape: str = "box"  # box | sphere
    center: Vec3 = (0.0, 0.0, 0.0)
    size: Vec3 = (1.0, 1.0, 1.0)  # box edge lengths
    radius: float = 1.0  # sphere
    sigma_t: Vec3 = (1.0, 1.0, 1.0)

    @property
    def type(self) -> MediumKind:
        return MediumKind.HOMOGENEOUS


@dataclass
class NanoVDBGrid:
    """A float NanoVDB grid in a .nvdb file, as ``warpvol.scene.nanovdb.read_grid`` checked it:
    where its voxels sit and what its values reach. The values stay in the file."""

    path: str
    voxel_size: Vec3  # world size of a voxel along x, y, z (the index-to-world map is a scale)
    origin: Vec3  # world position of voxel (0, 0, 0), its centre
    active_min: tuple[int, int, int]  # index bounding box of the active voxels, inclusive
    active_max: tuple[int, int, int]
    leaves: int  # 8^3 leaf nodes stored
    voxels: int  # active voxels
    value_max: float  # the largest value stored (voxels, tiles, background)
    outside_leaves: float  # the largest value a lookup returns outside the leaves (tiles, background)
    grid_bytes: int  # the grid's size in memory


@dataclass
class GridMedium(Medium):
    """Cell-centred density samples over [bounds_min, bounds_max] (media/grid.py): a dense array
    ``density`` [z, y, x], or a NanoVDB grid ``volume`` whose voxel ``volume_index_min`` +
    (i, j, k) is sample (i, j, k) of a ``volume_dims`` grid (then ``density`` is None)."""

    density: np.ndarray | None = field(default_factory=lambda: np.zeros((1, 1, 1), np.float32))  # [z, y, x]
    bounds_min: Vec3 = (-1.0, -1.0, -1.0)
    bounds_max: Vec3 = (1.0, 1.0, 1.0)
    sigma_t_scale: Vec3 = (1.0, 1.0, 1.0)
    volume: NanoVDBGrid | None = None
    volume_index_min: tuple[int, int, int] = (0, 0, 0)
    volume_dims: tuple[int, int, int] = (1, 1, 1)  # samples along x, y, z

    @property
    def type(self) -> MediumKind:
        return MediumKind.GRID

    @property
    def dims(self) -> tuple[int, int, int]:
        """Samples along x, y, z."""
        if self.volume is not None:
            return self.volume_dims
        dz, dy, dx = self.density.shape
        return dx, dy, dz


@dataclass
class RBFMedium(Medium):
    """sigma_t(x) = peak sum_i a_i exp(-|x - c_i|^2 / (2 r_i^2)): Gaussians of their own
    standard deviation r_i (``radii``) and amplitude a_i (``amplitudes``; Giroud & Biri's c and
    a), ``radius`` the largest r_i."""

    centers: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))
    radius: float = 0.5  # the largest Gaussian's standard deviation
    peak: Vec3 = (1.0, 1.0, 1.0)  # sigma_t at the centre of a Gaussian of amplitude 1
    radii: np.ndarray | None = None  # (N,) each Gaussian's standard deviation; None: all ``radius``
    amplitudes: np.ndarray | None = None  # (N,) each Gaussian's amplitude; None: all 1

    def gaussians(self) -> tuple[np.ndarray, np.ndarray]:
        """(radii, amplitudes), one entry per centre, float32."""
        n = len(self.centers)
        radii = np.full(n, self.radius, np.float32) if self.radii is None else np.asarray(self.radii, np.float32)
        amps = np.ones(n, np.float32) if self.amplitudes is None else np.asarray(self.amplitudes, np.float32)
        return radii, amps

    @property
    def type(self) -> MediumKind:
        return MediumKind.RBF


@dataclass
class ParticleMedium(Medium):
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))
    radius: float = 0.1  # every particle a sphere of this radius
    sigma_t: Vec3 = (1.0, 1.0, 1.0)  # uniform inside each sphere; overlaps add
    # > 0: the cloud is built of blocks of this many particles (Umenhoffer & Szirmay-Kalos 2005): positions are
    # block-major, and every block is the same template of particles, moved
    block_size: int = 0

    @property
    def type(self) -> MediumKind:
        return MediumKind.PARTICLES


@dataclass
class Surface:
    """An opaque two-sided surface, already triangulated (vertices (V, 3), faces (F, 3))."""

    type: str  # mesh | box | plane | sphere | procedural
    vertices: np.ndarray
    faces: np.ndarray
    diffuse: np.ndarray  # (F, 3) per-face Lambertian reflectance
    specular: float = 0.0
    shininess: float = 20.0
    name: str = ""
    static: bool = True


@dataclass
class Scene:
    name: str
    camera: Camera
    lights: list[Light] = field(default_factory=list)
    media: list[Medium] = field(default_factory=list)
    surfaces: list[Surface] = field(default_factory=list)
    background: Vec3 = (0.0, 0.0, 0.0)
    source: str = "<dict>"  # file the scene came from, for messages
