"""Bad input (issue 12, fuzzing findings): each answer is one line naming the file or path, the
key and what is allowed, given before any kernel runs; nothing half-written is left behind."""

import copy
import os
import sys

import numpy as np
import pytest

import warpvol as wv
from warpvol import image
from warpvol.cli import main
from warpvol.scene import SceneError, load_scene

CAMERA = {"origin": [0, 0, 4], "target": [0, 0, 0], "width": 8, "height": 6}
FOG = {"type": "homogeneous", "shape": "box", "size": [1, 1, 1], "sigma_t": 1.0, "albedo": 0.5}


def scene(*media, surfaces=()):
    return {"name": "t", "camera": dict(CAMERA), "background": 0.1,
            "lights": [{"type": "point", "position": [0, 1, 0], "intensity": 1.0}],
            "media": [copy.deepcopy(m) for m in media], "surfaces": list(surfaces)}


def write_toml(path, medium_lines, surface_lines=""):
    path.write_text('[camera]\norigin = [0, 0, 4]\ntarget = [0, 0, 0]\nwidth = 8\nheight = 6\n'
                    f'[[media]]\n{medium_lines}\n' + (f'[[surfaces]]\n{surface_lines}\n' if surface_lines else ""))
    return str(path)


def one_line_error(fn, *args, error=SceneError):
    with pytest.raises(error) as err:
        fn(*args)
    msg = str(err.value)
    assert "\n" not in msg, msg
    return msg


# --- 1. empty media and non-finite meshes -------------------------------------------------------

RBF = {"type": "rbf", "radius": 0.2, "peak": 3.0, "albedo": 0.9}
PARTICLES = {"type": "particles", "radius": 0.1, "sigma_t": 3.0, "albedo": 0.9}


@pytest.mark.parametrize("medium, key, allowed", [
    (dict(RBF, centers=[]), "media[0].centers: has no centres", "at least one centre"),
    (dict(PARTICLES, positions=[]), "media[0].positions: has no particles", "at least one particle"),
    (dict(PARTICLES, generator={"kind": "cloud", "count": 0}), "media[0].generator.count: 0 is out of range",
     "integer in [1,"),
], ids=["rbf-no-centres", "particles-no-positions", "generator-count-0"])
def test_empty_media_are_errors(medium, key, allowed):
    msg = one_line_error(load_scene, scene(medium))
    assert msg.startswith("<dict>: " + key) and "(allowed: " in msg and allowed in msg.split("(allowed: ")[1], msg


@pytest.mark.parametrize("kind", ["rbf", "particles"])
def test_empty_npy_is_an_error(tmp_path, kind):
    np.save(tmp_path / "none.npy", np.zeros((0, 3), np.float32))
    extra = "radius = 0.2\npeak = 3.0" if kind == "rbf" else "radius = 0.1\nsigma_t = 3.0"
    path = write_toml(tmp_path / "s.toml", f'type = "{kind}"\nfile = "none.npy"\nalbedo = 0.9\n{extra}')
    msg = one_line_error(load_scene, path)
    what = "centre" if kind == "rbf" else "particle"
    assert msg.startswith(f"{path}: media[0].file: "), msg
    assert "none.npy" in msg and f"holds no {what}s" in msg and f"at least one {what}" in msg, msg


def test_obj_with_nan_vertex_is_an_error(tmp_path):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 nan 0\nv 1 1 0\nf 1 2 3\n")
    path = write_toml(tmp_path / "s.toml", 'type = "homogeneous"\nsize = [1, 1, 1]\nsigma_t = 1\nalbedo = 0.5',
                      'type = "mesh"\nfile = "tri.obj"')
    msg = one_line_error(load_scene, path)
    assert msg.startswith(f"{path}: surfaces[0].file: cannot read "), msg
    assert "tri.obj" in msg and "line 2" in msg and "3 finite numbers" in msg, msg


# --- 5. unreadable files --------------------------------------------------------------------------

@pytest.mark.parametrize("content", [b"garbage, not numpy", None], ids=["not-npy", "object-array"])
def test_garbage_npy_names_the_file(tmp_path, content):
    npy = tmp_path / "centres.npy"
    if content is None:
        np.save(npy, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    else:
        npy.write_bytes(content)
    path = write_toml(tmp_path / "s.toml", 'type = "rbf"\nfile = "centres.npy"\nradius = 0.2\npeak = 3\nalbedo = 0.9')
    msg = one_line_error(load_scene, path)
    assert msg.startswith(f"{path}: media[0].file: cannot read {str(npy)!r}: "), msg
    assert "allowed: a .npy file of shape (N, 3)" in msg and "allow_pickle" not in msg, msg


def test_binary_scene_file_names_the_file(tmp_path):
    p = tmp_path / "scene.toml"
    p.write_bytes(b'name = "x"\n\xff\xfe\x00binary')
    msg = one_line_error(load_scene, str(p))
    assert msg.startswith(f"{p}: ") and "UTF-8" in msg and "allowed:" in msg, msg


# --- 2. output paths, checked before the render ----------------------------------------------------

def render_cli(capsys, *args, out):
    """Run `render` on a tiny scene; the scene name is bad on purpose, so a path error that is
    not reported first would be hidden behind a scene error."""
    rc = main(["render", "no-such-scene", "--technique", "raymarch", *args, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    return rc, err


@pytest.mark.parametrize("make_out, says", [
    (lambda d: d / "missing" / "x.png", "does not exist"),
    (lambda d: (d / "file.txt").write_text("") or d / "file.txt" / "x.png", "is a file, not a folder"),
    (lambda d: d, "is a folder"),
    (lambda d: d / "x.jpg", "unknown image type '.jpg'"),
    (lambda d: d / "noext", "unknown image type ''"),
], ids=["missing-folder", "below-a-file", "existing-folder", "jpg", "no-extension"])
def test_output_path_checked_before_anything(tmp_path, capsys, make_out, says):
    out = make_out(tmp_path)
    rc, err = render_cli(capsys, out=out)
    assert rc == 2 and len(err.splitlines()) == 1 and err.startswith("warpvol: error: "), err
    assert str(out) in err and says in err and "allowed: " in err, err


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's read-only folder")
def test_output_in_unwritable_folder():
    with pytest.raises(ValueError, match=r"/proc/x\.png: cannot write in folder /proc.*allowed: "):
        image.check_output_path("/proc/x.png")


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root may write in any folder")
def test_output_in_read_only_folder(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(ValueError, match="cannot write in folder"):
            image.check_output_path(str(ro / "x.exr"))
    finally:
        ro.chmod(0o700)


def test_good_output_path_passes(tmp_path):
    for ext in (".exr", ".png", ".npy", ".PNG"):
        image.check_output_path(str(tmp_path / f"x{ext}"))
    assert os.listdir(tmp_path) == []  # the write probe leaves nothing behind


# --- 3. atomic image writes ----------------------------------------------------------------------

def test_interrupted_write_keeps_the_old_file(tmp_path, monkeypatch):
    out = tmp_path / "x.png"
    wv.save_image(str(out), np.full((6, 8, 3), 0.5, np.float32))
    before = out.read_bytes()

    def broken_writer(path, rgb8):
        with open(path, "wb") as fh:
            fh.write(b"\x89PNG half")
        raise KeyboardInterrupt

    monkeypatch.setattr(image, "_write_png", broken_writer)
    with pytest.raises(KeyboardInterrupt):
        wv.save_image(str(out), np.zeros((6, 8, 3), np.float32))
    assert out.read_bytes() == before
    assert os.listdir(tmp_path) == ["x.png"]  # no temporary file left


def test_atomic_write_replaces_with_usual_mode(tmp_path):
    out = tmp_path / "x.npy"
    wv.save_image(str(out), np.zeros((2, 2, 3), np.float32))
    wv.save_image(str(out), np.ones((2, 2, 3), np.float32))
    np.testing.assert_array_equal(np.load(out), 1.0)
    assert os.listdir(tmp_path) == ["x.npy"]
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask  # not mkstemp's 0600


# --- 4. numbers on the command line and in settings -----------------------------------------------

@pytest.mark.parametrize("args, says", [
    (["--exposure", "nan"], "argument --exposure: 'nan' is not a finite number (allowed: a finite number"),
    (["--exposure", "inf"], "argument --exposure: 'inf' is not a finite number (allowed: a finite number"),
    (["--spp", "abc"], "argument --spp: 'abc' is not an integer (allowed: a whole number"),
], ids=["exposure-nan", "exposure-inf", "spp-abc"])
def test_bad_numbers_on_the_command_line(tmp_path, capsys, args, says):
    with pytest.raises(SystemExit) as exc:
        main(["render", "fog-box", *args, "--out", str(tmp_path / "x.png")])
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2 and len(err.splitlines()) == 1 and err.startswith("warpvol: error: "), err
    assert says in err, err
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_non_finite_setting_names_the_key(device, value):
    with pytest.raises(wv.SettingsError) as err:
        wv.render(scene(FOG), technique="raymarch", device=device, steps=float(value))
    msg = str(err.value)
    assert f"steps={float(value)!r} is not finite (allowed: 1.." in msg, msg


def test_set_nan_on_the_command_line(tmp_path, capsys):
    rc = main(["render", "fog-box", "--technique", "raymarch", "--set", "steps=nan", "--out", str(tmp_path / "x.png")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "steps=nan is not finite (allowed: " in err and "convert" not in err, err


def test_a_choice_takes_its_name():
    """A choice setting takes its values' names (the API and ``--set``), stored as the number;
    an unknown name is refused with the names and the closest of them."""
    from warpvol.cli import _parse_set
    from warpvol.pipeline import resolve_settings
    from warpvol.techniques import TECHNIQUES

    spec = TECHNIQUES["depth_impostors"].SETTINGS
    assert resolve_settings("depth_impostors", spec, {"light_pass": "fourier", "object_depth": "billboards"}) == \
        {**{k: s.default for k, s in spec.items()}, "light_pass": 2, "object_depth": 0}
    settings, _ = _parse_set(["light_pass=exact"], "depth_impostors")
    assert resolve_settings("depth_impostors", spec, settings)["light_pass"] == 0
    with pytest.raises(wv.SettingsError) as err:
        resolve_settings("depth_impostors", spec, {"light_pass": "fourir"})
    assert "light_pass='fourir' is not one of its names; did you mean fourier? (allowed: 0 or 'exact', 1 or " \
           "'slices', 2 or 'fourier';" in str(err.value), str(err.value)
    with pytest.raises(wv.SettingsError) as err:  # a name where the setting has none
        resolve_settings("depth_impostors", spec, {"slices": "many"})
    assert "must be an integer" in str(err.value)


def test_an_on_off_setting_takes_on_off_and_booleans():
    """Every 0/1 setting is a flag by name (``names=FLAG``): "on" / "off" through the API and
    ``--set``, and True / False from Python, stored as 1 / 0; a number setting still refuses a bool."""
    from warpvol.cli import _parse_set
    from warpvol.pipeline import FLAG, resolve_settings
    from warpvol.techniques import TECHNIQUES

    flags = [(t, k) for t, cls in TECHNIQUES.items() for k, s in cls.SETTINGS.items()
             if isinstance(s.default, int) and (s.lo, s.hi) == (0, 1) and not (s.names and s.names != FLAG)]
    assert len(flags) >= 9 and all(TECHNIQUES[t].SETTINGS[k].names == FLAG for t, k in flags), flags
    spec = TECHNIQUES["illumination_network"].SETTINGS
    got = resolve_settings("illumination_network", spec, {"warm": False, "half": "on"})
    assert (got["warm"], got["half"]) == (0, 1) and type(got["warm"]) is int
    settings, _ = _parse_set(["warm=off"], "illumination_network")
    assert resolve_settings("illumination_network", spec, settings)["warm"] == 0
    with pytest.raises(wv.SettingsError) as err:
        resolve_settings("illumination_network", spec, {"warm": "maybe"})
    assert "(allowed: 0 or 'off', 1 or 'on';" in str(err.value), str(err.value)
    with pytest.raises(wv.SettingsError):
        resolve_settings("illumination_network", spec, {"directions": True})


# --- 6. messages that pointed the wrong way ------------------------------------------------------

def test_setting_of_another_technique(tmp_path, capsys):
    rc = main(["render", "fog-box", "--technique", "raymarch", "--set", "spp=4", "--out", str(tmp_path / "x.png")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert "spp is a setting of reference, not of raymarch (allowed for raymarch: extinction_grid, ms_directions, ms_near, multiple_scattering, shadow_grid, shadow_steps" in err, err


def test_technique_refusing_a_scene_names_media_not_counts(device):
    with pytest.raises(wv.SettingsError) as err:
        wv.Renderer(scene(FOG, FOG), technique="illumination_network", device=device)
    msg = str(err.value)
    assert "has media[0] of type homogeneous, media[1] of type homogeneous" in msg, msg


# --- 7. Python 3.10 ---------------------------------------------------------------------------------

def test_cli_reads_values_without_the_tomllib_module(monkeypatch):
    """On Python 3.10 there is no tomllib; the CLI uses the scene loader's (tomli there)."""
    from warpvol.cli import _parse_set

    monkeypatch.setitem(sys.modules, "tomllib", None)  # `import tomllib` now fails
    assert _parse_set(["steps=3", "camera.width=8"], "raymarch") == ({"steps": 3}, ["camera.width=8"])
