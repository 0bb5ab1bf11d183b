"""Export a Scene to a Mitsuba 3 scene dict, for validation against its volpath integrator.

Requires ``mitsuba`` with a variant set (``mi.set_variant("scalar_rgb")``). Supported:
homogeneous box and sphere media (null boundaries, media by reference so the camera may
sit inside one), dense grid media and RBF media as Mitsuba heterogeneous media over a
box (an RGB ``gridvolume`` of sigma_t at cell centres: the grid's own samples, or the
Gaussians' sum sampled over their cut-off box at ``rbf_cells`` cells along its longest
side, each Gaussian with its own radius and amplitude), point and directional lights, constant background, surfaces as
two-sided diffuse triangle meshes (the same triangles warpvol renders, written to
temporary .obj files), a pinhole camera
with a vertical field of view and a box pixel filter. Phases: isotropic, hg, rayleigh.

Surfaces must lie outside the media (and not touch their boundaries): Mitsuba takes a ray
that leaves a surface with no ``exterior`` medium to be in vacuum, so a floor inside fog
or coplanar with a fog box's face renders differently there (measured: 2 % darker).
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from .model import GridMedium, HomogeneousMedium, RBFMedium, Scene


def _rgb(v):
    return {"type": "rgb", "value": [float(x) for x in v]}


def _inside(m: HomogeneousMedium, p) -> bool:
    p = np.asarray(p) - np.asarray(m.center)
    if m.shape == "sphere":
        return float(np.dot(p, p)) < m.radius**2
    return bool(np.all(np.abs(p) < 0.5 * np.asarray(m.size)))


_TMP: list = []


def _tmpdir() -> str:
    """A folder for the exported meshes that lives as long as the process."""
    if not _TMP:
        _TMP.append(tempfile.TemporaryDirectory(prefix="warpvol-mitsuba-"))
    return _TMP[0].name


#: Cut-off of an exported RBF's Gaussians, in standard deviations (media/rbf.py's CUTOFF).
RBF_CUTOFF = 5.0


def rbf_samples(m: RBFMedium, cells: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sigma_t of RBF medium ``m`` at the cell centres of a grid over its cut-off box,
    ``cells`` cells along the longest side: ([z, y, x, 3] float32, box min, box max)."""
    centres = np.asarray(m.centers, np.float64).reshape(-1, 3)
    radii, amps = (a.astype(np.float64) for a in m.gaussians())
    cut = RBF_CUTOFF * radii[:, None]
    lo, hi = (centres - cut).min(0), (centres + cut).max(0)
    h = float((hi - lo).max()) / cells
    dims = np.maximum(1, np.ceil((hi - lo) / h).astype(int))  # x, y, z
    hi = lo + dims * h
    axes = [lo[a] + (np.arange(dims[a]) + 0.5) * h for a in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    density = np.zeros(z.shape)
    for c, r, a in zip(centres, radii, amps):
        d2 = (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2
        density += np.where(d2 < (RBF_CUTOFF * r) ** 2, a * np.exp(-0.5 * d2 / (r * r)), 0.0)
    return (density[..., None] * np.asarray(m.peak, np.float64)).astype(np.float32), lo, hi


def _heterogeneous(i: int, m, rbf_cells: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sigma_t at cell centres [z, y, x, 3] and the box of grid or RBF medium ``m``."""
    if isinstance(m, GridMedium):
        if m.density is None:
            raise ValueError(f"to_mitsuba: media[{i}] is a NanoVDB grid; only dense grids are exported")
        values = np.asarray(m.density, np.float64)[..., None] * np.asarray(m.sigma_t_scale, np.float64)
        return values.astype(np.float32), np.asarray(m.bounds_min, float), np.asarray(m.bounds_max, float)
    return rbf_samples(m, rbf_cells)


def to_mitsuba(scene: Scene, spp: int = 64, max_bounces: int = -1, seed: int = 0, rbf_cells: int = 96) -> dict:
    """Mitsuba scene dict. ``max_bounces`` counts scattering events (-1: unlimited);
    Mitsuba's ``max_depth`` is one more (single scattering is max_depth = 2). ``rbf_cells``:
    the grid an RBF medium is sampled on, cells along its box's longest side (the error at
    a cell h is O(h^2 / r^2) for Gaussians of standard deviation r)."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    cam = scene.camera
    sensor = {
        "type": "perspective",
        "fov": cam.fov_y,
        "fov_axis": "y",
        "to_world": T().look_at(origin=list(cam.origin), target=list(cam.target), up=list(cam.up)),
        "film": {"type": "hdrfilm", "width": cam.width, "height": cam.height, "rfilter": {"type": "box"},
                 "pixel_format": "rgb"},
        "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
    }
    d = {"type": "scene", "integrator": {"type": "volpath", "max_depth": -1 if max_bounces < 0 else max_bounces + 1}}
    for i, m in enumerate(scene.media):
        if not isinstance(m, (HomogeneousMedium, GridMedium, RBFMedium)):
            raise ValueError(f"to_mitsuba: media[{i}] is {m.type}; only homogeneous, dense grid and RBF media are "
                             "exported")
        if m.phase.type not in ("isotropic", "hg", "rayleigh"):
            raise ValueError(f"to_mitsuba: media[{i}].phase {m.phase.type!r} has no Mitsuba counterpart")
        phase = {"type": m.phase.type}
        if m.phase.type == "hg":
            phase["g"] = m.phase.g
        ref = {"type": "ref", "id": f"medium_{i}"}
        if isinstance(m, HomogeneousMedium):
            scale = max(m.sigma_t) or 1.0
            d[f"medium_{i}"] = {"type": "homogeneous", "albedo": _rgb(m.albedo), "scale": scale,
                                "sigma_t": _rgb(np.asarray(m.sigma_t) / scale), "phase": phase}
            inside = _inside(m, cam.origin)
            if m.shape == "box":
                shape = {"type": "cube", "to_world": T().translate(list(m.center)).scale([0.5 * s for s in m.size])}
            else:
                shape = {"type": "sphere", "center": list(m.center), "radius": m.radius}
        else:
            values, lo, hi = _heterogeneous(i, m, rbf_cells)
            scale = float(values.max()) or 1.0
            box = T().translate(list(map(float, lo))).scale(list(map(float, hi - lo)))  # the unit cube to the box
            d[f"medium_{i}"] = {"type": "heterogeneous", "albedo": _rgb(m.albedo), "scale": scale, "phase": phase,
                                "sigma_t": {"type": "gridvolume", "grid": mi.VolumeGrid(values / scale),
                                            "to_world": box}}
            inside = bool(np.all((np.asarray(cam.origin) > lo) & (np.asarray(cam.origin) < hi)))
            shape = {"type": "cube", "to_world": T().translate(list(map(float, 0.5 * (lo + hi))))
                     .scale(list(map(float, 0.5 * (hi - lo))))}
        d[f"medium_shape_{i}"] = {**shape, "bsdf": {"type": "null"}, "interior": ref}
        if inside:
            sensor["medium"] = ref
    d["sensor"] = sensor
    for i, light in enumerate(scene.lights):
        if light.type == "point":
            d[f"light_{i}"] = {"type": "point", "position": list(light.position), "intensity": _rgb(light.strength)}
        elif light.type == "directional":
            d[f"light_{i}"] = {"type": "directional", "direction": list(light.direction), "irradiance": _rgb(light.strength)}
        else:
            raise ValueError(f"to_mitsuba: lights[{i}] is a spot light; its falloff differs from Mitsuba's")
    if any(scene.background):
        d["background"] = {"type": "constant", "radiance": _rgb(scene.background)}
    for i, s in enumerate(scene.surfaces):
        if s.specular > 0:
            raise ValueError(f"to_mitsuba: surfaces[{i}] has a Phong lobe; only diffuse surfaces are exported")
        colours, which = np.unique(s.diffuse, axis=0, return_inverse=True)
        for k, colour in enumerate(colours):
            faces = s.faces[which.reshape(-1) == k]
            path = os.path.join(_tmpdir(), f"surface_{id(s)}_{i}_{k}.obj")
            with open(path, "w") as fh:
                fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in s.vertices)
                fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)
            d[f"surface_{i}_{k}"] = {"type": "obj", "filename": path, "face_normals": True,
                                     "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": _rgb(colour)}}}
    return d
