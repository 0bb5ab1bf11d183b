"""Property-based fuzzing (hypothesis): random valid scenes render, random malformed ones are refused.

* Valid scenes, drawn from the whole format (every light, medium and surface kind, extinction
  from 1e-3 to 1e6, albedo 0 to 1, |g| up to 0.9999, media 1e-6 thick, lights inside media,
  planes as the only surface), rendered tiny by every technique that accepts them: the image
  is finite and non-negative. A technique may refuse a scene only with ``SettingsError``
  before it runs (illumination_network takes particle clouds without surfaces, say).
* Hard scenes, seeded (``hard_scene``): lights at a medium's centre, on its surface, at its
  corner or at a Gaussian's or particle's centre, extinction 1e-6 to 1e6 and RGB with a zero
  channel, media 1e-6 across, the camera inside or looking straight at a light: every marcher
  at its defaults, the multiple-scattering term on and off, renders every pixel finite and
  non-negative; and the scenes that rendered NaN (``NAN_SCENES``), each named for its cause.
* Malformed scenes: a valid scene with one key broken (a wrong type, out of range, NaN, an
  unknown key, an empty medium), written as TOML and given to the command line: exit status
  2 and one line on stderr that names the file and the key and says what is allowed.

The examples are derandomised (the same ones on every run, so CI is reproducible);
``WARPVOL_FUZZ_EXAMPLES`` raises their number for a longer hunt, and hypothesis shrinks a
failure to a small scene (``WARPVOL_HARD_SCENES`` raises the hard scenes' seeds; a failure names
its seeds). A render that does not finish within ``deadline`` is a hang, not a
slow render: the renders here take milliseconds once the kernels are compiled.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
from datetime import timedelta

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import warpvol as wv  # noqa: E402
from warpvol.cli import main  # noqa: E402
from warpvol.pipeline import SettingsError  # noqa: E402
from warpvol.techniques import TECHNIQUES  # noqa: E402

EXAMPLES = int(os.environ.get("WARPVOL_FUZZ_EXAMPLES", "40"))
FUZZ = settings(max_examples=EXAMPLES, derandomize=True, deadline=timedelta(seconds=120),
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture],
                database=None)  # the `device` fixture is a name, the same for every example

#: Each technique at settings that keep a render to milliseconds.
TINY = {name: cls.TINY for name, cls in TECHNIQUES.items()}  # each technique's own (``Technique.TINY``)
#: And each light-pass representation (media/lightpass.py) at a few points a sphere.
LIGHT_PASSES = [{"light_pass": k, "light_samples": 3, "light_slices": 3, "light_terms": 2} for k in (0, 1, 2)]

finite = lambda lo, hi: st.floats(lo, hi, allow_nan=False, allow_infinity=False)  # noqa: E731
log_uniform = lambda lo, hi: st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(10.0**e))  # noqa: E731
vec3 = lambda lo, hi: st.lists(finite(lo, hi), min_size=3, max_size=3)  # noqa: E731
unit = st.lists(finite(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1)
colour = st.one_of(finite(0, 1), st.lists(finite(0, 1), min_size=3, max_size=3))


@st.composite
def cameras(draw):
    origin = np.asarray(draw(vec3(-4, 4)))
    direction = np.asarray(draw(unit))
    if abs(np.dot(direction, [0, 1, 0])) > 0.99 * np.linalg.norm(direction):
        direction = direction + np.array([0.3, 0.0, 0.0])
    return {"origin": origin.tolist(), "target": (origin + direction).tolist(), "fov_y": draw(finite(10, 120)),
            "width": draw(st.integers(1, 9)), "height": draw(st.integers(1, 7))}


@st.composite
def lights(draw):
    kind = draw(st.sampled_from(["point", "spot", "directional"]))
    if kind == "directional":
        return {"type": kind, "direction": draw(unit), "irradiance": draw(log_uniform(1e-3, 1e3))}
    light = {"type": kind, "position": draw(vec3(-3, 3)), "intensity": draw(log_uniform(1e-3, 1e3))}
    if kind == "spot":
        light.update(direction=draw(unit), outer_angle=draw(finite(1, 179)))
    return light


@st.composite
def phases(draw):
    kind = draw(st.sampled_from(["isotropic", "hg", "cornette_shanks", "rayleigh", "tabulated"]))
    if kind in ("hg", "cornette_shanks"):
        g = draw(st.one_of(finite(-0.95, 0.95), st.sampled_from([-0.9999, -0.999, 0.99, 0.999, 0.9999])))
        return {"type": kind, "g": g}
    if kind == "tabulated":
        return {"type": kind, "values": draw(st.lists(finite(0, 10), min_size=2, max_size=6).filter(lambda v: max(v) > 1e-3))}
    return {"type": kind}


@st.composite
def media(draw, kind=None):
    kind = kind or draw(st.sampled_from(["homogeneous", "grid", "rbf", "particles"]))
    sigma = draw(st.one_of(log_uniform(1e-3, 1e2), st.just(1e6), st.lists(log_uniform(1e-3, 1e2), min_size=3, max_size=3)))
    common = {"albedo": draw(st.one_of(colour, st.sampled_from([0.99, 1.0]))), "phase": draw(phases())}
    centre = draw(vec3(-1, 1))
    if kind == "homogeneous":
        if draw(st.booleans()):
            size = draw(st.lists(st.one_of(finite(0.05, 3), st.just(1e-6)), min_size=3, max_size=3))
            return {"type": kind, "shape": "box", "center": centre, "size": size, "sigma_t": sigma, **common}
        return {"type": kind, "shape": "sphere", "center": centre, "radius": draw(finite(0.05, 2)), "sigma_t": sigma, **common}
    if kind == "grid":
        shape = tuple(draw(st.integers(1, 5)) for _ in range(3))
        seed = draw(st.integers(0, 1000))
        density = np.random.default_rng(seed).uniform(0, 1, shape).astype(np.float32)
        size = np.asarray(draw(st.lists(st.one_of(finite(0.1, 3), st.just(1e-6)), min_size=3, max_size=3)))
        lo = np.asarray(centre) - size / 2
        return {"type": kind, "density": density, "bounds_min": lo.tolist(), "bounds_max": (lo + size).tolist(),
                "sigma_t_scale": sigma, **common}
    count = draw(st.integers(1, 12))
    points = (np.asarray(centre) + np.random.default_rng(draw(st.integers(0, 1000))).normal(0, 0.4, (count, 3))).tolist()
    radius = draw(finite(0.02, 0.6))
    if kind == "rbf":
        if draw(st.booleans()):  # each Gaussian its own radius and amplitude (some amplitudes 0)
            radius = [draw(finite(0.02, 0.6)) for _ in range(count)]
            return {"type": kind, "centers": points, "radius": radius, "peak": sigma,
                    "amplitude": [draw(finite(0.0, 3.0)) for _ in range(count)], **common}
        return {"type": kind, "centers": points, "radius": radius, "peak": sigma, **common}
    return {"type": kind, "positions": points, "radius": radius, "sigma_t": sigma, **common}


@st.composite
def surfaces(draw):
    kind = draw(st.sampled_from(["plane", "box", "sphere"]))
    out = {"type": kind, "diffuse": draw(finite(0, 0.9))}
    if kind == "plane":
        out.update(center=draw(vec3(-2, 2)), normal=draw(unit), size=[draw(finite(0.1, 20)), draw(finite(0.1, 20))])
    elif kind == "box":
        out.update(center=draw(vec3(-2, 2)), size=draw(vec3(0.05, 2)))
    else:
        out.update(center=draw(vec3(-2, 2)), radius=draw(finite(0.05, 1.5)))
    return out


@st.composite
def scenes(draw):
    particle_cloud = draw(st.integers(0, 3)) == 0  # a quarter are what illumination_network takes
    if particle_cloud:
        medium_list = draw(st.lists(media("particles"), min_size=1, max_size=2))
        phase = medium_list[0]["phase"]
        for m in medium_list:
            m["phase"] = phase
        surface_list = []
    else:
        medium_list = draw(st.lists(media(), min_size=1, max_size=2))
        surface_list = draw(st.lists(surfaces(), max_size=2))
    return {"camera": draw(cameras()), "lights": draw(st.lists(lights(), max_size=2)), "media": medium_list,
            "surfaces": surface_list, "background": draw(st.one_of(finite(0, 2), st.lists(finite(0, 2), min_size=3, max_size=3)))}


@FUZZ
@given(scene=scenes())
def test_valid_scenes_render_finite_and_non_negative(device, scene):
    """Every technique that accepts a random valid scene renders it finite and non-negative;
    the reference and raymarch accept every scene."""
    loaded = wv.load_scene(scene)
    runs = list(TINY.items()) + [("illumination_network", {**TINY["illumination_network"], **lp}) for lp in LIGHT_PASSES]
    runs.append(("depth_impostors", {**TINY["depth_impostors"], "cluster": 3}))  # a cloud grouped into blocks
    for technique, tiny in runs:
        try:
            image = wv.render(loaded, technique=technique, device=device, **tiny).image
        except SettingsError:
            assert technique not in ("reference", "raymarch"), technique
            continue
        bad = ~np.isfinite(image) | (image < 0)
        assert not bad.any(), f"{technique}: {int(bad.any(axis=-1).sum())} bad pixels of {image.shape[0] * image.shape[1]}"


# --- hard scenes: every marcher, the multiple-scattering term on and off ----------------------

#: The marchers, each rendered at its own defaults with the multiple-scattering lattice at its
#: default (8 nodes a side) and off. depth_impostors takes particle clouds only.
MARCHERS = ("raymarch", "light_shafts", "rbf_propagation", "particle_glow", "depth_impostors")
LATTICE = (8, 0)
#: The seeds of ``hard_scene``; ``WARPVOL_HARD_SCENES`` raises their number for a longer hunt.
HARD_SCENES = int(os.environ.get("WARPVOL_HARD_SCENES", "30"))
KINDS = ("box", "sphere", "grid", "rbf", "particles")


def _camera(origin, target, fov_y, width, height):
    return {"origin": list(map(float, origin)), "target": list(map(float, target)), "fov_y": float(fov_y),
            "width": width, "height": height}


def _floor(y, diffuse):
    return [{"type": "plane", "center": [0.0, float(y), 0.0], "size": [6.0, 6.0], "diffuse": float(diffuse)}]


def _hard_sigma(rng):
    """Extinction from 1e-6 to 1e6, the values users met NaN at, RGB with a zero channel."""
    pick = rng.integers(0, 5)
    if pick == 0:
        return float(rng.choice([1e-6, 900.0, 1e3, 7e3, 1e6]))
    if pick == 1:
        return [0.0, 1.0, 1e3]
    if pick == 2:
        rgb = 10.0 ** rng.uniform(-6.0, 6.0, 3)
        rgb[rng.integers(0, 3)] = 0.0
        return rgb.tolist()
    return float(10.0 ** rng.uniform(-6.0, 6.0 if pick == 3 else 3.5))


def hard_scene(seed: int) -> dict:
    """A random scene of one medium (kind ``KINDS[seed % 5]``), 1e-6 to 3 across, its lights at
    the exact points where renders broke (its centre, a Gaussian's or a particle's centre, its
    surface, its corner; intensity 0 too) or outside, and the camera inside it or aimed at one of
    those points through a 3 x 3 image (the middle pixel's ray passes through it). Albedo 0 and
    1, |g| up to 0.9999, a floor and the sky at times."""
    rng = np.random.default_rng(seed)
    kind = KINDS[seed % len(KINDS)]
    centre = rng.uniform(-0.5, 0.5, 3)
    half = 1e-6 if rng.random() < 0.25 else float(rng.uniform(0.05, 1.5))
    medium = {"albedo": [0.0, 1.0, rng.uniform(0, 1, 3).tolist(), float(rng.uniform(0, 1))][rng.integers(0, 4)]}
    if rng.random() < 0.6:
        medium["phase"] = [{"type": "hg", "g": float(rng.choice([-0.9999, 0.9999, 0.7]))}, {"type": "rayleigh"},
                           {"type": "cornette_shanks", "g": float(rng.choice([-0.9999, 0.9999]))}][rng.integers(0, 3)]
    marks = [centre, centre + [half, 0.0, 0.0], centre + half]  # the centre, a face's centre, a corner
    if kind == "box":
        medium.update(type="homogeneous", shape="box", center=centre.tolist(), size=[2 * half] * 3,
                      sigma_t=_hard_sigma(rng))
    elif kind == "sphere":
        marks[2] = centre + half / np.sqrt(3.0)  # on the sphere
        medium.update(type="homogeneous", shape="sphere", center=centre.tolist(), radius=half, sigma_t=_hard_sigma(rng))
    elif kind == "grid":
        density = rng.uniform(0, 1, tuple(rng.integers(1, 6, 3))).astype(np.float32)
        medium.update(type="grid", density=density, bounds_min=(centre - half).tolist(),
                      bounds_max=(centre + half).tolist(), sigma_t_scale=_hard_sigma(rng))
    else:
        points = centre + rng.normal(0.0, half, (int(rng.choice([1, 3, 10, 31])), 3))
        points[0] = centre  # a light at a mark stands at a Gaussian's or a particle's centre
        radius = half if half < 1e-3 else float(rng.uniform(0.2, 0.8)) * half
        marks[1] = centre + [radius, 0.0, 0.0]  # on the first particle, a Gaussian's radius out
        if kind == "rbf":
            medium.update(type="rbf", centers=points.tolist(), radius=radius, peak=_hard_sigma(rng))
        else:
            medium.update(type="particles", positions=points.tolist(), radius=radius, sigma_t=_hard_sigma(rng))
    lights = []
    for _ in range(rng.integers(1, 3)):
        where = rng.integers(0, 6)
        if where == 5:
            direction = rng.normal(size=3) if rng.random() < 0.7 else np.array([0.0, -1.0, 0.0])
            lights.append({"type": "directional", "direction": direction.tolist(),
                           "irradiance": float(10.0 ** rng.uniform(-1, 1.5))})
            continue
        position = marks[where] if where < 3 else centre + (half if where == 3 else 3.0) * rng.uniform(-1, 1, 3)
        light = {"type": "spot" if rng.random() < 0.3 else "point", "position": position.tolist(),
                 "intensity": float(rng.choice([0.0, 1e-3, 1.0, 30.0, 1e3]))}
        if light["type"] == "spot":
            light.update(direction=rng.normal(size=3).tolist(), outer_angle=float(rng.choice([1.0, 60.0, 180.0])))
        lights.append(light)
    if rng.random() < 0.6:  # aimed at a mark (half the time the first light's) from outside or just beside it
        target = marks[rng.integers(0, 3)]
        if "position" in lights[0] and rng.random() < 0.5:
            target = np.asarray(lights[0]["position"])
        away = rng.normal(size=3)
        origin = target + away / np.linalg.norm(away) * 10.0 ** rng.uniform(-1.0, 0.7)
    else:  # inside the medium's box
        origin = centre + half * rng.uniform(-0.9, 0.9, 3)
        target = origin + rng.normal(size=3)
    scene = {"camera": _camera(origin, target, rng.uniform(10, 90), 3, 3), "lights": lights, "media": [medium]}
    if rng.random() < 0.3:
        scene["surfaces"] = _floor(centre[1] - half - rng.uniform(0.0, 0.5), rng.uniform(0.1, 0.9))
    if rng.random() < 0.3:
        scene["background"] = float(rng.choice([0.5, 1.0]))
    return scene


def bad_renders(scene, device) -> list[str]:
    """Each marcher that takes ``scene``, the lattice on and off, whose image has a pixel not
    finite or below 0 (raymarch takes every scene)."""
    loaded = wv.load_scene(scene)
    bad = []
    for technique in MARCHERS:
        for nodes in LATTICE:
            try:
                image = wv.render(loaded, technique=technique, device=device, multiple_scattering=nodes).image
            except SettingsError:
                assert technique != "raymarch"
                continue
            wrong = (~np.isfinite(image) | (image < 0)).any(axis=-1)
            if wrong.any():
                bad.append(f"{technique} multiple_scattering={nodes}: {int(wrong.sum())} of {wrong.size} pixels")
    return bad


def test_hard_scenes_stay_finite(device):
    """``hard_scene`` of seeds 0 .. HARD_SCENES - 1 (every medium kind, lights at its centre, on
    its surface, at a Gaussian's or particle's centre, extinction 1e-6 to 1e6, RGB with a zero
    channel, media 1e-6 across, the camera inside or looking straight at a light): every marcher
    renders every pixel finite and non-negative, with the multiple-scattering term and without.
    A failure names the seeds: ``hard_scene(seed)`` is the scene."""
    failures = {seed: bad for seed in range(HARD_SCENES) if (bad := bad_renders(hard_scene(seed), device))}
    assert not failures, "\n".join(f"hard_scene({seed}): {'; '.join(bad)}" for seed, bad in failures.items())


_rbf_cloud = (np.random.default_rng(9).normal(0.0, 0.6, (31, 3)) + [0.0, 1.0, 0.0]).round(3).tolist()

#: Scenes that rendered NaN. The first five: a node of the multiple-scattering lattice near a
#: lamp in dense fog overflowed e^(sigma (d - r)) to inf (scattering/kernels.py,
#: hat_light_direction), times its shadow ray's underflowed 0 (every pixel NaN at 8 nodes).
#: The last two: a pixel's ray through a light in a medium thinner than float32 resolves the
#: ray's t at that distance, a march step [t0, t0 + dt] with t0 + dt = t0 (physics/lights.py,
#: segment_mean_inverse_square: h = 0, 1 / 0; NaN times a light of intensity 0).
NAN_SCENES = {
    "lamp-at-a-gaussian-centre": {  # a user's: 31 Gaussians, peak 20, radius 0.64, over a floor
        "camera": _camera([0.0, 1.0, 4.0], [0.0, 0.5, 0.0], 45.0, 8, 6),
        "lights": [{"type": "point", "position": _rbf_cloud[0], "intensity": 5.0}],
        "media": [{"type": "rbf", "centers": _rbf_cloud, "radius": 0.64, "peak": 20.0, "albedo": 0.9}],
        "surfaces": _floor(-0.5, 0.5)},
    "lamp-at-a-particle-centre": {
        "camera": _camera([2.73, 0.342, 1.81], [-0.275, 0.125, 0.118], 36.6, 8, 6),
        "lights": [{"type": "point", "position": [-0.36, -0.0258, -0.0719], "intensity": 10.1}],
        "media": [{"type": "particles", "positions": [[-0.392, 0.15, 0.312], [-0.0186, 0.205, 0.362],
                                                      [-0.36, -0.0258, -0.0719]],
                   "radius": 0.253, "sigma_t": 1310.0, "albedo": 1.0, "phase": {"type": "hg", "g": 0.9}}]},
    "lamp-on-the-edge-of-an-rgb-box": {
        "camera": _camera([-1.751, 0.544, 3.838], [-0.137, 1.001, -0.01657], 75.07, 16, 12),
        "lights": [{"type": "directional", "direction": [-1.092, -0.4293, 1.345], "irradiance": 0.4249},
                   {"type": "point", "position": [0.456, 1.157, 0.4952], "intensity": 24.53}],
        "media": [{"type": "homogeneous", "shape": "box", "center": [-0.03169, 0.8412, -0.1597],
                   "size": [0.9753, 0.6314, 1.31], "sigma_t": [0.0, 1.0, 1000.0], "albedo": 0.3938,
                   "phase": {"type": "rayleigh"}}],
        "surfaces": _floor(0.1401, 0.8793)},
    "camera-in-a-box-of-1e6": {  # a spot light at the box's corner
        "camera": _camera([-0.01633, 0.236, -0.03154], [-0.9262, -0.3265, -0.1829], 58.62, 8, 6),
        "lights": [{"type": "directional", "direction": [0.1095, -0.7513, 0.3496], "irradiance": 3.37},
                   {"type": "spot", "position": [0.1551, 0.6509, 0.8729], "intensity": 0.2931,
                    "direction": [-1.657, 0.3082, -0.5242], "outer_angle": 80.59}],
        "media": [{"type": "homogeneous", "shape": "box", "center": [-0.07089, 0.09227, 0.0926],
                   "size": [0.452, 1.117, 1.561], "sigma_t": 1.0e6, "albedo": 1.0}],
        "surfaces": _floor(-0.63, 0.2362), "background": 0.1514},
    "spot-on-a-dense-grid-corner": {
        "camera": _camera([-0.167, 0.302, -0.0972], [-0.101, 0.993, -0.94], 79.1, 8, 6),
        "lights": [{"type": "spot", "position": [-0.37, -0.287, -1.13], "intensity": 9.57,
                    "direction": [-0.701, -2.23, -1.47], "outer_angle": 33.5}],
        "media": [{"type": "grid", "density": np.ones((2, 2, 2), np.float32), "bounds_min": [-0.37, -0.287, -1.13],
                   "bounds_max": [0.0566, 1.03, 0.875], "sigma_t_scale": 274000.0, "albedo": [1.0, 0.5, 0.0]}],
        "background": 0.791},
    "light-on-a-ray-through-a-tiny-sphere": {
        "camera": _camera([4.33, -0.179, -2.73], [-0.12, 0.283, 0.312], 36.3, 3, 3),
        "lights": [{"type": "point", "position": [-0.12, 0.283, 0.312], "intensity": 1.0}],
        "media": [{"type": "homogeneous", "shape": "sphere", "center": [-0.12, 0.283, 0.312], "radius": 5.73e-06,
                   "sigma_t": [0.0, 5060.0, 78400.0], "albedo": 0.422}]},
    "dark-lamp-on-a-ray-through-a-tiny-gaussian": {
        "camera": _camera([4.173, -8.065, 4.448], [0.4196, 0.07162, 0.4231], 38.99, 3, 3),
        "lights": [{"type": "point", "position": [0.4196, 0.07162, 0.4231], "intensity": 0.0}],
        "media": [{"type": "rbf", "centers": [[0.4196, 0.07162, 0.4231]], "radius": 1.68e-06, "peak": 7625.0,
                   "albedo": 0.0, "phase": {"type": "hg", "g": 0.9999}}],
        "background": 1.0},
}


@pytest.mark.parametrize("name", sorted(NAN_SCENES))
def test_scenes_that_rendered_nan_stay_finite(device, name):
    """Each scene that rendered NaN (``NAN_SCENES``) renders finite and non-negative with every
    marcher, the lattice on and off."""
    assert not bad_renders(NAN_SCENES[name], device)


# --- malformed scenes ------------------------------------------------------------------------

def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(float(v)))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    return "[" + ", ".join(_toml_value(x) for x in np.asarray(v, dtype=object).tolist()) + "]"


def to_toml(scene: dict) -> str:
    """A scene dict as TOML (tables and arrays of tables as in a scene file; grids need a file)."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in scene.items() if not isinstance(v, (dict, list)) or k == "background"]
    for key, value in scene.items():
        if isinstance(value, dict):
            lines += ["", f"[{key}]"] + [f"{k} = {_toml_value(v)}" for k, v in value.items()]
        elif isinstance(value, list) and key != "background":
            for item in value:
                lines += ["", f"[[{key}]]"] + [f"{k} = {_toml_value(v)}" for k, v in item.items()]
    return "\n".join(lines) + "\n"


#: (part, key, bad value, words the message must contain besides the key)
BREAKS = [
    ("camera", "width", 0, "allowed"), ("camera", "width", 2.5, "integer"), ("camera", "fov_y", 180.0, "allowed"),
    ("camera", "fov_y", math.nan, "allowed"), ("camera", "origin", [0, 0], "allowed"), ("camera", "zoom", 2, "unknown key"),
    ("lights", "type", "laser", "allowed"), ("lights", "intensity", -1.0, "allowed"), ("lights", "irradiance", math.inf, "allowed"),
    ("lights", "position", "up", "allowed"), ("media", "albedo", 1.5, "allowed"), ("media", "albedo", -0.1, "allowed"),
    ("media", "sigma_t", -2.0, "allowed"), ("media", "sigma_t", math.nan, "allowed"), ("media", "peak", -1.0, "allowed"),
    ("media", "radius", 0.0, "allowed"), ("media", "phase", {"type": "hg", "g": 1.0}, "allowed"),
    ("media", "phase", {"type": "hg", "g": math.nan}, "allowed"), ("media", "phase", {"type": "mie"}, "allowed"),
    ("media", "centers", [], "allowed"), ("media", "positions", [], "allowed"), ("media", "density", 3, "unknown key"),
    ("media", "shape", "cone", "allowed"), ("surfaces", "diffuse", 2.0, "allowed"), ("surfaces", "radius", -1.0, "allowed"),
    ("surfaces", "normal", [0, 0, 0], "allowed"), ("surfaces", "specular", math.nan, "allowed"),
]


def _target(scene, part):
    """The table a break applies to (the camera, or the first light, medium or surface), or
    None when the scene has no such part. A key the table does not take is still an error
    that must name it ("unknown key")."""
    if part == "camera":
        return scene["camera"]
    items = scene.get(part, [])
    return items[0] if items else None


@FUZZ
@given(scene=scenes(), which=st.integers(0, len(BREAKS) - 1))
def test_malformed_scenes_are_refused_with_one_line(tmp_path_factory, scene, which):
    """One broken key: exit status 2, one line on stderr naming the file and the key, with
    the allowed values; nothing is written."""
    part, key, bad, words = BREAKS[which]
    scene = {k: v for k, v in scene.items()}
    scene["media"] = [m for m in scene["media"] if m["type"] != "grid"]  # grids need a .npy file
    if not scene["media"]:
        scene["media"] = [{"type": "homogeneous", "shape": "sphere", "radius": 1.0, "sigma_t": 1.0, "albedo": 0.5}]
    table = _target(scene, part)
    if table is None:  # e.g. no lights to break: break the camera instead
        part, key, bad, words = BREAKS[0]
        table = scene["camera"]
    table[key] = bad
    folder = tmp_path_factory.mktemp("bad")
    path = folder / "scene.toml"
    path.write_text(to_toml(scene))
    out = folder / "out.png"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        status = main(["render", str(path), "--technique", "raymarch", "--out", str(out)])
    err = err.getvalue().strip()
    assert status == 2, (key, bad, err)
    assert len(err.splitlines()) == 1, err
    assert str(path) in err and key in err and words in err, (key, bad, err)
    assert not out.exists()
