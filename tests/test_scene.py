"""Scene loading: every bad input is one line naming the file, the key and the allowed range."""

import copy
import subprocess
import sys

import numpy as np
import pytest

import warpvol as wv
from warpvol.scene import SceneError, load_scene
from warpvol.scene.procedural import BUILTIN

BASE = {
    "name": "t",
    "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "width": 8, "height": 6},
    "lights": [{"type": "point", "position": [0, 1, 0], "intensity": 1.0}],
    "media": [{"type": "homogeneous", "shape": "box", "size": [1, 1, 1], "sigma_t": 1.0, "albedo": 0.5,
               "phase": {"type": "hg", "g": 0.2}}],
}


def with_(path, value):
    d = copy.deepcopy(BASE)
    node = d
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value
    return d


BAD = [
    (with_(["media", 0, "sigma_t"], -1.0), "media[0].sigma_t", ">= 0"),
    (with_(["media", 0, "albedo"], 1.5), "media[0].albedo", "[0, 1]"),
    (with_(["media", 0, "phase", "g"], 1.0), "media[0].phase.g", "(-1, 1)"),
    (with_(["media", 0, "phase", "g"], -1.2), "media[0].phase.g", "(-1, 1)"),
    (with_(["media", 0, "sigma_t"], float("nan")), "media[0].sigma_t", "not finite"),
    (with_(["media", 0, "size"], [1, float("inf"), 1]), "media[0].size", "non-finite"),
    (with_(["media", 0, "size"], [1, 0, 1]), "media[0].size", "out of range"),
    (with_(["media", 0, "colour"], 1), "media[0].colour", "unknown key"),
    (with_(["media", 0, "type"], "fog"), "media[0].type", "homogeneous | grid | rbf | particles"),
    (with_(["camera", "fov_y"], "wide"), "camera.fov_y", "a number"),
    (with_(["camera", "width"], 0), "camera.width", "integer in [1"),
    (with_(["camera", "up"], [0, 0, 1]), "camera.up", "parallel"),
    (with_(["lights", 0, "intensity"], -2), "lights[0].intensity", ">= 0"),
    (with_(["lights", 0, "type"], "area"), "lights[0].type", "point | spot | directional"),
    (with_(["media"], []), "media", "nothing to see"),
    (with_(["surfaces"], [{"type": "mesh", "file": "missing.obj"}]), "surfaces[0].file", "not found"),
    (with_(["media", 0], {"type": "grid", "file": "nope.npy", "bounds_min": [0, 0, 0], "bounds_max": [1, 1, 1], "albedo": 1}),
     "media[0].file", "not found"),
    (with_(["media", 0], {"type": "grid", "density": np.full((2, 2, 2), np.nan), "bounds_min": [0, 0, 0],
                          "bounds_max": [1, 1, 1], "albedo": 1}), "media[0].density", "NaN"),
    (with_(["surfaces"], [{"type": "box", "size": [1, 1, 1], "diffuse": 0.8, "specular": 0.5}]), "surfaces[0].specular", "<= 1"),
]


@pytest.mark.parametrize("scene,key,allowed", BAD, ids=[k for _, k, _ in BAD])
def test_bad_input_names_key_and_range(scene, key, allowed):
    with pytest.raises(SceneError) as err:
        load_scene(scene)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith("<dict>: " + key), msg
    assert allowed in msg, msg


def test_file_errors_name_the_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text('[camera]\norigin = [0, 0, 4]\ntarget = [0, 0, 0]\n\n[[media]]\ntype = "homogeneous"\n'
                 'size = [1, 1, 1]\nsigma_t = -3\nalbedo = 0.5\n')
    with pytest.raises(SceneError, match=r"bad\.toml: media\[0\]\.sigma_t: -3"):
        load_scene(str(p))


def test_cli_reports_bad_scene_without_traceback(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text('[camera]\norigin = [0, 0, 4]\ntarget = [0, 0, 0]\n[[media]]\ntype = "homogeneous"\n'
                 'size = [1, 1, 1]\nsigma_t = 1\nalbedo = 7\n')
    r = subprocess.run([sys.executable, "-m", "warpvol", "render", str(p), "--out", str(tmp_path / "x.png")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith("warpvol: error: ") and "media[0].albedo" in r.stderr


def test_toml_file_with_relative_paths(tmp_path):
    np.save(tmp_path / "density.npy", np.ones((2, 3, 4), np.float32))
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    p = tmp_path / "s.toml"
    p.write_text('name = "files"\n[camera]\norigin = [0, 0, 4]\ntarget = [0, 0, 0]\n'
                 '[[media]]\ntype = "grid"\nfile = "density.npy"\nbounds_min = [-1, -1, -1]\nbounds_max = [1, 1, 1]\n'
                 'albedo = [0.9, 0.8, 0.7]\nphase = { type = "rayleigh" }\n'
                 '[[surfaces]]\ntype = "mesh"\nfile = "tri.obj"\n'
                 '[[lights]]\ntype = "spot"\nposition = [0, 2, 0]\ndirection = [0, -1, 0]\nintensity = 3\n')
    s = load_scene(str(p))
    assert s.media[0].density.shape == (2, 3, 4) and s.media[0].albedo == (0.9, 0.8, 0.7)
    assert s.surfaces[0].faces.shape == (2, 3)  # the quad fanned into two triangles
    assert s.lights[0].type == "spot"


def test_overrides():
    s = load_scene(BASE, ["camera.width=33", "media.0.sigma_t=[1, 2, 3]"])
    assert s.camera.width == 33 and s.media[0].sigma_t == (1.0, 2.0, 3.0)
    with pytest.raises(SceneError, match="index"):
        load_scene(BASE, ["media.5.sigma_t=1"])


@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_builtin_scenes_load(name):
    s = load_scene(name)
    assert s.name == name and (s.media or s.surfaces)


def test_scenes_folder_files_load():
    import glob
    import os

    files = glob.glob(os.path.join(os.path.dirname(__file__), "..", "scenes", "*.toml"))
    assert files
    for f in files:
        load_scene(f)


def test_unknown_setting_and_technique():
    with pytest.raises(wv.SettingsError, match=r"unknown setting 'stepz'; did you mean steps\? \(allowed: extinction_grid, ms_directions, ms_near, multiple_scattering, shadow_grid, shadow_steps, sky_samples, step_length, steps\)"):
        wv.render(BASE, technique="raymarch", stepz=3)
    with pytest.raises(wv.SettingsError, match=r"spp=0 is out of range \(allowed: 1\.\."):
        wv.render(BASE, technique="reference", spp=0)
    with pytest.raises(wv.SettingsError, match="unknown technique"):
        wv.render(BASE, technique="magic")


def test_kinds_are_members_past_the_loader():
    """Past the loader a light's and a medium's kind is a member of LightKind / MediumKind (named
    by the member in the code, not by a string), still equal to and printed as its name."""
    from warpvol.scene.model import Light, LightKind, MediumKind

    scene = wv.load_scene("rbf-cornell")
    assert all(isinstance(light.type, LightKind) for light in scene.lights)
    assert all(isinstance(m.type, MediumKind) for m in scene.media)
    assert scene.media[0].type is MediumKind.RBF and scene.media[0].type == "rbf" and f"{scene.media[0].type}" == "rbf"
    assert Light("spot", strength=(1.0, 1.0, 1.0)).type is LightKind.SPOT
