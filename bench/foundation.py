"""Measure the foundation on this machine and write results/foundation/<machine>.json + README.md.

    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so python -m warpvol.bench.foundation [--out results/foundation]

(``apt-get install libllvm19`` provides that library; without it Mitsuba's llvm variant is skipped.)

Render times of the built-in scenes (reference at 64 spp, raymarch at 64 steps), the
reference's camera paths per second, the CPU thread split's speed-up, the reference's time
against Mitsuba 3 at equal spp, and the start-up time of `python -m warpvol render` with a
cold and a warm kernel cache. Compilation is excluded from frame times (one warm-up frame).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
import warp as wp

import warpvol as wv
from warpvol.scene.procedural import BUILTIN

LAMP = "scenes/lamp-outside.toml"  # the scene tests/test_mitsuba.py validates the reference on


def machine() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return f"{line.split(':', 1)[1].strip()}, {os.cpu_count()} cores"
    except OSError:
        pass
    return platform.processor() or platform.machine()


def commit() -> str:
    r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return r.stdout.strip() or "unknown"


def median_time(fn, repeats=3):
    fn()  # warm-up: compile / load
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), max(times) - min(times)


def scene_times():
    rows = []
    for name in BUILTIN:
        scene = wv.load_scene(name)
        npix = scene.camera.width * scene.camera.height
        t_ref, spread_ref = median_time(lambda: wv.render(scene, technique="reference", device="cpu", spp=64), 1)
        t_rm, spread_rm = median_time(lambda: wv.render(scene, technique="raymarch", multiple_scattering=0, device="cpu"), 3)
        rows.append({"scene": name, "size": [scene.camera.width, scene.camera.height],
                     "reference_64spp_s": t_ref, "reference_paths_per_s": npix * 64 / t_ref,
                     "raymarch_64steps_s": t_rm, "raymarch_spread_s": spread_rm})
        print(f"{name:<16} reference 64 spp {t_ref:7.2f} s ({npix * 64 / t_ref / 1e6:.2f} M paths/s)  raymarch {t_rm * 1e3:8.1f} ms")
    return rows


def thread_speedup():
    scene = wv.load_scene("fog-box")
    out = {}
    for n in ("1", "2"):
        os.environ["WARPVOL_THREADS"] = n
        out[n], _ = median_time(lambda: wv.render(scene, technique="reference", device="cpu", spp=16), 3)
    os.environ.pop("WARPVOL_THREADS")
    print(f"thread split: 1 thread {out['1']:.2f} s, 2 threads {out['2']:.2f} s, speed-up {out['1'] / out['2']:.2f}x")
    return {"scene": "fog-box", "spp": 16, "one_thread_s": out["1"], "two_threads_s": out["2"], "speedup": out["1"] / out["2"]}


def mitsuba_ratio():
    try:
        import mitsuba as mi
    except ImportError:
        return None
    rows = []
    for variant in ("llvm_ad_rgb", "scalar_rgb"):
        if variant.startswith("llvm") and not os.environ.get("DRJIT_LIBLLVM_PATH"):
            # with the system's LLVM 15 this variant aborts the process
            rows.append({"variant": variant, "error": "skipped: set DRJIT_LIBLLVM_PATH to an LLVM 19 library"})
            continue
        try:
            mi.set_variant(variant)
            mi.render(mi.load_dict(wv.scene.to_mitsuba(wv.load_scene(LAMP), spp=4)))
        except Exception as exc:  # noqa: BLE001 - report why a variant is unusable here
            rows.append({"variant": variant, "error": str(exc).splitlines()[0][:200]})
            continue
        for name, scene in (("lamp-outside", wv.load_scene(LAMP, ["camera.width=128", "camera.height=96"])),
                            ("sunlit-haze", wv.load_scene("scenes/sunlit-haze.toml"))):
            spp = 64
            d = wv.scene.to_mitsuba(scene, spp=spp)
            t_mi, _ = median_time(lambda: mi.render(mi.load_dict(d)), 3)
            t_us, _ = median_time(lambda: wv.render(scene, technique="reference", device="cpu", spp=spp), 3)
            rows.append({"variant": variant, "scene": name, "spp": spp, "mitsuba_s": t_mi, "warpvol_s": t_us,
                         "ratio": t_us / t_mi})
            print(f"mitsuba {variant} {name}: mitsuba {t_mi:.2f} s, warpvol {t_us:.2f} s, ratio {t_us / t_mi:.2f}")
    return rows


def startup():
    out = {}
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "WARP_CACHE_PATH": cache}
        cmd = [sys.executable, "-m", "warpvol", "render", "fog-box", "--technique", "raymarch", "--out", f"{tmp}/a.png"]
        for label in ("cold", "cached"):
            t = time.perf_counter()
            subprocess.run(cmd, env=env, check=True, capture_output=True)
            out[f"{label}_s"] = time.perf_counter() - t
    print(f"start-up (render fog-box raymarch): cold cache {out['cold_s']:.1f} s, cached {out['cached_s']:.2f} s")
    return out


def write_readme(path, data):
    lines = [
        "# Foundation measurements",
        "",
        f"Machine: {data['machine']}. Warp {data['warp']}, commit {data['commit']}, device cpu.",
        f"Produced by `{data['command']}`; the numbers below are generated from `{os.path.basename(data['json'])}`.",
        "",
        "## Built-in scenes (default size), median wall time per frame, compile excluded",
        "",
        "| scene | size | reference 64 spp (s) | M camera paths/s | raymarch 64 steps (ms) |",
        "|---|---|---|---|---|",
    ]
    for r in data["scenes"]:
        lines.append(f"| {r['scene']} | {r['size'][0]}x{r['size'][1]} | {r['reference_64spp_s']:.2f} | "
                     f"{r['reference_paths_per_s'] / 1e6:.2f} | {r['raymarch_64steps_s'] * 1e3:.1f} |")
    t = data["threads"]
    lines += ["", "## CPU thread split", "",
              f"fog-box, reference 16 spp: 1 thread {t['one_thread_s']:.2f} s, 2 threads {t['two_threads_s']:.2f} s: "
              f"speed-up {t['speedup']:.2f}x.", ""]
    if data.get("mitsuba"):
        lines += ["## Reference vs Mitsuba 3 volpath, same scene and spp", "",
                  "| Mitsuba variant | scene | spp | Mitsuba (s) | warpvol (s) | warpvol / Mitsuba |", "|---|---|---|---|---|---|"]
        for r in data["mitsuba"]:
            if "error" in r:
                lines.append(f"| {r['variant']} | not usable here: {r['error']} | | | | |")
            else:
                lines.append(f"| {r['variant']} | {r['scene']} | {r['spp']} | {r['mitsuba_s']:.3f} | {r['warpvol_s']:.3f} | {r['ratio']:.2f} |")
        lines.append("")
    if data.get("startup"):
        s = data["startup"]
        lines += ["## Start-up", "", f"`python -m warpvol render fog-box --technique raymarch --out a.png`: "
                  f"cold kernel cache {s['cold_s']:.1f} s, cached {s['cached_s']:.2f} s (wall, whole process).", ""]
    with open(path, "w") as fh:
        fh.write("\n".join(lines))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="results/foundation")
    ap.add_argument("--skip-startup", action="store_true")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    wv.device.init()
    data = {"machine": machine(), "warp": wp.__version__, "commit": commit(),
            "command": ("DRJIT_LIBLLVM_PATH=" + os.environ["DRJIT_LIBLLVM_PATH"] + " " if os.environ.get("DRJIT_LIBLLVM_PATH") else "")
            + "python -m warpvol.bench.foundation --out " + args.out}
    data["scenes"] = scene_times()
    data["threads"] = thread_speedup()
    data["mitsuba"] = mitsuba_ratio()
    data["startup"] = None if args.skip_startup else startup()
    data["json"] = os.path.join(args.out, "cpu.json")
    with open(data["json"], "w") as fh:
        json.dump(data, fh, indent=1)
    write_readme(os.path.join(args.out, "README.md"), data)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
