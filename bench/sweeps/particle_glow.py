"""Sweeps of particle_glow: the glowy-light paper's figure 5, physics against the reference, speed against raymarch, stability."""

from __future__ import annotations

import functools
import statistics
import time

import numpy as np

import warpvol as wv

from ..harness import reference_image, time_frames
from .common import near_point, score


#: The paper's model at the steps these pages have always used: single scattering and the glow
#: (no multiple-scattering lattice, which stands in for the glow), 128 steps.
PAPER = {"multiple_scattering": 0, "steps": 128}


def glow_scene(quick: bool, width: int = 320, height: int = 240):
    """The built-in dusty-lamp: a point lamp in dusty air (homogeneous, sigma_t 0.25, albedo
    0.9, isotropic), a floor, and a shade beside the lamp casting a shadow through the dust."""
    if quick:
        width, height = 32, 24
    return wv.load_scene("dusty-lamp", [f"camera.width={width}", f"camera.height={height}"])


def glow_figure5_grid(quick: bool) -> list[dict]:
    sets = [(2.0, 0.1, 0), (0.0, 0.1, 0), (0.5, 0.5, 0), (0.5, 0.5, 1)]
    return [{"mu": m, "sigma": sg, "cdf": c} for m, sg, c in (sets[:2] if quick else sets)]


def glow_figure5(params: dict, device: str, quick: bool) -> dict:
    """Figure 5's parameter sets (mu, sigma; A: 2, 0.1; B: 0, 0.1) and the defaults, with the
    log-normal CDF the text names (cdf 0) and the normal CDF equation 2 prints (cdf 1): the
    image, its frame time, the cells' mean density and the light the glow adds."""
    scene = glow_scene(quick)
    settings = {"mu": params["mu"], "sigma": params["sigma"], "density_cdf": params["cdf"]}
    r = wv.Renderer(scene, technique="particle_glow", **PAPER, device=device, **settings)
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("camera",))
    plain = wv.render(scene, technique="particle_glow", **PAPER, device=device, glow=0, **settings).image
    image = row["frame"].image
    row["table"] = {"mean density d": float(r.diagnostics()["density"].mean()),
                    "image mean": float(image.mean()),
                    "light the glow adds": f"{image.mean() / plain.mean() - 1:+.1%}"}
    row["images"] = {"image": image}
    row["scene"] = f"dusty-lamp {scene.camera.width}x{scene.camera.height}, 128 steps"
    return row


GLOW_TECHNIQUES = {"particle_glow": PAPER, "particle_glow (glow = 0)": {**PAPER, "glow": 0},
                   "particle_glow (specular 0.5)": {**PAPER, "specular": 0.5},
                   "raymarch": {"steps": 128, "multiple_scattering": 0},
                   "light_shafts": {"steps": 128, "block": 4, "multiple_scattering": 0}}


#: The lamp's core on the image: the pixels within this angle (radians) of the lamp as seen from the camera.
CORE_ANGLE = 0.05


def glow_physics_grid(quick: bool) -> list[dict]:
    names = list(GLOW_TECHNIQUES)
    return [{"technique": t} for t in (names[:2] if quick else names)]


def glow_physics(params: dict, device: str, quick: bool) -> dict:
    """How far the glow is from physics: the same scene (its medium already homogeneous, with
    the dust's sigma_t and phase function) by the reference, single and multiple
    scattering, against particle_glow, its direct sample alone (glow = 0), raymarch and
    light_shafts at 128 steps."""
    name = params["technique"]
    scene = glow_scene(quick, 160, 120)
    r = wv.Renderer(scene, technique=name.split(" ")[0], device=device, **GLOW_TECHNIQUES[name])
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("camera",))
    spp = 16 if quick else 512
    score(row, scene, device, spp)
    ms, _ = reference_image(scene, device, spp=spp, max_bounces=-1, pixel_area=0)
    image = row["frame"].image
    row["rel_rmse_multiple"] = wv.relative_rmse(image, ms)
    row["mean_ratio"] = float(image.mean() / ms.mean())
    # the error split at the lamp's core (its singular 1/d^2, a few pixels) and the rest of the image,
    # each scaled by the whole image's mean so the two add in quadrature weighted by their pixels
    core = near_point(scene.camera, scene.lights[0].position, CORE_ANGLE)
    scale = float(ms.mean())
    for part, mask in (("core", core), ("rest", ~core)):
        row[f"rel_rmse_{part}"] = float(np.sqrt(np.mean((image[mask] - ms[mask]) ** 2)) / scale) if mask.any() else 0.0
    row["core_pixels"] = int(core.sum())
    row["scene"] = f"dusty-lamp {scene.camera.width}x{scene.camera.height}"
    return row


def glow_speed_grid(quick: bool) -> list[dict]:
    return [{"width": 64 if quick else 640}]


def glow_speed(params: dict, device: str, quick: bool) -> dict:
    """particle_glow against the raymarch baseline with the same 128 steps on the same scene
    (dusty-lamp at 640x480, camera moving), frames timed in alternation so both see the same
    machine; the issue's bound: at most 1.5x."""
    w = params["width"]
    scene = glow_scene(False, w, w * 3 // 4)
    rs = {"particle_glow": wv.Renderer(scene, technique="particle_glow", **PAPER, device=device),
          "raymarch": wv.Renderer(scene, technique="raymarch", multiple_scattering=0, device=device, steps=128)}
    for r in rs.values():
        r.render()
    times = {k: [] for k in rs}
    for _ in range(2 if quick else 5):
        for k, r in rs.items():
            r.touch("camera")
            t = time.perf_counter()
            r.render()
            times[k].append(time.perf_counter() - t)
    glow, ray = (statistics.median(times[k]) * 1e3 for k in ("particle_glow", "raymarch"))
    row = time_frames(rs["particle_glow"], repeats=1, invalidate=("camera",))
    row["table"] = {"particle_glow ms": glow, "raymarch ms (128 steps)": ray, "glow / raymarch": f"{glow / ray:.2f}"}
    row["scene"] = f"dusty-lamp {w}x{w * 3 // 4}, 128 steps"
    return row


def glow_stability_grid(quick: bool) -> list[dict]:
    steps = (0.005,) if quick else (0.005, 0.0005)
    return ([{"glow": 1, "anchor": a, "grain": g, "step": st} for a in (0, 1) for g in ("world", "screen")
             for st in steps] + [{"glow": 0, "anchor": 0, "grain": "world", "step": st} for st in steps])


def _moved_lamp(dx: float, move_scene: bool, width: int, height: int) -> dict:
    """dusty-lamp seen from a camera moved dx along x; ``move_scene``: the scene moved by -dx
    instead (the same picture of the lamp, but the grain textures, fixed in the world, now
    stay put on the screen: the counterfactual of screen-space grain)."""
    from warpvol.scene.procedural import dusty_lamp

    d = dusty_lamp()
    d["camera"]["width"], d["camera"]["height"] = width, height
    if move_scene:
        d["lights"][0]["position"][0] -= dx
        d["media"][0]["center"][0] -= dx
        for surface in d["surfaces"]:
            surface["center"][0] -= dx
    else:
        d["camera"]["origin"][0] += dx
        d["camera"]["target"][0] += dx
    return d


def glow_stability(params: dict, device: str, quick: bool) -> dict:
    """Temporal stability: a camera moving ``step`` along x a frame (4 frames); the mean
    frame-to-frame change relative to the image's mean, and the fraction of pixels that pop
    (change by more than 10%). Grain that shimmers would leave a floor as step -> 0; grain
    that moves with the world changes in proportion to the motion (change / step constant).
    grain = screen: the counterfactual of grain fixed to the screen (the scene moved instead)."""
    w, h = (32, 24) if quick else (160, 120)
    frames = []
    for k in range(4):
        scene = _moved_lamp(params["step"] * k, params["grain"] == "screen", w, h)
        frames.append(wv.render(scene, technique="particle_glow", **PAPER, device=device, glow=params["glow"],
                                anchor=params["anchor"]).image.astype(np.float64).mean(-1))
    change = [np.abs(b - a).mean() / a.mean() for a, b in zip(frames, frames[1:])]
    pops = [np.mean(np.abs(b - a) > 0.1 * np.maximum(a, 1e-3)) for a, b in zip(frames, frames[1:])]
    r = wv.Renderer(_moved_lamp(0.0, False, w, h), technique="particle_glow", **PAPER, device=device, glow=params["glow"],
                    anchor=params["anchor"])
    row = time_frames(r, repeats=1, invalidate=("camera",))
    row["table"] = {"mean change": float(np.mean(change)), "change / step": float(np.mean(change) / params["step"]),
                    "pixels that pop (> 10%)": float(np.mean(pops))}
    row["scene"] = f"dusty-lamp {w}x{h}, camera moving along x"
    return row


#: The ground-truth room: a box of dust 2 units wide (mean sigma_t GT_SIGMA, albedo 0.9,
#: isotropic), a lamp inside it, a ball beside the lamp casting a shadow through the dust, a
#: floor; particle_glow's textures with cells of GT_CELL (24 per side of the box), the explicit
#: particles GT_PER_CELL d a cell on average, spheres of GT_RADIUS cells.
GT_SIGMA, GT_CELL, GT_PER_CELL, GT_RADIUS = 0.8, 2.0 / 24.0, 1.0, 0.3
GT_LAMP = [0.0, 0.6, 0.0]
#: No explicit particle within this distance of the lamp (a lamp among particles lights the nearest
#: ones by 1/d^2 without bound: specks that would outweigh the rest of the image and its noise).
GT_CLEAR = 0.2
GT_GLOW = {"off": {"glow": 0, "multiple_scattering": 0}, "nearest": {"glow": 1, "multiple_scattering": 0},
           "two": {"glow": 2, "multiple_scattering": 0}, "two, summed": {"glow": 2, "multiple_scattering": 0},
           "lattice": {"glow": 0, "multiple_scattering": 8}}


GT_NOTE = ("The paper's claim (section 5): the glow \"mimics multi-scattering model by projecting single-scattering "
           "from different particles acting as a luminaire\", taking \"the first and second closest particles\". "
           "What it imitates: a medium of explicit particles, here drawn from particle_glow's own density texture "
           "(`warpvol.scene.procedural.glow_particles`: a Poisson number of mean d a cell, spheres of 0.3 cells, their "
           "sigma_t set so the box's mean extinction is the homogeneous dust's 0.8; none within 0.2 of the lamp, whose "
           "1/d^2 would light the nearest without bound) and rendered by the reference "
           "with all orders of scattering. particle_glow renders the homogeneous dust, its particles only in the "
           "textures (the paper's set-up). How to read it: *error outside the lamp* is the RMSE over the pixels "
           "beyond 0.05 rad of the lamp, over their mean in the particles' image, the reference's noise removed; "
           "two draws differ from each other by their own grain, so no deterministic image comes nearer a draw than "
           "*the homogeneous reference's* column allows; *grain* is the RMS of what a 3x3 blur takes away, over the "
           "mean, beside the explicit particles' own (noise removed). *two, summed* is the off image plus twice "
           "what the two averaged particles add (the march is linear in its source): the other reading of "
           "section 5.")


def glow_room(medium: dict, name: str, width: int, height: int) -> dict:
    return {"name": name, "background": [0.0, 0.0, 0.0],
            "camera": {"origin": [0.0, 0.2, 3.6], "target": [0.0, 0.0, 0.0], "fov_y": 45.0, "width": width,
                       "height": height},
            "lights": [{"type": "point", "position": GT_LAMP, "intensity": [3.0, 3.0, 3.0]}],
            "media": [{**medium, "albedo": 0.9, "phase": {"type": "isotropic"}}],
            "surfaces": [{"type": "sphere", "center": [0.35, 0.25, 0.1], "radius": 0.18, "diffuse": 0.5},
                         {"type": "plane", "center": [0.0, -1.0, 0.0], "normal": [0, 1, 0], "size": [4, 4],
                          "diffuse": 0.5}]}


def glow_particle_draw(draw: int, width: int, height: int) -> dict:
    """The room with explicit particles drawn from particle_glow's density texture at its
    defaults (``scene.procedural.glow_particles``, seed ``draw``), none within GT_CLEAR of the
    lamp, their sigma_t set so that the box's mean extinction is GT_SIGMA."""
    from warpvol.scene.procedural import density_texture, glow_particles

    s = wv.technique_class("particle_glow").SETTINGS
    d = density_texture(s["texture_res"].default, s["mu"].default, s["sigma"].default, s["density_x"].default,
                        s["density_cdf"].default == 0, s["seed"].default)
    points = glow_particles(d, GT_CELL, [-1, -1, -1], [1, 1, 1], GT_PER_CELL, draw)
    points = points[np.linalg.norm(points - np.asarray(GT_LAMP), axis=1) > GT_CLEAR]
    r = GT_RADIUS * GT_CELL
    sigma = GT_SIGMA * 8.0 / (len(points) * 4.0 / 3.0 * np.pi * r**3)
    return glow_room({"type": "particles", "positions": points.tolist(), "radius": r, "sigma_t": sigma},
                     f"glow-particles-{draw}", width, height)


def fine_detail(image: np.ndarray, mask: np.ndarray) -> float:
    """The RMS over ``mask`` of what a 3x3 box blur takes from the image (RGB averaged)."""
    lum = np.asarray(image, np.float64).mean(-1)
    pad = np.pad(lum, 1, mode="edge")
    blur = sum(pad[i:i + lum.shape[0], j:j + lum.shape[1]] for i in range(3) for j in range(3)) / 9.0
    return float(np.sqrt(np.mean((lum - blur)[mask] ** 2)))


@functools.lru_cache(maxsize=4)
def _particles_and_noise(draw: int, w: int, h: int, spp: int, device: str) -> tuple[dict, np.ndarray]:
    """A draw's scene and an image of its reference's noise, made once per draw for the rows
    that share them: two seeds of spp / 16 each, half their difference 4x the noise of the mean
    of two seeds of spp (variance 16 / spp over 2 against 1 / (2 spp)), scaled down by 4."""
    particles = glow_particle_draw(draw, w, h)
    lo = max(spp // 16, 1)
    a, b = (wv.render(particles, technique="reference", device=device, spp=lo, max_bounces=-1, seed=k).image
            for k in (11, 12))
    return particles, (a.astype(np.float64) - b) / 8.0


def glow_truth_grid(quick: bool) -> list[dict]:
    draws = (0,) if quick else (0, 1, 2)
    return [{"technique": "particle_glow", "variant": v, **GT_GLOW[v], "draw": k} for k in draws for v in GT_GLOW]


def glow_truth(params: dict, device: str, quick: bool) -> dict:
    """particle_glow on the room's homogeneous dust (the paper's medium: its particles only in
    the textures) against the reference on explicit particles drawn from the same density
    texture (all orders, 1024 spp a seed, pixel centres), one draw a row: the glow off, the
    nearest particle (equations 3-4), the two nearest averaged (section 5; ``glow`` = 2) and
    summed (the off image plus twice what the two add: the march is linear in its source), and
    the multiple-scattering lattice in place of the glow. Errors outside the lamp's core (its
    1/d^2 singularity, the same in every image), the references' noise removed in quadrature."""
    w, h = (16, 12) if quick else (80, 60)
    spp = 16 if quick else 1024
    table = glow_room({"type": "homogeneous", "shape": "box", "center": [0, 0, 0], "size": [2, 2, 2],
                       "sigma_t": GT_SIGMA}, "glow-room", w, h)
    scene = wv.load_scene(table)
    settings = {"steps": 128, "cell": GT_CELL, **GT_GLOW[params["variant"]]}
    r = wv.Renderer(scene, technique="particle_glow", device=device, **settings)
    row = time_frames(r, repeats=2 if quick else 3, invalidate=("camera",))
    image = row["frame"].image.astype(np.float64)
    if params["variant"] == "two, summed":
        off = wv.render(scene, technique="particle_glow", device=device, **{**settings, "glow": 0}).image
        image = 2.0 * image - off
    particles, noise_image = _particles_and_noise(params["draw"], w, h, spp, device)
    ref, _ = reference_image(particles, device, spp=spp, max_bounces=-1, pixel_area=0)
    smooth, _ = reference_image(scene, device, spp=spp, max_bounces=-1, pixel_area=0)
    rest = ~near_point(scene.camera, GT_LAMP, CORE_ANGLE)
    scale = float(ref.astype(np.float64).mean(-1)[rest].mean())

    def error(x, y):
        return float(np.sqrt(np.mean((np.asarray(x, np.float64) - y)[rest] ** 2)) / scale)

    def less_noise(e, n):
        return float(np.sqrt(max(e**2 - n**2, 0.0)))

    noise = error(noise_image, 0.0)
    row["table"] = {
        "error outside the lamp": less_noise(error(image, ref), noise),
        "the homogeneous reference's": less_noise(error(smooth, ref), noise),
        "mean / the particles'": float(image.mean(-1)[rest].mean() / scale),
        "grain": fine_detail(image, rest) / float(image.mean(-1)[rest].mean()),
        "the particles' grain": less_noise(fine_detail(ref, rest), fine_detail(noise_image, rest)) / scale,
        "HDR-FLIP": float(wv.hdr_flip(image.astype(np.float32), ref)),
        "reference noise": noise,
    }
    if params["draw"] == 0 and params["variant"] in ("nearest", "lattice"):
        row["images"] = {"image": image.astype(np.float32)}
        if params["variant"] == "nearest":
            row["images"]["particles_reference"] = ref
    row["scene"] = f"glow-room {w}x{h}, particles draw {params['draw']}"
    row["scene_table"] = table
    return row
