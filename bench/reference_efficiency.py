"""The reference's efficiency at equal noise, 1 / (variance x time), on the particle and RBF
built-ins: paths per second alone do not say how long an image of a given quality takes,
since an estimator can buy lower variance with time. Renders each case with several seeds
and writes one JSON file per checkout; ``--table`` puts two of them side by side.

    # in the checkout to measure (the script uses only the public API, so an older
    # checkout's warpvol can be measured with this file):
    PYTHONPATH=. python /path/to/bench/reference_efficiency.py --out results/reference-speed/efficiency-NAME.json
    python -m bench.reference_efficiency --table OLD.json NEW.json > results/reference-speed/efficiency.md
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import time

import numpy as np

# (label, scene, overrides, spp, seeds, settings)
CASES = [
    ("rbf-single 160x120, all orders", "rbf-single", [], 16, 2, {}),
    ("rbf-cornell 160x120, all orders", "rbf-cornell", [], 16, 2, {}),
    ("rbf-cornell 80x60, single scattering at pixel centres", "rbf-cornell",
     ["camera.width=80", "camera.height=60"], 64, 2, {"max_bounces": 1, "pixel_area": 0}),
    ("rbf-thick-fog 32x24, all orders", "rbf-thick-fog", ["camera.width=32", "camera.height=24"], 8, 8, {}),
    ("particle-cloud 160x120, all orders", "particle-cloud", [], 16, 2, {}),
]


def measure(label, name, overrides, spp, seeds, settings) -> dict:
    import warpvol as wv

    scene = wv.load_scene(name, overrides)
    wv.render(scene, "reference", device="cpu", spp=1, **settings)  # compile, upload, BVH
    images, seconds = [], []
    for seed in range(1, seeds + 1):
        t = time.perf_counter()
        images.append(np.asarray(wv.render(scene, "reference", device="cpu", spp=spp, seed=seed, **settings).image,
                                 np.float64))
        seconds.append(time.perf_counter() - t)
    x = np.array(images)
    mean = float(x.mean())
    per_pixel = x.var(0, ddof=1)
    variance = float(np.mean(per_pixel)) / mean**2  # one render's per-pixel variance, relative to mean^2
    # the median pixel's: robust where a few paths carry much of the variance (point lights
    # inside scattering media give double scattering a log-divergent second moment)
    median = float(np.median(per_pixel[per_pixel > 0])) / mean**2  # of the pixels with any noise (not the sky's)
    t = float(np.mean(seconds))
    return {"case": label, "spp": spp, "seeds": seeds, "seconds": t, "mean": mean, "relative_variance": variance,
            "efficiency": 1.0 / (variance * t), "median_relative_variance": median,
            "median_efficiency": 1.0 / (median * t)}


def table(old_path: str, new_path: str) -> str:
    old, new = (json.load(open(p)) for p in (old_path, new_path))
    lines = ["# The reference at equal noise", "",
             f"Efficiency 1 / (variance x time) of the reference path tracer, commit {old['commit']} against "
             f"{new['commit']}, measured one after the other on {new['machine']} (`bench/reference_efficiency.py`; "
             "data: the two JSON files beside this page). Variance: one render's per-pixel variance over the seeds, "
             "relative to the squared image mean, averaged over pixels; and the median pixel's, which a few "
             "bright paths do not move (rbf-thick-fog's point lights sit inside a scattering medium, where double "
             "scattering has a log-divergent second moment in both estimators: its mean variance swings 2x "
             "between runs).",
             "", "| case | spp x seeds | seconds (old, new) | paths / s gain | relative variance (old, new) | "
             "gain at equal noise | median pixel's variance (old, new) | gain at its equal noise |",
             "|---|---|---|---|---|---|---|---|"]
    for a, b in zip(old["rows"], new["rows"]):
        lines.append(f"| {a['case']} | {a['spp']} x {a['seeds']} | {a['seconds']:.2f}, {b['seconds']:.2f} | "
                     f"{a['seconds'] / b['seconds']:.1f}x | {a['relative_variance']:.3g}, {b['relative_variance']:.3g} | "
                     f"**{b['efficiency'] / a['efficiency']:.1f}x** | {a['median_relative_variance']:.3g}, "
                     f"{b['median_relative_variance']:.3g} | **{b['median_efficiency'] / a['median_efficiency']:.1f}x** |")
    return "\n".join(lines) + "\n"


def cpu_model() -> str:
    """The CPU's model name and core count (/proc/cpuinfo), else platform's name. Not
    ``harness.device_name`` / ``git_commit``: this file runs inside older checkouts, whose
    ``bench`` package may lack them, and the commit it records is the measured checkout's
    (the working directory's), not this file's."""
    try:
        names = [ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")]
        return f"{names[0]}, {len(names)} cores"
    except (OSError, IndexError):
        return platform.processor() or platform.machine()


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out")
    ap.add_argument("--table", nargs=2, metavar=("OLD", "NEW"))
    ap.add_argument("--record", help="what the file is a record of (a side of a comparison measured back to back): "
                                     "bench report --stale then gives it the status record, not probed")
    args = ap.parse_args(argv)
    if args.table:
        print(table(*args.table), end="")
        return
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    rows = []
    for case in CASES:
        rows.append(measure(*case))
        print(f"{rows[-1]['case']}: {rows[-1]['seconds']:.2f} s, relative variance {rows[-1]['relative_variance']:.3g}",
              flush=True)
    doc = {"command": "bench/reference_efficiency.py", "commit": commit, "machine": cpu_model(),
           "measured": time.strftime("%Y-%m-%d %H:%M:%S"), "rows": rows}
    if args.record:
        doc["record"] = args.record
    with open(args.out, "w") as fh:
        json.dump(doc, fh, indent=1)
        fh.write("\n")


if __name__ == "__main__":
    main()
