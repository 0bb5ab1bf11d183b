"""Named sweeps: one per table of the papers (bench/paper_tables.toml), accuracy sweeps (error
against the reference vs time) and the pipeline's own overhead. A paper's sweep becomes runnable when its technique lands.
"""

from __future__ import annotations

import itertools
import statistics
import time
import sys
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

import warpvol as wv

from .harness import baseline_image, reference_image, time_frames

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PAPER_TABLES = tomllib.loads((Path(__file__).parent / "paper_tables.toml").read_text())


@dataclass
class Sweep:
    """A named list of independent points and how to measure one.

    ``grid(quick)`` gives the points (parameter dicts); ``measure(params, device, quick)``
    returns the row's measured fields. ``paper`` is the table's path in paper_tables.toml
    and ``figure(table, params)`` the paper's number for a point. ``kind`` picks the report:
    ``paper``, ``accuracy`` or ``overhead``.
    """

    name: str
    doc: str
    technique: str
    kind: str
    grid: Callable[[bool], list[dict]] | None = None
    measure: Callable[[dict, str, bool], dict] | None = None
    paper: tuple[str, ...] = ()
    figure: Callable[[dict, dict], object] | None = None
    issue: int | None = None
    note: str = ""  # what the report adds below its sections: how to read the rows

    @property
    def available(self) -> bool:
        return self.grid is not None and self.technique in wv.technique_names()

    def points(self, quick: bool = False) -> list[dict]:
        if not self.available:
            raise ValueError(f"sweep {self.name!r} waits for technique {self.technique!r} "
                             f"({f'issue {self.issue}' if self.issue else 'no issue yet'}); "
                             f"runnable now: {', '.join(n for n, s in SWEEPS.items() if s.available)}")
        return self.grid(quick)

    def table(self) -> dict | None:
        node = PAPER_TABLES
        for key in self.paper:
            node = node[key]
        return node if self.paper else None

    def paper_figure(self, params: dict):
        return self.figure(self.table(), params) if self.figure and self.paper else None


# --- raymarch: error against the reference vs time -----------------------------------------

def _accuracy_scene(quick: bool):
    """smoke-grid: a heterogeneous grid, a directional light, a floor it shadows."""
    width, height = (32, 24) if quick else (160, 120)
    return wv.load_scene("smoke-grid", [f"camera.width={width}", f"camera.height={height}"])


REFERENCE_SPP = {True: 16, False: 8192}  # per seed; two seeds are averaged


def _raymarch_grid(quick: bool) -> list[dict]:
    steps = [4, 16] if quick else [4, 8, 16, 32, 64, 128]
    grids = [0, 8] if quick else [0, 16, 32, 64]
    return [{"steps": s, "shadow_grid": g} for g, s in itertools.product(grids, steps)]


def score(row: dict, scene, device: str, spp: int, max_bounces: int = 1, pixel_area: int = 0) -> np.ndarray:
    """Add to ``row`` the relative RMSE of its frame against the reference at pixel centres
    (``max_bounces`` 1: single scattering, what the real-time techniques compute, without
    their error; two seeds of ``spp``), raw and with the reference's own noise removed: that
    noise adds in quadrature, E[err^2 to a noisy ref] = err^2 + floor^2. Returns the reference."""
    ref, floor = reference_image(scene, device, spp=spp, max_bounces=max_bounces, pixel_area=pixel_area)
    row["rel_rmse"] = wv.relative_rmse(row["frame"].image, ref)
    row["rel_rmse_corrected"] = max(row["rel_rmse"] ** 2 - floor**2, 0.0) ** 0.5
    row["reference"] = {"spp": 2 * spp, "max_bounces": max_bounces, "pixel_area": pixel_area, "rel_rmse_floor": floor}
    row["scene"] = f"{scene.name} {scene.camera.width}x{scene.camera.height}"
    return ref


def score_against_reference(row: dict, scene, device: str, spp: int) -> dict:
    """``score`` in single scattering; returns the row."""
    score(row, scene, device, spp)
    return row


def _raymarch_accuracy(params: dict, device: str, quick: bool) -> dict:
    scene = _accuracy_scene(quick)
    r = wv.Renderer(scene, technique="raymarch", device=device, steps=params["steps"],
                    shadow_steps=params["steps"], shadow_grid=params["shadow_grid"])
    return score_against_reference(time_frames(r, repeats=2 if quick else 3), scene, device, REFERENCE_SPP[quick])


# --- the pipeline's own cost per frame ----------------------------------------------------

def _overhead_grid(quick: bool) -> list[dict]:
    return [{"case": "all_cached"}, {"case": "all_ran"}]


def _overhead(params: dict, device: str, quick: bool) -> dict:
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
    return row


# --- light shafts (Tóth & Umenhoffer 2009) ----------------------------------------------------------------

def shafts_scene(quick: bool, width=800, height=600):
    """colonnade-shafts: 65 660 triangles, one point light in homogeneous fog."""
    if quick:
        width, height = 80, 60
    return wv.load_scene("colonnade-shafts", [f"camera.width={width}", f"camera.height={height}"])


SHAFT_MODES = {"no_scattering": dict(scattering=0, block=1), "scattering": dict(block=1),
               "scattering_interleaved": dict(block=4)}


def _shafts_table_grid(quick: bool) -> list[dict]:
    return [{"mode": m} for m in SHAFT_MODES]


def _shafts_frame(params: dict, device: str, quick: bool) -> dict:
    """A frame with a moving camera and light over static geometry: shadow maps, the surface
    pass, the march and the block sums run; the BVH and the medium stay cached."""
    settings = {"steps": 64, "edges": 0, **SHAFT_MODES.get(params.get("mode"), {}),  # the paper's block sum
                **{k: v for k, v in params.items() if k != "mode"}}
    r = wv.Renderer(shafts_scene(quick), technique="light_shafts", device=device, **settings)
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("camera", "lights"))
    row["settings"] = settings
    return row


def _shafts_sweep_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"steps": 16, "block": 1}, {"steps": 16, "block": 4}]
    nm = [{"steps": n, "block": m, "shadow_map_res": 256} for n in (16, 32, 64, 128, 256) for m in (1, 2, 4, 8)]
    return nm + [{"steps": 64, "block": 4, "shadow_map_res": r} for r in (64, 128, 512, 1024)]


ACCURACY_SIZE = (320, 240)


def _shafts_accuracy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"steps": 16, "block": 1, "shadow_map_res": 64}, {"steps": 16, "block": 4, "shadow_map_res": 64}]
    nm = [{"steps": n, "block": m, "shadow_map_res": 256} for m in (1, 2, 4) for n in (16, 32, 64, 128, 256)]
    return nm + [{"steps": 64, "block": 4, "shadow_map_res": r} for r in (64, 128, 512, 1024)]


def _shafts_accuracy(params: dict, device: str, quick: bool) -> dict:
    scene = shafts_scene(quick, *ACCURACY_SIZE)
    base = baseline_image(scene, "raymarch", device, steps=64 if quick else 1024)
    r = wv.Renderer(scene, technique="light_shafts", device=device, edges=0, **params)  # the paper's block sum
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("camera", "lights"))
    score_against_reference(row, scene, device, 16 if quick else 1024)
    row["rel_rmse_raymarch"] = wv.relative_rmse(row["frame"].image, base)
    row["reference"]["raymarch_steps"] = 64 if quick else 1024
    return row


def _shafts_edges_grid(quick: bool) -> list[dict]:
    return [{"block": m, "edges": e} for m in ((2, 4) if quick else (2, 3, 4, 8)) for e in (0, 1)]


def _shafts_edges(params: dict, device: str, quick: bool) -> dict:
    """What interleaving costs at depth discontinuities: the interleaved image against the same
    N taken per pixel, in pixels within M/2 of a depth jump (> 10 % between neighbours) and in
    the others. Jitter off, so only the interleaving differs."""
    import numpy as np

    scene = shafts_scene(quick)
    full_r = wv.Renderer(scene, technique="light_shafts", device=device, steps=64, block=1, jitter=0)
    full = full_r.render().image
    depth = np.minimum(full_r.arrays(resolution=2)["depth"], 1e3)
    jump = np.zeros(depth.shape, bool)
    for axis in (0, 1):
        d = np.abs(np.diff(depth, axis=axis)) > 0.1 * np.minimum(depth[:-1] if axis == 0 else depth[:, :-1],
                                                                  depth[1:] if axis == 0 else depth[:, 1:])
        after, before = [(0, 0), (0, 0)], [(0, 0), (0, 0)]
        after[axis], before[axis] = (0, 1), (1, 0)
        jump |= np.pad(d, after) | np.pad(d, before)  # both pixels of a jumping pair
    m = params["block"]
    near = jump.copy()
    for _ in range(m // 2):  # grow by M/2 pixels: the block window's reach
        near[1:] |= near[:-1]
        near[:-1] |= near[1:]
        near[:, 1:] |= near[:, :-1]
        near[:, :-1] |= near[:, 1:]
    r = wv.Renderer(scene, technique="light_shafts", device=device, steps=64, block=m, jitter=0,
                    edges=params.get("edges", 0))
    row = time_frames(r, repeats=1 if quick else 3, invalidate=("camera", "lights"))
    err = np.abs(row["frame"].image - full).mean(axis=2) / full.mean()
    row.update(edge_pixels=float(near.mean()), rel_err_edges=float(err[near].mean()),
               rel_err_elsewhere=float(err[~near].mean()), scene=f"colonnade-shafts {scene.camera.width}x"
               f"{scene.camera.height}, N = 64")
    return row


def _shafts_speedup_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"steps": 16, "block": 2}]
    return [{"steps": n, "block": 4} for n in (16, 32, 64, 128, 256)] + [{"steps": 64, "block": m} for m in (2, 8)]


def _shafts_speedup(params: dict, device: str, quick: bool) -> dict:
    """The march stage alone with M x M interleaving and without it (M = 1), same N, the two
    timed in alternation in one process so the machine's drift hits both alike: min and
    median of each, and the speed-up of the mins (the issue's target: >= 0.7 M^2)."""
    import statistics
    import time

    n, m = params["steps"], params["block"]
    scene = shafts_scene(quick)
    rs = {k: wv.Renderer(scene, technique="light_shafts", device=device, steps=n, block=k, edges=0) for k in (1, m)}
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


def _shafts_paper_fps(table: dict, params: dict):
    return next((r["fps"] for r in table["rows"] if r["mode"] == params.get("mode")), None)


# --- RBF propagation (Giroud & Biri 2011) -------------------------------------------------------------

TABLE2_COLUMNS = {"1L_P": (1, False), "1L": (1, True), "2L": (2, True), "4L": (4, True), "8L": (8, True)}


def _rbf_scene(quick: bool, lights: int = 1, rbfs: int | None = None, width: int = 800, height: int = 600):
    """rbf-thick-fog's box and first ``lights`` lights; its 1000 RBFs, or ``rbfs`` random ones
    whose radius shrinks as rbfs^(-1/3) so the fog's mass stays about the same."""
    import numpy as np

    if quick:
        width, height = 80, 60
    from warpvol.scene.procedural import rbf_thick_fog

    d = rbf_thick_fog()
    d["camera"].update(width=width, height=height)
    d["lights"] = d["lights"][:lights]
    if rbfs is not None:
        rng = np.random.default_rng(rbfs)
        d["media"][0].update(centers=rng.uniform(-0.85, 0.85, (rbfs, 3)), radius=0.12 * (1000 / rbfs) ** (1 / 3))
    return wv.load_scene(d)


def _table2_grid(quick: bool) -> list[dict]:
    grids = (15, 20) if quick else (15, 20, 30, 40)
    cols = ("1L_P", "1L") if quick else tuple(TABLE2_COLUMNS)
    return [{"grid": g, "column": c} for g in grids for c in cols]


def _table2(params: dict, device: str, quick: bool) -> dict:
    """Precomputed (P): only the march runs; dynamic: medium and lights change every frame."""
    lights, dynamic = TABLE2_COLUMNS[params["column"]]
    r = wv.Renderer(_rbf_scene(quick, lights), technique="rbf_propagation", device=device, grid=params["grid"])
    return time_frames(r, repeats=2 if quick else 3, invalidate=("medium", "lights", "camera") if dynamic else ("camera",))


def _table2_fps(table: dict, params: dict):
    row = next(r for r in table["rows"] if r["grid"] == params["grid"])
    return row["fps"][table["columns"].index(params["column"])]


def _table3_grid(quick: bool) -> list[dict]:
    counts = (1, 125) if quick else (1, 125, 1000, 8000, 27000)
    return [{"rbfs": n, "column": c} for n in counts for c in ("dynamic", "static")]


def _table3(params: dict, device: str, quick: bool) -> dict:
    r = wv.Renderer(_rbf_scene(quick, 1, params["rbfs"]), technique="rbf_propagation", device=device, grid=20)
    dynamic = params["column"] == "dynamic"
    return time_frames(r, repeats=2 if quick else 3, invalidate=("medium", "lights", "camera") if dynamic else ("camera",))


def _table3_fps(table: dict, params: dict):
    row = next(r for r in table["rows"] if r["rbfs"] == params["rbfs"])
    return row["fps"][("dynamic", "static").index(params["column"])]


def _rules_grid(quick: bool) -> list[dict]:
    grids = (8, 12) if quick else (10, 15, 20, 30, 40)
    return [{"grid": g, "rule": r, "wavefront": w} for g in grids for r in (0, 1) for w in (1, 0)]


def _rules(params: dict, device: str, quick: bool) -> dict:
    """The OPV against optical depth marched from each cell centre to each light through the
    same EV (8 steps per cell), on rbf-cornell's medium and two lights."""
    import numpy as np

    scene = wv.load_scene("rbf-cornell", ["camera.width=8", "camera.height=6"])
    r = wv.Renderer(scene, technique="rbf_propagation", device=device, **params)
    row = time_frames(r, repeats=1 if quick else 3, invalidate=("lights",))
    a = r.arrays(for_view=True)
    err = np.abs(a["optical_depth"] - a["optical_depth_exact"])[..., 0]
    exact = a["optical_depth_exact"][..., 0]
    row.update(mean_abs_error=float(err.mean()), mean_exact=float(exact.mean()),
               rel_error=float(err.mean() / exact.mean()), max_abs_error=float(err.max()),
               p95_rel_cell=float(np.percentile(err / np.maximum(exact, 1e-3), 95)))
    return row


def _scaling_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"stage": "propagate", "grid": 8, "iterations": 4}, {"stage": "march", "width": 40, "steps": 16}]
    prop = [{"stage": "propagate", "grid": g, "iterations": i} for g in (10, 20, 30, 40) for i in (10, 40)]
    march = [{"stage": "march", "width": w, "steps": st} for w in (200, 400, 800) for st in (16, 64, 256)]
    return prop + march


def _scaling(params: dict, device: str, quick: bool) -> dict:
    """One stage's time as its work grows: propagation (whole-grid sweeps, the paper's scheme)
    against cells x sweeps, the march against pixels x steps (rbf-cornell, 2 lights, 4:3)."""
    if params["stage"] == "propagate":
        scene = wv.load_scene("rbf-cornell", ["camera.width=8", "camera.height=6"])
        r = wv.Renderer(scene, technique="rbf_propagation", device=device, grid=params["grid"], wavefront=0,
                        iterations=params["iterations"])
        row = time_frames(r, repeats=2 if quick else 5, invalidate=("lights",))
        row["work"] = params["grid"] ** 3 * params["iterations"]
    else:
        w = params["width"]
        scene = wv.load_scene("rbf-cornell", [f"camera.width={w}", f"camera.height={w * 3 // 4}"])
        r = wv.Renderer(scene, technique="rbf_propagation", device=device, grid=20, steps=params["steps"])
        row = time_frames(r, repeats=2 if quick else 5, invalidate=("camera",))
        row["work"] = w * (w * 3 // 4) * params["steps"]
    row["stage_ms"] = row["stages"][params["stage"]]["median_ms"]
    return row


def _rbf_accuracy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"grid": 8, "steps": 16}, {"grid": 16, "steps": 16}]
    return [{"grid": g, "steps": s} for g in (10, 15, 20, 30, 40) for s in (16, 32, 64, 128)]


def _rbf_accuracy(params: dict, device: str, quick: bool) -> dict:
    w, h = (32, 24) if quick else (80, 60)
    scene = wv.load_scene("rbf-cornell", [f"camera.width={w}", f"camera.height={h}"])
    r = wv.Renderer(scene, technique="rbf_propagation", device=device, **params)
    return score_against_reference(time_frames(r, repeats=2 if quick else 3), scene, device, 16 if quick else 1024)


# --- illumination networks (Szirmay-Kalos et al. 2005) -----------------------------------------------------

SUN2 = {"type": "directional", "direction": [0.6, 0.8, -0.3], "irradiance": 1.5}  # the paper's second, bottom-right


def network_scene(quick: bool, n: int = 1024, width: int = 512, albedo: float = 0.9, sky: bool = True,
                   seed: int = 1):
    """particle-cloud as in the paper's results: ``n`` particles (radius scaled by n^(-1/3)
    so the cloud's volume stays put), albedo 0.9, g = 0, 2 R tau = 20 expected collisions
    across it, two directional lights and sky."""
    from warpvol.scene.procedural import particle_cloud

    d = particle_cloud()
    if quick:
        n, width = min(n, 128), min(width, 32)
    radius = 0.12 * (1024 / n) ** (1 / 3)
    R = 1.2 + radius
    sigma = 10.0 * R**2 / (n * radius**3)  # mean tau over the ball = n sigma r^3 / R^3 = 20 / (2 R)
    d["camera"].update(width=width, height=width)
    d["lights"] = [d["lights"][0], SUN2]
    d["background"] = d["background"] if sky else [0.0, 0.0, 0.0]
    d["media"][0].update(generator={"kind": "cloud", "count": n, "seed": seed, "extent": 1.2}, radius=radius,
                         sigma_t=sigma, albedo=albedo, phase={"type": "hg", "g": 0.0})
    return wv.load_scene(d)


FP32_PEAK_GFLOPS = {"NVIDIA H200": 67_000.0}  # vendor figure, FP32 without tensor cores


def peak_gflops(device: str) -> float | None:
    """The device's FP32 peak: a vendor figure for known GPUs; for the CPU, cores x clock x
    FMA lanes (AVX-512: 16 x 2 flops a cycle, AVX2: 8 x 2), one FMA unit per core assumed."""
    import os

    import warp as wp

    if str(device).startswith("cuda"):
        name = wp.get_device(device).name
        return next((v for k, v in FP32_PEAK_GFLOPS.items() if k in name), None)
    try:
        with open("/proc/cpuinfo") as f:
            info = f.read()
    except OSError:
        return None
    mhz = [float(line.split(":")[1]) for line in info.splitlines() if line.startswith("cpu MHz")]
    if not mhz:
        return None
    lanes = 16 if "avx512f" in info else 8 if "avx2" in info else 4
    return len(os.sched_getaffinity(0)) * max(mhz) / 1000.0 * lanes * 2


def untimed_row(frames: int, **fields) -> dict:
    """A row that measures no frame time (convergence, error bounds): the common fields empty."""
    return {"first_frame_ms": 0.0, "median_ms": float("nan"), "spread_ms": [0, 0], "frames": frames, "stages": {},
            **fields}


def _network_table_grid(quick: bool) -> list[dict]:
    return [{"particles": 1024, "directions": 128}, {"particles": 512, "directions": 128}]


def _network_frame(params: dict, device: str, quick: bool) -> dict:
    """A frame as in the paper: lights and camera moving, one iteration, 512x512 splat; and
    the cost of one iteration alone (median of 20) with its multiply-add rate."""
    import time

    import warp as wp

    n, D = params["particles"], params["directions"]
    scene = network_scene(quick, n, params.get("width", 512))
    r = wv.Renderer(scene, technique="illumination_network", device=device, directions=D,
                    window=params.get("window", 0), iterations=1, tolerance=0.0)
    row = time_frames(r, repeats=2 if quick else 10, invalidate=("camera", "lights"))
    t = r.technique
    times = []
    for _ in range(3 if quick else 20):
        t0 = time.perf_counter()
        t.step(measure=False)
        wp.synchronize_device(t.device)
        times.append(time.perf_counter() - t0)
    it = sorted(times)[len(times) // 2]
    builds = []
    for _ in range(1 if quick else 3):
        r.touch("medium")
        builds.append(r.render().stages["network"].ms)
    gflops = 2.0 * 3 * n * D * D / it / 1e9
    peak = peak_gflops(device)
    row.update(iteration_ms=it * 1000.0, gflops=gflops, peak_gflops=peak,
               peak_fraction=gflops / peak if peak else None, window=r.diagnostics()["window"],
               network_ms=sorted(builds)[len(builds) // 2],
               scene=f"{n} particles, {scene.camera.width}x{scene.camera.height}, 2 suns + sky")
    return row


def _network_sweep_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"particles": 64, "directions": 16}, {"particles": 128, "directions": 32}]
    return ([{"particles": n, "directions": 128} for n in (256, 512, 1024, 2048, 4096, 8192, 16384)]
            + [{"particles": 1024, "directions": d} for d in (32, 64, 256, 512)]
            + [{"particles": 1024, "directions": 128, "window": m} for m in (32, 128)])


CONVERGENCE_SHOWN = (20, 40, 60, 80)


def _convergence_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"albedo": 0.9, "window": 0}]
    return [{"albedo": a, "window": m} for m in (0, 16) for a in (0.9, 0.99)]


def _convergence(params: dict, device: str, quick: bool) -> dict:
    """Figure 6: iterations from zero on the paper's cloud (1024 particles, 128 directions):
    the relative L2 change per iteration and the error to the converged solution, of the
    network I and of the image. Saves the images at 20/40/60/80 iterations."""
    import numpy as np

    iters = 20 if quick else 300
    scene = network_scene(quick, 1024, 256, albedo=params["albedo"])
    r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=0,
                    window=params.get("window", 0))
    r.render()
    t = r.technique
    nets, changes = [], []
    for k in range(iters):
        changes.append(t.step(measure=True))
        if k + 1 <= 100:  # the first 100 iterates (memory: N D 3 floats each)
            nets.append(t.radiance_network())
    r.update(settings={"iterations": 0})
    converged = t.radiance_network()
    shown = {}
    for k in CONVERGENCE_SHOWN + (iters,):
        if k <= iters:
            t.set_radiance_network(nets[k - 1] if k <= len(nets) else converged)
            r.touch("camera")
            shown[k] = r.render().image.copy()
    final = shown[iters]
    net_err = [float(np.sqrt(((x - converged) ** 2).sum() / (converged**2).sum())) for x in nets]
    img_err = {k: wv.relative_rmse(v, final) for k, v in shown.items()}
    return untimed_row(iters, change=changes, network_error=net_err,
                       image_error={str(k): v for k, v in img_err.items()},
                       images={str(k): v for k, v in shown.items() if k in CONVERGENCE_SHOWN})


def _network_accuracy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"particles": 64, "directions": 16, "window": 0}, {"particles": 64, "directions": 32, "window": 0}]
    return ([{"particles": n, "directions": d, "window": 0} for n in (256, 1024) for d in (16, 32, 64, 128, 256)]
            + [{"particles": 1024, "directions": 128, "window": m} for m in (8, 16, 32, 96)])


def _network_accuracy(params: dict, device: str, quick: bool) -> dict:
    """The converged image against the multiple-scattering reference on the same particles
    (48x48 at pixel centres), the window from the paper's rule (window = 0) or given."""
    w = 24 if quick else 48
    scene = network_scene(quick, params["particles"], w)
    r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=2000, tolerance=1e-5,
                    directions=params["directions"], window=params["window"])
    row = time_frames(r, repeats=1 if quick else 2, invalidate=("lights",))
    row["window_used"] = r.diagnostics()["window"]
    row["iterations_to_converge"] = r.diagnostics()["iterations"]
    ref = score(row, scene, device, 16 if quick else 128, max_bounces=-1)
    row["mean_ratio"] = float(row["frame"].image.mean() / ref.mean())
    row["scene"] = f"{params['particles']} particles {w}x{w}"
    return row


def _lightpass_grid(quick: bool) -> list[dict]:
    """The old default (exact, 4 points a sphere), exact at more points, and each map
    representation over its resolution, read at 16 points a sphere."""
    if quick:
        return [{"light_pass": 0, "light_samples": 4}, {"light_pass": 1, "light_slices": 8, "light_samples": 16}]
    return ([{"light_pass": 0, "light_samples": k} for k in (4, 16, 64)]
            + [{"light_pass": 1, "light_slices": s, "light_samples": 16} for s in (4, 8, 16, 32, 64)]
            + [{"light_pass": 1, "light_slices": 32, "light_samples": 4}]
            + [{"light_pass": 2, "light_terms": k, "light_samples": 16} for k in (4, 8, 16, 32)])


_LIGHTPASS_TRUTH: dict = {}


def _lightpass_truth(scene, device: str, quick: bool):
    """The direct light with exact transmittance averaged over 256 points of each sphere
    (light_pass = 0), and the converged image it gives: the yardstick of every row."""
    key = (scene.name, device, quick)
    if key not in _LIGHTPASS_TRUTH:
        r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=2000, tolerance=1e-5,
                        light_pass=0, light_samples=64 if quick else 256, light_tolerance=0.0)
        image = r.render().image
        _LIGHTPASS_TRUTH[key] = (r.diagnostics()["direct"].astype(np.float64), image)
    return _LIGHTPASS_TRUTH[key]


def _lightpass_accuracy(params: dict, device: str, quick: bool) -> dict:
    """What the light pass's representation and resolution buy: the direct light per particle
    against the exact sphere mean (relative RMSE over particles, lights and channels), the
    converged image against the image from that exact direct light (how far the image moves)
    and against the reference; the direct stage's time with both suns moving each frame."""
    n, w = (128, 24) if quick else (1024, 48)
    scene = network_scene(quick, n, w)
    settings = {"light_tolerance": 0.0, **params}  # no fallback: measure the representation itself
    r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=2000, tolerance=1e-5,
                    **settings)
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("lights",))
    truth, truth_image = _lightpass_truth(scene, device, quick)
    direct = r.diagnostics()["direct"].astype(np.float64)
    row["direct_rel_rmse"] = float(np.sqrt(np.sum((direct - truth) ** 2) / np.sum(truth**2)))
    row["direct_ms"] = row["stages"]["direct"]["median_ms"]
    row["texels"] = r.diagnostics()["light_texels"]
    image = row["frame"].image
    row["image_move"] = wv.relative_rmse(image, truth_image)
    score(row, scene, device, 16 if quick else 128, max_bounces=-1)
    row["scene"] = f"{n} particles {w}x{w}, 2 suns + sky, D = 128"
    return row


def _lightpass_scaling_grid(quick: bool) -> list[dict]:
    return [{"n": n} for n in ((128, 256) if quick else (1024, 2048, 4096, 8192))]


def _lightpass_scaling(params: dict, device: str, quick: bool) -> dict:
    """The light pass as particles get finer: ``n`` particles of radius 0.12 (1024 / n)^(1/3)
    with sigma_t r fixed (each particle as thick as at n = 1024, the cloud thicker as n^(1/3)),
    both suns turning 3 degrees a frame about y, D = 128, at the default light_tolerance. The
    direct stage's time per frame, and where the map ended: texels a side, refinements in the
    last frame, its measured error, and whether it fell back to exact chords."""
    n, w = params["n"], (32 if quick else 128)
    base = network_scene(False, 1024, w)  # radius 0.12 and its sigma_t at n = 1024
    radius = 0.12 * (1024 / n) ** (1 / 3)
    d = particle_cloud_dict(base, n, radius, (np.asarray(base.media[0].sigma_t) * 0.12 / radius).tolist())
    scene = wv.load_scene(d)
    r = wv.Renderer(scene, technique="illumination_network", device=device, directions=128, iterations=1)
    lights = list(scene.lights)
    turn = [0]

    def move():
        turn[0] += 1
        a = np.radians(3.0 * turn[0])
        rot = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
        r.update(lights=[dataclasses.replace(light, direction=tuple(rot @ np.asarray(light.direction, float)))
                         if light.type == "directional" else light for light in lights])

    row = time_frames(r, repeats=3 if quick else 8, invalidate=None, before=move)
    diag = r.diagnostics()
    row["table"] = {"direct ms": row["stages"]["direct"]["median_ms"], "texels": diag["light_texels"],
                    "refined": diag["light_refined"], "error": diag["light_error"], "fell back": diag["light_fell_back"]}
    row.update(scene=f"n particles of radius 0.12 (1024 / n)^(1/3), sigma_t r fixed, {w}x{w}, D = 128, 2 suns turning "
                   "3 degrees a frame + sky, light_tolerance at its default")
    return row


def particle_cloud_dict(scene, n: int, radius: float, sigma_t: float) -> dict:
    """``scene`` (a network_scene) as a table with ``n`` particles of ``radius`` and ``sigma_t``."""
    from warpvol.scene.procedural import particle_cloud

    d = particle_cloud()
    d["camera"].update(width=scene.camera.width, height=scene.camera.height)
    d["lights"] = [d["lights"][0], SUN2]
    d["media"][0].update(generator={"kind": "cloud", "count": n, "seed": 1, "extent": 1.2}, radius=radius,
                         sigma_t=sigma_t, albedo=0.9, phase={"type": "hg", "g": 0.0})
    return d


def _albedo_grid(quick: bool) -> list[dict]:
    return [{"albedo": a} for a in ((0.5,) if quick else (0.5, 0.8, 0.95))]


def _albedo_bound(params: dict, device: str, quick: bool) -> dict:
    """The paper's claim that a step's error eps grows to at most eps / (1 - a) over the
    iteration. Without sky (so zero iterations give exactly single scattering): eps is the
    RMSE of the single-scattering image (iterations = 0) against the reference with one
    scattering event, the total is the converged image's RMSE against the unlimited one."""
    w, spp = (24, 16) if quick else (32, 256)
    scene = network_scene(quick, 256, w, albedo=params["albedo"], sky=False)
    out = {}
    for bounces, settings in ((1, {"iterations": 0}), (-1, {"iterations": 3000, "tolerance": 1e-6})):
        r = wv.Renderer(scene, technique="illumination_network", device=device, directions=128, **settings)
        image = r.render().image
        ref, floor = reference_image(scene, device, spp=spp, max_bounces=bounces, pixel_area=0)
        out[bounces] = (wv.rmse(image, ref), wv.rmse(ref, 0.0), floor)
    eps, total = out[1][0], out[-1][0]
    a = params["albedo"]
    return untimed_row(1, eps_rmse=eps, total_rmse=total, bound=eps / (1 - a), holds=bool(total <= eps / (1 - a)),
                       ss_rms=out[1][1], ms_rms=out[-1][1], reference_floor=[out[1][2], out[-1][2]],
                       scene=f"256 particles {w}x{w}, no sky, D = 128")


def drifting_cloud(positions, frame: int, spin: float = 0.02, wander: float = 0.02):
    """An animated cloud: turned by ``spin`` radians a frame about y, each particle wandering
    on its own small circle (``wander`` in scene units)."""
    import numpy as np

    p = np.asarray(positions, np.float64)
    a = spin * frame
    c, s_ = np.cos(a), np.sin(a)
    turned = np.c_[c * p[:, 0] + s_ * p[:, 2], p[:, 1], -s_ * p[:, 0] + c * p[:, 2]]
    phase = np.arange(len(p)) * 2.399963
    return (turned + wander * np.c_[np.cos(0.3 * frame + phase), np.sin(0.3 * frame + phase), np.zeros(len(p))]).astype(
        np.float32)


def _animated_grid(quick: bool) -> list[dict]:
    return [{"refresh": k} for k in ((0, 4) if quick else (0, 1, 4, 16, 32))]


def _animated(params: dict, device: str, quick: bool) -> dict:
    """The paper's future work: a drifting cloud (1024 particles, 128 directions, one iteration
    a frame) with the visibility network re-peeled ``refresh`` directions a frame (0: all).
    Error: the frame's image against the same frame with the whole network rebuilt."""
    import time

    import numpy as np

    frames = 6 if quick else 48
    scene = network_scene(quick, 1024, 128)
    base = scene.media[0]
    runs = {}
    for k in sorted({0, params["refresh"]}):
        r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=1, tolerance=0.0,
                        refresh=k)
        r.render()
        for _ in range(20 if not quick else 2):  # settle the static cloud first
            r.touch("camera")
            r.render()
        images, ms, net = [], [], []
        for f in range(1, frames + 1):
            r.update(medium=dataclasses.replace(base, positions=drifting_cloud(base.positions, f)))
            t0 = time.perf_counter()
            frame = r.render()
            ms.append((time.perf_counter() - t0) * 1000.0)
            net.append(frame.stages["network"].ms)
            images.append(frame.image)
        runs[k] = (images, ms, net)
    images, ms, net = runs[params["refresh"]]
    full = runs[0][0]
    err = [wv.relative_rmse(a, b) for a, b in zip(images, full)]
    return {"first_frame_ms": 0.0, "median_ms": float(np.median(ms)), "spread_ms": [min(ms), max(ms)],
            "frames": frames, "stages": {}, "network_ms": float(np.median(net)), "error_per_frame": err,
            "mean_error": float(np.mean(err[frames // 4:])), "final_error": err[-1],
            "scene": "1024 particles, 128x128, turning 0.02 rad and wandering 0.02 a frame"}


# --- the papers' tables: runnable once their techniques land ------------------------------

def _row_fps(table: dict, params: dict):
    for row in table["rows"]:
        if all(row.get(k) == v for k, v in params.items() if k in row):
            return row["fps"]
    return None


# --- depth impostors (Umenhoffer & Szirmay-Kalos 2005) ----------------------------------------------------------

IMPOSTOR_SUN = {"type": "directional", "direction": [0.5, -0.8, -0.3], "irradiance": 2.0}


def impostor_scene(quick: bool, n: int = 8000, per_block: int = 200, width: int = 512, surface: bool = False,
                   seed: int = 3):
    """Umenhoffer & Szirmay-Kalos 2005's set-up: ``n`` particles built of n / per_block copies of one block (one
    particle a block: the paper's "no blocks"), one directional light. The block's radius
    scales as (per_block / n)^(1/3), so the cloud's volume and density stay put; particle
    radius 0.04 x (8000 / n)^(1/3), sigma_t 12 (sigma_t r = 0.48 at 8000), albedo 0.9, HG
    g = 0.3, a dim sky. ``surface``: a grey plane through the cloud's centre, facing the camera
    at an angle (an object in the cloud)."""
    if quick:
        n, per_block, width = min(n, 400), min(per_block, 20), min(width, 32)
    per_block = max(1, min(per_block, n))
    blocks = n // per_block
    radius = 0.04 * (8000 / n) ** (1 / 3)
    d = {"name": "impostor-cloud", "background": [0.05, 0.07, 0.1],
         "camera": {"origin": [0.0, 0.3, 4.2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40.0, "width": width,
                    "height": width},
         "lights": [IMPOSTOR_SUN],
         "media": [{"type": "particles", "radius": radius, "sigma_t": 12.0, "albedo": 0.9,
                    "phase": {"type": "hg", "g": 0.3},
                    "generator": {"kind": "blocks", "blocks": blocks, "per_block": per_block, "seed": seed,
                                  "extent": 1.0, "block_extent": (per_block / (blocks * per_block)) ** (1 / 3)}}]}
    if surface:
        d["surfaces"] = [{"type": "plane", "center": [0.0, 0.0, 0.0], "normal": [0.3, 0.2, 1.0], "size": [4.0, 4.0],
                          "diffuse": 0.5}]
    return wv.load_scene(d)


IMPOSTOR_FIG5_NOTE = """\
**Set-ups.** `setup=paper` is the paper's figure 5: one sun, a black sky, and the camera and
the sun moving every frame (the camera orbits 2 degrees and the sun turns 3 a frame), so the
camera impostors of the template (the b term) are made again every frame. `setup=ours` is our
default scene: a dim sky lights the cloud too (8 more light passes, one per sky direction, and
9 lights to shade each texel), the camera fixed (its impostors cached). Each set-up's FPS ratio
is to its own first row (no blocks).

**Stages.** *light*: the light pass, block by block where the cloud is built of blocks (one
light impostor per template and light, b work, splatted once per instance, N / b); *impostors*:
the template's camera impostor; *shade*: the light at every impostor texel (blocks) or particle
(no blocks); *gather*: every pixel composites the instances over it, nearest first.

**The paper's no-block row.** On the paper's GPU each particle on its own is a draw with a
read-back of its light from the light pass, so the per-particle cost is fixed overhead and
blocks remove it almost wholly (25x at 40 blocks). Here no stage has a per-particle overhead
of that kind: with no blocks a particle costs its shading (a few light-map reads) and its
pixels in the gather, and blocks save only the part of that work that is per particle, not
the pixels a block still covers. That is why our best ratio is smaller than the paper's.
"""


def _impostor_fig5_grid(quick: bool) -> list[dict]:
    blocks = (0, 20) if quick else (0, 1600, 800, 400, 40, 20)
    return [{"blocks": b, "setup": s} for s in ("paper", "ours") for b in blocks]


def _moving_frames(r: wv.Renderer, scene, repeats: int) -> dict:
    """``time_frames`` for the paper's animation: before every frame the camera orbits the
    cloud by 2 degrees and the sun turns by 3 (and the medium is marked changed), so every
    stage runs, the camera impostors (the b term) included."""
    cam, sun = scene.camera, dict(IMPOSTOR_SUN)
    frame_no = [0]

    def move():
        frame_no[0] += 1
        a, b = np.radians(2.0 * frame_no[0]), np.radians(3.0 * frame_no[0])
        o = np.asarray(cam.origin, float)
        origin = [o[0] * np.cos(a) + o[2] * np.sin(a), o[1], -o[0] * np.sin(a) + o[2] * np.cos(a)]
        d = np.asarray(sun["direction"], float)
        direction = [d[0] * np.cos(b) - d[2] * np.sin(b), d[1], d[0] * np.sin(b) + d[2] * np.cos(b)]
        r.update(camera=dataclasses.replace(cam, origin=tuple(origin)), lights=[{**sun, "direction": direction}])
        r.touch("medium")

    return time_frames(r, repeats, invalidate=None, before=move)


def _impostor_frame(params: dict, device: str, quick: bool) -> dict:
    """A frame of an animated cloud, 512x512; blocks = 0: every particle on its own.
    ``setup`` "paper": the paper's figure 5, a single sun and a black sky, the camera and
    the sun moving every frame; "ours" (and the N sweep): our defaults, a dim sky (8 sky
    directions, each its own light pass), the medium and the lights marked changed every
    frame and the camera fixed (the camera impostors cached)."""
    n = params.get("particles", 8000)
    blocks = params.get("blocks")
    per_block = params.get("per_block") or (1 if not blocks else n // blocks)
    scene = impostor_scene(quick, n, per_block, params.get("width", 512))
    paper = params.get("setup") == "paper"
    if paper:
        scene = dataclasses.replace(scene, background=(0.0, 0.0, 0.0))
    r = wv.Renderer(scene, technique="depth_impostors", device=device)
    repeats = 2 if quick else 8
    row = _moving_frames(r, scene, repeats) if paper else time_frames(r, repeats, invalidate=("medium", "lights"))
    d = r.diagnostics()
    row.update(instances=d["instances"], per_block=per_block, light_texels=d["light_texels"],
               light_template_texels=d["light_template_texels"],
               scene=f"{len(scene.media[0].positions)} particles, {d['instances']} instances of {per_block}, "
                     f"{scene.camera.width}x{scene.camera.height}, "
                     + ("one sun, black sky, camera and sun moving" if paper else "one sun and a dim sky, camera fixed"))
    return row


def _impostor_sweep_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"particles": 400, "per_block": b} for b in (1, 20)]
    return [{"particles": n, "per_block": b} for n in (1000, 8000, 64000) for b in (1, 5, 20, 50, 200, 1000) if b <= n]


def _impostor_accuracy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"light": "slices", "terms": 4, "res": 8}, {"light": "exact", "terms": 0, "res": 8}]
    return ([{"light": "slices", "terms": s, "res": 16} for s in (1, 2, 4, 8, 16, 32)]
            + [{"light": "slices", "terms": 4, "res": r} for r in (4, 8, 32, 64)]
            + [{"light": "fourier", "terms": k, "res": 16} for k in (2, 4, 8, 16)]
            + [{"light": "exact", "terms": 0, "res": r} for r in (16, 64)]
            + [{"light": "slices", "terms": 4, "res": 16, "sky": k} for k in (0, 1, 4, 16, 64)]
            + [{"light": "slices", "terms": 4, "res": 16, "widen": w} for w in (0.5, 1.0, 2.0, 4.0)])


def _impostor_settings(params: dict) -> dict:
    kind = {"exact": 0, "slices": 1, "fourier": 2}[params["light"]]
    out = {"light_pass": kind, "impostor_res": params["res"]}
    for key, setting in (("sky", "sky_samples"), ("widen", "widen")):
        if key in params:
            out[setting] = params[key]
    if kind == 1:
        out["slices"] = params["terms"]
    elif kind == 2:
        out["light_terms"] = params["terms"]
    return out


def _impostor_accuracy(params: dict, device: str, quick: bool) -> dict:
    """The image against the single-scattering reference at pixel centres, 2000 particles in
    40 blocks of 50 (96x96); and how much the technique leaves out: the single-scattering
    reference's mean over the multiple-scattering one's."""
    n, b, w = (400, 20, 24) if quick else (2000, 50, 96)
    scene = impostor_scene(quick, n, b, w)
    r = wv.Renderer(scene, technique="depth_impostors", device=device, **_impostor_settings(params))
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("medium", "lights"))
    spp = 16 if quick else 256
    ref = score(row, scene, device, spp)
    ms, _ = reference_image(scene, device, spp=spp, max_bounces=-1, pixel_area=0)
    image = row["frame"].image
    row["rel_rmse_multiple"] = wv.relative_rmse(image, ms)
    row["mean_ratio"] = float(image.mean() / ref.mean())
    row["single_of_multiple"] = float(ref.mean() / ms.mean())
    row["scene"] = f"{n} particles in {n // b} blocks of {b}, {w}x{w}, one sun"
    return row


def _plane_in_blocks(scene, centres: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """(H, W) mask of the pixels whose ray meets the scene's plane inside some block's
    bounding sphere (where depth impostors and billboards differ)."""
    cam, plane = scene.camera, scene.surfaces[0]
    o = np.asarray(cam.origin, float)
    f = np.asarray(cam.target, float) - o
    f /= np.linalg.norm(f)
    rgt = np.cross(f, cam.up)
    rgt /= np.linalg.norm(rgt)
    up = np.cross(rgt, f)
    th = np.tan(np.radians(cam.fov_y) / 2)
    px, py = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
    sx, sy = 2 * px / cam.width - 1, 1 - 2 * py / cam.height
    d = f + sx[..., None] * rgt * th * cam.width / cam.height + sy[..., None] * up * th
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    v = np.asarray(plane.vertices, float)
    n = np.cross(v[1] - v[0], v[2] - v[0])
    n /= np.linalg.norm(n)
    t_s = ((v[0] - o) @ n) / (d @ n)
    hit = o + t_s[..., None] * d
    dist = np.linalg.norm(hit[..., None, :] - np.asarray(centres, float)[None, None], axis=-1)
    return np.any(dist < np.asarray(reach, float)[None, None], axis=-1) & (t_s > 0)


def _impostor_objects_grid(quick: bool) -> list[dict]:
    return [{"object_depth": k, "per_block": b} for b in ((20,) if quick else (50, 200)) for k in (0, 1)]


def _impostor_objects(params: dict, device: str, quick: bool) -> dict:
    """Objects in clouds (section 2.4): a plane through the cloud; depth impostors (the block's
    opacity cut at the surface) against billboards (a block wholly in front or behind),
    both against the single-scattering reference, over the image and over the pixels where
    the plane lies inside the cloud (the reference's cloud changes there by over 2%)."""
    n, w = (400, 24) if quick else (2000, 96)
    b = params["per_block"]
    scene = impostor_scene(quick, n, b, w, surface=True)
    r = wv.Renderer(scene, technique="depth_impostors", device=device, object_depth=params["object_depth"],
                    light_pass=0)
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("medium", "lights"))
    ref = score(row, scene, device, 16 if quick else 256)
    image = row["frame"].image
    band = _plane_in_blocks(scene, r.diagnostics()["block_centres"], r.diagnostics()["block_reach"])
    row["band_pixels"] = int(band.sum())
    row["rel_rmse_band"] = wv.relative_rmse(image[band], ref[band]) if band.any() else float("nan")
    row["scene"] = (f"{n} particles in {n // b} blocks of {b}, a plane through the cloud, {w}x{w}; band: the "
                    f"{row['band_pixels']} pixels where the plane lies inside a block's bounding sphere")
    row["images"] = {"image": image}
    return row


# --- particle glow (the glowy-light paper) ----------------------------------------------------------------


def glow_scene(quick: bool, width: int = 320, height: int = 240):
    """The built-in dusty-lamp: a point lamp in dusty air (homogeneous, sigma_t 0.25, albedo
    0.9, isotropic), a floor, and a shade beside the lamp casting a shadow through the dust."""
    if quick:
        width, height = 32, 24
    return wv.load_scene("dusty-lamp", [f"camera.width={width}", f"camera.height={height}"])


def _glow_figure5_grid(quick: bool) -> list[dict]:
    sets = [(2.0, 0.1, 0), (0.0, 0.1, 0), (0.5, 0.5, 0), (0.5, 0.5, 1)]
    return [{"mu": m, "sigma": sg, "cdf": c} for m, sg, c in (sets[:2] if quick else sets)]


def _glow_figure5(params: dict, device: str, quick: bool) -> dict:
    """Figure 5's parameter sets (mu, sigma; A: 2, 0.1; B: 0, 0.1) and the defaults, with the
    log-normal CDF the text names (cdf 0) and the normal CDF equation 2 prints (cdf 1): the
    image, its frame time, the cells' mean density and the light the glow adds."""
    scene = glow_scene(quick)
    settings = {"mu": params["mu"], "sigma": params["sigma"], "density_cdf": params["cdf"]}
    r = wv.Renderer(scene, technique="particle_glow", device=device, **settings)
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("camera",))
    plain = wv.render(scene, technique="particle_glow", device=device, glow=0, **settings).image
    image = row["frame"].image
    row["table"] = {"mean density d": float(r.diagnostics()["density"].mean()),
                    "image mean": float(image.mean()),
                    "light the glow adds": f"{image.mean() / plain.mean() - 1:+.1%}"}
    row["images"] = {"image": image}
    row["scene"] = f"dusty-lamp {scene.camera.width}x{scene.camera.height}, 128 steps"
    return row


GLOW_TECHNIQUES = {"particle_glow": {}, "particle_glow (glow = 0)": {"glow": 0},
                   "particle_glow (specular 0.5)": {"specular": 0.5}, "raymarch": {"steps": 128},
                   "light_shafts": {"steps": 128, "block": 4}}


def _glow_physics_grid(quick: bool) -> list[dict]:
    names = list(GLOW_TECHNIQUES)
    return [{"technique": t} for t in (names[:2] if quick else names)]


def _glow_physics(params: dict, device: str, quick: bool) -> dict:
    """How far the glow is from physics: the same scene (its medium already homogeneous, with
    the dust's sigma_t and phase function) by the reference, single and multiple
    scattering, against particle_glow, its direct sample alone (glow = 0), raymarch and
    light_shafts at 128 steps."""
    name = params["technique"]
    scene = glow_scene(quick, 160, 120)
    r = wv.Renderer(scene, technique=name.split(" ")[0], device=device, **GLOW_TECHNIQUES[name])
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("camera",))
    spp = 16 if quick else 512
    score(row, scene, device, spp)
    ms, _ = reference_image(scene, device, spp=spp, max_bounces=-1, pixel_area=0)
    image = row["frame"].image
    row["rel_rmse_multiple"] = wv.relative_rmse(image, ms)
    row["mean_ratio"] = float(image.mean() / ms.mean())
    row["scene"] = f"dusty-lamp {scene.camera.width}x{scene.camera.height}"
    return row


def _glow_speed_grid(quick: bool) -> list[dict]:
    return [{"width": 64 if quick else 640}]


def _glow_speed(params: dict, device: str, quick: bool) -> dict:
    """particle_glow against the raymarch baseline with the same 128 steps on the same scene
    (dusty-lamp at 640x480, camera moving), frames timed in alternation so both see the same
    machine; the issue's bound: at most 1.5x."""
    w = params["width"]
    scene = glow_scene(False, w, w * 3 // 4)
    rs = {"particle_glow": wv.Renderer(scene, technique="particle_glow", device=device),
          "raymarch": wv.Renderer(scene, technique="raymarch", device=device, steps=128)}
    for r in rs.values():
        r.render()
    times = {k: [] for k in rs}
    for _ in range(2 if quick else 5):
        for k, r in rs.items():
            r.touch("camera")
            t = time.perf_counter()
            r.render()
            times[k].append(time.perf_counter() - t)
    glow, ray = (statistics.median(times[k]) * 1e3 for k in ("particle_glow", "raymarch"))
    row = time_frames(rs["particle_glow"], repeats=1, invalidate=("camera",))
    row["table"] = {"particle_glow ms": glow, "raymarch ms (128 steps)": ray, "glow / raymarch": f"{glow / ray:.2f}"}
    row["scene"] = f"dusty-lamp {w}x{w * 3 // 4}, 128 steps"
    return row


def _glow_stability_grid(quick: bool) -> list[dict]:
    steps = (0.005,) if quick else (0.005, 0.0005)
    return ([{"glow": 1, "anchor": a, "grain": g, "step": st} for a in (0, 1) for g in ("world", "screen")
             for st in steps] + [{"glow": 0, "anchor": 0, "grain": "world", "step": st} for st in steps])


def _moved_lamp(dx: float, move_scene: bool, width: int, height: int) -> dict:
    """dusty-lamp seen from a camera moved dx along x; ``move_scene``: the scene moved by -dx
    instead (the same picture of the lamp, but the grain textures, fixed in the world, now
    stay put on the screen: the counterfactual of screen-space grain)."""
    from warpvol.scene.procedural import dusty_lamp

    d = dusty_lamp()
    d["camera"]["width"], d["camera"]["height"] = width, height
    if move_scene:
        d["lights"][0]["position"][0] -= dx
        d["media"][0]["center"][0] -= dx
        for surface in d["surfaces"]:
            surface["center"][0] -= dx
    else:
        d["camera"]["origin"][0] += dx
        d["camera"]["target"][0] += dx
    return d


def _glow_stability(params: dict, device: str, quick: bool) -> dict:
    """Temporal stability: a camera moving ``step`` along x a frame (4 frames); the mean
    frame-to-frame change relative to the image's mean, and the fraction of pixels that pop
    (change by more than 10%). Grain that shimmers would leave a floor as step -> 0; grain
    that moves with the world changes in proportion to the motion (change / step constant).
    grain = screen: the counterfactual of grain fixed to the screen (the scene moved instead)."""
    w, h = (32, 24) if quick else (160, 120)
    frames = []
    for k in range(4):
        scene = _moved_lamp(params["step"] * k, params["grain"] == "screen", w, h)
        frames.append(wv.render(scene, technique="particle_glow", device=device, glow=params["glow"],
                                anchor=params["anchor"]).image.astype(np.float64).mean(-1))
    change = [np.abs(b - a).mean() / a.mean() for a, b in zip(frames, frames[1:])]
    pops = [np.mean(np.abs(b - a) > 0.1 * np.maximum(a, 1e-3)) for a, b in zip(frames, frames[1:])]
    r = wv.Renderer(_moved_lamp(0.0, False, w, h), technique="particle_glow", device=device, glow=params["glow"],
                    anchor=params["anchor"])
    row = time_frames(r, repeats=1, invalidate=("camera",))
    row["table"] = {"mean change": float(np.mean(change)), "change / step": float(np.mean(change) / params["step"]),
                    "pixels that pop (> 10%)": float(np.mean(pops))}
    row["scene"] = f"dusty-lamp {w}x{h}, camera moving along x"
    return row


# --- every technique on one front ---------------------------------------------------------------

# family -> a scene (built-in name or file) and its overrides
FRONT_FAMILIES = {"fog and occluders": ("fog-box", []), "haze under a sky": ("scenes/sunlit-haze.toml", []),
                  "thin haze": ("scenes/sunlit-haze.toml", ["media.0.sigma_t=0.15"]),
                  "thick haze": ("scenes/sunlit-haze.toml", ["media.0.sigma_t=5"]),
                  "light inside fog": ("point-in-fog", []), "grid": ("smoke-grid", []), "RBF": ("rbf-single", []),
                  "particles": ("particle-cloud", [])}
FRONT_LADDERS = {"reference": ("spp", (4, 16, 64, 256)), "raymarch": ("steps", (8, 32, 128)),
                 "light_shafts": ("steps", (16, 64, 256)), "rbf_propagation": ("grid", (10, 20, 40)),
                 "particle_glow": ("steps", (32, 128)), "illumination_network": ("directions", (32, 128)),
                 "depth_impostors": ("slices", (4, 16)), "mitsuba": ("spp", (4, 16, 64, 256))}
FRONT_SIZE = (64, 48)


def front_scene(family: str, quick: bool):
    w, h = (16, 12) if quick else FRONT_SIZE
    source, overrides = FRONT_FAMILIES[family]
    return wv.load_scene(source, [f"camera.width={w}", f"camera.height={h}", *overrides])


def _front_grid(quick: bool) -> list[dict]:
    """Every (family, technique, level) a technique can render: those whose Renderer accepts
    the scene (a technique refuses a medium it does not model); Mitsuba 3 (volpath, all orders)
    where it is installed and the scene has homogeneous media only (``to_mitsuba``), not in a
    quick sweep."""
    import importlib.util

    out = []
    for family in FRONT_FAMILIES:
        scene = front_scene(family, quick)
        for technique, (knob, levels) in FRONT_LADDERS.items():
            if technique == "mitsuba":
                if quick or importlib.util.find_spec("mitsuba") is None or \
                        any(m.type != "homogeneous" for m in scene.media):
                    continue
            else:
                try:
                    wv.Renderer(scene, technique=technique, device="cpu")
                except (wv.SettingsError, ValueError):
                    continue
            out += [{"family": family, "technique": technique, knob: v} for v in (levels[:1] if quick else levels)]
    return out


def _front(params: dict, device: str, quick: bool) -> dict:
    """One technique at one quality level against the physical answer (the reference, all
    orders of scattering, sky included; two seeds of 2048 spp): relative RMSE with the
    reference's noise removed, and the time of a whole frame (every stage run). Iterative
    techniques run to convergence in the frame (illumination_network: up to 2000 iterations).
    Mitsuba 3 (its llvm_ad_rgb variant where its LLVM loads, else scalar_rgb; a pixel-area
    box filter) against the reference over pixel areas, its time after a warm-up render."""
    family, technique = params["family"], params["technique"]
    knob = FRONT_LADDERS[technique][0]
    scene = front_scene(family, quick)
    if technique == "mitsuba":
        run = mitsuba_time(scene, params["spp"], image=True)
        frame = wv.Frame(run["image"], run["image"].shape[:2], f"mitsuba {run['variant']}", "cpu", {}, {}, [])
        row = {"first_frame_ms": None, "median_ms": 1000.0 * run["seconds"], "frames": 1, "stages": {},
               "frame": frame, "variant": run["variant"]}
        ref = score(row, scene, device, 16 if quick else 2048, max_bounces=-1, pixel_area=1)
        row["leaves_out"] = []
    else:
        settings = {knob: params[knob]}
        if technique == "illumination_network":  # converged in every timed frame, from zero each time
            settings.update(iterations=2000, warm=0)
        r = wv.Renderer(scene, technique=technique, device=device, **settings)
        row = time_frames(r, repeats=1 if quick else 2)
        ref = score(row, scene, device, 16 if quick else 2048, max_bounces=-1)
        row["leaves_out"] = row["frame"].leaves_out
    row["mean_ratio"] = float(row["frame"].image.mean() / ref.mean())
    row["media"] = sorted({m.type for m in scene.media})
    row["scene"] = f"{scene.name} {scene.camera.width}x{scene.camera.height}"
    return row


# --- the reference's own speed -----------------------------------------------------------------

SPEED_SCENES = ["fog-box", "point-in-fog", "smoke-grid", "rbf-single", "rbf-cornell", "rbf-thick-fog", "particle-cloud"]


def cumulus_scene(width: int = 80, height: int = 60):
    """A cumulus-like cloud of 400 spheres (radius 0.12, sigma_t 6 each, overlaps add, albedo
    0.9, isotropic) under a directional sun and a constant sky: issue 14's yardstick."""
    return wv.load_scene({
        "name": "cumulus-400", "background": [0.3, 0.4, 0.6],
        "camera": {"origin": [0, 0.3, 3.2], "target": [0, 0, 0], "fov_y": 45, "width": width, "height": height},
        "lights": [{"type": "directional", "direction": [0.4, -1, -0.3], "irradiance": 3.0}],
        "media": [{"type": "particles", "generator": {"kind": "cloud", "count": 400, "seed": 7}, "radius": 0.12,
                   "sigma_t": 6.0, "albedo": 0.9}]})


def _speed_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"scene": s, "spp": 4} for s in ("fog-box", "particle-cloud", "cumulus-400")]
    # rbf-thick-fog (1000 RBFs, 8 lights inside: ~200 paths/s) takes 2 spp, the cumulus issue 14's 4096
    return ([{"scene": s, "spp": 2 if s == "rbf-thick-fog" else 64} for s in SPEED_SCENES]
            + [{"scene": "cumulus-400", "spp": 4096}])


_MITSUBA_RUN = """
import pickle, sys, time
import numpy as np
import mitsuba as mi
from warpvol.scene import to_mitsuba
variant, scene, spp, keep = pickle.load(sys.stdin.buffer)
mi.set_variant(variant)
try:
    description = to_mitsuba(scene, spp=spp)
except ValueError:
    sys.exit(3)  # not a scene Mitsuba renders the same way
scene = mi.load_dict(description)
mi.render(scene, spp=1)  # JIT and set-up
t = time.perf_counter()
image = np.array(mi.render(scene, spp=spp))
seconds = time.perf_counter() - t
if keep:
    np.save(keep, image.astype(np.float32))
print(seconds, float(image.mean()))
"""


def mitsuba_time(scene, spp: int, image: bool = False) -> dict | None:
    """Mitsuba 3 volpath on the same scene and spp, in a child process (a variant whose LLVM
    does not fit the machine aborts the process): llvm_ad_rgb, else scalar_rgb. Seconds after
    a warm-up render, the image mean (and with ``image`` the image, H x W x 3) and the variant;
    None when Mitsuba is missing or cannot render the scene (``to_mitsuba`` exports homogeneous
    media only)."""
    import glob
    import importlib.util
    import os
    import pickle
    import subprocess
    import sys

    if importlib.util.find_spec("mitsuba") is None:
        return None
    env = dict(os.environ)
    if "DRJIT_LIBLLVM_PATH" not in env:  # Dr.Jit's LLVM backend needs a newer LLVM than Debian 12's 15
        found = sorted(glob.glob("/usr/lib/*/libLLVM-19.so") + glob.glob("/usr/lib/*/libLLVM-2[0-9].so"))
        if found:
            env["DRJIT_LIBLLVM_PATH"] = found[-1]
    import tempfile

    with tempfile.TemporaryDirectory(prefix="warpvol-mitsuba-") as tmp:
        keep = os.path.join(tmp, "image.npy") if image else ""
        for variant in ("llvm_ad_rgb", "scalar_rgb"):
            run = subprocess.run([sys.executable, "-c", _MITSUBA_RUN], input=pickle.dumps((variant, scene, spp, keep)),
                                 capture_output=True, timeout=3600, env=env)
            if run.returncode == 3:
                return None
            if run.returncode == 0:
                seconds, mean = (float(v) for v in run.stdout.split()[-2:])
                out = {"variant": variant, "seconds": seconds, "mean": mean}
                if image:
                    out["image"] = np.load(keep)
                return out
    return None


def _speed(params: dict, device: str, quick: bool) -> dict:
    """Camera paths per second of the reference (all orders of scattering, pixel area), after a
    1-spp frame that compiles and uploads; RGB extinction traces each channel on its own, so a
    pixel sample there is three paths. Mitsuba's time where it can render the scene."""
    import time

    from warpvol import device as dev

    width, height = (32, 24) if quick else (80, 60) if params["scene"] == "cumulus-400" else (160, 120)
    if params["scene"] == "cumulus-400":
        scene = cumulus_scene(width, height)
    else:
        scene = wv.load_scene(params["scene"], [f"camera.width={width}", f"camera.height={height}"])
    r = wv.Renderer(scene, technique="reference", device=device, spp=1)
    first = time.perf_counter()
    r.render()
    first_ms = 1000.0 * (time.perf_counter() - first)
    r.update(settings={"spp": params["spp"]})
    start = time.perf_counter()
    frame = r.render()
    seconds = time.perf_counter() - start
    grey = r.diagnostics()["grey"]  # the reference's own rule for one launch or three
    paths = width * height * params["spp"] * (1 if grey else 3)
    cores = dev.threads() if device == "cpu" else 1
    row = {"frames": 1, "first_frame_ms": first_ms, "median_ms": 1000.0 * seconds, "seconds": seconds,
           "paths": paths, "paths_per_s": paths / seconds, "paths_per_s_per_core": paths / seconds / cores,
           "cores": cores, "mean": float(frame.image.mean()), "scene": f"{scene.name} {width}x{height}"}
    row["mitsuba"] = mitsuba_time(scene, params["spp"])
    return row


SWEEPS: dict[str, Sweep] = {s.name: s for s in [
    Sweep("depth-impostors", "Umenhoffer & Szirmay-Kalos 2005 figure 5: 8000 particles under one directional light, no blocks and 1600, "
          "800, 400, 40, 20 blocks; a frame of an animated cloud under a moving light at 512x512",
          "depth_impostors", "paper", _impostor_fig5_grid, _impostor_frame, paper=("depth_impostors",),
          figure=_row_fps, issue=15, note=IMPOSTOR_FIG5_NOTE),
    Sweep("depth-impostors-sweep", "depth_impostors over N (1000, 8000, 64000 particles) and the block size "
          "(1..1000 particles a block): where the fastest block size lies as N grows",
          "depth_impostors", "paper", _impostor_sweep_grid, _impostor_frame, issue=15),
    Sweep("depth-impostors-accuracy", "depth_impostors against the single-scattering reference: light-pass slices "
          "S = 1..32, impostor resolution 4..64, Fourier terms K = 2..16, the exact light, sky directions 0..64 and the "
          "forward-scattering widening 0.5..4 radii (also against the multiple-scattering reference)",
          "depth_impostors", "accuracy", _impostor_accuracy_grid, _impostor_accuracy, issue=15),
    Sweep("depth-impostors-objects", "objects in clouds (Umenhoffer & Szirmay-Kalos 2005 section 2.4): a plane through the cloud, depth "
          "impostors against billboards, both against the single-scattering reference",
          "depth_impostors", "accuracy", _impostor_objects_grid, _impostor_objects, issue=15),
    Sweep("particle-glow-figure5", "particle_glow: the glowy-light paper figure 5's density distributions (mu, sigma; A: 2, "
          "0.1; B: 0, 0.1), the defaults (0.5, 0.5), log-normal (cdf 0, the text) and normal (cdf 1, equation 2 as "
          "printed) CDFs, dusty-lamp 320x240", "particle_glow", "table", _glow_figure5_grid, _glow_figure5, issue=16),
    Sweep("particle-glow-physics", "particle_glow against the reference on the same homogeneous medium (single and "
          "multiple scattering), beside its direct sample alone, raymarch and light_shafts, dusty-lamp 160x120",
          "particle_glow", "accuracy", _glow_physics_grid, _glow_physics, issue=16),
    Sweep("particle-glow-speed", "particle_glow against the raymarch baseline, 128 steps each, dusty-lamp 640x480, "
          "timed in alternation (the issue's bound: 1.5x)", "particle_glow", "table", _glow_speed_grid, _glow_speed,
          issue=16),
    Sweep("particle-glow-stability", "particle_glow: the frame-to-frame change of a slowly moving camera's image, "
          "the grain fixed in the world (as built) against grain that moves with the screen, and without the glow",
          "particle_glow", "table", _glow_stability_grid, _glow_stability, issue=16),
    Sweep("accuracy-vs-time", "every technique that can render a scene family, at a ladder of its quality knob, "
          "against the physical answer (the reference, all orders of scattering, sky included): relative RMSE "
          "against ms per frame, 64x48; Mitsuba 3's volpath (llvm_ad_rgb) beside them where it can export the scene "
          "(homogeneous media)", "reference", "front", _front_grid, _front, issue=17),
    Sweep("raymarch-accuracy", "raymarch: relative RMSE against the single-scattering reference vs ms per frame, "
          "sweeping steps (= shadow_steps) and the baked light-volume size (0 = marched shadow rays)",
          "raymarch", "accuracy", _raymarch_grid, _raymarch_accuracy),
    Sweep("pipeline-overhead", "the pipeline's bookkeeping per frame (stage cache checks, timing, the Frame)",
          "raymarch", "overhead", _overhead_grid, _overhead),
    Sweep("light-shafts", "Tóth & Umenhoffer 2009 section 5: no scattering / scattering / scattering + interleaved (N = 64, "
          "M = 4), colonnade-shafts 800x600, camera and light moving (shadow maps, surface pass, march, block sums "
          "every frame; the BVH of the static geometry cached)",
          "light_shafts", "paper", _shafts_table_grid, _shafts_frame, paper=("light_shafts",),
          figure=_shafts_paper_fps, issue=4),
    Sweep("light-shafts-sweep", "light_shafts frame time over N (steps), M (block) and shadow-map resolution, "
          "colonnade-shafts 800x600, camera and light moving",
          "light_shafts", "paper", _shafts_sweep_grid, _shafts_frame, issue=4),
    Sweep("light-shafts-speedup", "light_shafts: the march stage's speed-up from M x M interleaving over the same N "
          "without it, both timed in alternation (target >= 0.7 M^2), colonnade-shafts 800x600",
          "light_shafts", "speedup", _shafts_speedup_grid, _shafts_speedup, issue=4),
    Sweep("light-shafts-edges", "light_shafts: the error interleaving leaves at depth discontinuities (mean |interleaved"
          " - per-pixel N = 64| / mean, near depth jumps and elsewhere), with the paper's block sum (edges = 0) and the "
          "depth-aware one (edges = 1), colonnade-shafts 800x600",
          "light_shafts", "edges", _shafts_edges_grid, _shafts_edges, issue=4),
    Sweep("light-shafts-accuracy", "light_shafts: relative RMSE against the single-scattering reference (and the "
          "1024-step raymarch with exact shadow rays) vs ms per frame, over N, M and shadow-map resolution, "
          "colonnade-shafts 320x240",
          "light_shafts", "accuracy", _shafts_accuracy_grid, _shafts_accuracy, issue=4),
    Sweep("rbf-table2", "Giroud & Biri 2011 Table 2: grid 15..40, 1 light precomputed (P: only the march runs) and 1/2/4/8 "
          "dynamic lights (medium and lights change every frame), rbf-thick-fog's 1000 RBFs, 800x600",
          "rbf_propagation", "paper", _table2_grid, _table2, paper=("rbf_propagation", "table2"),
          figure=_table2_fps, issue=5),
    Sweep("rbf-table3", "Giroud & Biri 2011 Table 3: 1..27 000 RBFs at grid 20, one light, dynamic (all stages) and static "
          "(only the march), 800x600",
          "rbf_propagation", "paper", _table3_grid, _table3, paper=("rbf_propagation", "table3"),
          figure=_table3_fps, issue=5),
    Sweep("rbf-propagation-rules", "Giroud & Biri 2011 equation 6 as printed (rule 0) and corrected (rule 1), wavefront or "
          "whole-grid sweeps, against optical depth marched from each cell centre to each light (rbf-cornell)",
          "rbf_propagation", "rules", _rules_grid, _rules, issue=5),
    Sweep("rbf-scaling", "rbf_propagation: propagation time against cells x sweeps and march time against pixels x "
          "steps, with the fitted exponents",
          "rbf_propagation", "scaling", _scaling_grid, _scaling, issue=5),
    Sweep("rbf-accuracy", "rbf_propagation: relative RMSE against the single-scattering reference vs ms per frame, "
          "over grid size and march steps, rbf-cornell 80x60",
          "rbf_propagation", "accuracy", _rbf_accuracy_grid, _rbf_accuracy, issue=5),
    Sweep("illumination-network", "Szirmay-Kalos et al. 2005 section 4: 1024 and 512 particles at 128 directions, one iteration "
          "per frame, lights and camera moving, 512x512 (direct light, emission, one iteration, splat)",
          "illumination_network", "paper", _network_table_grid, _network_frame, paper=("illumination_network",),
          figure=_row_fps, issue=6),
    Sweep("illumination-network-sweep", "illumination_network over N (256..16384 particles) and D (32..512 "
          "directions), window by the paper's rule unless given: frame, one iteration (with its multiply-add rate) "
          "and the visibility-network build",
          "illumination_network", "paper", _network_sweep_grid, _network_frame, issue=6),
    Sweep("illumination-network-convergence", "Szirmay-Kalos et al. 2005 figure 6: change per iteration and error to the converged "
          "solution, iterating from zero, 1024 particles, 128 directions, albedo 0.9 and 0.99, the window by the "
          "paper's rule (window=0, M = 63) and M = 16",
          "illumination_network", "convergence", _convergence_grid, _convergence, issue=6),
    Sweep("illumination-network-accuracy", "illumination_network: converged image against the multiple-scattering "
          "reference vs ms per frame (lights moving), over N, D and the window M, 48x48",
          "illumination_network", "accuracy", _network_accuracy_grid, _network_accuracy, issue=6),
    Sweep("illumination-network-animated", "beyond Szirmay-Kalos et al. 2005: a drifting cloud with the visibility network "
          "re-peeled k directions a frame (0: all), error against the full rebuild per frame and frame time",
          "illumination_network", "animated", _animated_grid, _animated, issue=6),
    Sweep("illumination-network-lightpass", "the shared light pass (media/lightpass.py) in illumination_network: "
          "exact transmittance (BVH) at 4, 16, 64 points a sphere, depth slices S = 4..64 and Fourier terms "
          "K = 4..32 at 16 points; the direct light per particle against the exact sphere mean, and the image",
          "illumination_network", "lightpass", _lightpass_grid, _lightpass_accuracy, issue=20),
    Sweep("illumination-network-lightpass-scaling", "the shared light pass as particles get finer (1024..8192 "
          "particles, radius ~ n^(-1/3), sigma_t r fixed, both suns turning 3 degrees a frame): the direct stage's ms "
          "and the map it ended at (texels, refinements, error, fallback to exact)",
          "illumination_network", "table", _lightpass_scaling_grid, _lightpass_scaling),
    Sweep("illumination-network-albedo", "Szirmay-Kalos et al. 2005's bound: the error of one step eps grows to at most "
          "eps / (1 - a); single- and multiple-scattering RMSE against the reference at albedo 0.5, 0.8, 0.95",
          "illumination_network", "bound", _albedo_grid, _albedo_bound, issue=6),
    Sweep("reference-speed", "the reference path tracer: camera paths per second (and per core) on the built-in "
          "scenes at 160x120, 64 spp, and a 400-sphere cumulus at 80x60, 4096 spp, all orders of scattering; "
          "Mitsuba 3 volpath timed on the same scene where it can render it",
          "reference", "speed", _speed_grid, _speed, issue=14),
]}
