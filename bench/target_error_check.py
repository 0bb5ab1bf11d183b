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
from warpvol.scene.procedural import brightened, random_cloud, random_scene

from .fingerprint import probe
from .harness import device_name, git_commit

# technique: (target, scenes, the truth's settings (or a function of the frame giving them): every
# discretisation setting at its limit, what the truth is)
#: The multiple-scattering lattice in a marcher's truth: at the top target_error takes it to (its cost
#: grows as n^4 D), where the frame may have moved it; its bias beyond is the frame's own estimate's part.
LATTICE = {b.setting: b.top for b in wv.technique_class("raymarch").QUALITY.biases if b.when == "multiple"}
CASES = {
    "raymarch": (0.01, "random_scene", [{"steps": 1024, "shadow_steps": 1024, "sky_samples": 1024, **LATTICE}],
                 "1024 steps and shadow steps, 1024 sky directions, the lattice at its top"),
    "light_shafts": (0.02, "random_scene", [{"steps": 8192, "block": 1, "shadow_steps": 1024, "shadow_map_res": 2048,
                                             **LATTICE}],
                     "8192 steps, block 1, 2048-texel shadow maps, the lattice at its top"),
    "particle_glow": (0.01, "random_scene", [{"steps": 4096, "shadow_steps": 1024, "shadow_map_res": 2048, **LATTICE}],
                      "4096 steps, 2048-texel shadow maps, the lattice at its top"),
    "rbf_propagation": (0.05, "random_scene", [{"grid": 256, "steps": 1024, **LATTICE}],
                        "grid 256, 1024 steps, the lattice at its top"),
    "depth_impostors": (0.02, "random_cloud", [{"light_pass": 0, "impostor_res": 128, "light_samples": 1024,
                                                "sky_samples": 256, **LATTICE}],
                        "exact light pass (the sky's too), 128-texel impostors, 1024 light samples, 256 sky "
                        "directions, the lattice at its top"),
    "illumination_network": (0.03, "random_cloud", [{"directions": 4096, "direction_seed": k, "window_at": 128,
                                                     "light_pass": 0, "light_samples": 1024} for k in (3, 4)],
                             "two turned sets of 4096 directions (the window held at D = 128's), exact light pass, "
                             "1024 light samples"),
    # the truth's noise must be well under the frame's: at least 4x the frame's samples in each half
    "reference": (0.03, "random_scene", lambda frame: [{"spp": max(8192, 4 * frame.settings["spp"]), "seed": k}
                                                       for k in (3, 4)], "2 x max(8192, 4 x the frame's) spp"),
}

#: Scene seeds start here by default: far from the seeds (0-29) the rules were chosen on.
FIRST = 5000


def check_scene(kind: str, seed: int) -> tuple[dict, float]:
    """A scene for the check and its brightness factor k: ``random_scene`` or ``random_cloud``
    of ``seed``, every light and the sky scaled by k = 10^U(-3, 3), the point light (if any)
    put inside the medium or 2.5 units outside it, and (random_scene) half the time a sphere
    occluder by the medium."""
    scene = {"random_scene": random_scene, "random_cloud": random_cloud}[kind](seed)
    rng = np.random.default_rng(seed + 7919)
    k = float(10 ** rng.uniform(-3.0, 3.0))
    scene = brightened(scene, k)
    for light in scene["lights"]:
        if light["type"] == "point":
            d = rng.normal(size=3)
            light["position"] = (rng.uniform(-0.3, 0.3, 3) if rng.random() < 0.5 else 2.5 * d / np.linalg.norm(d)).tolist()
    if rng.random() < 0.5 and kind == "random_scene":  # a cloud's own particles occlude it
        d = rng.normal(size=3)
        scene["surfaces"] = list(scene.get("surfaces", [])) + [
            {"type": "sphere", "center": (0.9 * d / np.linalg.norm(d)).tolist(), "radius": float(rng.uniform(0.15, 0.35)),
             "diffuse": 0.5}]
    return scene, k


def command_of(args, ap) -> str:
    """The command line that measures what ``args`` asks for."""
    command = "PYTHONPATH=. .venv/bin/python -m bench.target_error_check"
    for key in ("scenes", "first", "out"):  # the options that change which scenes or where they go
        if getattr(args, key) != ap.get_default(key):
            command += f" --{key} {getattr(args, key)}"
    return command + (f" --only {' '.join(args.only)}" if args.only else "")


def write(args, ap, out: Path, path: Path, rows: list) -> None:
    """data.json and README.md of the rows so far (each row names the command that measured it)."""
    command = "PYTHONPATH=. .venv/bin/python -m bench.target_error_check"
    for key in ("first", "out"):
        if getattr(args, key) != ap.get_default(key):
            command += f" --{key} {getattr(args, key)}"
    doc = {"command": command, "device": device_name("cpu"),
           "machine": platform.processor() or platform.machine(), "warp": wp.config.version, "commit": git_commit(),
           "measured": time.strftime("%Y-%m-%d %H:%M:%S"), "rows": rows}
    path.write_text(json.dumps(doc, indent=1) + "\n")
    lines = ["# target_error on seeded random scenes", "",
             f"Measured by `{doc['command']}` on {doc['device']} (Warp {doc['warp']}, commit {doc['commit']}, "
             f"{doc['measured']}); data: [data.json](data.json).", "",
             *[f"Rows of {', '.join(sorted({r['technique'] for r in rows if r.get('command') == c}))} re-measured by "
               f"`{c}`." for c in sorted({r["command"] for r in rows if r.get("command")}) if c != doc["command"]],
             "",
             "Each technique renders seeded random scenes (seeds in the column *seeds*) "
             "(`bench.target_error_check.check_scene`: `warpvol.scene.procedural.random_scene`, a homogeneous "
             "box or sphere or a random density grid, thin to thick (sigma_t 0.1-5), point or directional light, "
             "sky or none, floor or none, half of them with a sphere occluder; `random_cloud`, 60-200 spheres), "
             "every light and the sky times k = 10^U(-3, 3), the point light inside the medium or 2.5 units "
             "outside it. The truth is the same technique with every discretisation setting at its limit "
             "(column *truth*); where it is the mean of two seeds (the reference, illumination_network) its own "
             "noise, from their spread, is taken out in quadrature. Met: the truth at most the target. Within 2x: estimate / truth in [0.5, 2]. "
             "Moved: scenes where target_error took a bias setting to its limit (`frame.moved_to_limit`).", "",
             "| technique | target | truth | seeds | mean radiance (min, max) | met | within 2x | "
             "estimate / truth (min, median, max) | knob chosen (median) | moved |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for technique in CASES:
        rs = [r for r in rows if r["technique"] == technique]
        if not rs:
            continue
        ratio = np.array([r["estimate"] / r["truth"] if r["truth"] > 0 else np.inf for r in rs])
        knob = [list(r["knob"].values())[0] for r in rs if r["knob"]]
        radiance = [r["mean_radiance"] for r in rs]
        moved = {k: sum(k in r["moved"] for r in rs) for k in sorted({k for r in rs for k in r["moved"]})}
        seeds = [int(r["scene"].rsplit(", ", 1)[1].rstrip(")")) for r in rs]
        lines.append(f"| {technique} | {rs[0]['target']} | {rs[0]['truth_is']} | {min(seeds)}-{max(seeds)} ({len(rs)}) | "
                     f"{min(radiance):.2g}, {max(radiance):.2g} | "
                     f"{sum(r['truth'] <= r['target'] for r in rs)} | {int(np.sum((ratio >= 0.5) & (ratio <= 2)))} | "
                     f"{ratio.min():.2f}, {np.median(ratio):.2f}, {ratio.max():.2f} | "
                     f"{int(np.median(knob)) if knob else '–'} | "
                     f"{', '.join(f'{k} ({n})' for k, n in moved.items()) or '–'} |")
    (out / "README.md").write_text("\n".join(lines) + "\n")



def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=10)
    ap.add_argument("--first", type=int, default=FIRST, help="the first scene's seed")
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
        for seed in range(args.first, args.first + args.scenes):
            scene, k = check_scene(kind, seed)
            t = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                try:
                    frame = wv.render(scene, technique, device="cpu", target_error=target)
                except wv.SettingsError as e:  # a technique that does not model the scene's media
                    print(f"{technique} {kind}({seed}): {e}")
                    continue
                seconds = time.perf_counter() - t
                fines = [wv.render(scene, technique, device="cpu", **f).image.astype(np.float64)
                         for f in (fine(frame) if callable(fine) else fine)]
            truth_image = np.mean(fines, axis=0)
            # a truth of two seeds has noise of its own (the reference at 2 x 8192 spp can be noisier than the
            # frame): measured from their spread as target_error measures a level's, taken out in quadrature
            noise = wv.relative_rmse(truth_image + 0.5 * np.abs(fines[0] - fines[1]), truth_image) if len(fines) == 2 else 0.0
            truth = float(np.sqrt(max(wv.relative_rmse(frame.image, truth_image) ** 2 - noise**2, 0.0)))
            knob = wv.technique_class(technique).QUALITY.knob  # what target_error raised
            rows.append({"technique": technique, "scene": f"check_scene({kind!r}, {seed})", "brightness": k,
                         "mean_radiance": float(np.mean(truth_image)), "target": target,
                         "estimate": frame.error_estimate, "biases": frame.bias_estimates, "truth": truth, "truth_noise": noise,
                         "truth_is": truth_is, "knob": {knob: frame.settings[knob]}, "moved": frame.moved_to_limit,
                         "seconds": seconds, "command": command_of(args, ap),
                         # what bench report --stale renders again: the scene's table at the settings found
                         "probe": probe({"technique": technique,
                                         "params": {"technique": technique, knob: frame.settings[knob],
                                                    **frame.moved_to_limit}}, scene)})
            print(f"{technique} {kind}({seed}): estimate {frame.error_estimate:.3g} truth {truth:.3g} "
                  f"{rows[-1]['knob']} {seconds:.1f} s", flush=True)
        write(args, ap, out, path, rows)  # after each scene: a stopped run keeps what it measured
if __name__ == "__main__":
    main()
