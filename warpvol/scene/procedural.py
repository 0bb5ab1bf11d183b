"""Built-in scenes (as scene dicts, validated like files) and procedural media."""

from __future__ import annotations

import math
import os

import numpy as np


def cloud_particles(count: int, seed: int = 1, center=(0.0, 0.0, 0.0), extent: float = 1.0) -> np.ndarray:
    """``count`` positions inside a ball of radius ``extent``, with density proportional to a
    collision-density field rho(r) = (1 - |r|^2)^2 modulated by a few seeded lumps.
    Rejection sampling, so the positions follow rho exactly."""
    rng = np.random.default_rng(seed)
    lumps = rng.uniform(-0.6, 0.6, size=(5, 3))
    out = np.zeros((0, 3))
    while len(out) < count:
        p = rng.uniform(-1.0, 1.0, size=(max(4 * count, 64), 3))
        r2 = np.sum(p * p, axis=1)
        rho = np.clip(1.0 - r2, 0.0, None) ** 2 * (0.4 + np.exp(-np.sum((p[:, None] - lumps) ** 2, -1) / 0.08).sum(1) * 0.6)
        keep = rng.uniform(0.0, 2.0, size=len(p)) < rho
        out = np.concatenate([out, p[keep]])
    return (np.asarray(center) + extent * out[:count]).astype(np.float32)


def block_particles(blocks: int, per_block: int, seed: int = 1, center=(0.0, 0.0, 0.0), extent: float = 1.0,
                    block_extent: float = 0.25) -> np.ndarray:
    """A cloud built of ``blocks`` copies of one block of ``per_block`` particles (Umenhoffer & Szirmay-Kalos 2005's
    hierarchy): block centres by ``cloud_particles`` in a ball of radius ``extent``, the block
    a ``cloud_particles`` cluster of radius ``block_extent`` about its own centroid.
    Positions are block-major, (blocks * per_block, 3)."""
    centres = cloud_particles(blocks, seed, center, extent).astype(np.float64)
    template = cloud_particles(per_block, seed + 7919, (0.0, 0.0, 0.0), block_extent).astype(np.float64)
    template -= template.mean(axis=0)
    return (centres[:, None, :] + template[None]).reshape(-1, 3).astype(np.float32)


def split_blocks(positions: np.ndarray, block_size: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(template offsets (b, 3), instance centres (K, 3)) when ``positions`` are K copies of
    one block of ``block_size`` particles (block-major), else None."""
    n = len(positions)
    if block_size <= 1 or n % block_size:
        return None
    blocks = positions.reshape(-1, block_size, 3).astype(np.float64)
    centres = blocks.mean(axis=1)
    template = blocks[0] - centres[0]
    scale = max(float(np.abs(positions).max()), 1e-6)
    if np.abs(blocks - centres[:, None] - template[None]).max() > 1e-5 * scale:
        return None
    return template, centres


def smoke_density(n: int = 32, seed: int = 3) -> np.ndarray:
    """A (n, n, n) plume: sum of seeded Gaussian puffs rising along y, in [0, 1]."""
    rng = np.random.default_rng(seed)
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    z, y, x = np.meshgrid(c, c, c, indexing="ij")
    d = np.zeros((n, n, n))
    for _ in range(24):
        py = rng.uniform(-0.8, 0.7)
        px, pz = 0.25 * (py + 1.0) * rng.normal(size=2) * 0.6
        s = 0.12 + 0.12 * (py + 1.0)
        d += np.exp(-((x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2) / (2 * s * s))
    return (d / d.max()).astype(np.float32)


def sparse_cloud_density(n: int = 128, seed: int = 5, out: np.ndarray | None = None) -> np.ndarray:
    """A cumulus cloud in an (n, n, n) box [z, y, x] over [-1, 1]^3, zero outside nine seeded
    balls that fill about 5% of the box: each ball adds (1 - r^2/R^2)^2 times a smooth
    multiplicative ripple in [0.5, 1], rounded to multiples of 1/64 (so sums stay exact in
    float32 and the NanoVDB file zips small). Computed ball by ball inside its bounding box,
    32 planes at a time, so n = 1024 takes seconds and memory the size of ``out`` (which must
    hold zeros: a new array by default, or e.g. a memory-mapped .npy)."""
    rng = np.random.default_rng(seed)
    out = np.zeros((n, n, n), np.float32) if out is None else out
    balls = 9
    c = rng.uniform([-0.45, -0.12, -0.3], [0.45, 0.12, 0.3], (balls, 3))
    c[:, 1] += 0.25 * (1.0 - np.abs(c[:, 0]) / 0.45)  # taller in the middle
    radius = rng.uniform(0.215, 0.34, balls)
    freq, phase = rng.uniform(3.0, 9.0, (balls, 3)), rng.uniform(0.0, 2.0 * np.pi, (balls, 3))
    coord = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    for k in range(balls):
        lo = np.clip(np.floor((c[k] - radius[k] + 1.0) / 2.0 * n - 0.5).astype(int), 0, n)
        hi = np.clip(np.ceil((c[k] + radius[k] + 1.0) / 2.0 * n + 0.5).astype(int), 0, n)
        x, y = coord[lo[0] : hi[0]], coord[lo[1] : hi[1]]
        rx, ry = np.sin(freq[k, 0] * x + phase[k, 0]), np.sin(freq[k, 1] * y + phase[k, 1])
        for z0 in range(lo[2], hi[2], 32):
            z = coord[z0 : min(z0 + 32, hi[2])]
            r2 = ((x - c[k, 0]) ** 2)[None, None, :] + ((y - c[k, 1]) ** 2)[None, :, None] + \
                ((z - c[k, 2]) ** 2)[:, None, None]
            ripple = 0.75 + 0.25 * rx[None, None, :] * ry[None, :, None] * \
                np.sin(freq[k, 2] * z + phase[k, 2])[:, None, None]
            d = np.round(np.clip(1.0 - r2 / radius[k] ** 2, 0.0, None) ** 2 * ripple * 64.0) / 64.0
            block = out[z0 : z0 + len(z), lo[1] : hi[1], lo[0] : hi[0]]
            np.add(block, d.astype(np.float32), out=block)
    return out


#: The built-in NanoVDB cloud: ``sparse_cloud_density()`` over [-1, 1]^3 written by
#: ``warpvol.save_volume(NANOVDB_CLOUD, sparse_cloud_density(), (-1, -1, -1), (1, 1, 1), codec="zip")``
#: (tests/test_nanovdb.py checks that it still holds exactly those samples).
def _normal_cdf(z: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.vectorize(math.erf)(z / math.sqrt(2.0)))


def density_texture(res: int, mu: float, sigma: float, x_max: float, lognormal: bool, seed: int) -> np.ndarray:
    """res^3 cell densities d = CDF(x | mu, sigma), x uniform in (0, x_max] per cell (float32)."""
    x = (1.0 - np.random.default_rng(seed).random(res**3)) * x_max  # (0, x_max]
    z = (np.log(x) - mu) / sigma if lognormal else (x - mu) / sigma
    return _normal_cdf(z).astype(np.float32)


def direction_texture(res: int, seed: int) -> np.ndarray:
    """res^3 unit vectors, uniformly distributed over the sphere (float32)."""
    u = np.random.default_rng(seed).random((res**3, 2))
    z = 1.0 - 2.0 * u[:, 0]
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1).astype(np.float32)


def glow_particles(density: np.ndarray, cell: float, lo, hi, per_cell: float, seed: int) -> np.ndarray:
    """Explicit particles drawn from particle_glow's density texture (``density_texture``, res^3
    cells of side ``cell`` tiling space from the origin, as the technique reads it): in each cell
    of the box [lo, hi] a Poisson number of mean ``per_cell`` d, placed uniformly in the cell (and
    the box). The medium the glow imitates: where d is high the particles crowd, where it is low
    they thin out."""
    res = round(len(density) ** (1.0 / 3.0))
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    first, last = np.floor(lo / cell).astype(int), np.ceil(hi / cell).astype(int)
    idx = np.stack(np.meshgrid(*(np.arange(f, l) for f, l in zip(first, last)), indexing="ij"), -1).reshape(-1, 3)
    wrapped = idx % res
    d = density[(wrapped[:, 2] * res + wrapped[:, 1]) * res + wrapped[:, 0]].astype(np.float64)
    rng = np.random.default_rng(seed)
    count = rng.poisson(per_cell * d)
    corner = np.repeat(idx * cell, count, axis=0)
    points = corner + rng.random((len(corner), 3)) * cell
    keep = np.all((points >= lo) & (points <= hi), axis=1)
    return points[keep]


NANOVDB_CLOUD = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "nanovdb-cloud.nvdb")


def _camera(width=160, height=120, origin=(0.0, 0.0, 3.9), target=(0.0, 0.0, 0.0), fov_y=40.0):
    return {"origin": list(origin), "target": list(target), "up": [0.0, 1.0, 0.0], "fov_y": fov_y,
            "width": width, "height": height}


def fog_box():
    """Cornell box filled with forward-scattering fog, a point light inside the fog."""
    return {
        "name": "fog-box",
        "camera": _camera(),
        "lights": [{"type": "point", "position": [0.3, 0.7, 0.2], "intensity": [6.0, 5.6, 5.0]}],
        "media": [{"type": "homogeneous", "shape": "box", "center": [0, 0, 0], "size": [1.98, 1.98, 1.98],
                   "sigma_t": 0.6, "albedo": 0.8, "phase": {"type": "hg", "g": 0.3}}],
        "surfaces": [{"type": "procedural", "name": "cornell_box", "diffuse": 0.7},
                     {"type": "box", "center": [-0.35, -0.6, -0.3], "size": [0.5, 0.8, 0.5], "diffuse": 0.6}],
    }


def hazy_sun():
    """Haze over a floor under a low sun behind it and a blue sky, a pillar casting a shaft that
    the haze's forward scattering shows against the glow toward the sun: the first
    render (``python -m warpvol demo``), where single scattering is most of the light."""
    return {
        "name": "hazy-sun",
        "background": [0.06, 0.09, 0.16],
        "camera": _camera(origin=(0.0, 0.6, 4.2), target=(0.0, -0.1, 0.0), fov_y=45.0),
        "lights": [{"type": "directional", "direction": [-0.35, -0.45, 0.8], "irradiance": [3.0, 2.8, 2.4]}],
        "media": [{"type": "homogeneous", "shape": "box", "center": [0, 0, 0], "size": [3.0, 2.0, 3.0],
                   "sigma_t": [0.3, 0.38, 0.5], "albedo": 0.8, "phase": {"type": "hg", "g": 0.6}}],
        "surfaces": [{"type": "plane", "center": [0, -1.0, 0], "normal": [0, 1, 0], "size": [8.0, 8.0], "diffuse": 0.5},
                     {"type": "box", "center": [0.45, 0.2, -0.3], "size": [0.35, 2.4, 0.35], "diffuse": 0.6}],
    }


def point_in_fog():
    """A point light in fog that fills everything (the Sun et al. 2005 airlight set-up)."""
    return {
        "name": "point-in-fog",
        "camera": _camera(origin=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), fov_y=60.0),
        "lights": [{"type": "point", "position": [0.4, 0.2, -2.0], "intensity": 10.0}],
        "media": [{"type": "homogeneous", "shape": "sphere", "center": [0, 0, 0], "radius": 50.0,
                   "sigma_t": 0.3, "albedo": 1.0, "phase": {"type": "isotropic"}}],
    }


def smoke_grid():
    """A smoke plume from a density grid over a floor, lit by the sun and a blue sky."""
    return {
        "name": "smoke-grid",
        "background": [0.05, 0.08, 0.12],
        "camera": _camera(origin=(0.0, 0.2, 4.2), target=(0.0, 0.0, 0.0)),
        "lights": [{"type": "directional", "direction": [-0.5, -1.0, -0.3], "irradiance": [3.0, 2.9, 2.6]}],
        "media": [{"type": "grid", "density": smoke_density(), "bounds_min": [-1, -1, -1], "bounds_max": [1, 1, 1],
                   "sigma_t_scale": 6.0, "albedo": 0.9, "phase": {"type": "hg", "g": 0.5}}],
        "surfaces": [{"type": "plane", "center": [0, -1.0, 0], "normal": [0, 1, 0], "size": [8, 8], "diffuse": 0.5}],
    }


def rbf_cornell():
    """Cornell box with 16 Gaussian puffs and two point lights (Giroud & Biri 2011, figure 4)."""
    g = np.linspace(-0.45, 0.45, 4)
    centers = [[x, -0.4 + 0.25 * np.sin(3 * x + z), z] for x in g for z in g]
    return {
        "name": "rbf-cornell",
        "camera": _camera(),
        "lights": [{"type": "point", "position": [-0.5, 0.8, 0.3], "intensity": [4.0, 3.2, 2.4]},
                   {"type": "point", "position": [0.6, 0.6, -0.2], "intensity": [1.6, 2.4, 4.0]}],
        "media": [{"type": "rbf", "centers": centers, "radius": 0.18, "peak": 3.0, "albedo": 0.9,
                   "phase": {"type": "isotropic"}}],
        "surfaces": [{"type": "procedural", "name": "cornell_box", "diffuse": 0.7}],
    }


def rbf_single():
    """Cornell box with one large Gaussian RBF and one point light (Giroud & Biri 2011, figure 4a)."""
    return {
        "name": "rbf-single",
        "camera": _camera(),
        "lights": [{"type": "point", "position": [0.0, 0.8, 0.2], "intensity": [4.0, 3.6, 3.0]}],
        "media": [{"type": "rbf", "centers": [[0.0, -0.2, 0.0]], "radius": 0.35, "peak": 4.0, "albedo": 0.9,
                   "phase": {"type": "isotropic"}}],
        "surfaces": [{"type": "procedural", "name": "cornell_box", "diffuse": 0.7}],
    }


def rbf_thick_fog():
    """Cornell box filled with thick fog of 1000 RBFs, lit by eight coloured point lights
    (Giroud & Biri 2011, figure 4c)."""
    rng = np.random.default_rng(7)
    centers = rng.uniform(-0.85, 0.85, (1000, 3))
    colours = [[2, 1, 1], [1, 2, 1], [1, 1, 2], [2, 2, 1], [2, 1, 2], [1, 2, 2], [2, 2, 2], [1.5, 1.5, 1]]
    lights = [{"type": "point", "position": [0.6 * np.cos(a), 0.5 * np.sin(2 * a), 0.6 * np.sin(a)],
               "intensity": [0.4 * c for c in col]} for a, col in zip(np.linspace(0, 2 * np.pi, 8, endpoint=False),
                                                                      colours)]
    return {
        "name": "rbf-thick-fog",
        "camera": _camera(),
        "lights": lights,
        "media": [{"type": "rbf", "centers": centers, "radius": 0.12, "peak": 1.5, "albedo": 0.9,
                   "phase": {"type": "hg", "g": 0.3}}],
        "surfaces": [{"type": "procedural", "name": "cornell_box", "diffuse": 0.7}],
    }


def particle_cloud():
    """A cloud of 1024 overlapping spheres under the sun and a sky (Szirmay-Kalos et al. 2005 set-up)."""
    return {
        "name": "particle-cloud",
        "background": [0.25, 0.35, 0.55],
        "camera": _camera(origin=(0.0, 0.0, 4.5)),
        "lights": [{"type": "directional", "direction": [-0.4, -1.0, -0.5], "irradiance": 4.0}],
        "media": [{"type": "particles", "generator": {"kind": "cloud", "count": 1024, "seed": 1, "extent": 1.2},
                   "radius": 0.12, "sigma_t": 4.0, "albedo": 0.95, "phase": {"type": "hg", "g": 0.6}}],
    }


def colonnade_shafts():
    """A fog-filled colonnade (65 660 triangles), one point light behind it, 800x600 (Tóth & Umenhoffer 2009)."""
    return {
        "name": "colonnade-shafts",
        "camera": _camera(width=800, height=600, origin=(1.2, 1.4, 7.0), target=(0.0, 2.0, 0.0), fov_y=45.0),
        "lights": [{"type": "point", "position": [0.3, 2.2, -1.6], "intensity": 30.0}],
        "media": [{"type": "homogeneous", "shape": "box", "center": [0, 2.6, 1.0], "size": [16, 5.4, 18],
                   "sigma_t": 0.08, "albedo": 0.9, "phase": {"type": "hg", "g": 0.3}}],
        "surfaces": [{"type": "procedural", "name": "colonnade", "diffuse": 0.6}],
    }


def dusty_lamp():
    """A lamp in dusty air over a floor, a shade beside it casting a shadow through the dust
    (the glowy-light paper's setting: glow and shafts through visible particles), 320x240."""
    return {
        "name": "dusty-lamp",
        "background": [0.0, 0.0, 0.0],
        "camera": _camera(width=320, height=240, origin=(0.0, 0.4, 5.0), target=(0.0, 0.3, 0.0), fov_y=45.0),
        "lights": [{"type": "point", "position": [0.0, 1.1, 0.0], "intensity": [9.0, 8.0, 6.5]}],
        "media": [{"type": "homogeneous", "shape": "box", "center": [0.0, 0.6, 0.0], "size": [5.0, 3.6, 5.0],
                   "sigma_t": 0.25, "albedo": 0.9, "phase": {"type": "isotropic"}}],
        "surfaces": [{"type": "plane", "center": [0.0, -1.2, 0.0], "normal": [0.0, 1.0, 0.0], "size": [5.0, 5.0],
                      "diffuse": 0.5},
                     {"type": "box", "center": [0.45, 0.75, 0.0], "size": [0.5, 0.06, 0.9], "diffuse": 0.3}],
    }


def nanovdb_cloud():
    """A cumulus cloud stored sparsely (NanoVDB, 128^3 voxels, 5% of them occupied), under the sun and a sky."""
    return {
        "name": "nanovdb-cloud",
        "background": [0.25, 0.35, 0.55],
        "camera": _camera(origin=(0.0, 0.35, 2.6), target=(0.0, 0.1, 0.0)),
        "lights": [{"type": "directional", "direction": [-0.6, -0.7, -0.4], "irradiance": 4.0}],
        "media": [{"type": "grid", "file": NANOVDB_CLOUD, "bounds_min": [-1, -1, -1], "bounds_max": [1, 1, 1],
                   "sigma_t_scale": 8.0, "albedo": 0.95, "phase": {"type": "hg", "g": 0.6}}],
    }


def street_lamp(x: float = 0.6, width: int = 320, height: int = 240) -> dict:
    """A new user's first scene: a lamp at (x, 3.5, 0) just under the arm of a pole, in thin haze
    20 wide and 6 high over a floor (sigma_t 0.2, albedo 0.9, HG g 0.5), the camera inside the
    haze (results/street-lamp, tests/test_scattering.py)."""
    return {"name": "street-lamp", "background": [0.01, 0.012, 0.02],
            "camera": {"origin": [0.0, 1.5, 8.0], "target": [0.0, 2.0, 0.0], "fov_y": 45.0, "width": width,
                       "height": height},
            "lights": [{"type": "point", "position": [x, 3.5, 0.0], "intensity": [12.0, 9.0, 5.0]}],
            "media": [{"type": "homogeneous", "shape": "box", "center": [0.0, 3.0, 0.0], "size": [20.0, 6.0, 20.0],
                       "sigma_t": 0.2, "albedo": 0.9, "phase": {"type": "hg", "g": 0.5}}],
            "surfaces": [{"type": "plane", "center": [0.0, 0.0, 0.0], "size": [20.0, 20.0], "diffuse": 0.4},
                         {"type": "box", "center": [0.0, 1.8, 0.0], "size": [0.1, 3.6, 0.1], "diffuse": 0.2},
                         {"type": "box", "center": [0.35, 3.65, 0.0], "size": [0.8, 0.05, 0.1], "diffuse": 0.2}]}


# --- seeded random scenes (target_error's coverage: tests/test_target_error.py, bench/target_error_check.py)

def random_scene(seed: int) -> dict:
    """A seeded 16x12 scene for ``target_error``'s checks: a homogeneous box or sphere or a
    random density grid, a point or directional light, a sky or none, a floor or none."""
    rng = np.random.default_rng(seed)
    if rng.random() < 0.5:
        shape = str(rng.choice(["box", "sphere"]))
        medium = {"type": "homogeneous", "shape": shape, "center": rng.uniform(-0.2, 0.2, 3).tolist(),
                  "sigma_t": float(10 ** rng.uniform(-1, 0.7)), "albedo": float(rng.uniform(0.3, 1.0)),
                  "phase": {"type": "hg", "g": float(rng.uniform(-0.5, 0.8))}}
        if shape == "box":
            medium["size"] = rng.uniform(0.8, 2.0, 3).tolist()
        else:
            medium["radius"] = float(rng.uniform(0.6, 1.2))
    else:
        n = int(rng.integers(4, 12))
        medium = {"type": "grid", "density": rng.uniform(0, 1, (n, n, n)).astype(np.float32),
                  "bounds_min": [-1, -1, -1], "bounds_max": [1, 1, 1], "sigma_t_scale": float(10 ** rng.uniform(-0.5, 0.8)),
                  "albedo": float(rng.uniform(0.3, 1.0))}
    if rng.random() < 0.5:
        light = {"type": "point", "position": rng.uniform(-1.2, 1.2, 3).tolist(), "intensity": float(rng.uniform(1, 6))}
    else:
        light = {"type": "directional", "direction": (rng.normal(size=3) - [0, 2, 0]).tolist(),
                 "irradiance": float(rng.uniform(1, 3))}
    sky = rng.uniform(0, 0.3, 3).tolist() if rng.random() < 0.5 else [0.0, 0.0, 0.0]
    floor = [{"type": "plane", "center": [0, -1.1, 0], "normal": [0, 1, 0], "size": [4, 4], "diffuse": 0.5}]
    return {"name": f"random-{seed}", "background": sky,
            "camera": {"origin": (rng.normal(size=3) * 0.3 + [0, 0.3, 3.5]).tolist(), "target": [0, 0, 0],
                       "fov_y": 45.0, "width": 16, "height": 12},
            "lights": [light], "media": [medium], "surfaces": floor if rng.random() < 0.5 else []}


def brightened(scene: dict, k: float) -> dict:
    """A copy of the scene table ``scene`` with every light's strength (point ``intensity``,
    directional ``irradiance``) and the sky (``background``) times ``k``: the same image
    times k, as light transport is linear in its sources."""
    def times(v):
        return float(k * v) if np.isscalar(v) else (k * np.asarray(v, dtype=float)).tolist()

    lights = [{**light, **{key: times(light[key]) for key in ("intensity", "irradiance") if key in light}}
              for light in scene["lights"]]
    return {**scene, "lights": lights, "background": [k * c for c in scene.get("background", [0.0, 0.0, 0.0])]}


def random_cloud(seed: int) -> dict:
    """A seeded particle cloud (what illumination_network takes): 60 to 200 spheres, sun or
    point light, a sky or none."""
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(60, 200))
    light = ({"type": "directional", "direction": (rng.normal(size=3) - [0, 2, 0]).tolist(),
              "irradiance": float(rng.uniform(1, 4))} if rng.random() < 0.5 else
             {"type": "point", "position": rng.uniform(-1.5, 1.5, 3).tolist(), "intensity": float(rng.uniform(2, 8))})
    return {"name": f"random-cloud-{seed}", "background": rng.uniform(0, 0.4, 3).tolist() if rng.random() < 0.7 else [0, 0, 0],
            "camera": {"origin": [0.0, 0.0, 3.0], "target": [0, 0, 0], "fov_y": 40.0, "width": 16, "height": 12},
            "lights": [light],
            "media": [{"type": "particles", "positions": rng.uniform(-0.6, 0.6, (n, 3)).tolist(),
                       "radius": float(rng.uniform(0.1, 0.2)), "sigma_t": float(10 ** rng.uniform(0, 0.8)),
                       "albedo": float(rng.uniform(0.5, 0.99)), "phase": {"type": "hg", "g": float(rng.uniform(0, 0.7))}}]}


BUILTIN = {
    "hazy-sun": hazy_sun,
    "fog-box": fog_box,
    "point-in-fog": point_in_fog,
    "smoke-grid": smoke_grid,
    "rbf-cornell": rbf_cornell,
    "rbf-single": rbf_single,
    "rbf-thick-fog": rbf_thick_fog,
    "particle-cloud": particle_cloud,
    "colonnade-shafts": colonnade_shafts,
    "dusty-lamp": dusty_lamp,
    "nanovdb-cloud": nanovdb_cloud,
}
