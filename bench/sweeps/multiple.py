"""The marchers' multiple-scattering term (warpvol.scattering) against the all-orders reference,
per scene family: each marcher without it (its paper's model, at its defaults and at four times
its quality knob, the time the term costs and more) and with it (the default lattice); and the
lattice's convergence on a fog box and smoke-grid beside the reference's own error over time."""

from __future__ import annotations

import warpvol as wv

from ..harness import time_frames
from .common import score

# family -> a scene (built-in name or file) and its overrides
MS_FAMILIES = {
    "fog box, thin": ("fog-box", ["media.0.sigma_t=0.15"]),
    "fog box": ("fog-box", []),
    "fog box, thick": ("fog-box", ["media.0.sigma_t=2.4"]),
    "light inside fog": ("point-in-fog", []),
    "haze under a sky": ("scenes/sunlit-haze.toml", []),
    "thick haze": ("scenes/sunlit-haze.toml", ["media.0.sigma_t=5"]),
    "smoke": ("smoke-grid", []),
    "cloud": ("nanovdb-cloud", []),
    "RBF": ("rbf-single", []),
    "particles": ("particle-cloud", []),
}
MS_MARCHERS = {"raymarch": "steps", "light_shafts": "steps", "particle_glow": "steps", "rbf_propagation": "grid",
               "depth_impostors": "slices"}
#: The lattice's ladder (nodes per axis, directions) and the reference's, on the convergence families.
MS_LADDER = ((4, 8), (8, 16), (16, 32), (24, 48))
#: ... and points with four directions a node axis (the error's floor on these families is the
#: directions' quadrature, ray effects from the lights' first scattering), with the march's steps
#: (nodes, directions, steps): the converging solver's cheapest ways under 0.05.
MS_DIRECTIONS_RICH = ((8, 32, 32), (16, 64, 64))
REFERENCE_LADDER = (16, 64, 256, 1024)
CONVERGENCE = ("fog box", "smoke")
MS_SIZE = (64, 48)
MS_DEFAULT = {k: wv.technique_class("raymarch").SETTINGS[k].default for k in ("multiple_scattering", "ms_directions")}
MS_NOTE = ("How to read it: \"off\" is the technique's paper model (single scattering; particle_glow: its glow), "
           "\"off, 4x the knob\" the same given four times its steps (or grid, or slices), which costs more than "
           "the term and shows that the missing light is not a discretisation error; \"on\" is the technique at its "
           "defaults, the lattice included. Error: relative RMSE against the reference with all orders of "
           "scattering (two seeds of 2048 spp, its noise removed in quadrature). The lattice's method: "
           "[docs/multiple-scattering.md](../../docs/multiple-scattering.md).")


def ms_scene(family: str, quick: bool):
    w, h = (16, 12) if quick else MS_SIZE
    source, overrides = MS_FAMILIES[family]
    return wv.load_scene(source, [f"camera.width={w}", f"camera.height={h}", *overrides])


def ms_grid(quick: bool) -> list[dict]:
    out = []
    for family in (list(MS_FAMILIES)[:2] if quick else MS_FAMILIES):
        scene = ms_scene(family, quick)
        for technique, knob in MS_MARCHERS.items():
            try:
                r = wv.Renderer(scene, technique=technique, device="cpu")
            except (wv.SettingsError, ValueError):
                continue
            base = r.settings[knob]
            out += [{"family": family, "technique": technique, knob: base, "multiple_scattering": 0},
                    {"family": family, "technique": technique, knob: 4 * base, "multiple_scattering": 0},
                    {"family": family, "technique": technique, knob: base, **MS_DEFAULT}]
        if family in CONVERGENCE and not quick:
            out += [{"family": family, "technique": "raymarch", "multiple_scattering": n, "ms_directions": d}
                    for n, d in MS_LADDER]
            out += [{"family": family, "technique": "raymarch", "multiple_scattering": n, "ms_directions": d,
                     "steps": steps} for n, d, steps in MS_DIRECTIONS_RICH]
            # at pixel centres, as the truth and the marchers are sampled (a pixel's area differs
            # from its centre by more than the lattice's error where a light sits in the image)
            out += [{"family": family, "technique": "reference", "spp": spp, "pixel_area": 0}
                    for spp in REFERENCE_LADDER]
    return out


def ms_measure(params: dict, device: str, quick: bool) -> dict:
    """One row against the physical answer (the reference, all orders, two seeds of 2048 spp):
    relative RMSE with the reference's noise removed, the image mean over the reference's,
    the whole frame's time (every stage run) and what the model leaves out."""
    family, technique = params["family"], params["technique"]
    scene = ms_scene(family, quick)
    settings = {k: v for k, v in params.items() if k not in ("family", "technique")}
    r = wv.Renderer(scene, technique=technique, device=device, **settings)
    row = time_frames(r, repeats=1 if quick else 2)
    ref = score(row, scene, device, 16 if quick else 2048, max_bounces=-1)
    row["leaves_out"] = row["frame"].leaves_out
    row["mean_ratio"] = float(row["frame"].image.mean() / ref.mean())
    row["media"] = sorted({m.type for m in scene.media})
    row["settings"] = {k: r.settings[k] for k in ("multiple_scattering", "ms_directions") if k in r.settings}
    row["scattering"] = {k: v for k, v in r.diagnostics().items() if k.startswith("ms_")}
    return row
