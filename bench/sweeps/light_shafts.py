"""Sweeps of light_shafts: Tóth & Umenhoffer 2009 section 5, the sweeps over N, M and shadow maps, the edges interleaving leaves, accuracy."""

from __future__ import annotations

import warpvol as wv

from ..harness import baseline_image, time_frames
from .common import score_against_reference

#: light_shafts as the paper has it: single scattering, every sample shared by the block sum
PAPER_MODEL = {"multiple_scattering": 0, "light_ball": 0}


def shafts_scene(quick: bool, width=800, height=600):
    """colonnade-shafts: 65 660 triangles, one point light in homogeneous fog."""
    if quick:
        width, height = 80, 60
    return wv.load_scene("colonnade-shafts", [f"camera.width={width}", f"camera.height={height}"])


SHAFT_MODES = {"no_scattering": dict(scattering=0, block=1), "scattering": dict(block=1),
               "scattering_interleaved": dict(block=4)}


def shafts_table_grid(quick: bool) -> list[dict]:
    return [{"mode": m} for m in SHAFT_MODES]


def shafts_frame(params: dict, device: str, quick: bool) -> dict:
    """A frame with a moving camera and light over static geometry: shadow maps, the surface
    pass, the march and the block sums run; the BVH and the medium stay cached."""
    settings = {"steps": 64, "edges": 0, **SHAFT_MODES.get(params.get("mode"), {}),  # the paper's block sum
                **{k: v for k, v in params.items() if k != "mode"}}
    scene = shafts_scene(quick)
    r = wv.Renderer(scene, technique="light_shafts", device=device, **PAPER_MODEL, **settings)
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("camera", "lights"))
    row["settings"] = settings
    row["scene"] = f"colonnade-shafts {scene.camera.width}x{scene.camera.height}"
    return row


def shafts_sweep_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"steps": 16, "block": 1}, {"steps": 16, "block": 4}]
    nm = [{"steps": n, "block": m, "shadow_map_res": 256} for n in (16, 32, 64, 128, 256) for m in (1, 2, 4, 8)]
    return nm + [{"steps": 64, "block": 4, "shadow_map_res": r} for r in (64, 128, 512, 1024)]


ACCURACY_SIZE = (320, 240)


def shafts_accuracy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"steps": 16, "block": 1, "shadow_map_res": 64}, {"steps": 16, "block": 4, "shadow_map_res": 64}]
    nm = [{"steps": n, "block": m, "shadow_map_res": 256} for m in (1, 2, 4) for n in (16, 32, 64, 128, 256)]
    return nm + [{"steps": 64, "block": 4, "shadow_map_res": r} for r in (64, 128, 512, 1024)]


def shafts_accuracy(params: dict, device: str, quick: bool) -> dict:
    scene = shafts_scene(quick, *ACCURACY_SIZE)
    base = baseline_image(scene, "raymarch", device, steps=64 if quick else 1024)
    r = wv.Renderer(scene, technique="light_shafts", device=device, **PAPER_MODEL, edges=0, **params)  # the paper's block sum
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("camera", "lights"))
    score_against_reference(row, scene, device, 16 if quick else 1024)
    row["rel_rmse_raymarch"] = wv.relative_rmse(row["frame"].image, base)
    row["reference"]["raymarch_steps"] = 64 if quick else 1024
    return row


def near_depth_jumps(r, m: int):
    """The pixels within M/2 of a depth jump (> 10 % between neighbours) in renderer ``r``'s
    visible surface: where a block sum of M x M pixels mixes two depths."""
    import numpy as np

    depth = np.minimum(r.arrays(resolution=2)["depth"], 1e3)
    jump = np.zeros(depth.shape, bool)
    for axis in (0, 1):
        d = np.abs(np.diff(depth, axis=axis)) > 0.1 * np.minimum(depth[:-1] if axis == 0 else depth[:, :-1],
                                                                  depth[1:] if axis == 0 else depth[:, 1:])
        after, before = [(0, 0), (0, 0)], [(0, 0), (0, 0)]
        after[axis], before[axis] = (0, 1), (1, 0)
        jump |= np.pad(d, after) | np.pad(d, before)  # both pixels of a jumping pair
    near = jump.copy()
    for _ in range(m // 2):  # grow by M/2 pixels: the block window's reach
        near[1:] |= near[:-1]
        near[:-1] |= near[1:]
        near[:, 1:] |= near[:, :-1]
        near[:, :-1] |= near[:, 1:]
    return near


def shafts_edges_grid(quick: bool) -> list[dict]:
    return [{"block": m, "edges": e} for m in ((2, 4) if quick else (2, 3, 4, 8)) for e in (0, 1)]


def shafts_edges(params: dict, device: str, quick: bool) -> dict:
    """What interleaving costs at depth discontinuities: the interleaved image against the same
    N taken per pixel, in pixels within M/2 of a depth jump (> 10 % between neighbours) and in
    the others. Jitter off, so only the interleaving differs."""
    import numpy as np

    scene = shafts_scene(quick)
    full_r = wv.Renderer(scene, technique="light_shafts", device=device, **PAPER_MODEL, steps=64, block=1, jitter=0)
    full = full_r.render().image
    m = params["block"]
    near = near_depth_jumps(full_r, m)
    r = wv.Renderer(scene, technique="light_shafts", device=device, **PAPER_MODEL, steps=64, block=m, jitter=0,
                    edges=params.get("edges", 0))
    row = time_frames(r, repeats=1 if quick else 3, invalidate=("camera", "lights"))
    err = np.abs(row["frame"].image - full).mean(axis=2) / full.mean()
    row.update(edge_pixels=float(near.mean()), rel_err_edges=float(err[near].mean()),
               rel_err_elsewhere=float(err[~near].mean()), scene=f"colonnade-shafts {scene.camera.width}x"
               f"{scene.camera.height}, N = 64")
    return row


EQUAL_TIME_TRUTH = {"steps": 2048, "block": 1, "jitter": 0, "edges": 0}


def shafts_equal_time_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"steps": 16, "block": 1, "edges": 0}, {"steps": 64, "block": 4, "edges": 0}]
    return ([{"steps": n, "block": 1, "edges": 0} for n in (8, 16, 32, 64, 128)]
            + [{"steps": n, "block": m, "edges": e} for m in (2, 4, 8) for e in (0, 1) for n in (16, 32, 64, 128, 256)])


def shafts_equal_time(params: dict, device: str, quick: bool) -> dict:
    """Tóth & Umenhoffer's claim that interleaving keeps the quality at a fraction of the cost,
    at equal frame time: each (N, M) against the technique's own converged image (N = 2048, M = 1,
    no jitter: the same shadow maps, so the error is the sampling's alone), over the image, in the
    pixels within M/2 of a depth jump (where the block sum mixes depths) and elsewhere; the paper's
    block sum (edges = 0) and the depth-aware one (edges = 1)."""
    import numpy as np

    scene = shafts_scene(quick, *ACCURACY_SIZE)
    truth = baseline_image(scene, "light_shafts", device, **PAPER_MODEL, **(
        {**EQUAL_TIME_TRUTH, "steps": 256} if quick else EQUAL_TIME_TRUTH))
    m = params["block"]
    r = wv.Renderer(scene, technique="light_shafts", device=device, **PAPER_MODEL, **params)
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("camera", "lights"))
    near = near_depth_jumps(r, m) if m > 1 else np.zeros(truth.shape[:2], bool)
    err = np.abs(row["frame"].image - truth).mean(axis=2) / truth.mean()
    row["table"] = {"error": wv.relative_rmse(row["frame"].image, truth),
                    "mean abs, near depth jumps": float(err[near].mean()) if near.any() else 0.0,
                    "mean abs, elsewhere": float(err[~near].mean()),
                    "pixels near jumps": float(near.mean())}
    row["scene"] = (f"colonnade-shafts {scene.camera.width}x{scene.camera.height}, camera and light moving; the truth "
                    "light_shafts at N = 2048, M = 1, no jitter (same shadow maps)")
    return row


def shafts_speedup_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"steps": 16, "block": 2}]
    return [{"steps": n, "block": 4} for n in (16, 32, 64, 128, 256)] + [{"steps": 64, "block": m} for m in (2, 8)]


def shafts_speedup(params: dict, device: str, quick: bool) -> dict:
    """The march stage alone with M x M interleaving and without it (M = 1), same N, the two
    timed in alternation in one process so the machine's drift hits both alike: min and
    median of each, and the speed-up of the mins (the issue's target: >= 0.7 M^2)."""
    import statistics
    import time

    n, m = params["steps"], params["block"]
    scene = shafts_scene(quick)
    rs = {k: wv.Renderer(scene, technique="light_shafts", device=device, **PAPER_MODEL, steps=n, block=k, edges=0) for k in (1, m)}
    t0 = time.perf_counter()
    for r in rs.values():
        r.render()
    first = (time.perf_counter() - t0) * 1000.0
    times = {1: [], m: []}
    for _ in range(2 if quick else 5):
        for k, r in rs.items():
            times[k].append(r.run_stage("march"))
    ms = {k: {"min": min(v), "median": statistics.median(v)} for k, v in times.items()}
    speedup = ms[1]["min"] / ms[m]["min"]
    return {"first_frame_ms": first, "median_ms": ms[m]["median"], "frames": len(times[m]),
            "march_ms_m1": ms[1], "march_ms": ms[m], "speedup": speedup,
            "speedup_median": ms[1]["median"] / ms[m]["median"], "fraction_of_m2": speedup / (m * m),
            "stages": {}, "scene": f"colonnade-shafts {scene.camera.width}x{scene.camera.height}"}


def shafts_paper_fps(table: dict, params: dict):
    return next((r["fps"] for r in table["rows"] if r["mode"] == params.get("mode")), None)
