"""target_error on seeded random scenes, every technique that takes it: the error estimate
against the truth (the same technique at a fine setting), and whether the truth meets the
target. Writes results/target-error/ (data.json and README.md).

    PYTHONPATH=. .venv/bin/python -m bench.target_error_check
"""

from __future__ import annotations

import argparse
import json
import platform
import time
import warnings
from pathlib import Path

import numpy as np
import warp as wp

import warpvol as wv
from warpvol.scene.procedural import random_cloud, random_scene

from .harness import device_name, git_commit

# technique: (target, scenes, the truth's settings, what the truth is)
CASES = {
    "raymarch": (0.01, "random_scene", [{"steps": 1024, "shadow_steps": 1024}], "1024 steps"),
    "light_shafts": (0.02, "random_scene", [{"steps": 16384}], "16384 steps"),
    "particle_glow": (0.01, "random_scene", [{"steps": 4096}], "4096 steps"),
    "rbf_propagation": (0.05, "random_scene", [{"grid": 256}], "grid 256"),
    "depth_impostors": (0.02, "random_cloud", [{"slices": 512}], "512 slices"),
    "illumination_network": (0.03, "random_cloud", [{"directions": 1024, "direction_seed": k, "window_at": 128}
                                                    for k in (3, 4)], "two turned sets of 1024 directions"),
    "reference": (0.03, "random_scene", [{"spp": 8192, "seed": k} for k in (3, 4)], "2 x 8192 spp"),
}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=10)
    ap.add_argument("--first", type=int, default=0, help="the first scene's seed (20: scenes no rule was chosen on)")
    ap.add_argument("--out", default="results/target-error")
    ap.add_argument("--only", nargs="*", default=None)
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "data.json"
    doc = json.loads(path.read_text()) if path.exists() else {"rows": []}
    rows = [r for r in doc["rows"] if args.only is not None and r["technique"] not in args.only]
    for technique, (target, kind, fine, truth_is) in CASES.items():
        if args.only is not None and technique not in args.only:
            continue
        make = {"random_scene": random_scene, "random_cloud": random_cloud}[kind]
        for seed in range(args.first, args.first + args.scenes):
            scene = make(seed)
            t = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                try:
                    frame = wv.render(scene, technique, device="cpu", target_error=target)
                except wv.SettingsError as e:  # a technique that does not model the scene's media
                    print(f"{technique} {kind}({seed}): {e}")
                    continue
                seconds = time.perf_counter() - t
                truth_image = np.mean([wv.render(scene, technique, device="cpu", **f).image.astype(np.float64)
                                       for f in fine], axis=0)
            truth = wv.relative_rmse(frame.image, truth_image)
            knob = wv.technique_class(technique).QUALITY[0]  # what target_error raised
            rows.append({"technique": technique, "scene": f"{kind}({seed})", "target": target,
                         "estimate": frame.error_estimate, "truth": truth, "truth_is": truth_is,
                         "knob": {knob: frame.settings[knob]}, "seconds": seconds})
            print(f"{technique} {kind}({seed}): estimate {frame.error_estimate:.3g} truth {truth:.3g} "
                  f"{rows[-1]['knob']} {seconds:.1f} s", flush=True)
    command = "PYTHONPATH=. .venv/bin/python -m bench.target_error_check"
    for key in ("first", "out"):  # the options that change which scenes or where they go
        if getattr(args, key) != ap.get_default(key):
            command += f" --{key} {getattr(args, key)}"
    doc = {"command": command, "device": device_name("cpu"),
           "machine": platform.processor() or platform.machine(), "warp": wp.config.version, "commit": git_commit(),
           "measured": time.strftime("%Y-%m-%d %H:%M:%S"), "rows": rows}
    path.write_text(json.dumps(doc, indent=1) + "\n")
    lines = ["# target_error on seeded random scenes", "",
             f"Measured by `{doc['command']}` on {doc['device']} (Warp {doc['warp']}, commit {doc['commit']}, "
             f"{doc['measured']}); data: [data.json](data.json).", "",
             f"Each technique renders seeded random scenes, seeds {args.first} to {args.first + args.scenes - 1} "
             "(`warpvol.scene.procedural.random_scene`: homogeneous "
             "box or sphere or a random density grid, point or directional light, sky or none, floor or none; "
             "`random_cloud`: 60-200 spheres) with `target_error`; the truth is the same technique at a fine "
             "setting. Met: the truth at most the target. Within 2x: estimate / truth in [0.5, 2]. The levelled "
             "techniques stop at the first level whose three-level extrapolation meets the target and whose "
             "error, measured against the next level (`warpvol.api.measured_error`), does too; the reference "
             "at its two runs' standard error.", "",
             "| technique | target | truth | scenes | met | within 2x | estimate / truth (min, median, max) | "
             "knob chosen (median) |", "|---|---|---|---|---|---|---|---|"]
    for technique in CASES:
        rs = [r for r in rows if r["technique"] == technique]
        if not rs:
            continue
        ratio = np.array([r["estimate"] / r["truth"] if r["truth"] > 0 else np.inf for r in rs])
        knob = [list(r["knob"].values())[0] for r in rs if r["knob"]]
        lines.append(f"| {technique} | {rs[0]['target']} | {rs[0]['truth_is']} | {len(rs)} | "
                     f"{sum(r['truth'] <= r['target'] for r in rs)} | {int(np.sum((ratio >= 0.5) & (ratio <= 2)))} | "
                     f"{ratio.min():.2f}, {np.median(ratio):.2f}, {ratio.max():.2f} | "
                     f"{int(np.median(knob)) if knob else '–'} |")
    (out / "README.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
