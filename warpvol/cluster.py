"""Work on a Dask cluster (``distributed``): sweep points as tasks, and the reference's samples
split into passes with independent seeds, summed in float64.

    python -m warpvol bench SWEEP --workers 4                      # a LocalCluster on this machine
    python -m warpvol bench SWEEP --scheduler tcp://HOST:8786      # a cluster of `dask worker`s
    python -m warpvol render SCENE --spp 65536 --workers 4         # the reference only

``connect`` gives a ``distributed.Client``: of a ``LocalCluster`` of worker processes with one
thread each (Warp's CPU launches use every core of the machine from whichever thread calls
them, and a GPU wants one process), or of a running cluster's scheduler. A sweep's points go
to ``bench.harness.run_sweep`` through ``client.get_executor(pure=False)``; the client writes
each row as it arrives, and a row says which device and host measured it.

Faults: when a worker dies, the scheduler runs the tasks it held again on the others (a task
may lose ``distributed.scheduler.allowed-failures`` workers, 3 by default, before it fails), so
a killed worker costs time, never a point or a pass. A ``LocalCluster``'s nanny also starts the
lost worker again.

One GPU per worker: on a machine with several GPUs, ``--workers N`` gives worker i the GPU
i mod G (``CUDA_VISIBLE_DEVICES``), where it is ``cuda:0``. On a real cluster, start one
``dask worker ... --nthreads 1`` per GPU with its own ``CUDA_VISIBLE_DEVICES``, or use
dask-cuda's ``dask cuda worker``, which does exactly that.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import time

import numpy as np
from distributed import Client, LocalCluster, Nanny, get_worker

from . import device as dev
from .api import render, technique_class
from .pipeline import Frame, StageRun, resolve_settings

#: Passes of a distributed reference render per worker thread: a fast worker (a GPU) takes more
#: of them than a slow one, and a lost worker takes a small share of the image with it.
PASSES_PER_THREAD = 4

#: How long a client tries to reach a scheduler, and then waits for its first worker, in seconds.
CONNECT_S, WORKER_WAIT_S = 10.0, 60.0


@contextlib.contextmanager
def connect(workers: int | None = None, scheduler: str | None = None, gpus: int | None = None):
    """A ``distributed.Client``: of a new ``LocalCluster`` of ``workers`` processes (one thread
    each; closed on exit), or of the cluster whose scheduler listens at ``scheduler``
    (``tcp://HOST:8786``). Dask's own logging below errors and its dashboard stay off.

    ``gpus``: GPUs to share out, worker i seeing GPU i mod ``gpus`` (default: the CUDA
    devices of this machine; fewer than two: every worker sees them all).
    """
    if (workers is None) == (scheduler is None):
        raise ValueError("give workers (a LocalCluster here) or scheduler (tcp://HOST:8786), not both")
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_S)
        except OSError as exc:
            raise ValueError(f"cannot reach the Dask scheduler at {scheduler} ({exc}; start one with "
                             f"`dask scheduler` and workers with `dask worker {scheduler} --nthreads 1`)") from None
        with client:
            try:
                client.wait_for_workers(1, timeout=WORKER_WAIT_S)
            except TimeoutError:
                raise ValueError(f"no Dask worker joined {scheduler} in {WORKER_WAIT_S:.0f} s (start one with "
                                 f"`dask worker {scheduler} --nthreads 1`)") from None
            yield client
        return
    if workers < 1:
        raise ValueError(f"--workers {workers}: at least 1 (allowed: a whole number of worker processes >= 1)")
    if gpus is None:
        gpus = sum(1 for d in dev.available() if d.startswith("cuda"))
    extra = {"worker_class": _OneGPU, "gpus": gpus} if gpus >= 2 else {}
    # no dashboard; the scheduler's HTTP server (health checks) on a free port of localhost, not
    # on 8787 (taken by another cluster: a warning)
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
                      silence_logs=logging.ERROR, **extra) as cluster, Client(cluster) as client:
        yield client


class _OneGPU(Nanny):
    """A LocalCluster worker that sees one GPU: worker i (its name) GPU i mod ``gpus``."""

    def __init__(self, *args, gpus: int, name, env: dict | None = None, **kwargs):
        env = {**(env or {}), "CUDA_VISIBLE_DEVICES": str(int(name) % gpus)}
        super().__init__(*args, name=name, env=env, **kwargs)


def split_samples(spp: int, passes: int, seed: int = 0) -> list[tuple[int, int]]:
    """``spp`` samples in at most ``passes`` passes as even as can be: (spp, seed) per pass.

    Pass j draws with seed ``seed + j`` (mod 2^31). Inside a render the reference launches
    its samples in chunks of about 2^20 paths, chunk k with the seed ``seed * 1 000 003 + k``,
    and seeds every thread from that and its index: consecutive seeds give distinct chunk
    seeds, so passes draw independent streams, while a pass makes fewer than a million
    launches (10^12 paths).
    """
    passes = max(1, min(spp, passes))
    q, r = divmod(spp, passes)
    return [(q + (1 if j < r else 0), (seed + j) % 2**31) for j in range(passes)]


def combine(passes: list[dict]) -> np.ndarray:
    """The mean image over passes (each ``{"image": H x W x 3, "spp": n}``), weighted by each
    pass's samples and summed in float64."""
    total = sum(p["spp"] for p in passes)
    return sum(p["spp"] * p["image"].astype(np.float64) for p in passes) / total


def render_pass(scene, spp: int, seed: int, device: str | None, settings: dict) -> dict:
    """One pass of a distributed reference render, run on a worker: its mean image and where it ran."""
    t0 = time.perf_counter()
    frame = render(scene, "reference", device, False, spp=spp, seed=seed, **settings)
    return {"image": frame.image, "spp": spp, "seed": seed, "device": frame.device, "host": socket.gethostname(),
            "worker": get_worker().address, "seconds": time.perf_counter() - t0, "leaves_out": frame.leaves_out}


def submit_reference(client, scene, device: str | None = None, passes: int | None = None, **settings) -> list:
    """Submit a reference render of ``scene`` (loaded) as passes: Dask futures of ``render_pass``.

    ``settings`` are the reference's (``spp``, ``seed``, ``max_bounces``, ``pixel_area``),
    checked here before anything is sent; ``device`` None lets each worker pick its own;
    ``passes`` defaults to ``PASSES_PER_THREAD`` per worker thread.
    """
    resolved = resolve_settings("reference", technique_class("reference").SETTINGS, settings)
    spp, seed = resolved.pop("spp"), resolved.pop("seed")
    passes = passes or PASSES_PER_THREAD * max(1, sum(client.nthreads().values()))
    return [client.submit(render_pass, scene, n, s, device, resolved, pure=False)
            for n, s in split_samples(spp, passes, seed)]


def render_reference(client, scene, device: str | None = None, passes: int | None = None, **settings) -> Frame:
    """The reference render of ``scene`` on the cluster: ``submit_reference``, then ``combine``.

    The image estimates the same mean as ``warpvol.render(scene, "reference", spp=...)``. With
    seed S the passes draw with the seeds S, S + 1, ... (``split_samples``): independent of
    each other, and of a local render whose seed is none of those. ``frame.device`` says which
    devices and hosts took part; ``frame.stages["passes"]`` is the passes' time summed over the
    workers.
    """
    results = client.gather(submit_reference(client, scene, device, passes, **settings))
    where = sorted({f"{r['device']} on {r['host']}" for r in results})
    workers = len({r["worker"] for r in results})
    stages = {"passes": StageRun("ran", 1000.0 * sum(r["seconds"] for r in results))}
    spp = sum(r["spp"] for r in results)
    cam = scene.camera
    return Frame(combine(results).astype(np.float32), (cam.height, cam.width), "reference",
                 f"{workers} Dask worker{'s' if workers != 1 else ''} ({', '.join(where)})",
                 {**settings, "spp": spp}, stages, results[0]["leaves_out"])

