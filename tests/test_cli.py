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
