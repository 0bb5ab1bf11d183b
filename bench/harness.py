"""The sweep runner: measure each point of a sweep, write each row as soon as it is measured.

A sweep is a list of independent points (parameter dicts). ``run_sweep`` measures the
points that ``results/<sweep>/<device>.json`` does not hold yet (so an interrupted run
resumes), shows a progress bar with ETA, and rewrites the file after every row (atomically:
a reader sees the old file or the new one, never half of one). Points can be handed to any
``concurrent.futures.Executor`` (``measure_point`` is a top-level function of picklable
arguments: a ``Sweep`` holds top-level functions), so a cluster can run them: ``python -m
warpvol bench SWEEP --workers N | --scheduler tcp://HOST:8786`` hands them to Dask
(``warpvol.cluster``), and each row names the device and the host that measured it.
The runner knows sweeps only through the object it is given; ``sweeps`` imports it, not the
other way round.

Frame times exclude JIT compilation and warm-up: the first frame is timed apart
(``first_frame_ms``); then ``repeats`` frames are timed with every scene part marked
changed, so every stage the scene calls for runs. Each row records the median and the
spread (min..max) over those frames, the per-stage medians, and the peak memory.
"""

from __future__ import annotations

import ctypes
import gc
import hashlib
import json
import os
import platform
import re
import socket
import statistics
import subprocess
import time
import uuid
from dataclasses import fields, is_dataclass
from pathlib import Path

import numpy as np
import warp as wp
from tqdm import tqdm

import warpvol as wv
from warpvol import device as dev
from .fingerprint import probe

REPO = Path(__file__).resolve().parent.parent
CACHE = Path(os.environ.get("WARPVOL_CACHE", Path.home() / ".cache" / "warpvol"))


def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def device_name(device: str) -> str:
    """What the row ran on, in words: the GPU's name, or the CPU model and its cores."""
    if device.startswith("cuda"):
        return wp.get_device(device).name
    return f"{cpu_name()}, {os.cpu_count()} cores"


def device_slug(device: str | None) -> str:
    """File name for a device's rows: ``cpu``, or the GPU's name (``nvidia-h200``); for None,
    the device this process picks (``warpvol.device.pick``: a cluster's worker its own)."""
    device = dev.pick(device)
    if not device.startswith("cuda"):
        return "cpu"
    name = wp.get_device(device).name.lower().replace("geforce ", "")
    return re.sub(r"[^a-z0-9]+", "-", name).strip("-")


def git_commit() -> str:
    try:  # a cluster's worker may run an installed copy, without git
        r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=REPO)
    except OSError:
        return "unknown"
    return r.stdout.strip() or "unknown"


def write_atomic(path: Path, write) -> None:
    """Write ``path`` through ``write(binary file)`` into a temporary file beside it, then
    rename that over ``path``: a reader (a resumed run, another worker sharing a cache) sees
    the old file or the whole new one, and an interrupted write leaves no half file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    try:
        with open(tmp, "xb") as fh:
            write(fh)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


class PeakMemory:
    """Peak memory while the block runs, in MB above what was in use when it started.

    CPU: the process's resident-set high-water mark (reset through /proc/self/clear_refs),
    after freed memory is returned to the system (``malloc_trim``).
    CUDA: Warp's memory-pool high-water mark; it cannot be reset, so a block that stays
    below an earlier peak reports its own allocations at the end instead.
    """

    def __init__(self, device: str):
        self.device = device
        self.mb = 0.0

    @staticmethod
    def _status(key: str) -> float:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key):
                    return float(line.split()[1]) / 1024.0
        return 0.0

    def __enter__(self):
        if self.device.startswith("cuda"):
            self.base = wp.get_mempool_used_mem_current(self.device) / 2**20
            self.high = wp.get_mempool_used_mem_high(self.device) / 2**20
        else:
            # hand what earlier rows freed back to the system first: otherwise a row reuses it and
            # its resident set never rises above the baseline (every row after the first read 0)
            gc.collect()
            try:
                ctypes.CDLL("libc.so.6").malloc_trim(0)
            except (OSError, AttributeError):
                pass
            try:
                with open("/proc/self/clear_refs", "w") as fh:
                    fh.write("5")
            except OSError:
                pass
            self.base = self._status("VmRSS:")
        return self

    def __exit__(self, *exc):
        if self.device.startswith("cuda"):
            high = wp.get_mempool_used_mem_high(self.device) / 2**20
            now = wp.get_mempool_used_mem_current(self.device) / 2**20
            self.mb = (high if high > self.high else now) - self.base
        else:
            self.mb = self._status("VmHWM:") - self.base
        self.mb = max(self.mb, 0.0)


def time_frames(renderer: wv.Renderer, repeats: int, invalidate: tuple[str, ...] | None = (),
                before=None) -> dict:
    """Time ``repeats`` frames after a warm-up frame.

    ``invalidate``: scene parts marked changed before each frame (``()``: all parts, so every
    stage the scene calls for runs; ``None``: none, as for a static scene). ``before``: a
    callable run before each timed frame, untimed (an animation's update).
    """
    t0 = time.perf_counter()
    renderer.render()
    first = time.perf_counter() - t0
    times, stages = [], []
    for _ in range(repeats):
        if invalidate is not None:
            renderer.touch(*invalidate)
        if before is not None:
            before()
        t = time.perf_counter()
        frame = renderer.render()
        times.append(time.perf_counter() - t)
        stages.append(frame.stages)
    return {
        "first_frame_ms": first * 1000.0,
        "median_ms": statistics.median(times) * 1000.0,
        "spread_ms": [min(times) * 1000.0, max(times) * 1000.0],
        "frames": repeats,
        "stages": {name: {"status": stages[-1][name].status,
                          "median_ms": statistics.median(s[name].ms for s in stages)} for name in stages[-1]},
        "frame": frame,
    }


def digest(obj) -> str:
    """A stable hash of a scene (dataclasses, tuples, numpy arrays) and settings."""
    h = hashlib.sha256()

    def feed(x):
        if is_dataclass(x):
            h.update(type(x).__name__.encode())
            for f in fields(x):
                if f.name != "source":
                    h.update(f.name.encode())
                    feed(getattr(x, f.name))
        elif isinstance(x, np.ndarray):
            h.update(str(x.dtype).encode() + str(x.shape).encode())
            h.update(np.ascontiguousarray(x).tobytes())
        elif isinstance(x, dict):
            for k in sorted(x):
                h.update(str(k).encode())
                feed(x[k])
        elif isinstance(x, (list, tuple)):
            h.update(b"[")
            for v in x:
                feed(v)
            h.update(b"]")
        else:
            h.update(repr(x).encode())

    feed(obj)
    return h.hexdigest()[:16]


#: Bumped when the reference's estimator changes, so cached images from an older one are not
#: reused: 2 = free flight by superposition, independent forked random streams and Russian
#: roulette capped at 0.995 (same means, other noise).
REFERENCE_VERSION = 6  # 6: continuations aimed at the lamps (same means, other noise); 3: single scattering includes the sky's light; 4: the floor in relative_rmse's measure; 5: shadow rays at concave edges


def _reference_path(scene, settings: dict) -> Path:
    """Where ``reference_image`` keeps ``scene`` (loaded) rendered with ``settings``."""
    return CACHE / "reference" / f"{scene.name}-{digest([scene, settings, REFERENCE_VERSION])}.npz"


def reference_cached(scene, **settings) -> bool:
    """Whether ``reference_image`` of ``scene`` with these settings is on disk already."""
    return _reference_path(wv.load_scene(scene), settings).exists()


def reference_image(scene, device: str, **settings) -> tuple[np.ndarray, float]:
    """The reference rendering of ``scene`` (mean of two seeds) and its own relative RMSE.

    Cached on disk under $WARPVOL_CACHE (default ~/.cache/warpvol), keyed by the scene and
    the settings, so a sweep renders it once. The noise floor is estimated from the two
    seeds: per pixel the mean's standard error is |a - b| / 2.
    """
    scene = wv.load_scene(scene)
    path = _reference_path(scene, settings)
    if path.exists():
        data = np.load(path)
        return data["image"], float(data["floor"])
    a = wv.render(scene, technique="reference", device=device, progress=True, seed=1, **settings).image
    b = wv.render(scene, technique="reference", device=device, progress=True, seed=2, **settings).image
    image = 0.5 * (a.astype(np.float64) + b)
    se = np.abs(a.astype(np.float64) - b) / 2.0
    floor = wv.relative_rmse(image + se, image)  # in the measure the floor is taken out of
    write_atomic(path, lambda fh: np.savez_compressed(fh, image=image.astype(np.float32), floor=floor))
    return image.astype(np.float32), floor


def baseline_image(scene, technique: str, device: str, **settings) -> np.ndarray:
    """A deterministic technique's image (e.g. a finely stepped raymarch), cached on disk like
    ``reference_image``."""
    scene = wv.load_scene(scene)
    path = CACHE / technique / f"{scene.name}-{digest([scene, settings])}.npy"
    if path.exists():
        return np.load(path)
    image = wv.render(scene, technique=technique, device=device, progress=True, **settings).image
    write_atomic(path, lambda fh: np.save(fh, image))
    return image


def row_key(params: dict) -> str:
    return json.dumps(params, sort_keys=True)


def results_path(out: Path, sweep: str, slug: str, quick: bool) -> Path:
    return Path(out) / sweep / f"{slug}{'-quick' if quick else ''}.json"


def load_rows(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return json.loads(path.read_text())["rows"]


def write_rows(path: Path, sweep, rows: list[dict], command: str) -> None:
    doc = {"sweep": sweep.name, "description": sweep.doc, "command": command, "rows": rows}
    write_atomic(path, lambda fh: fh.write((json.dumps(doc, indent=1) + "\n").encode()))


def measure_point(sweep, params: dict, device: str | None, quick: bool) -> dict:
    """Measure one point of ``sweep`` (a ``sweeps.Sweep``): the row, with the common fields filled in.

    ``device`` None: the one this process picks (``warpvol.device.pick``). The row names the
    device and the host it ran on (a cluster's worker, not the client)."""
    device = dev.pick(device)
    with PeakMemory(device) as mem:
        row = sweep.measure(params, device, quick)
    row.pop("frame", None)
    table = row.pop("scene_table", None)  # the table a generated scene was built from: its probe's scene
    row = {"sweep": sweep.name, "technique": sweep.technique, "params": params, **row,
           "peak_mem_mb": round(mem.mb, 1), "device": device_name(device), "host": socket.gethostname(),
           "warp": wp.config.version,
           "commit": git_commit(), "paper": sweep.paper_figure(params),
           "measured": time.strftime("%Y-%m-%d %H:%M:%S")}
    if not quick:  # what bench report --stale renders again (bench/fingerprint.py)
        row["probe"] = probe(row, table)
    return row


def run_sweep(sweep, device: str | None, out: Path, quick: bool = False, executor=None, progress: bool = True,
              command: str = "", slug: str | None = None) -> Path:
    """Measure every point of ``sweep`` not yet in its results file; return the file's path.

    ``executor``: a ``concurrent.futures.Executor`` that runs ``measure_point`` (e.g. a Dask
    client's): each row is written as it arrives (the file keeps the sweep's order); None: one
    point after another here.
    ``device`` None: each point on the device its process picks. ``slug`` names the file
    (``<out>/<sweep>/<slug>[-quick].json``; default ``device_slug(device)``).
    """
    path = results_path(out, sweep.name, slug or device_slug(device), quick)
    rows = load_rows(path)
    done = {row_key(r["params"]) for r in rows}
    todo = [p for p in sweep.points(quick) if row_key(p) not in done]
    bar = tqdm(total=len(todo), desc=sweep.name, unit="point", disable=not progress)
    command = command or (f"python -m warpvol bench {sweep.name}{' --quick' if quick else ''}"
                          f"{f' --device {device}' if device else ''}")
    order = {row_key(p): i for i, p in enumerate(sweep.points(quick))}

    def keep(row):
        images = row.pop("images", None)
        if images:  # pictures a row shows (name -> H x W x 3), written beside the JSON
            slug = "-".join(f"{k}{v}" for k, v in row["params"].items())
            row["images"] = {}
            path.parent.mkdir(parents=True, exist_ok=True)
            for name, image in images.items():
                file = f"{path.stem}-{slug}-{name}.png"
                wv.save_image(str(path.parent / file), image)
                row["images"][name] = file
        rows.append(row)
        rows.sort(key=lambda r: order.get(row_key(r["params"]), len(order)))
        write_rows(path, sweep, rows, command)
        bar.update(1)

    if executor is None:
        for params in todo:
            bar.set_postfix_str(", ".join(f"{k}={v}" for k, v in params.items()), refresh=False)
            keep(measure_point(sweep, params, device, quick))
    else:
        futures = [executor.submit(measure_point, sweep, p, device, quick) for p in todo]
        from concurrent.futures import as_completed

        for fut in as_completed(futures):
            keep(fut.result())
    bar.close()
    if not todo:
        write_rows(path, sweep, rows, command)
    return path
