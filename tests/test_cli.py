"""The command line and image files, as a user runs them."""

import re
import subprocess
import sys

import numpy as np
import pytest

import warpvol as wv
from warpvol import device as dev


def run(*args):
    return subprocess.run([sys.executable, "-m", "warpvol", *args], capture_output=True, text=True)


def test_render_writes_exr_png_npy(tmp_path):
    pytest.importorskip("OpenEXR")
    outs = [tmp_path / "a.exr", tmp_path / "a.png", tmp_path / "a.npy"]
    r = run("render", "fog-box", "--technique", "raymarch", "--set", "camera.width=40", "--set", "camera.height=30",
            "--set", "steps=32", "--timings", *sum((["--out", str(o)] for o in outs), []))
    assert r.returncode == 0, r.stderr
    assert "march" in r.stdout
    exr, npy = wv.load_image(str(outs[0])), np.load(outs[2])
    assert exr.shape == (30, 40, 3) and exr.dtype == np.float32
    np.testing.assert_array_equal(exr, npy)  # float32 EXR is lossless
    assert outs[1].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert npy.max() > 0


def test_exr_roundtrip_and_orientation(tmp_path):
    pytest.importorskip("OpenEXR")
    img = np.zeros((4, 6, 3), np.float32)
    img[0, :, 0] = 1.0  # top row red
    img[:, -1, 2] = 2.5  # right column blue, HDR
    wv.save_image(str(tmp_path / "t.exr"), img)
    np.testing.assert_array_equal(wv.load_image(str(tmp_path / "t.exr")), img)


def test_bad_extension_and_bad_device(tmp_path):
    r = run("render", "fog-box", "--technique", "raymarch", "--out", str(tmp_path / "x.jpg"))
    assert r.returncode == 2 and "allowed: .exr, .png, .npy" in r.stderr and "Traceback" not in r.stderr
    r = run("render", "fog-box", "--device", "cuda:7", "--out", str(tmp_path / "x.png"))
    assert r.returncode == 2 and "device 'cuda:7' is not available" in r.stderr


def test_scenes_lists_builtins():
    r = run("scenes")
    assert r.returncode == 0 and "fog-box" in r.stdout and "particle-cloud" in r.stdout


def test_device_pick(monkeypatch):
    monkeypatch.setenv("WARPVOL_DEVICE", "cpu")
    assert dev.pick() == "cpu"
    monkeypatch.delenv("WARPVOL_DEVICE")
    assert dev.pick() in dev.available()
    with pytest.raises(dev.DeviceError, match="allowed: cpu"):
        dev.pick("tpu")


def test_a_command_prints_its_own_line_and_nothing_else(tmp_path):
    """No Warp banner, no "Module ... load" lines, no CUDA-driver warning: those need --verbose."""
    out = tmp_path / "X.png"
    r = subprocess.run([sys.executable, "-m", "warpvol", "render", "fog-box", "--technique", "raymarch",
                        "--set", "camera.width=8", "--set", "camera.height=6", "--out", str(out)],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert r.returncode == 0, r.stdout
    assert re.fullmatch(rf"fog-box: raymarch on \S+, 8x6, \d+\.\d\d s -> {re.escape(str(out))}\n", r.stdout), r.stdout
    verbose = run("render", "fog-box", "--technique", "raymarch", "--set", "camera.width=8", "--set", "camera.height=6",
                  "--out", str(out), "--verbose")
    assert verbose.returncode == 0 and "Warp" in verbose.stdout + verbose.stderr


def test_typos_are_answered_with_the_name_meant(tmp_path):
    """A misspelt setting, technique, scene key or table names what was meant, in one line."""
    with pytest.raises(wv.SettingsError, match=r"unknown setting 'stepz'; did you mean steps\?"):
        wv.render("fog-box", "raymarch", stepz=4)
    with pytest.raises(wv.SettingsError, match=r"unknown technique 'raymarh'; did you mean raymarch\?"):
        wv.render("fog-box", "raymarh")
    with pytest.raises(wv.SceneError, match=r"sigma_t: missing \(there is a key 'sigma_tt': a misspelling of sigma_t\?\)"):
        wv.load_scene({"camera": {"origin": [0, 0, 3], "target": [0, 0, 0], "width": 4, "height": 3},
                       "media": [{"type": "homogeneous", "shape": "sphere", "radius": 1, "sigma_tt": 0.5,
                                  "albedo": 0.5}]})
    with pytest.raises(wv.SceneError, match=r"camera: missing \(there is a key 'camra'"):
        wv.load_scene({"camra": {}, "media": []})
    with pytest.raises(wv.SceneError, match=r"albdo: unknown key; did you mean albedo\?"):
        wv.load_scene("fog-box", ["media.0.albdo=0.5"])
    r = run("render", "fog-box", "--technique", "raymarch", "--set", "stepz=4", "--out", str(tmp_path / "x.png"))
    assert r.returncode == 2 and "stepz is not a setting of raymarch; did you mean steps?" in r.stderr
    assert r.stderr.count("\n") == 1 and not (tmp_path / "x.png").exists()


def test_the_api_takes_the_clis_overrides():
    """``overrides`` spells scene keys as ``--set`` does, as a dict or KEY=VALUE strings, in
    render and Renderer alike; a loaded Scene is refused with what to do instead."""
    small = {"camera.width": 12, "camera.height": 9, "media.0.sigma_t": 1.2}
    a = wv.render("fog-box", "raymarch", device="cpu", overrides=small, steps=8)
    b = wv.Renderer("fog-box", "raymarch", device="cpu", overrides=[f"{k}={v}" for k, v in small.items()],
                    steps=8).render()
    c = wv.render(wv.load_scene("fog-box", [f"{k}={v}" for k, v in small.items()]), "raymarch", device="cpu", steps=8)
    assert a.image.shape == (9, 12, 3)
    np.testing.assert_array_equal(a.image, b.image)
    np.testing.assert_array_equal(a.image, c.image)
    with pytest.raises(wv.SceneError, match="allowed: for a loaded Scene, dataclasses.replace"):
        wv.render(wv.load_scene("fog-box"), "raymarch", overrides={"camera.width": 8})


def test_a_frame_shows_itself_in_a_notebook():
    """``Frame._repr_png_``: a PNG of the image's size (what Jupyter shows), the same pixels
    ``save_image`` writes."""
    import zlib

    frame = wv.render("fog-box", "raymarch", device="cpu", overrides={"camera.width": 10, "camera.height": 7}, steps=8)
    png = frame._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert int.from_bytes(png[16:20], "big") == 10 and int.from_bytes(png[20:24], "big") == 7
    idat = png.index(b"IDAT")
    raw = zlib.decompress(png[idat + 4: idat + 4 + int.from_bytes(png[idat - 4: idat], "big")])
    rows = np.frombuffer(raw, np.uint8).reshape(7, 1 + 10 * 3)[:, 1:].reshape(7, 10, 3)
    from warpvol.image import tonemap

    np.testing.assert_array_equal(rows, tonemap(frame.image))


def test_a_built_in_scene_prints_as_toml_that_loads_back(tmp_path):
    """``scenes NAME --toml`` writes a scene file that renders as the built-in does; a grid too
    large for TOML is refused in one line; ``scenes`` prints whole descriptions; ``render``
    without --out writes SCENE.TECHNIQUE.png."""
    r = run("scenes", "rbf-cornell", "--toml")
    assert r.returncode == 0, r.stderr
    path = tmp_path / "mine.toml"
    path.write_text(r.stdout)
    size = ["camera.width=8", "camera.height=6"]
    a = wv.render(wv.load_scene("rbf-cornell", size), "raymarch", device="cpu", multiple_scattering=0, steps=8)
    b = wv.render(wv.load_scene(str(path), size), "raymarch", device="cpu", multiple_scattering=0, steps=8)
    np.testing.assert_array_equal(a.image, b.image)
    r = run("scenes", "smoke-grid", "--toml")
    assert r.returncode == 2 and "too large for a TOML file" in r.stderr and r.stderr.count("\n") == 1
    r = run("scenes")
    assert "(the Sun et al. 2005 airlight set-up)" in r.stdout
    r = subprocess.run([sys.executable, "-m", "warpvol", "render", "fog-box", "--technique", "raymarch", "--set",
                        "camera.width=8", "--set", "camera.height=6"], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "fog-box.raymarch.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_warning_is_one_line_of_the_tools_own(tmp_path):
    """A target the technique cannot reach ends with a warning: one line, ``warpvol: warning: ...``,
    not Python's file, line number and source line."""
    r = run("render", "fog-box", "--technique", "raymarch", "--set", "camera.width=8", "--set", "camera.height=6",
            "--set", "multiple_scattering=0", "--set", "target_error=1e-7", "--out", str(tmp_path / "w.png"))
    assert r.returncode == 0, r.stderr
    warned = [line for line in r.stderr.splitlines() if "warning" in line.lower()]
    assert len(warned) == 1 and warned[0].startswith("warpvol: warning: raymarch: error estimate"), r.stderr
    assert "cli.py" not in r.stderr and "wv.render(" not in r.stderr


def test_the_demo_captions_each_half(tmp_path):
    """demo: the two halves side by side (a 4-pixel gap) and, under each, its caption in the
    5 x 7 font (``image.text_mask``): two lines, 9 font pixels each plus a 2-pixel margin, white
    ink (1 at the image's exposure) on black; the caption's first letter is the technique's."""
    from warpvol.image import FONT, text_mask

    out = tmp_path / "demo.npy"
    r = run("demo", "--set", "camera.width=40", "--set", "camera.height=30", "--out", str(out))
    assert r.returncode == 0, r.stderr
    image = np.load(out)
    assert image.shape == (30 + 20, 2 * 40 + 4, 3)
    caption = image[30:, :40, 0]
    ink = caption > 0
    assert np.allclose(caption[ink], caption[ink].max())  # one ink value
    letter = ink[2:9, 2:7].astype(int)  # "L" of light_shafts
    np.testing.assert_array_equal(letter, text_mask(["L"], 7)[2:9, 2:7].astype(int))
    np.testing.assert_array_equal(letter @ (1 << np.arange(4, -1, -1)), FONT["L"])
    reference = image[30:, 44:, 0] > 0
    np.testing.assert_array_equal(reference[2:9, 2:7].astype(int) @ (1 << np.arange(4, -1, -1)), FONT["R"])


def test_text_is_cut_at_the_width_and_unknown_characters_shown():
    from warpvol.image import FONT, text_mask

    m = text_mask(["AAAA", "#"], 14)  # two characters fit in 14 pixels (each 6 wide, from 2 in)
    assert m.shape == (2 + 2 * 9, 14)
    bits = lambda rows: ((np.array(rows)[:, None] >> np.arange(4, -1, -1)) & 1)
    np.testing.assert_array_equal(m[2:9, 2:7], bits(FONT["A"]))
    np.testing.assert_array_equal(m[2:9, 8:13], bits(FONT["A"]))
    assert m[2:9, 13:].sum() == 0
    np.testing.assert_array_equal(m[11:18, 2:7], bits(FONT["?"]))
    big = text_mask(["1"], 20, scale=2)
    np.testing.assert_array_equal(big[4:18:2, 4:14:2], bits(FONT["1"]))
