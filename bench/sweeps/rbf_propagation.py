"""Sweeps of rbf_propagation: Giroud & Biri 2011 tables 2 and 3, the propagation rules, scaling and accuracy."""

from __future__ import annotations

import warpvol as wv

from ..harness import time_frames
from .common import score_against_reference

TABLE2_COLUMNS = {"1L_P": (1, False), "1L": (1, True), "2L": (2, True), "4L": (4, True), "8L": (8, True)}

TABLE2_NOTE = """\
**Lights.** The paper packs four lights' optical depths in the RGBA of one texel, so one
texture fetch serves lights 1-4 and its march costs about the same for 1, 2 and 4 lights
(its 62, 62, 51 FPS at grid 15). Here a cell's lights lie side by side in the OPV in the same
way: a march step finds its trilinear corners and weights once, for the extinction and every
light. What a light still adds to a step is its own work: its eight neighbouring reads, its
falloff and cone, its phase function and its transmittance (one exp for a grey medium). On a
GPU that is arithmetic the fetch hides; on two CPU cores it is the cost, so the *march* column
grows with the lights here where the paper's stays flat to four.
"""


def _rbf_scene(quick: bool, lights: int = 1, rbfs: int | None = None, width: int = 800, height: int = 600):
    """rbf-thick-fog's box and first ``lights`` lights; its 1000 RBFs, or ``rbfs`` random ones
    whose radius shrinks as rbfs^(-1/3) so the fog's mass stays about the same."""
    import numpy as np

    if quick:
        width, height = 80, 60
    from warpvol.scene.procedural import rbf_thick_fog

    d = rbf_thick_fog()
    d["camera"].update(width=width, height=height)
    d["lights"] = d["lights"][:lights]
    if rbfs is not None:
        rng = np.random.default_rng(rbfs)
        d["media"][0].update(centers=rng.uniform(-0.85, 0.85, (rbfs, 3)), radius=0.12 * (1000 / rbfs) ** (1 / 3))
    return wv.load_scene(d)


def table2_grid(quick: bool) -> list[dict]:
    grids = (15, 20) if quick else (15, 20, 30, 40)
    cols = ("1L_P", "1L") if quick else tuple(TABLE2_COLUMNS)
    return [{"grid": g, "column": c} for g in grids for c in cols]


def table2(params: dict, device: str, quick: bool) -> dict:
    """Precomputed (P): only the march runs; dynamic: medium and lights change every frame."""
    lights, dynamic = TABLE2_COLUMNS[params["column"]]
    scene = _rbf_scene(quick, lights)
    r = wv.Renderer(scene, technique="rbf_propagation", multiple_scattering=0, device=device, grid=params["grid"])
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("medium", "lights", "camera") if dynamic else ("camera",))
    row["scene"] = f"rbf-thick-fog {scene.camera.width}x{scene.camera.height}, {lights} lights"
    return row


def table2_fps(table: dict, params: dict):
    row = next(r for r in table["rows"] if r["grid"] == params["grid"])
    return row["fps"][table["columns"].index(params["column"])]


def table3_grid(quick: bool) -> list[dict]:
    counts = (1, 125) if quick else (1, 125, 1000, 8000, 27000)
    return [{"rbfs": n, "column": c} for n in counts for c in ("dynamic", "static")]


def table3(params: dict, device: str, quick: bool) -> dict:
    scene = _rbf_scene(quick, 1, params["rbfs"])
    r = wv.Renderer(scene, technique="rbf_propagation", multiple_scattering=0, device=device, grid=20)
    dynamic = params["column"] == "dynamic"
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("medium", "lights", "camera") if dynamic else ("camera",))
    row["scene"] = f"rbf-thick-fog {scene.camera.width}x{scene.camera.height}, {params['rbfs']} RBFs, one light"
    return row


def table3_fps(table: dict, params: dict):
    row = next(r for r in table["rows"] if r["rbfs"] == params["rbfs"])
    return row["fps"][("dynamic", "static").index(params["column"])]


def rules_grid(quick: bool) -> list[dict]:
    grids = (8, 12) if quick else (10, 15, 20, 30, 40)
    return [{"grid": g, "rule": r, "wavefront": w} for g in grids for r in (0, 1) for w in (1, 0)]


def rules(params: dict, device: str, quick: bool) -> dict:
    """The OPV against optical depth marched from each cell centre to each light through the
    same EV (8 steps per cell), on rbf-cornell's medium and two lights."""
    import numpy as np

    scene = wv.load_scene("rbf-cornell", ["camera.width=8", "camera.height=6"])
    r = wv.Renderer(scene, technique="rbf_propagation", multiple_scattering=0, device=device, **params)
    row = time_frames(r, repeats=1 if quick else 3, invalidate=("lights",))
    a = r.arrays(for_view=True)
    err = np.abs(a["optical_depth"] - a["optical_depth_exact"])[..., 0]
    exact = a["optical_depth_exact"][..., 0]
    row.update(mean_abs_error=float(err.mean()), mean_exact=float(exact.mean()),
               rel_error=float(err.mean() / exact.mean()), max_abs_error=float(err.max()),
               p95_rel_cell=float(np.percentile(err / np.maximum(exact, 1e-3), 95)), scene="rbf-cornell 8x6")
    return row


def scaling_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"stage": "propagate", "grid": 8, "iterations": 4}, {"stage": "march", "width": 40, "steps": 16}]
    prop = [{"stage": "propagate", "grid": g, "iterations": i} for g in (10, 20, 30, 40) for i in (10, 40)]
    march = [{"stage": "march", "width": w, "steps": st} for w in (200, 400, 800) for st in (16, 64, 256)]
    return prop + march


def scaling(params: dict, device: str, quick: bool) -> dict:
    """One stage's time as its work grows: propagation (whole-grid sweeps, the paper's scheme)
    against cells x sweeps, the march against pixels x steps (rbf-cornell, 2 lights, 4:3)."""
    if params["stage"] == "propagate":
        scene = wv.load_scene("rbf-cornell", ["camera.width=8", "camera.height=6"])
        r = wv.Renderer(scene, technique="rbf_propagation", multiple_scattering=0, device=device, grid=params["grid"], wavefront=0,
                        iterations=params["iterations"])
        row = time_frames(r, repeats=2 if quick else 5, invalidate=("lights",))
        row["work"] = params["grid"] ** 3 * params["iterations"]
    else:
        w = params["width"]
        scene = wv.load_scene("rbf-cornell", [f"camera.width={w}", f"camera.height={w * 3 // 4}"])
        r = wv.Renderer(scene, technique="rbf_propagation", multiple_scattering=0, device=device, grid=20, steps=params["steps"])
        row = time_frames(r, repeats=2 if quick else 5, invalidate=("camera",))
        row["work"] = w * (w * 3 // 4) * params["steps"]
    row["stage_ms"] = row["stages"][params["stage"]]["median_ms"]
    row["scene"] = f"rbf-cornell {scene.camera.width}x{scene.camera.height}"
    return row


def rbf_accuracy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"grid": 8, "steps": 16}, {"grid": 16, "steps": 16}]
    return [{"grid": g, "steps": s} for g in (10, 15, 20, 30, 40) for s in (16, 32, 64, 128)]


def rbf_accuracy(params: dict, device: str, quick: bool) -> dict:
    w, h = (32, 24) if quick else (80, 60)
    scene = wv.load_scene("rbf-cornell", [f"camera.width={w}", f"camera.height={h}"])
    r = wv.Renderer(scene, technique="rbf_propagation", multiple_scattering=0, device=device, **params)
    return score_against_reference(time_frames(r, repeats=2 if quick else 3), scene, device, 16 if quick else 1024)


SHADOWS_SCENE = "scenes/rbf-shadows.toml"
#: The truth: raymarch's single scattering with every shadow ray marched through the Gaussians
#: themselves (no light volume, no extinction grid), 256 steps.
SHADOWS_TRUTH = {"multiple_scattering": 0, "steps": 256, "shadow_steps": 128, "shadow_grid": 0, "extinction_grid": 0}
SHADOWS_NOTE = ("Giroud & Biri 2011 propagate each light's optical depth cell to cell through the grid (their "
                "equations 5-10; the code's recurrence: each cell takes the optical depth of the neighbour "
                "toward the light plus the exact step integral of the extinction volume between them, "
                "docs/techniques/rbf_propagation.md). A dense puff (optical depth about 10) hangs between the "
                "light and a thin layer of puffs over a floor. \"shadow\" is the relative RMSE over the pixels "
                "the puff darkens by over 10% in the truth (raymarch, single scattering, every shadow ray "
                "marched through the Gaussians, 256 steps), \"image\" over all pixels; the per-cell columns "
                "compare the propagated optical depth with the one marched from each cell centre to the light "
                "through the same extinction volume (median and 95th percentile of the relative error), and "
                "in the cells the puff shadows (marched optical depth over 2).")


def shadows_grid(quick: bool) -> list[dict]:
    return [{"grid": g} for g in ((8, 16) if quick else (10, 15, 20, 30, 40, 60))]


def shadows(params: dict, device: str, quick: bool) -> dict:
    """rbf_propagation (its paper's model, single scattering) on rbf-shadows as the grid grows:
    its error in the dense puff's shadow and over the image against raymarched shadows, beside
    the per-cell optical-depth errors."""
    import dataclasses

    import numpy as np

    from ..harness import baseline_image

    size = ["camera.width=24", "camera.height=18"] if quick else []
    scene = wv.load_scene(SHADOWS_SCENE, size)
    truth = baseline_image(scene, "raymarch", device, **SHADOWS_TRUTH).astype(np.float64)
    open_sky = baseline_image(dataclasses.replace(scene, media=scene.media[1:]), "raymarch", device,
                              **SHADOWS_TRUTH).astype(np.float64)
    shadow = (open_sky - truth).mean(axis=2) > 0.1 * open_sky.mean(axis=2)  # what the puff darkens by over 10%
    r = wv.Renderer(scene, technique="rbf_propagation", multiple_scattering=0, device=device, **params)
    row = time_frames(r, repeats=1 if quick else 2)
    img = row["frame"].image.astype(np.float64)
    a = r.arrays(for_view=True)
    exact = a["optical_depth_exact"][..., 0]
    rel = np.abs(a["optical_depth"][..., 0] - exact) / np.maximum(exact, 1e-3)
    shade = exact > 2.0
    row["table"] = {
        "shadow pixels": int(shadow.sum()),
        "relative RMSE, shadow": wv.relative_rmse(img[shadow], truth[shadow]) if shadow.any() else float("nan"),
        "relative RMSE, image": wv.relative_rmse(img, truth),
        "image mean ÷ truth": float(img.mean() / truth.mean()),
        "per-cell median": float(np.median(rel)),
        "per-cell 95th pct": float(np.percentile(rel, 95)),
        "shadowed cells 95th pct": float(np.percentile(rel[shade], 95)) if shade.any() else float("nan"),
    }
    row["scene"] = f"{scene.name} {scene.camera.width}x{scene.camera.height}"  # its file under scenes/, for probes
    return row
