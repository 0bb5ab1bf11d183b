"""Compile warpvol's kernel modules for CUDA without a GPU (NVRTC, ahead of time), to catch
CUDA-only build errors on machines that have none:

    python -m warpvol.bench.cuda_compile [--arch 90] [module ...]

Modules default to every kernel module of warpvol (``device.KERNEL_MODULES``, as importing every
technique registers them); a name is a technique's (its kernel modules) or a module path under
warpvol (``media.lightpass``). All of them take about a minute and a half on two CPU cores. The PTX goes
to a temporary folder and is thrown away: this checks that the code builds, nothing more.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import tempfile
import time

import warp as wp

import warpvol as wv
from warpvol import device


def kernel_modules(names: list[str]) -> list[str]:
    """The kernel modules to build: every one warpvol registers once its techniques are imported
    (no names), or those of the named techniques and module paths."""
    for name in wv.technique_names():
        wv.technique_class(name)  # imports the technique, which registers its kernel modules
    built = [m for m in device.KERNEL_MODULES if wp.get_module(m).kernels]  # (geometry.camera: functions only)
    if not names:
        return built
    out = []
    for name in names:
        prefix = f"warpvol.techniques.{name}" if name in wv.technique_names() else f"warpvol.{name}"
        found = [m for m in built if m == prefix or m.startswith(prefix + ".")]
        if not found:
            raise SystemExit(f"cuda_compile: {name!r} is not a technique or a kernel module of warpvol")
        out += found
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--arch", type=int, default=90, help="SM architecture (90: H100/H200)")
    p.add_argument("modules", nargs="*", default=[],
                   help="technique names or kernel module paths under warpvol (default: all of them)")
    args = p.parse_args(argv)
    device.init()
    failed = 0
    with tempfile.TemporaryDirectory() as out:
        for module in kernel_modules(args.modules):
            mod = importlib.import_module(module)
            name = module.removeprefix("warpvol.")
            t = time.time()
            try:
                wp.compile_aot_module(mod, arch=args.arch, module_dir=out, use_ptx=True)
                print(f"{name}: compiled for sm_{args.arch} in {time.time() - t:.0f} s", flush=True)
            except Exception as e:  # report every module, then fail
                failed += 1
                print(f"{name}: FAILED for sm_{args.arch}: {e}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
