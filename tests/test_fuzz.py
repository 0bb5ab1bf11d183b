"""Property-based fuzzing (hypothesis): random valid scenes render, random malformed ones are refused.

* Valid scenes, drawn from the whole format (every light, medium and surface kind, extinction
  from 1e-3 to 1e6, albedo 0 to 1, |g| up to 0.9999, media 1e-6 thick, lights inside media,
  planes as the only surface), rendered tiny by every technique that accepts them: the image
  is finite and non-negative. A technique may refuse a scene only with ``SettingsError``
  before it runs (illumination_network takes particle clouds without surfaces, say).
* Malformed scenes: a valid scene with one key broken (a wrong type, out of range, NaN, an
  unknown key, an empty medium), written as TOML and given to the command line: exit status
  2 and one line on stderr that names the file and the key and says what is allowed.

The examples are derandomised (the same ones on every run, so CI is reproducible);
``WARPVOL_FUZZ_EXAMPLES`` raises their number for a longer hunt, and hypothesis shrinks a
failure to a small scene. A render that does not finish within ``deadline`` is a hang, not a
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

EXAMPLES = int(os.environ.get("WARPVOL_FUZZ_EXAMPLES", "40"))
FUZZ = settings(max_examples=EXAMPLES, derandomize=True, deadline=timedelta(seconds=120),
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture],
                database=None)  # the `device` fixture is a name, the same for every example

#: Each technique at settings that keep a render to milliseconds.
TINY = {
    "reference": {"spp": 2},
    "raymarch": {"steps": 12, "shadow_steps": 6},
    "light_shafts": {"steps": 8, "block": 2, "shadow_map_res": 16, "shadow_steps": 6},
    "rbf_propagation": {"grid": 6, "steps": 12},
    "illumination_network": {"directions": 8, "iterations": 3, "light_samples": 1},
    "depth_impostors": {"impostor_res": 4, "slices": 2, "light_samples": 2},
    "particle_glow": {"steps": 12, "shadow_map_res": 16, "shadow_steps": 6, "specular": 0.3},
}
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
