"""The scripts in examples/ run as a user would run them (at a small size) and do what they say."""

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run(script, *args, cwd):
    return subprocess.run([sys.executable, str(EXAMPLES / script), *args], capture_output=True, text=True, cwd=cwd)


def test_orbit(tmp_path):
    pytest.importorskip("PIL")
    r = run("orbit.py", "--size", "16x12", "--frames", "3", "--out", "o.gif", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("3 frames (orbit)") and (tmp_path / "o.gif").exists()


def test_side_by_side(tmp_path):
    r = run("side_by_side.py", "fog-box", "--size", "12x9", "--spp", "16", "--out", "s", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "raymarch" in r.stdout and "relative RMSE" in r.stdout
    assert (tmp_path / "s" / "reference.png").exists() and (tmp_path / "s" / "raymarch.png").exists()


def test_target_error(tmp_path):
    r = run("target_error.py", "--size", "16x12", "--target", "0.1", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "estimated error" in r.stdout and "auto: " in r.stdout
