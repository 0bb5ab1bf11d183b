"""A new user's first scene, a street lamp in thin haze: how close each marcher's image comes to the
reference block by block, and whether a lamp moving a little keeps its light.

    PYTHONPATH=. .venv/bin/python -m bench.street_lamp [--out results/street-lamp]

The scene (``street_lamp``): a lamp on a pole just under its arm, in haze 20 wide and 6 high over a
floor (sigma_t 0.2, albedo 0.9, HG g 0.5), the camera inside the haze. Each row renders it at
160x120 and compares 8x8-pixel blocks (16x16 at 320x240) with the reference's (pixel centres,
SPP samples): the lowest and highest ratio of a block's mean to the reference's, the image mean's
ratio and the relative RMSE. The moving lamp: the lamp moved 0.12 to the right in steps of 0.01,
raymarch at its defaults through one Renderer; the largest step of the frame mean and its whole
change, beside the reference's own change over the move (its two ends, SPP samples each); the
moving camera: the same for the camera moved 0.12 sideways. The reference's noise: two seeds at
NOISE_SPP, with and without the continuations aimed at the lamp (the reference's ``lamp_share``), the
relative standard error of one render away from the lamp's core and over the whole image, and
the same at equal time (noise x sqrt(seconds / the aimed render's seconds)). Writes data.json
and README.md under --out.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import warp as wp

import warpvol as wv
from warpvol.scene import procedural

from .harness import device_name, git_commit, time_frames

WIDTH, HEIGHT, BLOCK = 160, 120, 8
SPP = 1024
NOISE_SPP = 64
#: the lamp's core, left out of the noise away from it: 16 pixels around the lamp's own pixel
CORE = 16
#: what each row renders: (label, technique, settings)
ROWS = [
    ("raymarch (defaults)", "raymarch", {}),
    ("raymarch, near field off", "raymarch", {"ms_near": 0}),
    ("raymarch, 16 nodes a side", "raymarch", {"multiple_scattering": 16}),
    ("raymarch, single scattering", "raymarch", {"multiple_scattering": 0}),
    ("light_shafts (defaults)", "light_shafts", {}),
    ("light_shafts, every sample per pixel (block 1)", "light_shafts", {"block": 1}),
    ("particle_glow (defaults)", "particle_glow", {}),
]


def street_lamp(x: float = 0.6) -> dict:
    return procedural.street_lamp(x, WIDTH, HEIGHT)


def blocks(image: np.ndarray) -> np.ndarray:
    lum = image.mean(axis=2)
    return lum.reshape(HEIGHT // BLOCK, BLOCK, WIDTH // BLOCK, BLOCK).mean(axis=(1, 3))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/street-lamp")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    truth = wv.render(street_lamp(), "reference", device="cpu", spp=SPP, pixel_area=0, seed=1).image
    ref_seconds = time.perf_counter() - t
    moved = wv.render(street_lamp(0.72), "reference", device="cpu", spp=SPP, pixel_area=0, seed=2).image
    reference = blocks(truth)
    rows = []
    for label, technique, settings in ROWS:
        timed = time_frames(wv.Renderer(street_lamp(), technique, "cpu", one_shot=True, **settings), repeats=1)
        image, seconds = timed["frame"].image, timed["median_ms"] / 1000.0
        ratio = blocks(image) / reference
        rows.append({"row": label, "technique": technique, "params": {"technique": technique, **settings},
                     "seconds": seconds, "block_min": float(ratio.min()), "block_max": float(ratio.max()),
                     "mean_ratio": float(image.mean() / truth.mean()), "error": wv.relative_rmse(image, truth)})
        print(f"{label}: blocks {ratio.min():.2f}..{ratio.max():.2f}, error {rows[-1]['error']:.3f}", flush=True)
    motion = moving(lambda r, i: r.update(lights=[dict(type="point", position=[0.6 + 0.01 * i, 3.5, 0.0],
                                                       intensity=[12.0, 9.0, 5.0])]), moved.mean() / truth.mean() - 1.0)
    cam_end = street_lamp()
    cam_end["camera"]["origin"] = [0.12, 1.5, 8.0]
    cam_moved = wv.render(cam_end, "reference", device="cpu", spp=SPP, pixel_area=0, seed=3).image
    camera = moving(lambda r, i: r.update(camera=dict(origin=[0.01 * i, 1.5, 8.0])),
                    cam_moved.mean() / truth.mean() - 1.0)
    for what, row in (("lamp", motion), ("camera", camera)):
        print(f"moving {what}: largest step {row['largest_step']:.4f}, change {row['change']:+.4f} "
              f"(reference {row['reference_change']:+.4f})", flush=True)
    noise = reference_noise(truth)
    doc = {"command": "PYTHONPATH=. .venv/bin/python -m bench.street_lamp", "device": device_name("cpu"),
           "warp": wp.config.version, "commit": git_commit(), "measured": time.strftime("%Y-%m-%d %H:%M:%S"),
           "scene": street_lamp(), "spp": SPP, "reference_seconds": ref_seconds, "rows": rows, "moving_lamp": motion,
           "moving_camera": camera, "noise_spp": NOISE_SPP, "reference_noise": noise}
    (out / "data.json").write_text(json.dumps(doc, indent=1) + "\n")
    _readme(doc, out / "README.md")


def moving(step, reference_change: float) -> dict:
    """raymarch's frame means through one Renderer over 13 frames, ``step(renderer, i)`` moving
    the scene before frame i = 1..12, each over the first frame's; their largest step and whole
    change, beside the reference's change over the move."""
    r = wv.Renderer(street_lamp(), technique="raymarch", device="cpu")
    means = [float(r.render().image.mean())]
    for i in range(1, 13):
        step(r, i)
        means.append(float(r.render().image.mean()))
    m = np.array(means) / means[0]
    return {"means": m.tolist(), "largest_step": float(np.abs(np.diff(m)).max()), "change": float(m[-1] - 1.0),
            "reference_change": float(reference_change)}


def reference_noise(truth: np.ndarray) -> list[dict]:
    """The reference's noise on this scene with the continuations aimed at the lamp (its
    ``lamp_share`` at the default) and without (0): per row, seconds per render and the relative
    standard error of one render (two seeds) away from the lamp's core and over the whole image."""
    lamp = np.unravel_index(np.argmax(truth.mean(axis=2)), truth.shape[:2])
    yy, xx = np.mgrid[:HEIGHT, :WIDTH]
    away = np.maximum(np.abs(yy - lamp[0]), np.abs(xx - lamp[1])) > CORE
    rows, share = [], wv.technique_class("reference").SETTINGS["lamp_share"].default
    for label, s in (("phase and cosine directions only", 0.0), (f"aimed at the lamp (share {share})", share)):
        images, seconds = [], []
        for seed in (1, 2):
            t = time.perf_counter()
            images.append(wv.render(street_lamp(), "reference", device="cpu", spp=NOISE_SPP, pixel_area=0, seed=seed,
                                    lamp_share=s).image.astype(np.float64))
            seconds.append(time.perf_counter() - t)
        a, b = images
        sq = (a - b) ** 2 / 2.0  # one render's variance, per pixel
        rows.append({"row": label, "share": s, "seconds": float(np.mean(seconds)),
                     "noise_away": float(np.sqrt(sq[away].mean()) / (0.5 * (a + b))[away].mean()),
                     "noise": float(np.sqrt(sq.mean()) / (0.5 * (a + b)).mean())})
        print(f"reference, {label}: noise {rows[-1]['noise_away']:.3f} away from the lamp", flush=True)
    for row in rows:  # at the aimed render's time: noise falls as 1 / sqrt(time)
        scale = np.sqrt(row["seconds"] / rows[-1]["seconds"])
        row["noise_away_equal_time"], row["noise_equal_time"] = row["noise_away"] * scale, row["noise"] * scale
    return rows


def _readme(doc: dict, path: Path) -> None:
    mv = doc["moving_lamp"]
    lines = ["# street-lamp", "",
             "A new user's first scene: a lamp on a pole just under its arm, in thin haze over a floor (sigma_t 0.2, "
             "albedo 0.9, g 0.5; the haze 20 x 6 x 20, the camera inside it). Each technique against the "
             f"reference ({doc['spp']} spp, pixel centres, {doc['reference_seconds']:.0f} s), {WIDTH}x{HEIGHT}, "
             f"in {BLOCK}x{BLOCK}-pixel blocks.", "",
             f"Measured by `{doc['command']}` on {doc['device']} (Warp {doc['warp']}, commit {doc['commit']}, "
             f"{doc['measured']}); data: [data.json](data.json).", "",
             "| row | lowest block ÷ reference | highest | image mean ÷ reference | error | seconds |",
             "|---|---|---|---|---|---|"]
    for r in doc["rows"]:
        lines.append(f"| {r['row']} | {r['block_min']:.2f} | {r['block_max']:.2f} | {r['mean_ratio']:.3f} | "
                     f"{r['error']:.3f} | {r['seconds']:.2f} |")
    lines += ["", f"**The lamp moving** 0.12 to the right in steps of 0.01 (raymarch, defaults, one Renderer): the "
              f"frame mean's largest step {mv['largest_step'] * 100:.2f}%, its whole change {mv['change'] * 100:+.2f}%; "
              f"the reference's own change over the move {mv['reference_change'] * 100:+.2f}% (its two ends, each "
              "with its own noise).", "",
              f"**The camera moving** 0.12 sideways in steps of 0.01 (raymarch, defaults, one Renderer): the frame "
              f"mean's largest step {doc['moving_camera']['largest_step'] * 100:.2f}%, its whole change "
              f"{doc['moving_camera']['change'] * 100:+.2f}%; the reference's {doc['moving_camera']['reference_change'] * 100:+.2f}%.",
              "", f"**The reference's noise** ({doc['noise_spp']} spp, two seeds; relative standard error of one render; "
              f"away from the lamp: more than {CORE} pixels from its brightest pixel):", "",
              "| continuations | seconds | noise away from the lamp | whole image | away, at the aimed row's time |",
              "|---|---|---|---|---|"]
    for r in doc["reference_noise"]:
        lines.append(f"| {r['row']} | {r['seconds']:.2f} | {r['noise_away']:.3f} | {r['noise']:.3f} | "
                     f"{r['noise_away_equal_time']:.3f} |")
    lines += [""]
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
