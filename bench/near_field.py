"""The multiple-scattering lattice around lamps and in thick media: the part of the image that is
light scattered more than once, against the reference's, per scene family, with the near field's
first-collision split off (``ms_near=off``: every order on the lattice) and on (the default).

    PYTHONPATH=. .venv/bin/python -m bench.near_field [--out results/multiple-scattering-near-field]

The measure separates the term from single scattering (which the marchers compute themselves,
and which is right on all of these): the technique's *multiple-scattering part* is its image at
the defaults minus its image with ``multiple_scattering=0``; the reference's is its all-orders
image minus its single-scattering one (``max_bounces=1``), both pixel-centre. *part error* is the
RMSE of the difference over the all-orders reference's mean, *outside the core* the same without
the pixels within 3 of the lamp's, *energy* the part's sum over the reference's. The reference's
own noise in the part (two seeds' difference over sqrt 2) is in its row. Writes data.json and
README.md under --out.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import warp as wp

import warpvol as wv

from .harness import device_name, git_commit, time_frames

WIDTH, HEIGHT = 64, 48
SPP = 4096
CORE_PIXELS = 3


def lamp_in_ball(tau: float, g: float, albedo: float = 0.9) -> dict:
    """A point light just off the centre of a ball of fog of radius 1 and optical radius tau."""
    return {"camera": {"origin": [0, 0.3, 3.2], "target": [0, 0, 0], "fov_y": 45, "width": WIDTH, "height": HEIGHT},
            "lights": [{"type": "point", "position": [0.05, 0.02, 0.03], "intensity": 4.0}],
            "media": [{"type": "homogeneous", "shape": "sphere", "center": [0, 0, 0], "radius": 1.0, "sigma_t": tau,
                       "albedo": albedo, "phase": {"type": "hg", "g": g}}], "background": 0.0}


def lamp_in_box(tau: float, g: float, albedo: float = 0.9) -> dict:
    """The same lamp in a cube of fog 2 wide, optical half-width tau."""
    scene = lamp_in_ball(tau, g, albedo)
    scene["media"][0].update(shape="box", size=[2, 2, 2])
    del scene["media"][0]["radius"]
    return scene


def thick_box(tau: float, albedo: float, g: float, side: float) -> dict:
    """A cube of fog 2 wide, optical depth tau across, under the sun: side 0 lit on the faces the
    camera sees, 1 from the far side."""
    direction = [-0.4, -1.0, -0.3] if side == 0 else [1.0, -0.5, 0.2]
    return {"camera": {"origin": [1.5, 1.2, 3.5], "target": [0, 0, 0], "fov_y": 40, "width": WIDTH, "height": HEIGHT},
            "lights": [{"type": "directional", "direction": direction, "irradiance": 3.0}],
            "media": [{"type": "homogeneous", "shape": "box", "center": [0, 0, 0], "size": [2, 2, 2],
                       "sigma_t": tau / 2, "albedo": albedo, "phase": {"type": "hg", "g": g}}], "background": 0.0}


#: (family, scene)
FAMILIES = [
    ("lamp in a ball, optical radius 0.5, g 0.6", lamp_in_ball(0.5, 0.6)),
    ("lamp in a ball, optical radius 2.2, g 0", lamp_in_ball(2.2, 0.0)),
    ("lamp in a ball, optical radius 2.2, g 0.6", lamp_in_ball(2.2, 0.6)),
    ("lamp in a ball, optical radius 2.2, g 0.9", lamp_in_ball(2.2, 0.9)),
    ("lamp in a ball, optical radius 5, g 0.6", lamp_in_ball(5.0, 0.6)),
    ("lamp in a box, optical half-width 2.2, g 0.6", lamp_in_box(2.2, 0.6)),
    ("thick box, depth 12.8, albedo 0.95, g -0.3, lit in view", thick_box(12.8, 0.95, -0.3, 0)),
    ("thick box, depth 12.8, albedo 0.95, g -0.3, lit from behind", thick_box(12.8, 0.95, -0.3, 1)),
]
ROWS = [("the lattice alone (ms_near off)", {"ms_near": 0}), ("near field split (defaults)", {})]


def _timed(scene, technique: str, **settings):
    """A frame after a warm-up one (compile excluded), every stage re-run, and its seconds."""
    timed = time_frames(wv.Renderer(scene, technique, "cpu", one_shot=True, **settings), repeats=1)
    return timed["frame"], timed["median_ms"] / 1000.0


def measure(label: str, table: dict) -> list[dict]:
    scene = wv.load_scene(table)
    ref = {"pixel_area": 0, "spp": SPP}
    t = time.perf_counter()
    all_orders = wv.render(scene, "reference", device="cpu", seed=1, **ref).image
    seconds = time.perf_counter() - t
    again = wv.render(scene, "reference", device="cpu", seed=2, **ref).image
    single = wv.render(scene, "reference", device="cpu", seed=1, max_bounces=1, **ref).image
    truth = all_orders - single
    mean = float(all_orders.mean())
    lum = single.mean(axis=2)
    cy, cx = np.unravel_index(np.argmax(lum), lum.shape)
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH]
    outside = np.hypot(yy - cy, xx - cx) >= CORE_PIXELS if table["lights"][0]["type"] == "point" else np.ones_like(lum, bool)
    noise = float(np.sqrt(np.mean((all_orders - again) ** 2) / 2) / mean)
    rows = [{"family": label, "row": f"reference ({SPP} spp, pixel centres)", "seconds": seconds,
             "part_noise": noise, "part_noise_outside": float(np.sqrt(np.mean(((all_orders - again)[outside]) ** 2) / 2) / mean)}]
    off, _ = _timed(scene, "raymarch", multiple_scattering=0)
    for name, settings in ROWS:
        frame, seconds = _timed(scene, "raymarch", **settings)
        part = frame.image - off.image
        d = part - truth
        rows.append({"family": label, "row": name, "technique": "raymarch", "params": {"technique": "raymarch", **settings},
                     "seconds": seconds, "part_error": float(np.sqrt(np.mean(d**2)) / mean),
                     "part_error_outside": float(np.sqrt(np.mean(d[outside] ** 2)) / mean),
                     "energy": float(part.sum() / truth.sum()),
                     "image_error": float(np.sqrt(np.mean((frame.image - all_orders) ** 2)) / mean)})
        print(f"{label} | {name}: part {rows[-1]['part_error']:.3f} (outside the core "
              f"{rows[-1]['part_error_outside']:.3f}), energy {rows[-1]['energy']:.3f}, {seconds * 1e3:.0f} ms", flush=True)
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/multiple-scattering-near-field")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for label, table in FAMILIES:
        rows += measure(label, table)
    doc = {"command": "PYTHONPATH=. .venv/bin/python -m bench.near_field", "device": device_name("cpu"),
           "warp": wp.config.version, "commit": git_commit(), "measured": time.strftime("%Y-%m-%d %H:%M:%S"),
           "size": [WIDTH, HEIGHT], "spp": SPP, "families": dict(FAMILIES), "rows": rows}
    (out / "data.json").write_text(json.dumps(doc, indent=1) + "\n")
    _readme(doc, out / "README.md")


def _readme(doc: dict, path: Path) -> None:
    lines = ["# multiple-scattering-near-field", "",
             "The multiple-scattering lattice around a lamp inside fog and in thick media: the image's "
             "multiple-scattering part (the technique at its defaults minus with `multiple_scattering=0`) against "
             "the reference's (all orders minus single scattering), raymarch at the default 8 nodes a side and 16 "
             "directions, with the near field's first-collision split off and on.", "",
             f"Measured by `{doc['command']}` on {doc['device']} (Warp {doc['warp']}, commit {doc['commit']}, "
             f"{doc['measured']}); data: [data.json](data.json). {doc['size'][0]}x{doc['size'][1]}, the reference at "
             f"{doc['spp']} spp at pixel centres.", "",
             "*part error*: RMSE of the part's difference over the all-orders reference's mean; *outside the core*: "
             f"the same without the pixels within {CORE_PIXELS} of the lamp's; *energy*: the part's sum over the "
             "reference's. The reference row gives its own noise in the same measure (two seeds), a floor under "
             "every error beside it.", "",
             "| family | row | part error | outside the core | energy | image error | ms / frame |",
             "|---|---|---|---|---|---|---|"]
    for r in doc["rows"]:
        if "part_error" in r:
            lines.append(f"| {r['family']} | {r['row']} | {r['part_error']:.3f} | {r['part_error_outside']:.3f} | "
                         f"{r['energy']:.3f} | {r['image_error']:.3f} | {r['seconds'] * 1e3:.0f} |")
        else:
            lines.append(f"| {r['family']} | {r['row']}: its noise | {r['part_noise']:.3f} | "
                         f"{r['part_noise_outside']:.3f} | – | – | {r['seconds'] * 1e3:.0f} |")
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
