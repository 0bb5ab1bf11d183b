"""Edge softness: how wide the edge of a light shaft is in dense fog, particle_glow's glow against
the physical answer (the glowy-light paper's Figure 5 claim: the glow softens a shaft's edges in
dense media, where the light scattered by nearby particles reaches into the shadow).

    PYTHONPATH=. .venv/bin/python -m bench.glow_edges [--out results/particle-glow-edges]

The scene (``shaft_edge``): a box of dense fog lit by the sun from straight above, half of it
shadowed by a dark plane over it whose edge runs along the view direction, so the shaft's edge is
one vertical line in the image. A profile across it is the mean of the image's middle rows; its
edge width is the distance between where it crosses 10% and 90% of the way from the shadow's
plateau to the shaft's (interpolated between pixels, in scene units at the edge), and its *leak*
the shadow's plateau over the shaft's: the light that reaches into the shadow. Each row's profile
is compared with the reference's (all orders of scattering, 1% noise): the RMSE over the profile's
mean. Writes data.json, profiles.png and README.md under --out.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import warp as wp

import warpvol as wv

from .fingerprint import probe
from .harness import device_name, git_commit

WIDTH, HEIGHT = 96, 48
FOV_Y = 16.0
DISTANCE = 6.0
#: what each row renders: (label, technique, settings)
ROWS = [
    ("single scattering (raymarch)", "raymarch", {"multiple_scattering": 0}),
    ("particle_glow, glow off", "particle_glow", {"multiple_scattering": 0, "glow": 0}),
    ("particle_glow, nearest particle (defaults)", "particle_glow", {"multiple_scattering": 0, "glow": 1}),
    ("particle_glow, two nearest averaged", "particle_glow", {"multiple_scattering": 0, "glow": 2}),
    ("particle_glow, Figure 5 A (mu 2, sigma 0.1)", "particle_glow",
     {"multiple_scattering": 0, "glow": 1, "mu": 2.0, "sigma": 0.1}),
    ("particle_glow, Figure 5 B (mu 0, sigma 0.1)", "particle_glow",
     {"multiple_scattering": 0, "glow": 1, "mu": 0.0, "sigma": 0.1}),
    ("particle_glow, the lattice instead of the glow", "particle_glow", {}),
    ("raymarch, the lattice (defaults: 8 nodes a side)", "raymarch", {}),
    ("raymarch, the lattice at 16 nodes", "raymarch", {"multiple_scattering": 16}),
    ("raymarch, the lattice at 32 nodes", "raymarch", {"multiple_scattering": 32}),
]


def shaft_edge(sigma_t: float = 2.0) -> dict:
    """Dense fog (albedo 0.9, isotropic) under the sun from straight above, the half x < 0 shadowed
    by a dark plane over it; the camera looks along -z, so the shaft's edge is the image's middle
    column."""
    return {"name": "shaft-edge", "background": [0.0, 0.0, 0.0],
            "camera": {"origin": [0.0, 0.0, DISTANCE], "target": [0.0, 0.0, 0.0], "fov_y": FOV_Y,
                       "width": WIDTH, "height": HEIGHT},
            "lights": [{"type": "directional", "direction": [0.0, -1.0, 0.0], "irradiance": 3.0}],
            "media": [{"type": "homogeneous", "shape": "box", "center": [0.0, 0.0, 0.0], "size": [3.0, 2.0, 1.0],
                       "sigma_t": sigma_t, "albedo": 0.9, "phase": {"type": "isotropic"}}],
            "surfaces": [{"type": "plane", "center": [-1.6, 1.2, 0.0], "normal": [0.0, 1.0, 0.0], "size": [3.2, 3.0],
                          "diffuse": 0.0}]}


def profile(image: np.ndarray) -> np.ndarray:
    """The mean over the middle third of the rows, luminance averaged over RGB: one value a column."""
    h = image.shape[0]
    return np.asarray(image, np.float64)[h // 3: 2 * h // 3].mean(axis=(0, 2))


def pixel_width() -> float:
    """A pixel's width in scene units at the edge (the plane z = 0)."""
    return 2.0 * DISTANCE * np.tan(np.radians(FOV_Y) / 2.0) / HEIGHT


def crossing(p: np.ndarray, level: float) -> float:
    """The first column (fractional, linear between columns) where p rises through ``level``."""
    above = np.nonzero(p >= level)[0]
    if not len(above) or above[0] == 0:
        return float("nan")
    k = int(above[0])
    return k - 1 + (level - p[k - 1]) / max(p[k] - p[k - 1], 1e-30)


def edge(p: np.ndarray) -> dict:
    """The profile's plateaus (the shadow's: columns 10-35% across; the shaft's: 65-90%), its 10-90%
    edge width in scene units and its leak (shadow over shaft)."""
    n = len(p)
    lo = float(p[int(0.10 * n): int(0.35 * n)].mean())
    hi = float(p[int(0.65 * n): int(0.90 * n)].mean())
    span = hi - lo
    w = (crossing(p, lo + 0.9 * span) - crossing(p, lo + 0.1 * span)) * pixel_width()
    return {"shadow": lo, "shaft": hi, "edge_width": float(w), "leak": lo / hi if hi > 0 else float("nan")}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/particle-glow-edges")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = shaft_edge()
    scene = wv.load_scene(table)
    t = time.perf_counter()
    truth = wv.render(scene, "reference", device="cpu", target_error=0.01)
    truth_profile = profile(truth.image)
    rows = [{"row": "the reference, all orders (1% noise)", "technique": "reference",
             "params": {"technique": "reference", "spp": truth.settings["spp"]}, "seconds": time.perf_counter() - t,
             **edge(truth_profile), "profile_error": 0.0, "profile": truth_profile.tolist(),
             "probe": probe({"params": {"technique": "reference"}}, table)}]
    print(f"reference: {truth.settings['spp']} spp, edge {rows[0]['edge_width']:.3f}", flush=True)
    for label, technique, settings in ROWS:
        frame = wv.render(scene, technique, device="cpu", **settings)
        t = time.perf_counter()
        frame = wv.render(scene, technique, device="cpu", **settings)
        seconds = time.perf_counter() - t
        p = profile(frame.image)
        err = float(np.sqrt(np.mean((p - truth_profile) ** 2)) / truth_profile.mean())
        params = {"technique": technique, **settings}
        rows.append({"row": label, "technique": technique, "params": params, "seconds": seconds, **edge(p),
                     "profile_error": err, "profile": p.tolist(), "probe": probe({"params": params}, table)})
        print(f"{label}: edge {rows[-1]['edge_width']:.3f}, leak {rows[-1]['leak']:.3f}, error {err:.3f}", flush=True)
    doc = {"command": "PYTHONPATH=. .venv/bin/python -m bench.glow_edges", "device": device_name("cpu"),
           "warp": wp.config.version, "commit": git_commit(), "measured": time.strftime("%Y-%m-%d %H:%M:%S"),
           "scene": table, "pixel_width": pixel_width(), "rows": rows}
    (out / "data.json").write_text(json.dumps(doc, indent=1) + "\n")
    _plot(rows, out / "profiles.png")
    _readme(doc, out / "README.md")


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5), dpi=100)
    x = (np.arange(WIDTH) + 0.5 - WIDTH / 2) * pixel_width()
    for r in rows:
        ax.plot(x, r["profile"], lw=2.5 if r["technique"] == "reference" else 1.2, label=r["row"],
                color="black" if r["technique"] == "reference" else None)
    ax.set_xlabel("distance across the shaft's edge (scene units; the shadow at left)")
    ax.set_ylabel("radiance (middle rows' mean)")
    ax.set_xlim(-0.8, 0.8)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _readme(doc: dict, path: Path) -> None:
    rows = doc["rows"]
    lines = ["# particle-glow-edges", "",
             "Edge softness in dense fog: the width of a light shaft's edge, particle_glow's glow (the glowy-light "
             "paper's Figure 5 claim: the glow softens edges in dense media) against the physical answer.", "",
             f"Measured by `{doc['command']}` on {doc['device']} (Warp {doc['warp']}, commit {doc['commit']}, "
             f"{doc['measured']}); data: [data.json](data.json).", "",
             "The scene: a box of fog (sigma_t 2, albedo 0.9, isotropic; 3 x 2 x 1 units) under the sun from "
             "straight above, its half x < 0 shadowed by a dark plane over it whose edge runs along the view "
             f"direction, {WIDTH}x{HEIGHT}. A profile is the mean of the image's middle rows across the edge. "
             "*edge width*: from 10% to 90% of the way from the shadow's plateau to the shaft's, scene units "
             f"(a pixel is {doc['pixel_width']:.4f}); *leak*: the shadow's plateau over the shaft's; *profile error*: "
             "the RMSE of the profile against the reference's, over its mean.", "",
             "| row | edge width | leak | profile error | seconds |", "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['row']} | {r['edge_width']:.3f} | {r['leak']:.3f} | {r['profile_error']:.3f} | "
                     f"{r['seconds']:.2f} |")
    lines += ["", "![profiles across the edge](profiles.png)", ""]
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
