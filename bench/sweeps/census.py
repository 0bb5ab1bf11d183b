"""The census (``bench defaults``): every built-in scene with every technique that takes it, at
the technique's defaults, at the scene's own resolution and at 160x120: time per frame and per
stage, the error against the physical answer at 160x120, and each technique's time over the
reference's at 16 spp. The page a user reads before picking a technique."""

from __future__ import annotations

import time

import warpvol as wv
from warpvol.scene import BUILTIN

from ..harness import reference_cached, time_frames
from .common import score

CENSUS_SIZE = (160, 120)  # every row is also measured here, against the physical answer
REFERENCE_SPP = 16  # the yardstick a real-time technique's time is divided by
TRUTH_SPP = (16, 1024)  # the physical answer's spp per seed: the most that fits TRUTH_SECONDS, in this range
TRUTH_SECONDS = 100.0  # for both seeds
CENSUS_NOTE = (
    "How to read it: each technique at its defaults (nothing set), every stage run in every timed frame. "
    "\"÷ reference\" is the frame time over the reference's at 16 spp at the same size: above 1 a real-time technique "
    "costs more than a noisy path-traced frame. The error is the relative RMSE against the physical answer (the "
    "reference, all orders of scattering, two seeds at pixel centres, its own noise removed in quadrature; its spp "
    "and noise are in the last column), measured at 160x120 only: a converged reference at 800x600 takes hours on "
    "two cores. \"Leaves out\" is the technique's own account (`frame.leaves_out`) of what it does not model.")


def census_scene(name: str, size: tuple[int, int] | None):
    """A built-in scene at ``size`` (None: its own resolution)."""
    overrides = [] if size is None else [f"camera.width={size[0]}", f"camera.height={size[1]}"]
    return wv.load_scene(name, overrides)


def census_grid(quick: bool) -> list[dict]:
    """(scene, technique, size) for every technique whose Renderer takes the scene (one refusing
    a medium it does not model is left out), at the scene's own size and at 160x120; the
    reference at 16 spp. Quick: three scenes at 16x12."""
    out = []
    names = sorted(BUILTIN)[:3] if quick else sorted(BUILTIN)
    for name in names:
        own = census_scene(name, None).camera
        sizes = [(16, 12)] if quick else list(dict.fromkeys([(own.width, own.height), CENSUS_SIZE]))
        for technique in wv.technique_names():
            try:
                wv.Renderer(census_scene(name, CENSUS_SIZE), technique=technique, device="cpu")
            except (wv.SettingsError, ValueError):
                continue
            for w, h in sizes:
                p = {"scene": name, "technique": technique, "width": w, "height": h}
                if technique == "reference":
                    p["spp"] = REFERENCE_SPP
                out.append(p)
    return out


def truth_spp(scene, device: str, quick: bool) -> int:
    """The physical answer's spp per seed: the most already rendered (``reference_cached``), else
    a 4-spp frame is timed and the most spp (a power of 2 in TRUTH_SPP) whose two seeds fit
    TRUTH_SECONDS is taken."""
    if quick:
        return 16
    spp = TRUTH_SPP[1]
    while spp >= TRUTH_SPP[0]:
        if reference_cached(scene, spp=spp, max_bounces=-1, pixel_area=0):
            return spp
        spp //= 2
    r = wv.Renderer(scene, technique="reference", device=device, spp=4, pixel_area=0)
    r.render()
    r.touch()  # every stage again: an unchanged scene's second frame is cached
    t = time.perf_counter()
    r.render()
    per_spp = (time.perf_counter() - t) / 4.0
    spp = TRUTH_SPP[0]
    while spp * 2 <= TRUTH_SPP[1] and 2 * (2 * spp) * per_spp <= TRUTH_SECONDS:
        spp *= 2
    return spp


def census(params: dict, device: str, quick: bool) -> dict:
    """One technique at its defaults on one built-in scene: frame and stage times (a first frame,
    then two timed; one at sizes over 160x120), its time over the reference's at 16 spp (the
    sweep's row at the same size, once measured), and at 160x120 the error against the physical
    answer."""
    size = (params["width"], params["height"])
    scene = census_scene(params["scene"], size)
    settings = {"spp": params["spp"]} if "spp" in params else {}
    r = wv.Renderer(scene, technique=params["technique"], device=device, **settings)
    big = size[0] * size[1] > CENSUS_SIZE[0] * CENSUS_SIZE[1]
    row = time_frames(r, repeats=1 if (quick or big) else 2)
    row["scene"] = f"{scene.name} {size[0]}x{size[1]}"
    row["leaves_out"] = row["frame"].leaves_out
    row["defaults"] = {k: v for k, v in r.settings.items() if k in type(r.technique).SETTINGS}
    if quick or size == CENSUS_SIZE:
        spp = truth_spp(scene, device, quick)
        ref = score(row, scene, device, spp, max_bounces=-1, error_map=True)  # the map: where the error is
        row["mean_ratio"] = float(row["frame"].image.mean() / ref.mean())
    return row


def reference_ms(rows: list[dict], scene: str, size: tuple[int, int]) -> float | None:
    """The reference's frame time at 16 spp on ``scene`` at ``size``, from the sweep's rows."""
    for r in rows:
        p = r["params"]
        if p["technique"] == "reference" and p["scene"] == scene and (p["width"], p["height"]) == size:
            return r["median_ms"]
    return None

