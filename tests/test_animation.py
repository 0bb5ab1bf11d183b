"""Animations (warpvol.animation): one Renderer along a camera or light path, re-running only
what each frame's change feeds, written as a GIF, an MP4 or PNG frames."""

import math
import subprocess
import sys

import numpy as np
import pytest

import warpvol as wv

SMALL = {"camera.width": 16, "camera.height": 12}


def test_an_orbit_moves_the_camera_and_reruns_only_its_stages(device):
    """Frame k of an orbit is the scene rendered with its camera turned by 2 pi k / N about the
    target (a fresh render, bit for bit); the medium's, lights' and lattice's stages run once."""
    anim = wv.animate("fog-box", "raymarch", path="orbit", frames=4, device=device, overrides=SMALL, steps=16)
    assert len(anim.frames) == 4 and len(anim.seconds) == 4
    scene = wv.load_scene("fog-box", [f"{k}={v}" for k, v in SMALL.items()])
    np.testing.assert_array_equal(anim.frames[0], wv.render(scene, "raymarch", device=device, steps=16).image)
    o = np.array(scene.camera.origin)  # target at the origin, up +y: a quarter turn takes z to x
    turned = {**SMALL, "camera.origin": [o[2] * math.sin(math.pi / 2), o[1], o[2] * math.cos(math.pi / 2)]}
    fresh = wv.render("fog-box", "raymarch", device=device, overrides=turned, steps=16).image
    np.testing.assert_allclose(anim.frames[1], fresh, rtol=1e-5, atol=1e-6)
    assert not np.allclose(anim.frames[0], anim.frames[1])
    assert anim.stages["medium"] == {"ran": 1, "cached": 3, "skipped": 0}
    assert anim.stages["multiple"]["ran"] == 1 and anim.stages["multiple_view"]["ran"] == 4
    assert anim.stages["march"]["ran"] == 4


def test_the_lights_go_round_and_the_camera_stays(device):
    anim = wv.animate("fog-box", "raymarch", path="light", frames=3, device=device, overrides=SMALL, steps=16)
    assert anim.stages["lights"]["ran"] == 3 and anim.stages["medium"]["cached"] == 2
    assert not np.allclose(anim.frames[0], anim.frames[1])
    with pytest.raises(wv.SettingsError, match="has none"):
        wv.animate({"camera": {"origin": [0, 0, 3], "target": [0, 0, 0], "width": 4, "height": 3},
                    "background": [1, 1, 1], "media": [{"type": "homogeneous", "shape": "sphere", "radius": 1,
                                                        "sigma_t": 1, "albedo": 0.5}]}, "raymarch", path="light")


def test_gif_and_frames_are_written_and_bad_outputs_refused(tmp_path, device):
    PIL = pytest.importorskip("PIL.Image")
    gif = tmp_path / "a.gif"
    wv.animate("fog-box", "raymarch", path="dolly", frames=3, device=device, overrides=SMALL, steps=8, out=str(gif))
    im = PIL.open(gif)
    assert im.n_frames == 3 and im.size == (16, 12)
    wv.animate("fog-box", "raymarch", path="orbit", frames=2, device=device, overrides=SMALL, steps=8,
               out=str(tmp_path / "frames"))
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == ["frame_0000.png", "frame_0001.png"]
    with pytest.raises(ValueError, match=r"allowed: \.gif, \.mp4, or a folder"):
        wv.animate("fog-box", "raymarch", frames=2, out=str(tmp_path / "a.avi"))
    with pytest.raises(wv.SettingsError, match="unknown path 'spin'"):
        wv.animate("fog-box", "raymarch", path="spin")


def test_the_command_prints_its_lines(tmp_path):
    """``animate`` writes the file, prints the time per frame and each stage's counts, and a
    missing path is one line."""
    out = tmp_path / "o.gif"
    pytest.importorskip("PIL")
    r = subprocess.run([sys.executable, "-m", "warpvol", "animate", "fog-box", "--technique", "light_shafts",
                        "--orbit", "3", "--set", "camera.width=16", "--set", "camera.height=12", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("fog-box: light_shafts, 16x12, 3 frames (orbit): first ") and str(out) in r.stdout
    assert "  medium         ran 1, cached 2" in r.stdout and out.exists()
    r = subprocess.run([sys.executable, "-m", "warpvol", "animate", "fog-box"], capture_output=True, text=True)
    assert r.returncode == 2 and "give one of --orbit N, --dolly N, --light N" in r.stderr
