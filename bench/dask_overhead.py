"""What running a sweep's points on Dask costs a point, against the in-process loop.

    python -m bench.dask_overhead [--points 4] [--seconds 1.0] [--repeats 10] [--out results/dask-overhead]

Each point is a reference render of fog-box whose samples are chosen to take about
``--seconds`` here. The same points go through ``run_sweep`` twice a repeat, alternating: in
this process (``executor=None``, today's loop) and as tasks on a ``LocalCluster`` of one
worker process with one thread (``warpvol.cluster.connect``, as ``bench --workers 1``), whose
Warp launches use every core as the in-process ones do. Both ways are warmed up first by one
point (Warp's module loads); the cluster's start is timed apart. The overhead of a point is
(Dask wall time - in-process wall time) / points; on a machine that others share, the points'
own times wander more than that, so the time a point spends outside its render (wall time
minus the points' own measured times, over points) is compared too: what the harness and Dask
add around the work. The round trip of an empty task is timed on its own. Writes ``<out>/cpu.json`` (the numbers, the command, the machine) and its README.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import distributed
import warp as wp

import warpvol as wv
from warpvol import cluster

from .fingerprint import probe
from .harness import cpu_name, git_commit, run_sweep
from .sweeps import Sweep

SCENE = ("fog-box", ["camera.width=48", "camera.height=36"])


def _render_seconds(spp: int) -> float:
    t0 = time.perf_counter()
    wv.render(wv.load_scene(*SCENE), "reference", "cpu", spp=spp, seed=1)
    return time.perf_counter() - t0


def _measure(params: dict, device: str, quick: bool) -> dict:
    """One point: a reference render of ``params["spp"]`` samples (seed = the point's index)."""
    t0 = time.perf_counter()
    wv.render(wv.load_scene(*SCENE), "reference", device, spp=params["spp"], seed=params["i"])
    seconds = time.perf_counter() - t0
    return {"median_ms": 1000.0 * seconds, "spread_ms": [1000.0 * seconds] * 2, "frames": 1}


def _noop() -> None:
    return None


def _sweep(points: int, spp: int) -> Sweep:
    return Sweep("dask-overhead", f"{points} reference renders of {SCENE[0]} 48x36 at {spp} spp", "reference",
                 "overhead", lambda quick: [{"i": i, "spp": spp} for i in range(points)], _measure)


def _timed_sweep(sweep: Sweep, executor) -> tuple[float, float]:
    """Wall seconds of a whole sweep from nothing, and the seconds its points measured inside."""
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        path = run_sweep(sweep, "cpu", Path(out), executor=executor, progress=False)
        wall = time.perf_counter() - t0
        rows = json.loads(path.read_text())["rows"]
    return wall, sum(r["median_ms"] for r in rows) / 1000.0


def measure(points: int, seconds: float, repeats: int) -> dict:
    _render_seconds(4)  # Warp's module load, out of every number below
    spp = max(1, round(64 * seconds / statistics.median(_render_seconds(64) for _ in range(3))))
    sweep = _sweep(points, spp)
    t0 = time.perf_counter()
    with cluster.connect(workers=1) as client:
        start_s = time.perf_counter() - t0
        executor = client.get_executor(pure=False)
        first_point_s = _timed_sweep(_sweep(1, spp), executor)[0]  # the worker's imports, module load, a point
        empty = []
        for _ in range(50):
            t0 = time.perf_counter()
            client.submit(_noop, pure=False).result()
            empty.append(time.perf_counter() - t0)
        runs = []
        for _ in range(repeats):
            local_s, local_work = _timed_sweep(sweep, None)
            dask_s, dask_work = _timed_sweep(sweep, executor)
            local_out, dask_out = 1000.0 * (local_s - local_work) / points, 1000.0 * (dask_s - dask_work) / points
            runs.append({"local_s": round(local_s, 3), "dask_s": round(dask_s, 3),
                         "local_point_s": round(local_work / points, 3), "dask_point_s": round(dask_work / points, 3),
                         "overhead_per_point_ms": round(1000.0 * (dask_s - local_s) / points, 1),
                         "overhead_pct": round(100.0 * (dask_s - local_s) / local_s, 2),
                         "local_outside_ms": round(local_out, 1), "dask_outside_ms": round(dask_out, 1),
                         "outside_overhead_ms": round(dask_out - local_out, 1),
                         "outside_overhead_pct": round(100.0 * (dask_out - local_out) / (1000.0 * local_work / points),
                                                       2)})
    return {"points": points, "spp": spp, "scene": f"{SCENE[0]} 48x36, reference", "repeats": runs,
            "median_overhead_per_point_ms": statistics.median(r["overhead_per_point_ms"] for r in runs),
            "median_overhead_pct": statistics.median(r["overhead_pct"] for r in runs),
            "median_outside_overhead_ms": statistics.median(r["outside_overhead_ms"] for r in runs),
            "median_outside_overhead_pct": statistics.median(r["outside_overhead_pct"] for r in runs),
            "cluster_start_s": round(start_s, 2), "first_point_on_worker_s": round(first_point_s, 2),
            "empty_task_round_trip_ms": round(1000.0 * statistics.median(empty), 2)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.dask_overhead", description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=4)
    parser.add_argument("--seconds", type=float, default=1.0, help="about how long a point takes (default 1)")
    parser.add_argument("--repeats", type=int, default=10, help="alternations of the two ways (default 10)")
    parser.add_argument("--out", default="results/dask-overhead")
    args = parser.parse_args(argv)
    doc = {"command": " ".join(["python -m bench.dask_overhead", *(argv if argv is not None else sys.argv[1:])]),
           "machine": {"cpu": cpu_name(), "cores": os.cpu_count(), "python": platform.python_version(),
                       "load_average_before": [round(x, 2) for x in os.getloadavg()]},
           "warp": wp.config.version, "distributed": distributed.__version__, "commit": git_commit(),
           "measured": time.strftime("%Y-%m-%d %H:%M:%S"),
           **measure(args.points, args.seconds, args.repeats)}
    doc["machine"]["load_average_after"] = [round(x, 2) for x in os.getloadavg()]
    # what each point rendered, for bench report --stale: the scene and settings, with its probe
    point = {"scene": SCENE[0], "technique": "reference", "params": {"technique": "reference", "spp": doc["spp"]}}
    doc["rows"] = [{**point, "probe": probe(point)}]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cpu.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "README.md").write_text(readme(doc))
    print(f"dask-overhead: {doc['median_overhead_per_point_ms']:.1f} ms a point by wall time "
          f"({doc['median_overhead_pct']:.2f} %), {doc['median_outside_overhead_ms']:.1f} ms outside the points "
          f"({doc['median_outside_overhead_pct']:.2f} %) -> {out / 'cpu.json'}")
    return 0


def readme(doc: dict) -> str:
    m = doc["machine"]
    lines = [
        "# dask-overhead: a sweep's points on Dask against the in-process loop", "",
        f"{doc['points']} points, each a {doc['scene']} render at {doc['spp']} spp, through `run_sweep`: in "
        "process, and as tasks on a LocalCluster of one worker process with one thread (`bench --workers 1`); "
        "both warmed up first. Overhead = (Dask wall - in-process wall) / points. Outside = (wall - the points' own "
        "measured render times) / points: what the harness (and Dask) add around a point, less disturbed by other "
        "work on the machine than the renders themselves. Written by `python -m bench.dask_overhead` into "
        "`cpu.json` and this page.", "",
        f"Command: `{doc['command'].strip()}`  ", f"Machine: {m['cpu']}, {m['cores']} cores, Python {m['python']}, "
        f"load average {m['load_average_before'][0]} before and {m['load_average_after'][0]} after (other work on "
        f"the machine)  ", f"Warp {doc['warp']}, distributed {doc['distributed']}, commit {doc['commit']}, "
        f"{doc['measured']}", "",
        "| repeat | in-process s | Dask s | point s (in-process / Dask) | overhead ms a point | overhead % "
        "| outside ms a point (in-process / Dask) | outside overhead ms | % of a point |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(doc["repeats"], 1):
        lines.append(f"| {i} | {r['local_s']:.2f} | {r['dask_s']:.2f} | {r['local_point_s']:.3f} / "
                     f"{r['dask_point_s']:.3f} | {r['overhead_per_point_ms']:.1f} | {r['overhead_pct']:.2f} | "
                     f"{r['local_outside_ms']:.1f} / {r['dask_outside_ms']:.1f} | {r['outside_overhead_ms']:.1f} | "
                     f"{r['outside_overhead_pct']:.2f} |")
    lines += ["", f"Median: {doc['median_overhead_per_point_ms']:.1f} ms a point by wall time, "
              f"{doc['median_overhead_pct']:.2f} % of the in-process time; outside the points "
              f"{doc['median_outside_overhead_ms']:.1f} ms a point, {doc['median_outside_overhead_pct']:.2f} % "
              "of a point.", "",
              f"Once per run, not in the table: starting the cluster {doc['cluster_start_s']:.2f} s; the worker's "
              f"first point (its imports and Warp's module load, then the point) {doc['first_point_on_worker_s']:.2f} s. "
              f"An empty task's round trip: {doc['empty_task_round_trip_ms']:.2f} ms (median of 50).", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
