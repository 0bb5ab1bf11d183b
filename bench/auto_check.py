"""``technique="auto"`` with target 0.05 on fog boxes of any brightness: the image it returns
against the physical answer (a reference to 1% noise, all orders of scattering), or what it
says where it cannot. Writes results/auto-check/ (data.json and README.md).

    PYTHONPATH=. .venv/bin/python -m bench.auto_check
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np
import warp as wp

import warpvol as wv
from warpvol.scene.procedural import brightened

from .fingerprint import probe
from .harness import device_name, git_commit

TARGET = 0.05
#: fog boxes (thin, medium, thick) lit from inside and from outside; each at three brightnesses
BOXES = {"thin, lamp inside": (0.2, [0.3, 0.2, 0.1]), "medium, lamp inside": (1.0, [0.3, 0.2, 0.1]),
         "thick, lamp outside": (4.0, [0.4, 2.2, 0.8])}
BRIGHTNESS = (1e-3, 1.0, 1e3)


def fog_box(sigma_t: float, lamp: list, k: float) -> dict:
    """A fog box (2 units, albedo 0.8, HG 0.3) with one point light and a dim sky, 64x48, every
    light and the sky times k."""
    scene = {"name": f"fog-box-{sigma_t:g}", "background": [0.02, 0.03, 0.05],
             "camera": {"origin": [0.0, 0.3, 4.0], "target": [0, 0, 0], "fov_y": 45.0, "width": 64, "height": 48},
             "lights": [{"type": "point", "position": lamp, "intensity": 6.0}],
             "media": [{"type": "homogeneous", "shape": "box", "size": [2, 2, 2], "sigma_t": sigma_t, "albedo": 0.8,
                        "phase": {"type": "hg", "g": 0.3}}]}
    return brightened(scene, k)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/auto-check")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name, (sigma_t, lamp) in BOXES.items():
        truth = None
        for k in BRIGHTNESS:
            scene = fog_box(sigma_t, lamp, k)
            t = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                frame = wv.render(scene, "auto", device="cpu", target_error=TARGET)
            seconds = time.perf_counter() - t
            if truth is None:  # one truth per box, at k = 1e-3, scaled: the answer is linear in the lights
                truth = wv.render(scene, "reference", device="cpu", target_error=0.01).image.astype(np.float64) / k
            error = wv.relative_rmse(frame.image, truth * k)
            knob = wv.technique_class(frame.technique).QUALITY.knob
            rows.append({"box": name, "brightness": k, "mean_radiance": float(np.mean(truth * k)),
                         "technique": frame.technique, "choice": frame.choice, "estimate": frame.error_estimate,
                         "error": error, "seconds": seconds,
                         # what bench report --stale renders again: the box at the technique and knob auto chose
                         "probe": probe({"technique": frame.technique,
                                         "params": {"technique": frame.technique, knob: frame.settings[knob],
                                                    **frame.moved_to_limit}}, scene)})
            print(f"{name} k={k:g}: {frame.technique} error {error:.3g} ({seconds:.1f} s)", flush=True)
    doc = {"command": "PYTHONPATH=. .venv/bin/python -m bench.auto_check", "device": device_name("cpu"),
           "warp": wp.config.version, "commit": git_commit(), "measured": time.strftime("%Y-%m-%d %H:%M:%S"),
           "target": TARGET, "rows": rows}
    (out / "data.json").write_text(json.dumps(doc, indent=1) + "\n")
    lines = ["# auto on fog boxes of any brightness", "",
             f"Measured by `{doc['command']}` on {doc['device']} (Warp {doc['warp']}, commit {doc['commit']}, "
             f"{doc['measured']}); data: [data.json](data.json).", "",
             f"`technique=\"auto\"`, `target_error={TARGET}`, on fog boxes (2 units, albedo 0.8, a point light and a "
             "dim sky, 64x48) whose lights are scaled by k. The error is against the physical answer: the reference "
             "to 1% noise, all orders of scattering.", "",
             "| box | k | mean radiance | chosen | error | met | seconds | why |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['box']} | {r['brightness']:g} | {r['mean_radiance']:.3g} | {r['technique']} | "
                     f"{r['error']:.3g} | {'yes' if r['error'] <= TARGET else 'no'} | {r['seconds']:.1f} | "
                     f"{r['choice']} |")
    (out / "README.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
