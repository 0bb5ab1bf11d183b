"""The live view (warpvol.viz.live): its loop without a window, and the window off screen."""

import subprocess
import sys

import numpy as np
import pytest

import warpvol as wv

pytest.importorskip("pyvista")

from warpvol.viz.live import LiveView  # noqa: E402


def test_dragging_moves_the_camera_and_reruns_only_its_stages(device):
    live = LiveView("fog-box", "light_shafts", device, size=(16, 12))
    first = live.frame()
    assert "medium" in live.ran and "shadow_maps" in live.ran
    live.orbit(20.0, 5.0)
    moved = live.frame()
    assert not np.allclose(first, moved)
    assert {"medium", "lights", "shadow_maps", "multiple"}.isdisjoint(live.ran) and "march" in live.ran
    assert live.fps > 0.0
    cam = live.renderer.scene.camera
    fresh = wv.render("fog-box", "light_shafts", device=device,
                      overrides={"camera.width": 16, "camera.height": 12, "camera.origin": list(cam.origin)}).image
    np.testing.assert_allclose(moved, fresh, rtol=1e-5, atol=1e-6)


def test_keys_switch_technique_and_show_the_reference(device):
    live = LiveView("fog-box", "light_shafts", device, size=(8, 6))
    assert live.switch() != "light_shafts" and live.technique in live.techniques
    live.toggle_reference()
    a = live.frame()
    b = live.frame()
    assert live.ran == ["reference, 2 spp"] and a.shape == b.shape == (6, 8, 3)
    live.orbit(10.0)  # a camera move starts the running mean again
    live.frame()
    assert live.ran == ["reference, 1 spp"]
    with pytest.raises(wv.SettingsError, match="does not take"):
        LiveView("fog-box", "illumination_network", device, size=(8, 6))


def test_the_window_runs_off_screen(tmp_path):
    shot = tmp_path / "live.png"
    r = subprocess.run([sys.executable, "-m", "warpvol", "live", "fog-box", "--size", "32x24", "--frames", "4",
                        "--screenshot", str(shot)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("fog-box: live light_shafts, 32x24, 4 of the last frames at ") and "FPS" in r.stdout
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_no_display_or_no_pyvista_is_one_line(monkeypatch, capsys):
    """A window asked for where there is none to open (Linux, no $DISPLAY): exit 2 and one line
    that says how to render off screen; without pyvista, one line that says what to install."""
    import importlib.util

    from warpvol.cli import main

    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    for command in ("live", "view"):
        assert main([command, "fog-box"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "no display" in err and "--screenshot" in err, err
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "pyvista" else real(name, *a))
    assert main(["view", "fog-box", "--screenshot", "x.png"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install 'warpvol[viz]'" in err, err


def test_the_title_fits_the_window():
    """The title lists the stages a frame ran; at 800 pixels one line ran off the right edge
    ("...surface, mar"). Wrapped, no line is wider than the window at 8 pixels a character (the
    widest of the size-10 font's), and no word is lost."""
    from warpvol.viz.live import CHAR_PX, fitted

    title = ("raymarch (t: next, r: reference)  12.3 FPS  ran: medium, surfaces, lights, camera, multiple, "
             "multiple_view, light_volume, march, surface, march_sky, composite")
    lines = fitted(title, 800 - 16)
    assert len(lines) >= 2 and all(len(line) * CHAR_PX <= 800 - 16 for line in lines)
    assert " ".join(lines).split() == title.split()
