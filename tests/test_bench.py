"""The benchmark harness: --quick sweeps run end to end, rows carry what a result needs,
an interrupted sweep resumes, and reports are generated from the JSON."""

import json

import numpy as np

import pytest

import warpvol as wv

from warpvol.bench.harness import digest, load_rows, write_rows
from warpvol.bench.report import pareto_front, paper_section
from warpvol.bench.sweeps import SWEEPS
from warpvol.cli import main

ROW_FIELDS = {"sweep", "technique", "params", "device", "warp", "commit", "median_ms", "spread_ms", "stages",
              "first_frame_ms", "peak_mem_mb", "paper"}


@pytest.fixture
def out(tmp_path, monkeypatch):
    monkeypatch.setenv("WARPVOL_CACHE", str(tmp_path / "cache"))
    return tmp_path / "results"


def test_quick_accuracy_sweep_end_to_end_and_resume(device, out, capsys):
    assert main(["bench", "raymarch-accuracy", "--quick", "--device", device, "--out", str(out)]) == 0
    path = out / "raymarch-accuracy" / "cpu-quick.json"
    rows = load_rows(path)
    assert len(rows) == len(SWEEPS["raymarch-accuracy"].points(quick=True))
    for row in rows:
        assert ROW_FIELDS <= set(row), ROW_FIELDS - set(row)
        assert row["spread_ms"][0] <= row["median_ms"] <= row["spread_ms"][1]
        assert row["stages"]["march"]["status"] == "ran"
        assert 0.0 < row["rel_rmse"] < 1.0
    # more steps along the camera ray cannot make the marched image worse by more than the noise
    by = {(r["params"]["steps"], r["params"]["shadow_grid"]): r["rel_rmse"] for r in rows}
    floor = rows[0]["reference"]["rel_rmse_floor"]
    assert by[(16, 0)] <= by[(4, 0)] + floor
    readme = (out / "raymarch-accuracy" / "README.md").read_text()
    assert "relative RMSE" in readme and (out / "raymarch-accuracy" / "cpu-quick.png").stat().st_size > 1000
    # run again: every point is there, nothing is measured twice
    stamp = [r["measured"] + str(r["median_ms"]) for r in rows]
    assert main(["bench", "raymarch-accuracy", "--quick", "--device", device, "--out", str(out)]) == 0
    assert [r["measured"] + str(r["median_ms"]) for r in load_rows(path)] == stamp


def test_interrupted_sweep_keeps_its_rows_and_measures_the_rest(device, out):
    sweep = SWEEPS["pipeline-overhead"]
    path = out / sweep.name / "cpu-quick.json"
    assert main(["bench", sweep.name, "--quick", "--device", device, "--out", str(out)]) == 0
    rows = load_rows(path)
    write_rows(path, sweep, rows[:1], "test")  # as if stopped after the first row
    assert main(["bench", sweep.name, "--quick", "--device", device, "--out", str(out)]) == 0
    again = load_rows(path)
    assert again[0] == rows[0] and len(again) == len(rows)
    cached = next(r for r in again if r["params"]["case"] == "all_cached")
    assert cached["overhead_us"] > 0 and all(s["status"] == "cached" for s in cached["stages"].values())


def test_the_listing_names_every_sweep_and_its_technique(capsys):
    assert main(["bench", "--list"]) == 0
    listing = capsys.readouterr().out.splitlines()
    assert len(listing) == len(SWEEPS)
    for line, (name, sweep) in zip(listing, SWEEPS.items()):
        assert line.split()[:2] == [name, sweep.technique]


def test_paper_report_normalises_both_columns_to_the_first_row(tmp_path):
    rows = [{"sweep": "t", "params": {"mode": m}, "median_ms": ms, "paper": fps, "device": "d", "peak_mem_mb": 1.0,
             "stages": {}} for m, ms, fps in (("a", 1.0, 110.0), ("b", 4.0, 42.0))]
    lines = paper_section(rows, tmp_path / "t.png")
    assert "| mode=b | 42 | 250.0 | 0.382 | 0.250 |" in lines[3]
    assert (tmp_path / "t.png").exists()


def test_pareto_front_and_digest():
    assert pareto_front([(1.0, 0.5), (2.0, 0.6), (3.0, 0.1), (0.5, 0.9)]) == [3, 0, 2]
    assert digest({"a": [1, 2]}) == digest({"a": [1, 2]}) != digest({"a": [1, 3]})
    json.dumps(SWEEPS["raymarch-accuracy"].points(quick=True))  # points are plain data, for any executor


def test_the_census_covers_every_built_in_scene_at_both_sizes():
    """``bench defaults``: every built-in scene, every technique whose Renderer takes it, at the
    scene's own size and at 160x120 (once where they are the same), the reference at 16 spp."""
    from warpvol.bench.sweeps.census import CENSUS_SIZE, census_grid
    from warpvol.scene import BUILTIN

    points = census_grid(quick=False)
    assert {p["scene"] for p in points} == set(BUILTIN)
    for name in BUILTIN:
        own = wv.load_scene(name).camera
        sizes = {(own.width, own.height), CENSUS_SIZE}
        rows = [p for p in points if p["scene"] == name]
        techniques = {p["technique"] for p in rows}
        assert "reference" in techniques and len(techniques) >= 3
        for t in techniques:
            assert {(p["width"], p["height"]) for p in rows if p["technique"] == t} == sizes
            assert sum(p["technique"] == t for p in rows) == len(sizes)
        assert all(p["spp"] == 16 for p in rows if p["technique"] == "reference")


def test_hdr_flip_weighs_what_is_visible():
    """The second error measure (metrics.hdr_flip): 0 for identical images, free of exposure
    (both images scaled by 1000: the same score to float rounding), and unlike RMSE / mean not
    decided by a light's core: a core 100x the scene's radiance, 30% too bright in one pixel,
    is most of the RMSE and almost none of the FLIP, while the same scene with a 30% darker
    wall (a quarter of the pixels) scores the other way round."""
    rng = np.random.default_rng(0)
    ref = (0.2 + 0.05 * rng.random((48, 64, 3))).astype(np.float32)
    ref[20, 30] = 100.0  # the light's core
    core = ref.copy()
    core[20, 30] *= 1.3
    wall = ref.copy()
    wall[:, :16] *= 0.7
    assert wv.hdr_flip(ref, ref) == 0.0
    assert wv.hdr_flip(1000.0 * wall, 1000.0 * ref) == pytest.approx(wv.hdr_flip(wall, ref), rel=1e-3)
    assert wv.relative_rmse(core, ref) > wv.relative_rmse(wall, ref)
    assert wv.hdr_flip(core, ref) < 0.2 * wv.hdr_flip(wall, ref)
