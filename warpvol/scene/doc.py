"""docs/scene-format.md, written from the loader itself: every example scene below is loaded
with ``tables.RECORD`` on, so each key's type, allowed range and default are the ones the loader
checks; what a key means and its units come from ``MEANING``, which must name every key the
loader reads (``tests/test_docs.py`` fails otherwise, and when the checked-in page differs).

    python -m warpvol docs
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from . import load, tables
from .tables import REQUIRED

#: (table, key) -> what it is, with units. Table is the key's place with list indices dropped
#: ("media.phase"); a key whose meaning depends on the variant is keyed (table, key, variant).
MEANING = {
    ("", "name"): "the scene's name, used in output file names and messages (default: the file's stem)",
    ("", "background"): "radiance of the sky (uniform environment) seen by rays that leave the scene, RGB; "
                        "it also lights the media (in-scattered sky) where a technique gathers it",
    ("", "camera"): "the pinhole camera ([camera] table)",
    ("", "lights"): "the light sources ([[lights]] tables)",
    ("", "media"): "the participating media ([[media]] tables)",
    ("", "surfaces"): "opaque surfaces ([[surfaces]] tables)",
    ("camera", "origin"): "eye position, world units",
    ("camera", "target"): "the point looked at, world units",
    ("camera", "up"): "up direction (need not be unit or orthogonal to the view)",
    ("camera", "fov_y"): "vertical field of view, degrees",
    ("camera", "width"): "image width, pixels",
    ("camera", "height"): "image height, pixels",
    ("camera", "static"): "false: the camera moves between frames (animation hint; nothing is cached for it)",
    ("lights", "type"): "point (isotropic), spot (a point with a cone) or directional (a sun at infinity)",
    ("lights", "static"): "false: the light moves between frames (animation hint)",
    ("lights", "position"): "position, world units",
    ("lights", "intensity"): "radiant intensity, radiance units x area (W/sr in a physical scene), RGB or grey",
    ("lights", "irradiance"): "irradiance on a surface facing the sun, RGB or grey",
    ("lights", "direction", "directional"): "the direction light travels (from the sun into the scene)",
    ("lights", "direction", "spot"): "the cone's axis (the direction light travels)",
    ("lights", "outer_angle"): "half-angle of the cone, degrees; no light outside it",
    ("lights", "inner_angle"): "half-angle of the cone's full-intensity core, degrees (smooth fall-off to outer_angle)",
    ("media", "type"): "homogeneous (constant sigma_t in a box or ball), grid (a voxel density), rbf (a sum of "
                       "Gaussians) or particles (constant-density spheres)",
    ("media", "albedo"): "single-scattering albedo sigma_s / sigma_t, RGB or grey",
    ("media", "phase"): "the phase function ([media.phase] table; default isotropic)",
    ("media", "static"): "false: the medium changes between frames (animation hint)",
    ("media", "shape"): "box or sphere",
    ("media", "center"): "centre of the box or ball, world units",
    ("media", "sigma_t", "homogeneous"): "extinction coefficient, 1 / world unit, RGB or grey",
    ("media", "sigma_t", "particles"): "extinction coefficient inside each sphere, 1 / world unit, RGB or grey",
    ("media", "size"): "the box's edge lengths, world units",
    ("media", "radius", "homogeneous"): "the ball's radius, world units",
    ("media", "radius", "rbf"): "each Gaussian's standard deviation r, one for all or one a centre: sigma_t = peak "
                                "sum_i a_i exp(-|x - c_i|^2 / (2 r_i^2)), world units",
    ("media", "amplitude"): "each Gaussian's amplitude a_i (one a centre; Giroud & Biri's c)",
    ("media", "radius", "particles"): "each sphere's radius, world units",
    ("media", "density"): "voxel densities (D, H, W), x fastest, at cell centres (a scene given as a dict)",
    ("media", "file", "grid"): "a .npy (D, H, W) density array or a NanoVDB .nvdb float grid",
    ("media", "file", "rbf"): "a .npy array in place of centers: (N, 3) centres, or (N, 5) x, y, z, radius, amplitude",
    ("media", "file", "particles"): "a .npy (N, 3) array of sphere centres, in place of positions",
    ("media", "bounds_min"): "the grid's lower corner, world units (a .nvdb file: default the active voxels' box)",
    ("media", "bounds_max"): "the grid's upper corner, world units (a .nvdb file: default the active voxels' box)",
    ("media", "sigma_t_scale"): "extinction per unit density, 1 / world unit, RGB or grey",
    ("media", "centers"): "the Gaussians' centres, world units",
    ("media", "peak"): "extinction at the centre of a Gaussian of amplitude 1, 1 / world unit, RGB or grey",
    ("media", "positions"): "the spheres' centres, world units",
    ("media", "block_size"): "positions are block-major copies of one block of this many particles (0: no blocks); "
                             "depth_impostors' block hierarchy",
    ("media", "generator"): "particles made by a generator ([media.generator] table) instead of positions",
    ("media.generator", "kind"): "cloud (one random cloud) or blocks (copies of one random block)",
    ("media.generator", "seed"): "random seed",
    ("media.generator", "center"): "the cloud's centre, world units",
    ("media.generator", "extent"): "the cloud's half-size, world units",
    ("media.generator", "count"): "particles in the cloud",
    ("media.generator", "blocks"): "copies of the block",
    ("media.generator", "per_block"): "particles in each block",
    ("media.generator", "block_extent"): "a block's half-size, world units",
    ("media.phase", "type"): "isotropic, hg (Henyey-Greenstein), cornette_shanks, rayleigh, tabulated (values over "
                             "cos theta), mie (log-normal water droplets, needs the [mie] extra) or hg_draine "
                             "(Jendersie & d'Eon's fit)",
    ("media.phase", "g"): "mean cosine of the lobe (> 0 forward)",
    ("media.phase", "values"): "p at cos theta evenly spaced from -1 to 1, normalised on load",
    ("media.phase", "median_diameter_um"): "median droplet diameter, micrometres",
    ("media.phase", "sigma"): "log-normal width of the droplet sizes (0: one size)",
    ("media.phase", "refractive_index"): "the droplets' real refractive index (water 1.33)",
    ("media.phase", "diameter_um"): "droplet diameter whose fitted HG + Draine parameters are used, micrometres",
    ("media.phase", "g_hg"): "the HG lobe's mean cosine",
    ("media.phase", "g_d"): "the Draine lobe's g",
    ("media.phase", "alpha"): "the Draine lobe's alpha",
    ("media.phase", "w_d"): "the Draine lobe's weight (1 - w_d on the HG lobe)",
    ("surfaces", "type"): "mesh (.obj), box, plane, sphere or procedural (cornell_box, colonnade)",
    ("surfaces", "name"): "a label; for type = procedural, which one: cornell_box or colonnade",
    ("surfaces", "diffuse"): "Lambertian reflectance, RGB or grey",
    ("surfaces", "specular"): "normalised Phong lobe's weight (diffuse + specular <= 1)",
    ("surfaces", "shininess"): "Phong exponent",
    ("surfaces", "static"): "false: the surface moves between frames (animation hint)",
    ("surfaces", "file"): "a triangle or polygon .obj file",
    ("surfaces", "center"): "centre, world units",
    ("surfaces", "size", "box"): "edge lengths, world units",
    ("surfaces", "size", "plane"): "[width, height] of the rectangle, world units",
    ("surfaces", "size", "procedural"): "the Cornell box's edge lengths, world units",
    ("surfaces", "normal"): "the plane's normal",
    ("surfaces", "radius"): "the sphere's radius, world units",
    ("surfaces", "columns"): "the colonnade's columns",
    ("surfaces", "segments"): "segments around each column",
    ("surfaces", "stacks"): "stacks along each column",
}


def _examples(folder: str) -> list[dict]:
    """Scenes that between them take every branch of the loader."""
    np.save(os.path.join(folder, "density.npy"), np.ones((2, 2, 2), np.float32))
    np.save(os.path.join(folder, "points.npy"), np.zeros((1, 3), np.float32))
    with open(os.path.join(folder, "tri.obj"), "w") as fh:
        fh.write("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    from .procedural import NANOVDB_CLOUD

    cam = {"origin": [0, 0, 5], "target": [0, 0, 0]}
    lights = [{"type": "point", "position": [0, 2, 0], "intensity": 1},
              {"type": "spot", "position": [0, 2, 0], "direction": [0, -1, 0], "intensity": 1},
              {"type": "directional", "direction": [0, -1, 0], "irradiance": 1}]
    phases = [{"type": "isotropic"}, {"type": "hg", "g": 0.5}, {"type": "cornette_shanks", "g": 0.5},
              {"type": "rayleigh"}, {"type": "tabulated", "values": [1, 1]},
              {"type": "mie", "median_diameter_um": 10, "sigma": 0.3}, {"type": "hg_draine", "diameter_um": 20},
              {"type": "hg_draine", "g_hg": 0.9, "g_d": 0.5, "alpha": 10, "w_d": 0.4}]
    media = [{"type": "homogeneous", "shape": "box", "size": [1, 1, 1], "sigma_t": 1, "albedo": 0.9, "phase": p} for p in phases]
    media += [{"type": "homogeneous", "shape": "sphere", "radius": 1, "sigma_t": 1, "albedo": 0.9},
              {"type": "grid", "density": np.ones((2, 2, 2)), "bounds_min": [-1] * 3, "bounds_max": [1] * 3, "albedo": 1},
              {"type": "grid", "file": "density.npy", "bounds_min": [-1] * 3, "bounds_max": [1] * 3, "albedo": 1},
              {"type": "grid", "file": NANOVDB_CLOUD, "albedo": 1},
              {"type": "rbf", "centers": [[0, 0, 0]], "radius": 0.3, "peak": 1, "albedo": 1},
              {"type": "rbf", "file": "points.npy", "radius": 0.3, "peak": 1, "albedo": 1},
              {"type": "particles", "positions": [[0, 0, 0]], "radius": 0.1, "sigma_t": 1, "albedo": 1},
              {"type": "particles", "file": "points.npy", "radius": 0.1, "sigma_t": 1, "albedo": 1},
              {"type": "particles", "generator": {"kind": "cloud", "count": 4}, "radius": 0.1, "sigma_t": 1, "albedo": 1},
              {"type": "particles", "generator": {"kind": "blocks", "blocks": 2, "per_block": 2}, "radius": 0.1,
               "sigma_t": 1, "albedo": 1}]
    surfaces = [{"type": "mesh", "file": "tri.obj"}, {"type": "box", "size": [1, 1, 1]}, {"type": "plane"},
                {"type": "sphere", "radius": 1}, {"type": "procedural", "name": "cornell_box"},
                {"type": "procedural", "name": "colonnade", "columns": 2, "segments": 3, "stacks": 1}]
    return [{"camera": cam, "lights": lights, "media": [m], "surfaces": surfaces} for m in media]


def recorded_keys() -> list[tuple]:
    """(table, variants, key, kind, default, allowed) of every key the loader reads, in the
    order it first reads them; variants: "all" where every variant of the table reads the key,
    else those that do (a key whose meaning differs by variant: one row per variant)."""
    tables.RECORD = []
    try:
        with tempfile.TemporaryDirectory() as folder:
            for scene in _examples(folder):
                load.scene_from_dict(scene, os.path.join(folder, "example.toml"), folder)
        record = list(tables.RECORD)
    finally:
        tables.RECORD = None
    rows, variants = {}, {}
    for where, variant, key, kind, default, allowed in record:
        table = ".".join(part.split("[")[0] for part in where.split(".")) if where else ""
        variants.setdefault(table, {})[variant] = None
        split = any(len(k) == 3 and k[:2] == (table, key) for k in MEANING)
        row = rows.setdefault((table, key, variant if split else ""), [kind, default, allowed, {}])
        row[3][variant] = None
    keys = []
    for (table, key, variant), (kind, default, allowed, seen) in rows.items():
        every = [v for v in variants[table] if v]
        used = [v for v in seen if v]
        text = variant or ("all" if not every or used == every or not used else ", ".join(used))
        keys.append((table, text, key, kind, default, allowed))
    return keys


def meaning(table: str, variant: str, key: str) -> str | None:
    """What ``key`` of ``table`` means (for ``variant``), with units; None where undocumented."""
    return MEANING.get((table, key, variant), MEANING.get((table, key)))


#: Ranges that depend on another key (the recorded one is the example scene's).
DYNAMIC_RANGE = {("lights", "inner_angle"): "number in [0, outer_angle]"}


def _default_text(default, kind: str) -> str:
    if default is REQUIRED:
        return "required"
    if default is None:
        return "not set (see its meaning)"
    if isinstance(default, bool):
        return "true" if default else "false"
    if isinstance(default, (tuple, list)):
        return "[" + ", ".join(f"{x:g}" if isinstance(x, (int, float)) else repr(x) for x in default) + "]" if default else "[]"
    if isinstance(default, str):
        return f'"{default}"' if default else '""'
    return f"{default:g}" if isinstance(default, (int, float)) else str(default)


HEADINGS = {"": "Top level", "camera": "[camera]", "lights": "[[lights]]", "media": "[[media]]",
            "media.phase": "[media.phase]", "media.generator": "[media.generator]", "surfaces": "[[surfaces]]"}

EXAMPLE = '''name = "lamp-in-fog"
background = [0.02, 0.03, 0.05]          # the sky's radiance

[camera]
origin = [0.0, 0.4, 4.0]
target = [0.0, 0.0, 0.0]
width = 320
height = 240

[[lights]]
type = "point"
position = [0.0, 0.5, 0.0]
intensity = 8.0

[[media]]
type = "homogeneous"
shape = "box"
size = [2.0, 2.0, 2.0]
sigma_t = 1.5
albedo = 0.9
phase = { type = "hg", g = 0.4 }

[[surfaces]]
type = "plane"
center = [0.0, -1.0, 0.0]
size = [6.0, 6.0]
diffuse = 0.6
'''


def page() -> str:
    """The text of docs/scene-format.md."""
    keys = recorded_keys()
    lines = ["# Scene format", "",
             "<!-- written by `python -m warpvol docs` from the scene loader (warpvol/scene/load.py, "
             "media_tables.py, tables.py and doc.py); do not edit by hand -->", "",
             "A scene is a TOML file (or the same layout as a Python dict, where arrays may be numpy "
             "arrays). Paths are relative to the scene file. Every key is checked on load: an unknown "
             "key, a wrong type or a value out of range fails before anything renders, with a message "
             "that names the file, the key and what is allowed. Units: lengths in world units, "
             "extinction in 1 / world unit, angles in degrees; radiance is linear RGB in arbitrary "
             "units (the image scales with the lights). `--set key=value` on the command line "
             "overrides any key by its dotted path (`camera.width=64`, `media.0.sigma_t=2`).", "",
             "```toml", EXAMPLE.rstrip(), "```", "",
             "The built-in scenes (`python -m warpvol scenes`) and the files in `scenes/` are further "
             "examples.", ""]
    for table, heading in HEADINGS.items():
        rows = [k for k in keys if k[0] == table]
        if not rows:
            continue
        lines += [f"## {heading}", "", "| key | for | type | allowed | default | meaning |",
                  "|---|---|---|---|---|---|"]
        for _, variant, key, kind, default, allowed in rows:
            text = meaning(table, variant, key) or ""
            shown = "the file name's stem" if (table, key) == ("", "name") else _default_text(default, kind)
            allowed = DYNAMIC_RANGE.get((table, key), allowed)
            lines.append(f"| `{key}` | {variant} | {kind} | {allowed.replace('|', '&#124;')} | {shown} | {text} |")
        lines.append("")
    return "\n".join(lines)
