"""The reference path tracer's own speed, beside Mitsuba 3."""

from __future__ import annotations

import numpy as np

import warpvol as wv



SPEED_SCENES = ["fog-box", "point-in-fog", "smoke-grid", "rbf-single", "rbf-cornell", "rbf-thick-fog", "particle-cloud"]


def cumulus_scene(width: int = 80, height: int = 60):
    """A cumulus-like cloud of 400 spheres (radius 0.12, sigma_t 6 each, overlaps add, albedo
    0.9, isotropic) under a directional sun and a constant sky: issue 14's yardstick."""
    return wv.load_scene({
        "name": "cumulus-400", "background": [0.3, 0.4, 0.6],
        "camera": {"origin": [0, 0.3, 3.2], "target": [0, 0, 0], "fov_y": 45, "width": width, "height": height},
        "lights": [{"type": "directional", "direction": [0.4, -1, -0.3], "irradiance": 3.0}],
        "media": [{"type": "particles", "generator": {"kind": "cloud", "count": 400, "seed": 7}, "radius": 0.12,
                   "sigma_t": 6.0, "albedo": 0.9}]})


def speed_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"scene": s, "spp": 4} for s in ("fog-box", "particle-cloud", "cumulus-400")]
    # rbf-thick-fog (1000 RBFs, 8 lights inside: ~200 paths/s) takes 2 spp, the cumulus issue 14's 4096
    return ([{"scene": s, "spp": 2 if s == "rbf-thick-fog" else 64} for s in SPEED_SCENES]
            + [{"scene": "cumulus-400", "spp": 4096}])


_MITSUBA_RUN = """
import pickle, sys, time
import numpy as np
import mitsuba as mi
from warpvol.scene import to_mitsuba
variant, scene, spp, keep = pickle.load(sys.stdin.buffer)
mi.set_variant(variant)
try:
    description = to_mitsuba(scene, spp=spp)
except ValueError:
    sys.exit(3)  # not a scene Mitsuba renders the same way
scene = mi.load_dict(description)
mi.render(scene, spp=1)  # JIT and set-up
t = time.perf_counter()
image = np.array(mi.render(scene, spp=spp))
seconds = time.perf_counter() - t
if keep:
    np.save(keep, image.astype(np.float32))
print(seconds, float(image.mean()))
"""


def mitsuba_time(scene, spp: int, image: bool = False) -> dict | None:
    """Mitsuba 3 volpath on the same scene and spp, in a child process (a variant whose LLVM
    does not fit the machine aborts the process): llvm_ad_rgb, else scalar_rgb. Seconds after
    a warm-up render, the image mean (and with ``image`` the image, H x W x 3) and the variant;
    None when Mitsuba is missing or cannot render the scene (``to_mitsuba`` exports homogeneous
    media only)."""
    import glob
    import importlib.util
    import os
    import pickle
    import subprocess
    import sys

    if importlib.util.find_spec("mitsuba") is None:
        return None
    env = dict(os.environ)
    if "DRJIT_LIBLLVM_PATH" not in env:  # Dr.Jit's LLVM backend needs a newer LLVM than Debian 12's 15
        found = sorted(glob.glob("/usr/lib/*/libLLVM-19.so") + glob.glob("/usr/lib/*/libLLVM-2[0-9].so"))
        if found:
            env["DRJIT_LIBLLVM_PATH"] = found[-1]
    import tempfile

    with tempfile.TemporaryDirectory(prefix="warpvol-mitsuba-") as tmp:
        keep = os.path.join(tmp, "image.npy") if image else ""
        for variant in ("llvm_ad_rgb", "scalar_rgb"):
            run = subprocess.run([sys.executable, "-c", _MITSUBA_RUN], input=pickle.dumps((variant, scene, spp, keep)),
                                 capture_output=True, timeout=3600, env=env)
            if run.returncode == 3:
                return None
            if run.returncode == 0:
                seconds, mean = (float(v) for v in run.stdout.split()[-2:])
                out = {"variant": variant, "seconds": seconds, "mean": mean}
                if image:
                    out["image"] = np.load(keep)
                return out
    return None


def speed(params: dict, device: str, quick: bool) -> dict:
    """Camera paths per second of the reference (all orders of scattering, pixel area), after a
    1-spp frame that compiles and uploads; RGB extinction traces each channel on its own, so a
    pixel sample there is three paths. Mitsuba's time where it can render the scene."""
    import time

    from warpvol import device as dev

    width, height = (32, 24) if quick else (80, 60) if params["scene"] == "cumulus-400" else (160, 120)
    if params["scene"] == "cumulus-400":
        scene = cumulus_scene(width, height)
    else:
        scene = wv.load_scene(params["scene"], [f"camera.width={width}", f"camera.height={height}"])
    r = wv.Renderer(scene, technique="reference", device=device, spp=1)
    first = time.perf_counter()
    r.render()
    first_ms = 1000.0 * (time.perf_counter() - first)
    r.update(settings={"spp": params["spp"]})
    start = time.perf_counter()
    frame = r.render()
    seconds = time.perf_counter() - start
    grey = r.diagnostics()["grey"]  # the reference's own rule for one launch or three
    paths = width * height * params["spp"] * (1 if grey else 3)
    cores = dev.threads() if device == "cpu" else 1
    row = {"frames": 1, "first_frame_ms": first_ms, "median_ms": 1000.0 * seconds, "seconds": seconds,
           "paths": paths, "paths_per_s": paths / seconds, "paths_per_s_per_core": paths / seconds / cores,
           "cores": cores, "mean": float(frame.image.mean()), "scene": f"{scene.name} {width}x{height}"}
    row["mitsuba"] = mitsuba_time(scene, params["spp"])
    return row
