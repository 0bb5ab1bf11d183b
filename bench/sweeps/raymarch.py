"""raymarch: error against the reference vs time, and the pipeline's own cost per frame."""

from __future__ import annotations

import itertools

import warpvol as wv

from ..harness import time_frames
from .common import score_against_reference


def _accuracy_scene(quick: bool):
    """smoke-grid: a heterogeneous grid, a directional light, a floor it shadows."""
    width, height = (32, 24) if quick else (160, 120)
    return wv.load_scene("smoke-grid", [f"camera.width={width}", f"camera.height={height}"])


REFERENCE_SPP = {True: 16, False: 8192}  # per seed; two seeds are averaged


def raymarch_grid(quick: bool) -> list[dict]:
    steps = [4, 16] if quick else [4, 8, 16, 32, 64, 128]
    grids = [0, 8] if quick else [0, 16, 32, 64]
    return [{"steps": s, "shadow_grid": g} for g, s in itertools.product(grids, steps)]


def raymarch_accuracy(params: dict, device: str, quick: bool) -> dict:
    scene = _accuracy_scene(quick)
    r = wv.Renderer(scene, technique="raymarch", multiple_scattering=0, device=device, steps=params["steps"],
                    shadow_steps=params["steps"], shadow_grid=params["shadow_grid"])
    return score_against_reference(time_frames(r, repeats=2 if quick else 3), scene, device, REFERENCE_SPP[quick])


# --- the pipeline's own cost per frame ----------------------------------------------------

def overhead_grid(quick: bool) -> list[dict]:
    return [{"case": "all_cached"}, {"case": "all_ran"}]


def overhead(params: dict, device: str, quick: bool) -> dict:
    """Frame time with every stage cached: nothing but the bookkeeping (stage list, cache keys,
    the Frame). And, with every stage running, the frame's wall time minus the stages' own
    times, which adds what the CPU thread pool costs the Python thread between launches.
    On a 4x3-pixel smoke-grid."""
    scene = wv.load_scene("smoke-grid", ["camera.width=4", "camera.height=3"])
    r = wv.Renderer(scene, technique="raymarch", device=device, steps=4, shadow_grid=2, shadow_steps=2)
    repeats = 20 if quick else 2000
    if params["case"] == "all_cached":
        row = time_frames(r, repeats, invalidate=None)
        row["overhead_us"] = row["median_ms"] * 1000.0
    else:
        row = time_frames(r, repeats // 4)
        row["overhead_us"] = (row["median_ms"] - sum(s["median_ms"] for s in row["stages"].values())) * 1000.0
    row["scene"] = "smoke-grid 4x3"
    return row
