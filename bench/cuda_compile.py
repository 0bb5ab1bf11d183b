"""Compile warpvol's kernel modules for CUDA without a GPU (NVRTC, ahead of time), to catch
CUDA-only build errors on machines that have none:

    python -m warpvol.bench.cuda_compile [--arch 90] [module ...]

Modules default to every technique and the shared kernel modules (``SHARED``); all of them take
about a minute and a half on two CPU cores. The PTX goes
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


#: The kernel modules besides the techniques' (the lattice, the media's, the rasteriser's and the tile lists';
#: geometry.camera and media.lightmap hold functions only, built into the modules that call them).
SHARED = ("scattering.kernels", "shading", "media.grid", "media.lightpass", "media.blockpass", "media.volume",
          "geometry.raster", "geometry.tiles", "geometry.shadowmap")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--arch", type=int, default=90, help="SM architecture (90: H100/H200)")
    p.add_argument("modules", nargs="*", default=[*wv.technique_names(), *SHARED],
                   help="technique names or warpvol's other kernel modules (default: all of them)")
    args = p.parse_args(argv)
    device.init()
    failed = 0
    with tempfile.TemporaryDirectory() as out:
        for name in args.modules:
            mod = importlib.import_module(f"warpvol.{name}" if name in SHARED else f"warpvol.techniques.{name}")
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
