"""Sweeps and reference renders on a Dask cluster (warpvol.cluster), on a real LocalCluster of
two worker processes: the same rows as in-process, the same image within Monte Carlo noise,
and a worker killed in the middle loses nothing. On the CPU: what runs where is the same on
every device, and a GPU machine's workers would share one GPU here."""

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from functools import partial

import numpy as np
import pytest

pytest.importorskip("distributed", reason="Dask is the [dask] extra")
from distributed import as_completed  # noqa: E402

import warpvol as wv
from warpvol import cluster
from warpvol.bench.harness import load_rows, measure_point, run_sweep, write_rows
from warpvol.bench.sweeps import SWEEPS, Sweep
from warpvol.cli import main

pytestmark = pytest.mark.cpu_only  # Dask workers on the CPU (a GPU machine's would share its GPUs)

#: What a row holds that depends neither on timing nor on when it ran (HEAD may move meanwhile)
SAME = ("sweep", "technique", "params", "device", "host", "warp", "paper", "frames")


@pytest.fixture(scope="module")
def client():
    # gpus=2: worker i sees GPU i mod 2, as on a machine with two (no GPU is used here)
    with cluster.connect(workers=2, gpus=2) as c:
        yield c


def _visible_gpus():
    return os.environ.get("CUDA_VISIBLE_DEVICES")


def test_each_worker_sees_its_own_gpu(client):
    assert sorted(client.run(_visible_gpus).values()) == ["0", "1"]


def test_a_sweep_on_the_cluster_gives_the_serial_rows(client, tmp_path):
    sweep = SWEEPS["pipeline-overhead"]
    serial = load_rows(run_sweep(sweep, "cpu", tmp_path / "serial", quick=True, progress=False))
    path = run_sweep(sweep, "cpu", tmp_path / "dask", quick=True, progress=False,
                     executor=client.get_executor(pure=False))
    rows = load_rows(path)
    assert len(rows) == len(serial) == len(sweep.points(quick=True))
    for a, b in zip(rows, serial):
        assert set(a) == set(b)
        assert {k: a[k] for k in SAME} == {k: b[k] for k in SAME}
        assert {k: s["status"] for k, s in a["stages"].items()} == {k: s["status"] for k, s in b["stages"].items()}
        assert a["host"] == socket.gethostname() and a["median_ms"] > 0


def _points(quick):
    return [{"i": i} for i in range(8)]


def _dies_once(marks, params, device, quick):
    """A point of about 0.2 s; point 3 kills its worker process the first time it runs (and
    leaves a mark saying which process died)."""
    if params["i"] == 3:
        try:
            fd = os.open(os.path.join(marks, "killed"), os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            pass
        else:
            os.write(fd, str(os.getpid()).encode())
            os.close(fd)
            os._exit(1)
    time.sleep(0.2)
    return {"median_ms": 200.0, "pid": os.getpid()}


def test_a_killed_worker_and_an_interrupted_client_lose_no_point(client, tmp_path):
    sweep = Sweep("dies-once", "point 3 kills its worker once", "raymarch", "overhead", _points,
                  partial(_dies_once, str(tmp_path)))
    out = tmp_path / "results"
    path = out / sweep.name / "cpu-quick.json"
    # an interrupted run left two rows: they are kept, the other six are measured on the cluster
    first = [measure_point(sweep, p, "cpu", True) for p in _points(True)[:2]]
    write_rows(path, sweep, first, "test")
    run_sweep(sweep, "cpu", out, quick=True, progress=False, executor=client.get_executor(pure=False))
    rows = load_rows(path)
    assert [r["params"] for r in rows] == _points(True)  # every point once, in the sweep's order
    assert rows[:2] == first
    killed = int((tmp_path / "killed").read_text())
    assert rows[3]["pid"] != killed  # point 3 ran again in another process
    client.wait_for_workers(2, timeout=60)  # the nanny has started the lost worker again


def test_split_samples_and_combine():
    assert cluster.split_samples(10, 4, seed=7) == [(3, 7), (3, 8), (2, 9), (2, 10)]
    assert cluster.split_samples(3, 8, seed=2**31 - 1) == [(1, 2**31 - 1), (1, 0), (1, 1)]
    a, b = np.full((1, 1, 3), 1.0, np.float32), np.full((1, 1, 3), 4.0, np.float32)
    assert cluster.combine([{"image": a, "spp": 3}, {"image": b, "spp": 1}]).tolist() == [[[1.75] * 3]]


def test_a_distributed_reference_matches_a_local_one_with_a_worker_killed(client):
    """8 passes of 16 samples (seeds 0..7) against a local render of 128 (seed 1000); one worker
    is killed while it holds passes, which run again on the other.

    Tolerances: the passes are independent estimates, so their per-pixel spread gives the
    variance of the combined image (7 degrees of freedom a pixel); the local render, the same
    estimator at the same spp, has the same variance. The images' means then differ by at most
    5 standard errors (pixels independent; channels averaged first, since a path carries all
    three). The summed squared difference over twice the summed variance is 1 in expectation;
    its spread comes from a few pixels near the light that hold half the variance (0.5 to 1.7
    in 16 trials on fog-box and point-in-fog), hence 1/3 to 3. Passes that shared their random
    numbers would have no spread (the ratio infinite); a distributed image that shared the local
    one's, a ratio near 0."""
    scene = wv.load_scene("fog-box", ["camera.width=32", "camera.height=24"])
    futures = cluster.submit_reference(client, scene, "cpu", passes=8, spp=128, seed=0)
    next(as_completed(futures))  # the workers are warm and busy with the rest
    held = next((w, set(keys)) for w, keys in client.processing().items() if keys)
    os.kill(client.run(os.getpid)[held[0]], signal.SIGKILL)
    passes = client.gather(futures)
    assert sorted((p["spp"], p["seed"]) for p in passes) == [(16, s) for s in range(8)]
    rerun = [p["worker"] for f, p in zip(futures, passes) if f.key in held[1]]
    assert rerun and held[0] not in rerun
    image = cluster.combine(passes).mean(axis=2)
    local = wv.render(scene, "reference", "cpu", spp=128, seed=1000).image.astype(np.float64).mean(axis=2)
    spread = np.stack([p["image"].astype(np.float64).mean(axis=2) for p in passes]).var(axis=0, ddof=1)
    var = spread / len(passes)  # of the combined image, per pixel
    se = np.sqrt(2.0 * var.sum()) / image.size
    assert abs(image.mean() - local.mean()) <= 5.0 * se
    ratio = np.sum((image - local) ** 2) / np.sum(2.0 * var)
    assert 1.0 / 3.0 <= ratio <= 3.0, ratio
    client.wait_for_workers(2, timeout=60)


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """A cluster started as README says: ``dask scheduler``, then ``dask worker ADDRESS --nthreads 1``
    (here on a free port of localhost, without dashboards): its address."""
    info = tmp_path_factory.mktemp("dask") / "scheduler.json"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--dashboard-address", "127.0.0.1:0", "--scheduler-file", str(info)], **quiet)]
    try:
        deadline = time.monotonic() + 60.0
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        procs.append(subprocess.Popen([sys.executable, "-m", "dask", "worker", address, "--nthreads", "1",
                                       "--no-dashboard"], **quiet))
        yield address
    finally:
        for p in procs[::-1]:
            p.terminate()
            p.wait(timeout=30)


def test_the_cli_prints_its_own_lines_only(scheduler, tmp_path, capfd):
    out = tmp_path / "results"
    path = out / "pipeline-overhead" / "cpu-quick.json"
    for where in (["--workers", "1"], ["--scheduler", scheduler]):
        path.unlink(missing_ok=True)
        assert main(["bench", "pipeline-overhead", "--quick", "--device", "cpu", *where, "--out", str(out)]) == 0
        printed, errors = capfd.readouterr()  # workers' output included: they write to our stdout and stderr
        assert printed == f"pipeline-overhead: rows in {path}; report in {out / 'pipeline-overhead' / 'README.md'}\n"
        assert not re.search(r"distributed|INFO|WARNING|Traceback", errors), errors  # the progress bar only
        rows = load_rows(path)
        assert len(rows) == 2 and all(r["host"] == socket.gethostname() for r in rows)
        assert json.loads(path.read_text())["command"].endswith(f"--device cpu {' '.join(where)}")
    image = tmp_path / "ref.npy"
    r = subprocess.run([sys.executable, "-m", "warpvol", "render", "fog-box", "--set", "camera.width=8",
                        "--set", "camera.height=6", "--set", "spp=16", "--scheduler", scheduler, "--out", str(image)],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, check=False)
    assert r.returncode == 0, r.stdout
    assert re.fullmatch(rf"fog-box: reference on 1 Dask worker \(cpu on \S+\), 8x6, \d+\.\d\d s -> "
                        rf"{re.escape(str(image))}\n", r.stdout), r.stdout
    assert np.load(image).shape == (6, 8, 3)


def test_only_the_reference_runs_on_a_cluster(tmp_path, capsys):
    args = ["render", "fog-box", "--out", str(tmp_path / "x.png")]
    assert main([*args, "--technique", "raymarch", "--workers", "2"]) == 2
    assert "allowed: --technique reference" in capsys.readouterr().err
    assert main([*args, "--workers", "0"]) == 2
    assert "at least 1" in capsys.readouterr().err
    assert main([*args, "--set", "target_error=0.1", "--workers", "1"]) == 2
    assert "target_error is not supported on a cluster" in capsys.readouterr().err
