"""Sweeps of illumination_network: Szirmay-Kalos et al. 2005 section 4 and figure 6, accuracy, the light pass, the albedo bound, an animated cloud."""

from __future__ import annotations

import dataclasses

import numpy as np

import warpvol as wv

from ..harness import reference_image, time_frames
from .common import score

SUN2 = {"type": "directional", "direction": [0.6, 0.8, -0.3], "irradiance": 1.5}  # the paper's second, bottom-right


def network_scene(quick: bool, n: int = 1024, width: int = 512, albedo: float = 0.9, sky: bool = True,
                   seed: int = 1, lights: list | None = None, g: float = 0.0):
    """The Scene of ``network_table``."""
    return wv.load_scene(network_table(quick, n, width, albedo, sky, seed, lights, g))


def network_table(quick: bool, n: int = 1024, width: int = 512, albedo: float = 0.9, sky: bool = True,
                  seed: int = 1, lights: list | None = None, g: float = 0.0) -> dict:
    """particle-cloud as in the paper's results, as a scene table: ``n`` particles (radius scaled
    by n^(-1/3) so the cloud's volume stays put), albedo 0.9, HG ``g`` (0: the paper's isotropic
    phase), 2 R tau = 20 expected collisions across it, two directional lights (or ``lights``)
    and sky."""
    from warpvol.scene.procedural import particle_cloud

    d = particle_cloud()
    if quick:
        n, width = min(n, 128), min(width, 32)
    radius = 0.12 * (1024 / n) ** (1 / 3)
    R = 1.2 + radius
    sigma = 10.0 * R**2 / (n * radius**3)  # mean tau over the ball = n sigma r^3 / R^3 = 20 / (2 R)
    d["camera"].update(width=width, height=width)
    d["lights"] = lights if lights is not None else [d["lights"][0], SUN2]
    d["background"] = d["background"] if sky else [0.0, 0.0, 0.0]
    d["media"][0].update(generator={"kind": "cloud", "count": n, "seed": seed, "extent": 1.2}, radius=radius,
                         sigma_t=sigma, albedo=albedo, phase={"type": "hg", "g": g})
    return d


FP32_PEAK_GFLOPS = {"NVIDIA H200": 67_000.0}  # vendor figure, FP32 without tensor cores


def peak_gflops(device: str) -> float | None:
    """The device's FP32 peak: a vendor figure for known GPUs; for the CPU, cores x clock x
    FMA lanes (AVX-512: 16 x 2 flops a cycle, AVX2: 8 x 2), one FMA unit per core assumed."""
    import os

    import warp as wp

    if str(device).startswith("cuda"):
        name = wp.get_device(device).name
        return next((v for k, v in FP32_PEAK_GFLOPS.items() if k in name), None)
    try:
        with open("/proc/cpuinfo") as f:
            info = f.read()
    except OSError:
        return None
    mhz = [float(line.split(":")[1]) for line in info.splitlines() if line.startswith("cpu MHz")]
    if not mhz:
        return None
    lanes = 16 if "avx512f" in info else 8 if "avx2" in info else 4
    return len(os.sched_getaffinity(0)) * max(mhz) / 1000.0 * lanes * 2


def untimed_row(frames: int, **fields) -> dict:
    """A row that measures no frame time (convergence, error bounds): the common fields empty."""
    return {"first_frame_ms": 0.0, "median_ms": float("nan"), "spread_ms": [0, 0], "frames": frames, "stages": {},
            **fields}


def network_table_grid(quick: bool) -> list[dict]:
    return [{"particles": 1024, "directions": 128}, {"particles": 512, "directions": 128}]


def network_frame(params: dict, device: str, quick: bool) -> dict:
    """A frame as in the paper: lights and camera moving, one iteration, 512x512 splat; and
    the cost of one iteration alone (median of 20) with its multiply-add rate."""
    import time

    import warp as wp

    n, D = params["particles"], params["directions"]
    table = network_table(quick, n, params.get("width", 512))
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="illumination_network", device=device, directions=D,
                    window=params.get("window", 0), iterations=1, tolerance=0.0)
    row = time_frames(r, repeats=2 if quick else 10, invalidate=("camera", "lights"))
    t = r.technique
    times = []
    for _ in range(3 if quick else 20):
        t0 = time.perf_counter()
        t.step(measure=False)
        wp.synchronize_device(t.device)
        times.append(time.perf_counter() - t0)
    it = sorted(times)[len(times) // 2]
    builds = []
    for _ in range(1 if quick else 3):
        r.touch("medium")
        builds.append(r.render().stages["network"].ms)
    gflops = 2.0 * 3 * n * D * D / it / 1e9
    peak = peak_gflops(device)
    row.update(iteration_ms=it * 1000.0, gflops=gflops, peak_gflops=peak,
               peak_fraction=gflops / peak if peak else None, window=r.diagnostics()["window"],
               network_ms=sorted(builds)[len(builds) // 2],
               scene=f"{n} particles, {scene.camera.width}x{scene.camera.height}, 2 suns + sky", scene_table=table)
    return row


def network_sweep_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"particles": 64, "directions": 16}, {"particles": 128, "directions": 32}]
    return ([{"particles": n, "directions": 128} for n in (256, 512, 1024, 2048, 4096, 8192, 16384)]
            + [{"particles": 1024, "directions": d} for d in (32, 64, 256, 512)]
            + [{"particles": 1024, "directions": 128, "window": m} for m in (32, 128)])


CONVERGENCE_SHOWN = (20, 40, 60, 80)


def convergence_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"albedo": 0.9, "window": 0}]
    return ([{"albedo": a, "window": m} for m in (0, 16) for a in (0.9, 0.99)]
            + [{"albedo": a, "window": 0, "column": 4} for a in (0.9, 0.99)])


def convergence(params: dict, device: str, quick: bool) -> dict:
    """Figure 6: iterations from zero on the paper's cloud (1024 particles, 128 directions):
    the relative L2 change per iteration and the error to the converged solution, of the
    network I and of the image. Saves the images at 20/40/60/80 iterations."""
    import numpy as np

    iters = 20 if quick else 300
    table = network_table(quick, 1024, 256, albedo=params["albedo"])
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=0,
                    window=params.get("window", 0), column=params.get("column", 0))
    r.render()
    t = r.technique
    nets, changes = [], []
    for k in range(iters):
        changes.append(t.step(measure=True))
        if k + 1 <= 100:  # the first 100 iterates (memory: N D 3 floats each)
            nets.append(t.radiance_network())
    r.update(settings={"iterations": 0})
    converged = t.radiance_network()
    shown = {}
    for k in CONVERGENCE_SHOWN + (iters,):
        if k <= iters:
            t.set_radiance_network(nets[k - 1] if k <= len(nets) else converged)
            r.touch("camera")
            shown[k] = r.render().image.copy()
    final = shown[iters]
    net_err = [float(np.sqrt(((x - converged) ** 2).sum() / (converged**2).sum())) for x in nets]
    img_err = {k: wv.relative_rmse(v, final) for k, v in shown.items()}
    return untimed_row(iters, change=changes, network_error=net_err, scene_table=table,
                       image_error={str(k): v for k, v in img_err.items()},
                       images={str(k): v for k, v in shown.items() if k in CONVERGENCE_SHOWN})


def network_accuracy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"particles": 64, "directions": 16, "window": 0}, {"particles": 64, "directions": 32, "window": 0}]
    return ([{"particles": n, "directions": d, "window": 0} for n in (256, 1024) for d in (16, 32, 64, 128, 256)]
            + [{"particles": 1024, "directions": 128, "window": m} for m in (8, 16, 32, 96)]
            + [{"particles": n, "directions": 128, "window": 0, "column": k} for n in (256, 1024) for k in (2, 4, 8)])


def network_accuracy(params: dict, device: str, quick: bool) -> dict:
    """The converged image against the multiple-scattering reference on the same particles
    (48x48 at pixel centres), the window from the paper's rule (window = 0) or given."""
    w = 24 if quick else 48
    table = network_table(quick, params["particles"], w)
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=2000, tolerance=1e-5,
                    directions=params["directions"], window=params["window"], column=params.get("column", 0))
    row = time_frames(r, repeats=1 if quick else 2, invalidate=("lights",))
    row["window_used"] = r.diagnostics()["window"]
    row["iterations_to_converge"] = r.diagnostics()["iterations"]
    ref = score(row, scene, device, 16 if quick else 128, max_bounces=-1)
    row["mean_ratio"] = float(row["frame"].image.mean() / ref.mean())
    row["scene"] = f"{params['particles']} particles {w}x{w}"
    row["scene_table"] = table
    return row


def anisotropy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"g": g, "phase_norm": k, "directions": 32} for g in (0.0, 0.9) for k in (0, 1)]
    return ([{"g": g, "phase_norm": k, "directions": d} for g in (0.0, 0.6, 0.9) for k in (0, 1) for d in (64, 256)]
            + [{"g": g, "phase_norm": 1, "directions": 128, "sky": 0} for g in (0.0, 0.6)]
            + [{"g": 0.0, "phase_norm": 1, "directions": 128, "sky": s, "window": m} for s in (0, 1) for m in (8, 4)])


def anisotropy(params: dict, device: str, quick: bool) -> dict:
    """The network against the all-orders reference on the paper's cloud with forward-scattering
    particles (HG g), the phase matrix as tabulated (``phase_norm`` 0, the paper's) or scaled
    doubly stochastic (1, the default), at D directions: what the normalisation buys where the
    lobe is narrow against the directions' spacing. ``sky`` 0: the suns alone (a black sky), the light
    the sky's boundary radiance does not carry."""
    w = 24 if quick else 48
    table = network_table(quick, 256 if quick else 1024, w, g=params["g"], sky=bool(params.get("sky", 1)))
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=2000, tolerance=1e-5,
                    directions=params["directions"], phase_norm=params["phase_norm"], window=params.get("window", 0))
    row = time_frames(r, repeats=1 if quick else 2, invalidate=("lights",))
    row["linked"] = r.diagnostics()["linked"]  # (particle, direction) pairs with an upstream particle
    ref = score(row, scene, device, 16 if quick else 128, max_bounces=-1)
    row["mean_ratio"] = float(row["frame"].image.mean() / ref.mean())
    row["scene"] = (f"{len(scene.media[0].positions)} particles, HG g = {params['g']}, {w}x{w}"
                    + (", no sky" if not params.get("sky", 1) else ""))
    row["scene_table"] = table
    return row


def lightpass_grid(quick: bool) -> list[dict]:
    """The old default (exact, 4 points a sphere), exact at more points, and each map
    representation over its resolution, read at 16 points a sphere."""
    if quick:
        return [{"light_pass": 0, "light_samples": 4}, {"light_pass": 1, "light_slices": 8, "light_samples": 16}]
    return ([{"light_pass": 0, "light_samples": k} for k in (4, 16, 64)]
            + [{"light_pass": 1, "light_slices": s, "light_samples": 16} for s in (4, 8, 16, 32, 64)]
            + [{"light_pass": 1, "light_slices": 32, "light_samples": 4}]
            + [{"light_pass": 2, "light_terms": k, "light_samples": 16} for k in (4, 8, 16, 32)])


_LIGHTPASS_TRUTH: dict = {}


def _lightpass_truth(scene, device: str, quick: bool):
    """The direct light with exact transmittance averaged over 256 points of each sphere
    (light_pass = 0), and the converged image it gives: the yardstick of every row."""
    key = (scene.name, device, quick)
    if key not in _LIGHTPASS_TRUTH:
        r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=2000, tolerance=1e-5,
                        light_pass=0, light_samples=64 if quick else 256, light_tolerance=0.0)
        image = r.render().image
        _LIGHTPASS_TRUTH[key] = (r.diagnostics()["direct"].astype(np.float64), image)
    return _LIGHTPASS_TRUTH[key]


def lightpass_accuracy(params: dict, device: str, quick: bool) -> dict:
    """What the light pass's representation and resolution buy: the direct light per particle
    against the exact sphere mean (relative RMSE over particles, lights and channels), the
    converged image against the image from that exact direct light (how far the image moves)
    and against the reference; the direct stage's time with both suns moving each frame."""
    n, w = (128, 24) if quick else (1024, 48)
    table = network_table(quick, n, w)
    scene = wv.load_scene(table)
    settings = {"light_tolerance": 0.0, **params}  # no fallback: measure the representation itself
    r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=2000, tolerance=1e-5,
                    **settings)
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("lights",))
    truth, truth_image = _lightpass_truth(scene, device, quick)
    direct = r.diagnostics()["direct"].astype(np.float64)
    row["direct_rel_rmse"] = float(np.sqrt(np.sum((direct - truth) ** 2) / np.sum(truth**2)))
    row["direct_ms"] = row["stages"]["direct"]["median_ms"]
    row["texels"] = r.diagnostics()["light_texels"]
    image = row["frame"].image
    row["image_move"] = wv.relative_rmse(image, truth_image)
    score(row, scene, device, 16 if quick else 128, max_bounces=-1)
    row["scene"] = f"{n} particles {w}x{w}, 2 suns + sky, D = 128"
    row["scene_table"] = table
    return row


def lightpass_scaling_grid(quick: bool) -> list[dict]:
    return [{"n": n} for n in ((128, 256) if quick else (1024, 2048, 4096, 8192))]


def turning_suns(r, degrees: float = 3.0):
    """A ``before`` for ``time_frames``: each call turns the renderer's directional lights
    ``degrees`` further about y from where they started (other lights stay)."""
    lights = list(r.scene.lights)
    turn = [0]

    def move():
        turn[0] += 1
        a = np.radians(degrees * turn[0])
        rot = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
        r.update(lights=[dataclasses.replace(light, direction=tuple(rot @ np.asarray(light.direction, float)))
                         if light.type == "directional" else light for light in lights])

    return move


def lightpass_scaling(params: dict, device: str, quick: bool) -> dict:
    """The light pass as particles get finer: ``n`` particles of radius 0.12 (1024 / n)^(1/3)
    with sigma_t r fixed (each particle as thick as at n = 1024, the cloud thicker as n^(1/3)),
    both suns turning 3 degrees a frame about y, D = 128, at the default light_tolerance. The
    direct stage's time per frame, and where the map ended: texels a side, refinements in the
    last frame, its measured error, and whether it fell back to exact chords."""
    n, w = params["n"], (32 if quick else 128)
    base = network_scene(False, 1024, w)  # radius 0.12 and its sigma_t at n = 1024
    radius = 0.12 * (1024 / n) ** (1 / 3)
    d = particle_cloud_dict(base, n, radius, (np.asarray(base.media[0].sigma_t) * 0.12 / radius).tolist())
    scene = wv.load_scene(d)
    r = wv.Renderer(scene, technique="illumination_network", device=device, directions=128, iterations=1)
    row = time_frames(r, repeats=3 if quick else 8, invalidate=None, before=turning_suns(r))
    row["scene_table"] = d
    diag = r.diagnostics()
    row["table"] = {"direct ms": row["stages"]["direct"]["median_ms"], "texels": diag["light_texels"],
                    "refined": diag["light_refined"], "error": diag["light_error"], "fell back": diag["light_fell_back"]}
    row.update(scene=f"n particles of radius 0.12 (1024 / n)^(1/3), sigma_t r fixed, {w}x{w}, D = 128, 2 suns turning "
                   "3 degrees a frame + sky, light_tolerance at its default")
    return row


def lights_grid(quick: bool) -> list[dict]:
    counts = (1, 4) if quick else (1, 2, 4, 8, 16)
    return [{"lights": k, "sky": sky} for sky in (0, 1) for k in counts]


def lights_cost(params: dict, device: str, quick: bool) -> dict:
    """The paper's claim (Szirmay-Kalos et al. 2005, section 4) that the speed hardly depends on
    the number of lights or on the sky: 1024 particles, D = 128, one iteration a frame, 256x256,
    ``lights`` directional lights of equal total irradiance spread over the upper hemisphere
    (golden-angle spiral), under a black or a blue sky; every light turning 3 degrees a frame about
    y, so each frame re-runs the direct light (a light pass per light), the emission, the
    iteration and the splat."""
    k, w = params["lights"], (32 if quick else 256)
    golden = np.pi * (3.0 - np.sqrt(5.0))
    suns = []
    for i in range(k):
        y = -0.3 - 0.6 * (i + 0.5) / k  # pointing down, from steep to grazing
        phi = golden * i
        ring = np.sqrt(1.0 - y * y)
        suns.append({"type": "directional", "direction": [ring * np.cos(phi), y, ring * np.sin(phi)],
                     "irradiance": 3.0 / k})
    table = network_table(quick, 1024, w, sky=bool(params["sky"]), lights=suns)
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="illumination_network", device=device, directions=128, iterations=1)
    row = time_frames(r, repeats=3 if quick else 8, invalidate=None, before=turning_suns(r))
    stage = {k2: v["median_ms"] for k2, v in row["stages"].items() if v.get("status") == "ran"}
    row["table"] = {"direct ms": stage.get("direct", 0.0), "emission ms": stage.get("emission", 0.0),
                    "iterate ms": stage.get("iterate", 0.0), "splat ms": stage.get("splat", 0.0)}
    row["scene"] = (f"1024 particles, {w}x{w}, D = 128, k directional lights (total irradiance 3) turning 3 degrees a "
                    "frame, black or blue sky")
    row["scene_table"] = table
    return row


def particle_cloud_dict(scene, n: int, radius: float, sigma_t: float) -> dict:
    """``scene`` (a network_scene) as a table with ``n`` particles of ``radius`` and ``sigma_t``."""
    from warpvol.scene.procedural import particle_cloud

    d = particle_cloud()
    d["camera"].update(width=scene.camera.width, height=scene.camera.height)
    d["lights"] = [d["lights"][0], SUN2]
    d["media"][0].update(generator={"kind": "cloud", "count": n, "seed": 1, "extent": 1.2}, radius=radius,
                         sigma_t=sigma_t, albedo=0.9, phase={"type": "hg", "g": 0.0})
    return d


def albedo_grid(quick: bool) -> list[dict]:
    return [{"albedo": a} for a in ((0.5,) if quick else (0.5, 0.8, 0.95))]


def albedo_bound(params: dict, device: str, quick: bool) -> dict:
    """The paper's claim that a step's error eps grows to at most eps / (1 - a) over the
    iteration. Without sky (so zero iterations give exactly single scattering): eps is the
    RMSE of the single-scattering image (iterations = 0) against the reference with one
    scattering event, the total is the converged image's RMSE against the unlimited one."""
    w, spp = (24, 16) if quick else (32, 256)
    table = network_table(quick, 256, w, albedo=params["albedo"], sky=False)
    scene = wv.load_scene(table)
    out = {}
    for bounces, settings in ((1, {"iterations": 0}), (-1, {"iterations": 3000, "tolerance": 1e-6})):
        r = wv.Renderer(scene, technique="illumination_network", device=device, directions=128, **settings)
        image = r.render().image
        ref, floor = reference_image(scene, device, spp=spp, max_bounces=bounces, pixel_area=0)
        out[bounces] = (wv.rmse(image, ref), wv.rmse(ref, 0.0), floor)
    eps, total = out[1][0], out[-1][0]
    a = params["albedo"]
    return untimed_row(1, eps_rmse=eps, total_rmse=total, bound=eps / (1 - a), holds=bool(total <= eps / (1 - a)),
                       ss_rms=out[1][1], ms_rms=out[-1][1], reference_floor=[out[1][2], out[-1][2]],
                       scene=f"256 particles {w}x{w}, no sky, D = 128", scene_table=table)


def drifting_cloud(positions, frame: int, spin: float = 0.02, wander: float = 0.02):
    """An animated cloud: turned by ``spin`` radians a frame about y, each particle wandering
    on its own small circle (``wander`` in scene units)."""
    import numpy as np

    p = np.asarray(positions, np.float64)
    a = spin * frame
    c, s_ = np.cos(a), np.sin(a)
    turned = np.c_[c * p[:, 0] + s_ * p[:, 2], p[:, 1], -s_ * p[:, 0] + c * p[:, 2]]
    phase = np.arange(len(p)) * 2.399963
    return (turned + wander * np.c_[np.cos(0.3 * frame + phase), np.sin(0.3 * frame + phase), np.zeros(len(p))]).astype(
        np.float32)


def animated_grid(quick: bool) -> list[dict]:
    return [{"refresh": k} for k in ((0, 4) if quick else (0, 1, 4, 16, 32))]


def animated(params: dict, device: str, quick: bool) -> dict:
    """The paper's future work: a drifting cloud (1024 particles, 128 directions, one iteration
    a frame) with the visibility network re-peeled ``refresh`` directions a frame (0: all).
    Error: the frame's image against the same frame with the whole network rebuilt."""
    import time

    import numpy as np

    frames = 6 if quick else 48
    table = network_table(quick, 1024, 128)
    scene = wv.load_scene(table)
    base = scene.media[0]
    runs = {}
    for k in sorted({0, params["refresh"]}):
        r = wv.Renderer(scene, technique="illumination_network", device=device, iterations=1, tolerance=0.0,
                        refresh=k)
        r.render()
        for _ in range(20 if not quick else 2):  # settle the static cloud first
            r.touch("camera")
            r.render()
        images, ms, net = [], [], []
        for f in range(1, frames + 1):
            r.update(medium=dataclasses.replace(base, positions=drifting_cloud(base.positions, f)))
            t0 = time.perf_counter()
            frame = r.render()
            ms.append((time.perf_counter() - t0) * 1000.0)
            net.append(frame.stages["network"].ms)
            images.append(frame.image)
        runs[k] = (images, ms, net)
    images, ms, net = runs[params["refresh"]]
    full = runs[0][0]
    err = [wv.relative_rmse(a, b) for a, b in zip(images, full)]
    return {"first_frame_ms": 0.0, "median_ms": float(np.median(ms)), "spread_ms": [min(ms), max(ms)],
            "frames": frames, "stages": {}, "network_ms": float(np.median(net)), "error_per_frame": err,
            "mean_error": float(np.mean(err[frames // 4:])), "final_error": err[-1],
            "scene": "1024 particles, 128x128, turning 0.02 rad and wandering 0.02 a frame", "scene_table": table}
