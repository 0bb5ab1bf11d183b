"""One place that initialises Warp, picks the device and launches kernels.

Warp's own output (its init banner and "Module ... load on device" lines, log level INFO,
and the native "Could not find or load the NVIDIA CUDA driver" warning on machines without
a GPU driver) is off unless ``set_verbose(True)`` (``python -m warpvol ... --verbose``): a
command prints its own lines and nothing else.

``pick(None)`` is "cuda" when a CUDA device is present, else "cpu"; the environment
variable WARPVOL_DEVICE overrides it. Warp runs a CPU launch on one thread, so
``launch`` splits a CPU launch into one index range per core and runs them from a thread
pool (a launch releases the GIL); each kernel takes the range start as its first argument.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import weakref
from concurrent.futures import ThreadPoolExecutor

import warp as wp


#: Warp module options for every warpvol module that defines kernels (``kernel_module``): no
#: kernel of warpvol is differentiated, so Warp generates no adjoint code for them (a module
#: then compiles about 3x faster on the CPU; the forward code is the same).
KERNEL_OPTIONS = {"enable_backward": False}


#: Every warpvol module that defines kernels, as it was imported (``kernel_module``): what
#: ``bench.cuda_compile`` builds for CUDA.
KERNEL_MODULES: list[str] = []


def kernel_module(name: str) -> None:
    """Give the Warp module ``name`` (a Python module's ``__name__``, where its kernels are
    defined) warpvol's ``KERNEL_OPTIONS``; a user's own Warp modules keep Warp's defaults."""
    wp.set_module_options(KERNEL_OPTIONS, module=name)
    if name not in KERNEL_MODULES:
        KERNEL_MODULES.append(name)


class DeviceError(ValueError):
    """A device that does not exist on this machine was asked for."""


_pool: ThreadPoolExecutor | None = None


_verbose = False
_initialised = False


def set_verbose(verbose: bool) -> None:
    """Show Warp's own output (banner, module loads, CUDA-driver warning) or not (the default)."""
    global _verbose
    _verbose = verbose
    wp.config.log_level = wp.LOG_INFO if verbose else wp.LOG_WARNING


@contextlib.contextmanager
def _native_stderr_dropped():
    """Send what native code writes to file descriptor 2 to /dev/null while the block runs."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def init():
    """Initialise Warp once; unless verbose, without the CUDA-driver warning its native code
    prints straight to stderr on a machine with no GPU driver."""
    global _initialised
    if not _initialised:
        with contextlib.nullcontext() if _verbose else _native_stderr_dropped():
            wp.init()
        _initialised = True


def available() -> list[str]:
    init()
    return [str(d) for d in wp.get_devices()]


def pick(name: str | None = None) -> str:
    """The Warp device to use: ``name``, else $WARPVOL_DEVICE, else CUDA if present, else CPU."""
    init()
    name = name or os.environ.get("WARPVOL_DEVICE") or None
    devices = available()
    if name is None:
        return "cuda:0" if "cuda:0" in devices else "cpu"
    want = "cuda:0" if name == "cuda" else name
    if want not in devices:
        raise DeviceError(f"device {name!r} is not available (allowed: {', '.join(devices)})")
    return want


def threads() -> int:
    """CPU worker threads for split launches: WARPVOL_THREADS, else the usable cores."""
    env = os.environ.get("WARPVOL_THREADS")
    if env:
        return max(1, int(env))
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


PER_THREAD_CPU = 16


def per_thread(device: str) -> int:
    """Items (pixels, texels) one thread of a light per-item kernel takes in a row: 16 on the
    CPU, where Warp copies a kernel's arguments for every thread (a few kB for kernels given
    several array structs: tens of ns, as much as a light item's own work), 1 on CUDA."""
    return PER_THREAD_CPU if str(device) == "cpu" else 1


def groups(n: int, per: int) -> int:
    """Threads for ``n`` items taken ``per`` to a thread."""
    return -(-n // per)


MIN_SPLIT = 32768  # threads below which a CPU launch is not split (handing out chunks costs ~1 ms)


def _pool_of(n: int) -> ThreadPoolExecutor:
    """n - 1 worker threads: with the calling thread, n take chunks side by side."""
    global _pool
    if _pool is None or _pool._max_workers != n - 1:
        _pool = ThreadPoolExecutor(max_workers=n - 1)
    return _pool


def _run_chunks(kernel, device: str, n: int, jobs: list) -> None:
    """Run ``jobs`` (callables) on n threads, this one included, each taking the next job in
    turn (a chunk of pixels that costs more than the others does not hold the rest up)."""
    wp.load_module(kernel.module, device=device)  # once, before the threads launch from it
    queue = iter(jobs)
    lock = threading.Lock()

    def work():
        while True:
            with lock:
                job = next(queue, None)
            if job is None:
                return
            job()

    futures = [_pool_of(n).submit(work) for _ in range(n - 1)]
    work()
    for f in futures:
        f.result()


def launch(kernel, dim: int, inputs: list, device: str, split: bool = True, min_split: int | None = None,
           work: float = 1.0):
    """Launch ``kernel`` over ``dim`` threads; its first argument is the index offset.

    A CPU launch is split over the cores when its work, ``dim`` times ``work`` (the cost of
    one thread in units of a simple per-pixel thread, e.g. the samples each thread takes), is
    at least ``MIN_SPLIT``: a few thousand threads that each trace hundreds of paths fill
    every core. ``min_split`` overrides ``MIN_SPLIT`` for kernels whose threads each do much work."""
    n = threads() if split and str(device) == "cpu" else 1
    if n <= 1 or dim < n or dim * work < (MIN_SPLIT if min_split is None else min_split):  # handing out costs ~1 ms
        wp.launch(kernel, dim=dim, inputs=[0, *inputs], device=device)
        return
    chunks = 4 * n  # several per thread, so uneven pixels (a bright corner) balance out
    bounds = [dim * k // chunks for k in range(chunks + 1)]

    def chunk(k):
        return lambda: wp.launch(kernel, dim=bounds[k + 1] - bounds[k], inputs=[bounds[k], *inputs], device=device)

    _run_chunks(kernel, device, n, [chunk(k) for k in range(chunks) if bounds[k + 1] > bounds[k]])


_scratch_pool: dict = {}
_scratch_users = 0
_scratch_lock = threading.Lock()

#: The largest per-core copy kept between launches, in bytes: a larger one (a big light map) is made
#: for its launch and freed after. The pool holds one buffer per (device, type, core), each at most
#: this size, and frees them all when the last Renderer that used it is collected (``scratch_user``).
SCRATCH_KEEP = 32 << 20


def scratch_user(owner) -> None:
    """Count ``owner`` (a Renderer) among the scratch pool's users until it is collected; when the
    last one is, the pool's buffers are freed (a process that renders once does not keep them)."""
    global _scratch_users
    with _scratch_lock:
        _scratch_users += 1
    weakref.finalize(owner, _scratch_user_gone)


def _scratch_user_gone() -> None:
    global _scratch_users
    with _scratch_lock:
        _scratch_users -= 1
        if _scratch_users <= 0:
            _scratch_users = 0
            _scratch_pool.clear()


def scratch_bytes() -> int:
    """Bytes the scratch pool holds now."""
    return sum(b.capacity for b in _scratch_pool.values())


def _scratch(out, k: int):
    """Core k's private copy of ``out``: a view of a buffer kept between launches (a fresh
    allocation of a few MB costs more in page faults than the launch itself), set to ``out``;
    above SCRATCH_KEEP bytes a copy of its own, not kept."""
    if out.capacity > SCRATCH_KEEP:
        return wp.clone(out)
    key = (str(out.device), out.dtype, k)
    buf = _scratch_pool.get(key)
    if buf is None or buf.shape[0] < out.shape[0]:
        buf = _scratch_pool[key] = wp.empty(max(out.shape[0], 1024), dtype=out.dtype, device=out.device)
    view = buf[: out.shape[0]]
    wp.copy(view, out)
    return view


def launch_private(kernel, dim: int, inputs: list, out, merge, device: str, work: float | None = None):
    """Launch ``kernel`` (arguments: offset, *inputs, out) over ``dim`` threads that combine their
    results into ``out`` with atomics, ``out`` holding the combination's identity beforehand.
    Warp's CPU atomics are not atomic across threads, so on the CPU each core takes its share of
    the threads (interleaved chunks) into a private copy of ``out``, and the copies are folded
    into ``out`` by the elementwise ``merge(offset, copy, out)``. CUDA runs one launch.
    ``work``: the elements of ``out`` a thread touches on average; where the threads' work,
    dim x work, is less than the copies cost (every extra copy cleared and merged), one core
    runs it all instead."""
    n = threads() if str(device) == "cpu" else 1
    if n <= 1 or dim < MIN_SPLIT // 8 or (work is not None and dim * work < out.shape[0] * (n - 1)):
        wp.launch(kernel, dim=dim, inputs=[0, *inputs, out], device=device)
        return
    copies = [out] + [_scratch(out, k) for k in range(1, n)]
    chunks = 4 * n
    bounds = [dim * k // chunks for k in range(chunks + 1)]

    def share(w):
        def run():
            for k in range(w, chunks, n):
                if bounds[k + 1] > bounds[k]:
                    wp.launch(kernel, dim=bounds[k + 1] - bounds[k], inputs=[bounds[k], *inputs, copies[w]],
                              device=device)
        return run

    _run_chunks(kernel, device, n, [share(w) for w in range(n)])
    for c in copies[1:]:
        launch(merge, out.shape[0], [c, out], device)
