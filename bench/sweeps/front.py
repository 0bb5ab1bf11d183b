"""Every technique on one error-against-time front (accuracy-vs-time)."""

from __future__ import annotations

import warpvol as wv

from ..harness import time_frames
from .common import score
from .reference import mitsuba_time

# family -> a scene (built-in name or file) and its overrides


FRONT_FAMILIES = {"fog and occluders": ("fog-box", []), "haze under a sky": ("scenes/sunlit-haze.toml", []),
                  "thin haze": ("scenes/sunlit-haze.toml", ["media.0.sigma_t=0.15"]),
                  "thick haze": ("scenes/sunlit-haze.toml", ["media.0.sigma_t=5"]),
                  "light inside fog": ("point-in-fog", []), "grid": ("smoke-grid", []), "RBF": ("rbf-single", []),
                  "particles": ("particle-cloud", [])}
FRONT_LADDERS = {"reference": ("spp", (4, 16, 64, 256)), "raymarch": ("steps", (8, 32, 128)),
                 "light_shafts": ("steps", (16, 64, 256)), "rbf_propagation": ("grid", (10, 20, 40)),
                 "particle_glow": ("steps", (32, 128)), "illumination_network": ("directions", (32, 128)),
                 "depth_impostors": ("slices", (4, 16)), "mitsuba": ("spp", (4, 16, 64, 256))}
FRONT_SIZE = (64, 48)
#: The marchers' multiple-scattering term (warpvol.scattering): every level at 0 (the paper's model)
#: and at the default lattice, and the middle level at a finer one.
MARCHERS = ("raymarch", "light_shafts", "rbf_propagation", "particle_glow", "depth_impostors")
MS_DEFAULT = {"multiple_scattering": 8, "ms_directions": 16}
MS_FINE = {"multiple_scattering": 16, "ms_directions": 32}


def front_scene(family: str, quick: bool):
    w, h = (16, 12) if quick else FRONT_SIZE
    source, overrides = FRONT_FAMILIES[family]
    return wv.load_scene(source, [f"camera.width={w}", f"camera.height={h}", *overrides])


def front_grid(quick: bool) -> list[dict]:
    """Every (family, technique, level) a technique can render: those whose Renderer accepts
    the scene (a technique refuses a medium it does not model); Mitsuba 3 (volpath, all orders)
    where it is installed and the scene has homogeneous media only (``to_mitsuba``), not in a
    quick sweep."""
    import importlib.util

    out = []
    for family in FRONT_FAMILIES:
        scene = front_scene(family, quick)
        for technique, (knob, levels) in FRONT_LADDERS.items():
            if technique == "mitsuba":
                if quick or importlib.util.find_spec("mitsuba") is None or \
                        any(m.type != "homogeneous" for m in scene.media):
                    continue
            else:
                try:
                    wv.Renderer(scene, technique=technique, device="cpu")
                except (wv.SettingsError, ValueError):
                    continue
            levels = levels[:1] if quick else levels
            if technique == "reference":  # at pixel centres, as the truth and the real-time techniques
                out += [{"family": family, "technique": technique, knob: v, "pixel_area": 0} for v in levels]
                continue
            if technique not in MARCHERS:
                out += [{"family": family, "technique": technique, knob: v} for v in levels]
                continue
            out += [{"family": family, "technique": technique, knob: v, "multiple_scattering": 0} for v in levels]
            out += [{"family": family, "technique": technique, knob: v, **MS_DEFAULT} for v in levels]
            if not quick:
                out.append({"family": family, "technique": technique, knob: levels[len(levels) // 2], **MS_FINE})
    return out


def front(params: dict, device: str, quick: bool) -> dict:
    """One technique at one quality level against the physical answer (the reference, all
    orders of scattering, sky included; two seeds of 2048 spp): relative RMSE with the
    reference's noise removed, and the time of a whole frame (every stage run). Iterative
    techniques run to convergence in the frame (illumination_network: up to 2000 iterations).
    Mitsuba 3 (its llvm_ad_rgb variant where its LLVM loads, else scalar_rgb; a pixel-area
    box filter) against the reference over pixel areas, its time after a warm-up render."""
    family, technique = params["family"], params["technique"]
    knob = FRONT_LADDERS[technique][0]
    scene = front_scene(family, quick)
    if technique == "mitsuba":
        run = mitsuba_time(scene, params["spp"], image=True)
        frame = wv.Frame(run["image"], run["image"].shape[:2], f"mitsuba {run['variant']}", "cpu", {}, {}, [])
        row = {"first_frame_ms": None, "median_ms": 1000.0 * run["seconds"], "frames": 1, "stages": {},
               "frame": frame, "variant": run["variant"]}
        ref = score(row, scene, device, 16 if quick else 2048, max_bounces=-1, pixel_area=1)
        row["leaves_out"] = []
    else:
        settings = {k: v for k, v in params.items() if k not in ("family", "technique")}
        if technique == "illumination_network":  # converged in every timed frame, from zero each time
            settings.update(iterations=2000, warm=0)
        r = wv.Renderer(scene, technique=technique, device=device, **settings)
        row = time_frames(r, repeats=1 if quick else 2)
        ref = score(row, scene, device, 16 if quick else 2048, max_bounces=-1)
        row["leaves_out"] = row["frame"].leaves_out
    row["mean_ratio"] = float(row["frame"].image.mean() / ref.mean())
    row["media"] = sorted({m.type for m in scene.media})
    row["scene"] = f"{scene.name} {scene.camera.width}x{scene.camera.height}"
    return row
