"""Sweeps of depth_impostors: Umenhoffer & Szirmay-Kalos 2005 figure 5, block sizes, accuracy, objects in clouds."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

import warpvol as wv

from ..harness import reference_image, time_frames
from .common import pixel_directions, score


IMPOSTOR_SUN = {"type": "directional", "direction": [0.5, -0.8, -0.3], "irradiance": 2.0}


def impostor_scene(quick: bool, n: int = 8000, per_block: int = 200, width: int = 512, surface: bool = False,
                   seed: int = 3):
    """The Scene of ``impostor_table``."""
    return wv.load_scene(impostor_table(quick, n, per_block, width, surface, seed))


def impostor_table(quick: bool, n: int = 8000, per_block: int = 200, width: int = 512, surface: bool = False,
                   seed: int = 3) -> dict:
    """As a scene table: Umenhoffer & Szirmay-Kalos 2005's set-up: ``n`` particles built of n / per_block copies of one block (one
    particle a block: the paper's "no blocks"), one directional light. The block's radius
    scales as (per_block / n)^(1/3), so the cloud's volume and density stay put; particle
    radius 0.04 x (8000 / n)^(1/3), sigma_t 12 (sigma_t r = 0.48 at 8000), albedo 0.9, HG
    g = 0.3, a dim sky. ``surface``: a grey plane through the cloud's centre, facing the camera
    at an angle (an object in the cloud)."""
    if quick:
        n, per_block, width = min(n, 400), min(per_block, 20), min(width, 32)
    per_block = max(1, min(per_block, n))
    blocks = n // per_block
    radius = 0.04 * (8000 / n) ** (1 / 3)
    d = {"name": "impostor-cloud", "background": [0.05, 0.07, 0.1],
         "camera": {"origin": [0.0, 0.3, 4.2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40.0, "width": width,
                    "height": width},
         "lights": [IMPOSTOR_SUN],
         "media": [{"type": "particles", "radius": radius, "sigma_t": 12.0, "albedo": 0.9,
                    "phase": {"type": "hg", "g": 0.3},
                    "generator": {"kind": "blocks", "blocks": blocks, "per_block": per_block, "seed": seed,
                                  "extent": 1.0, "block_extent": (per_block / (blocks * per_block)) ** (1 / 3)}}]}
    if surface:
        d["surfaces"] = [{"type": "plane", "center": [0.0, 0.0, 0.0], "normal": [0.3, 0.2, 1.0], "size": [4.0, 4.0],
                          "diffuse": 0.5}]
    return d


IMPOSTOR_FIG5_NOTE = """\
**Set-ups.** `setup=paper` is the paper's figure 5: one sun, a black sky, and the camera and
the sun moving every frame (the camera orbits 2 degrees and the sun turns 3 a frame), so the
camera impostors of the template (the b term) are made again every frame. `setup=ours` is our
default scene: a dim sky lights the cloud too (8 more light passes, one per sky direction, and
9 lights to shade each texel), the camera fixed (its impostors cached). Each set-up's FPS ratio
is to its own first row (no blocks).

**Stages.** *light*: the light pass, block by block where the cloud is built of blocks (one
light impostor per template and light, b work, splatted once per instance, N / b); *impostors*:
the template's camera impostor (b particles x T^2 texels, each texel's chords weighed against the
others in front: b^2 T^2, why 20 blocks of 400 cost more here than 40 of 200); *shade*: the light
at every impostor texel (blocks) or particle (no blocks); *gather*: every pixel composites the
instances listed in its 8 x 8 pixel tile, nearest first. An instance is listed in the tiles
whose cone of rays meets its bounding sphere: a particle's own sphere, a block's reach R (its
impostor is read only within R of its centre, in its plane, where its spheres are). *T* (the
last column) is the camera impostor's texels a side,
from the block's size: 3 R / r (a texel two thirds of a particle radius r across, R the block's
radius), no finer than two pixels of the block's largest projected diameter; so the 1600 blocks
of 5 particles get T = 8, not the 16 a fixed resolution gave them (4x the texels to shade).

**The paper's no-block row.** On the paper's GPU each particle on its own is a draw with a
read-back of its light from the light pass, so the per-particle cost is fixed overhead and
blocks remove it almost wholly (25x at 40 blocks). Here no stage has a per-particle overhead
of that kind: with no blocks a particle costs its shading (a few light-map reads) and its
pixels in the gather, and blocks save only the part of that work that is per particle, not
the pixels a block still covers. The gather is the floor: the last column but one counts the
(pixel, instance) pairs it looks at, with no blocks mostly misses of a sphere test, with blocks
an impostor lookup each, on top of every pixel's own cost. That is why our best ratio is
smaller than the paper's.
"""


def impostor_fig5_grid(quick: bool) -> list[dict]:
    blocks = (0, 20) if quick else (0, 1600, 800, 400, 40, 20)
    return [{"blocks": b, "setup": s} for s in ("paper", "ours") for b in blocks]


def _moving_frames(r: wv.Renderer, scene, repeats: int) -> dict:
    """``time_frames`` for the paper's animation: before every frame the camera orbits the
    cloud by 2 degrees and the sun turns by 3 (and the medium is marked changed), so every
    stage runs, the camera impostors (the b term) included."""
    cam, sun = scene.camera, dict(IMPOSTOR_SUN)
    frame_no = [0]

    def move():
        frame_no[0] += 1
        a, b = np.radians(2.0 * frame_no[0]), np.radians(3.0 * frame_no[0])
        o = np.asarray(cam.origin, float)
        origin = [o[0] * np.cos(a) + o[2] * np.sin(a), o[1], -o[0] * np.sin(a) + o[2] * np.cos(a)]
        d = np.asarray(sun["direction"], float)
        direction = [d[0] * np.cos(b) - d[2] * np.sin(b), d[1], d[0] * np.sin(b) + d[2] * np.cos(b)]
        r.update(camera=dataclasses.replace(cam, origin=tuple(origin)), lights=[{**sun, "direction": direction}])
        r.touch("medium")

    return time_frames(r, repeats, invalidate=None, before=move)


def impostor_frame(params: dict, device: str, quick: bool) -> dict:
    """A frame of an animated cloud, 512x512; blocks = 0: every particle on its own.
    ``setup`` "paper": the paper's figure 5, a single sun and a black sky, the camera and
    the sun moving every frame; "ours" (and the N sweep): our defaults, a dim sky (8 sky
    directions, each its own light pass), the medium and the lights marked changed every
    frame and the camera fixed (the camera impostors cached)."""
    n = params.get("particles", 8000)
    blocks = params.get("blocks")
    per_block = params.get("per_block") or (1 if not blocks else n // blocks)
    table = impostor_table(quick, n, per_block, params.get("width", 512))
    paper = params.get("setup") == "paper"
    if paper:
        table["background"] = [0.0, 0.0, 0.0]
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="depth_impostors", multiple_scattering=0, device=device)
    repeats = 2 if quick else 8
    row = _moving_frames(r, scene, repeats) if paper else time_frames(r, repeats, invalidate=("medium", "lights"))
    d = r.diagnostics()
    row.update(instances=d["instances"], per_block=per_block, light_texels=d["light_texels"],
               impostor_res=d["impostor_res"], gather_tests=d["gather_tests"],
               light_template_texels=d["light_template_texels"],
               scene=f"{len(scene.media[0].positions)} particles, {d['instances']} instances of {per_block}, "
                     f"{scene.camera.width}x{scene.camera.height}, "
                     + ("one sun, black sky, camera and sun moving" if paper else "one sun and a dim sky, camera fixed"),
               scene_table=table)
    return row


def impostor_sweep_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"particles": 400, "per_block": b} for b in (1, 20)]
    return [{"particles": n, "per_block": b} for n in (1000, 8000, 64000) for b in (1, 5, 20, 50, 200, 1000) if b <= n]


def impostor_accuracy_grid(quick: bool) -> list[dict]:
    if quick:
        return [{"light": "slices", "terms": 4, "res": 8}, {"light": "exact", "terms": 0, "res": 8}]
    return ([{"light": "slices", "terms": s, "res": 16} for s in (1, 2, 4, 8, 16, 32)]
            + [{"light": "slices", "terms": 4, "res": r} for r in (0, 4, 8, 32, 64)]
            + [{"light": "fourier", "terms": k, "res": 16} for k in (2, 4, 8, 16)]
            + [{"light": "exact", "terms": 0, "res": r} for r in (0, 16, 64)]
            + [{"light": "slices", "terms": 4, "res": 16, "sky": k} for k in (0, 1, 4, 16, 64)]
            + [{"light": "slices", "terms": 4, "res": 16, "widen": w} for w in (0.5, 1.0, 2.0, 4.0)])


def _impostor_settings(params: dict) -> dict:
    kind = {"exact": 0, "slices": 1, "fourier": 2}[params["light"]]
    out = {"light_pass": kind, "impostor_res": params["res"]}
    for key, setting in (("sky", "sky_samples"), ("widen", "widen")):
        if key in params:
            out[setting] = params[key]
    if kind == 1:
        out["slices"] = params["terms"]
    elif kind == 2:
        out["light_terms"] = params["terms"]
    return out


def impostor_accuracy(params: dict, device: str, quick: bool) -> dict:
    """The image against the single-scattering reference at pixel centres, 2000 particles in
    40 blocks of 50 (96x96); and how much the technique leaves out: the single-scattering
    reference's mean over the multiple-scattering one's."""
    n, b, w = (400, 20, 24) if quick else (2000, 50, 96)
    table = impostor_table(quick, n, b, w)
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="depth_impostors", multiple_scattering=0, device=device, **_impostor_settings(params))
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("medium", "lights"))
    spp = 16 if quick else 256
    ref = score(row, scene, device, spp)
    ms, _ = reference_image(scene, device, spp=spp, max_bounces=-1, pixel_area=0)
    image = row["frame"].image
    row["rel_rmse_multiple"] = wv.relative_rmse(image, ms)
    row["mean_ratio"] = float(image.mean() / ref.mean())
    row["single_of_multiple"] = float(ref.mean() / ms.mean())
    row["impostor_res"] = r.diagnostics()["impostor_res"]
    row["scene"] = f"{n} particles in {n // b} blocks of {b}, {w}x{w}, one sun"
    row["scene_table"] = table
    return row


def _plane_hits(scene) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel (H, W), the distance along its ray to the scene's first surface's plane and the
    point where it meets it."""
    cam, plane = scene.camera, scene.surfaces[0]
    o = np.asarray(cam.origin, float)
    d = pixel_directions(cam)
    v = np.asarray(plane.vertices, float)
    n = np.cross(v[1] - v[0], v[2] - v[0])
    n /= np.linalg.norm(n)
    t_s = ((v[0] - o) @ n) / (d @ n)
    return t_s, o + t_s[..., None] * d


def _plane_in_blocks(scene, centres: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """(H, W) mask of the pixels whose ray meets the scene's plane inside some block's
    bounding sphere (where depth impostors and billboards differ)."""
    t_s, hit = _plane_hits(scene)
    dist = np.linalg.norm(hit[..., None, :] - np.asarray(centres, float)[None, None], axis=-1)
    return np.any(dist < np.asarray(reach, float)[None, None], axis=-1) & (t_s > 0)


def impostor_objects_grid(quick: bool) -> list[dict]:
    return [{"object_depth": k, "per_block": b} for b in ((20,) if quick else (50, 200)) for k in (0, 1)]


def impostor_objects(params: dict, device: str, quick: bool) -> dict:
    """Objects in clouds (section 2.4): a plane through the cloud; depth impostors (the block's
    opacity cut at the surface) against billboards (a block wholly in front or behind),
    both against the single-scattering reference, over the image and over the pixels where
    the plane lies inside the cloud (the reference's cloud changes there by over 2%)."""
    n, w = (400, 24) if quick else (2000, 96)
    b = params["per_block"]
    table = impostor_table(quick, n, b, w, surface=True)
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="depth_impostors", multiple_scattering=0, device=device, object_depth=params["object_depth"],
                    light_pass=0)
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("medium", "lights"))
    ref = score(row, scene, device, 16 if quick else 256)
    image = row["frame"].image
    band = _plane_in_blocks(scene, r.diagnostics()["block_centres"], r.diagnostics()["block_reach"])
    row["band_pixels"] = int(band.sum())
    row["rel_rmse_band"] = wv.relative_rmse(image[band], ref[band]) if band.any() else float("nan")
    row["scene"] = (f"{n} particles in {n // b} blocks of {b}, a plane through the cloud, {w}x{w}; band: the "
                    f"{row['band_pixels']} pixels where the plane lies inside a block's bounding sphere")
    row["scene_table"] = table
    row["images"] = {"image": image}
    return row


#: The clipping scene: a grid of CLIP_GRID^2 large particles (radius CLIP_RADIUS, sigma_t r = 0.6,
#: each its own instance: the paper's "no blocks") straddling a dark plane, each centre a seeded
#: offset of up to CLIP_RADIUS in front of it or behind it, lit by a sun from the camera's side.
CLIP_GRID, CLIP_RADIUS, CLIP_SIGMA = 5, 0.25, 2.4
#: A moving cloud drifts this far a frame (scene units) along the plane's normal, through it.
CLIP_DRIFT = 0.05
CLIP_NORMAL = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
CLIP_NOTE = ("The paper's claim (section 2.4): billboards \"are clipped by the objects of the scene\" where an "
             "object lies inside the cloud, and depth impostors repair it by cutting each impostor's opacity at the "
             "surface's depth. The scene: 25 large, translucent particles (radius 0.25, sigma_t r = 0.6), each its own "
             "instance, straddling a dark plane, lit by a sun from the camera's side. How to read it: *seam* is the "
             "RMSE over the pixels whose ray meets the plane inside a particle (or within one pixel's width of one), "
             "over their mean in the reference, single scattering (the technique's model, `multiple_scattering` = 0); "
             "*off-seam* the same over the particles' pixels away from the seam: the error of their shading, which "
             "the seam carries too; *clipping part* the seam's error with the off-seam error taken out in quadrature, "
             "what the clipping adds (the claim is about it: billboards against impostors, in one shading); "
             "*image* the same over the whole image, the reference's noise (last column, two seeds of 256 spp) "
             "removed. A one-particle instance is cut exactly along its chord at the surface; a billboard stands at "
             "its centre, wholly in front of the surface or behind it. *moving*: the particles drift 0.05 a frame "
             "along the plane's normal for four frames (`Renderer.update(medium=...)`), the errors the mean over the "
             "frames. *particle_shading*: sphere is the paper's one radiance a particle (its irradiance averaged over "
             "the sphere); chord shades each pixel's visible chord at the depth its light comes from. Where the particles crowd into a thick cloud (depth-impostors-objects), the seam is not what "
             "the error is made of: each particle is shaded with one radiance and the light pass holds the cloud "
             "alone (docs/techniques/depth_impostors.md).")


def clip_table(quick: bool) -> dict:
    """The clipping scene as a table (its particles listed: 25, a small table)."""
    rng = np.random.default_rng(7)
    t1 = np.cross(CLIP_NORMAL, [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(CLIP_NORMAL, t1)
    k = (np.arange(CLIP_GRID) - (CLIP_GRID - 1) / 2) * 2.2 * CLIP_RADIUS
    centres = [u * t1 + v * t2 + rng.uniform(-CLIP_RADIUS, CLIP_RADIUS) * CLIP_NORMAL for u in k for v in k]
    w = 24 if quick else 96
    return {"name": "impostor-clipping", "background": [0.05, 0.07, 0.1],
            "camera": {"origin": [0.0, 0.3, 4.2], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40.0, "width": w,
                       "height": w},
            "lights": [IMPOSTOR_SUN],
            "media": [{"type": "particles", "positions": [[round(float(x), 6) for x in c] for c in centres],
                       "radius": CLIP_RADIUS, "sigma_t": CLIP_SIGMA, "albedo": 0.9, "phase": {"type": "hg", "g": 0.3}}],
            "surfaces": [{"type": "plane", "center": [0.0, 0.0, 0.0], "normal": CLIP_NORMAL.tolist(), "size": [4.0, 4.0],
                          "diffuse": 0.05}]}


def _clip_seam(scene) -> np.ndarray:
    """(H, W) mask of the pixels whose ray meets the plane inside a particle, or within one
    pixel's width of one (where billboards and depth impostors differ)."""
    cam, m = scene.camera, scene.media[0]
    t_s, hit = _plane_hits(scene)
    pixel = t_s * 2.0 * np.tan(np.radians(cam.fov_y) / 2.0) / cam.height
    dist = np.linalg.norm(hit[..., None, :] - np.asarray(m.positions, float)[None, None], axis=-1).min(axis=-1)
    return (dist < m.radius + pixel) & (t_s > 0)


def _particle_pixels(scene) -> np.ndarray:
    """(H, W) mask of the pixels whose ray meets a particle in front of the plane (or with no
    plane behind it): where the particles' own shading shows, clipped or not."""
    cam, m = scene.camera, scene.media[0]
    o = np.asarray(cam.origin, float)
    d = pixel_directions(cam)
    t_s, _ = _plane_hits(scene)
    t_s = np.where(t_s > 0, t_s, np.inf)
    rel = np.asarray(m.positions, float) - o  # (N, 3)
    b = d @ rel.T  # (H, W, N): the centres' depths along each ray
    q = b * b - (rel * rel).sum(-1)[None, None] + m.radius**2
    near = b - np.sqrt(np.maximum(q, 0.0))
    return np.any((q > 0) & (near < t_s[..., None]) & (b + np.sqrt(np.maximum(q, 0.0)) > 0), axis=-1)


def impostor_clipping_grid(quick: bool) -> list[dict]:
    return [{"object_depth": k, "motion": mo, "particle_shading": sh} for mo in ("still", "moving")
            for sh in ("sphere", "chord") for k in ("billboards", "impostors")]


def impostor_clipping(params: dict, device: str, quick: bool) -> dict:
    """Billboards against depth impostors where large particles meet a plane through the cloud
    (section 2.4), both against the single-scattering reference: over the seam (the plane
    inside a particle) and over the image; still, and with the cloud drifting through the
    plane (the instances moved each frame)."""
    table = clip_table(quick)
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="depth_impostors", multiple_scattering=0, device=device,
                    object_depth=params["object_depth"], particle_shading=params["particle_shading"],
                    light_pass="exact")
    spp = 16 if quick else 256
    if params["motion"] == "still":
        row = time_frames(r, repeats=2 if quick else 5, invalidate=("medium", "lights"))
        frames = [(scene, row["frame"].image)]
    else:
        medium, normal = scene.media[0], CLIP_NORMAL
        r.render()
        frames, times, stages = [], [], []
        for k in range(4):
            moved = dataclasses.replace(medium, positions=(medium.positions - k * CLIP_DRIFT * normal).astype(np.float32))
            t = time.perf_counter()
            r.update(medium=moved)
            frame = r.render()
            times.append(time.perf_counter() - t)
            stages.append(frame.stages)
            frames.append((dataclasses.replace(scene, media=[moved]), frame.image))
        row = {"first_frame_ms": 0.0, "median_ms": float(np.median(times)) * 1e3,
               "spread_ms": [min(times) * 1e3, max(times) * 1e3], "frames": len(times),
               "stages": {n: {"status": stages[-1][n].status, "median_ms": float(np.median([s[n].ms for s in stages]))}
                          for n in stages[-1]}}
    seam, off, whole, flips, pixels = [], [], [], [], []
    for sc, image in frames:
        ref, floor = reference_image(sc, device, spp=spp, max_bounces=1, pixel_area=0)
        band = _clip_seam(sc)
        away = _particle_pixels(sc) & ~band
        pixels.append(int(band.sum()))
        seam.append(wv.relative_rmse(image[band], ref[band]) if band.any() else float("nan"))
        off.append(wv.relative_rmse(image[away], ref[away]) if away.any() else float("nan"))
        whole.append(max(wv.relative_rmse(image, ref) ** 2 - floor**2, 0.0) ** 0.5)
        flips.append(wv.hdr_flip(image, ref))
    seam_error, off_error = float(np.mean(seam)), float(np.mean(off))
    # what the clipping adds: the seam's error with the particles' own shading error (measured
    # away from the seam) taken out in quadrature
    row["table"] = {"seam error": seam_error, "off-seam error": off_error,
                    "clipping part": float(np.sqrt(max(seam_error**2 - off_error**2, 0.0))),
                    "image error": float(np.mean(whole)), "HDR-FLIP": float(np.mean(flips)),
                    "seam pixels": int(np.mean(pixels)), "reference noise (image)": float(floor)}
    if params["motion"] == "still" and params["particle_shading"] == "sphere":
        row["images"] = {"image": frames[0][1]}
        if params["object_depth"] == "impostors":
            row["images"]["reference"] = ref
    w = scene.camera.width
    row["scene"] = f"impostor-clipping {CLIP_GRID ** 2} large particles straddling a plane, {w}x{w}"
    row["scene_table"] = table
    return row


INSIDE_NOTE = ("A camera inside a cloud: 300 particles (radius 0.3, sigma_t 2, albedo 0.9, HG 0.3) spread over a "
               "2.4-unit cube around the eye, three of them placed to hold the eye (with the random ones, four do), "
               "under a sun; the technique against the single-scattering reference at pixel centres, the light pass "
               "at its default (depth slices). *eye inside*: the spheres that hold the eye; *mean / reference*: the "
               "image's mean over the reference's. A sphere that holds the eye is seen from inside: "
               "*sphere* shading gives it the one radiance of the whole sphere, lit side included, over the chord "
               "from the eye to its far side; *chord* shades that chord at the depth its light comes from.")


def inside_table(quick: bool) -> dict:
    """300 particles around the eye, three of them placed to hold it (a table: the positions listed)."""
    rng = np.random.default_rng(3)
    pos = rng.uniform(-1.2, 1.2, (300, 3))
    pos[:3] = [[0.05, 0.0, -0.05], [-0.1, 0.05, 0.1], [0.1, -0.12, 0.0]]  # spheres that hold the eye
    w, h = (24, 18) if quick else (96, 72)
    return {"name": "inside-cloud", "background": [0.05, 0.07, 0.1],
            "camera": {"origin": [0.0, 0.0, 0.0], "target": [0.0, 0.0, -1.0], "fov_y": 60.0, "width": w, "height": h},
            "lights": [IMPOSTOR_SUN],
            "media": [{"type": "particles", "positions": [[round(float(x), 6) for x in p] for p in pos], "radius": 0.3,
                       "sigma_t": 2.0, "albedo": 0.9, "phase": {"type": "hg", "g": 0.3}}]}


def impostor_inside_grid(quick: bool) -> list[dict]:
    return [{"object_depth": k, "particle_shading": sh} for sh in ("sphere", "chord") for k in ("billboards", "impostors")]


def impostor_inside(params: dict, device: str, quick: bool) -> dict:
    """Depth impostors with the camera inside the cloud, some particles holding the eye, against
    the single-scattering reference."""
    table = inside_table(quick)
    scene = wv.load_scene(table)
    r = wv.Renderer(scene, technique="depth_impostors", multiple_scattering=0, device=device,
                    object_depth=params["object_depth"], particle_shading=params["particle_shading"])
    row = time_frames(r, repeats=2 if quick else 5, invalidate=("medium", "lights"))
    impostors, chord = params["object_depth"] == "impostors", params["particle_shading"] == "chord"
    ref = score(row, scene, device, 16 if quick else 256, error_map=impostors and chord)
    m = scene.media[0]
    eye = np.asarray(scene.camera.origin, float)
    row["table"] = {"error": row["rel_rmse_corrected"], "HDR-FLIP": row["hdr_flip"],
                    "mean / reference": float(row["frame"].image.mean() / ref.mean()),
                    "eye inside": int(np.sum(np.linalg.norm(np.asarray(m.positions, float) - eye, axis=1) < m.radius)),
                    "reference noise": row["reference"]["rel_rmse_floor"]}
    if impostors:
        row.setdefault("images", {})["image"] = row["frame"].image
        if chord:
            row["images"]["reference"] = ref
    row["scene"] = f"inside-cloud 300 particles around the eye, {scene.camera.width}x{scene.camera.height}"
    row["scene_table"] = table
    return row
