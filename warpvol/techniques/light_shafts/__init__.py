"""Light shafts: shadow-mapped single scattering with interleaved sampling.

Tóth & Umenhoffer, "Real-time Volumetric Lighting in Participating Media", Eurographics
2009 short papers. Per pixel, the radiance of the visible surface L0 is
attenuated to the camera and the in-scattered light of every light is added along the
view ray (the paper's equation 1):

    L = L0 exp(-tau s) + sum_n Li(x(l_n)) exp(-tau l_n) dl,
    Li(x) = sigma_s p(cos) I / d^2 v(x) exp(-tau d),

with v(x) the shadow-map visibility of x from the light. Passes (stages):

* ``shadow_maps``: one map per light (cube map for point lights, perspective for spot,
  orthographic for directional; ``shadow_map_res``, ``depth_bias``), made by rasterising the
  triangles into each face (geometry/raster.py), or with ``raster`` = 0 by casting a ray per
  texel through the ``wp.Mesh``'s BVH. Skipped when the scene has no surfaces.
* ``visible``: what depends on the camera alone, per pixel: the visible surface, rasterised
  the same way (its distance and face), and the view ray's segment in the media. Cached
  while only the lights change.
* ``surface``: the radiance the visible surface reflects (the paper's step 1, the boundary
  condition L0) and its term of equation 1, L0 exp(-tau s). Skipped without surfaces.
* ``march``: the in-scattering sum. With interleaved sampling (section 4.1, ``block`` = M > 1)
  the N = ``steps`` samples of a ray are dealt out over M x M pixels: pixel (i, j) takes
  samples n = k, k + M^2, ... with k = i mod M + M (j mod M).
* ``block_rows``, ``block_cols``: the separable M x M box sum that gathers the N samples
  back (horizontal, then vertical; the window is the M x M pixels around a pixel, shifted
  inside the image at the borders, and holds every residue class k exactly once), then
  adds the surface term. Skipped when M = 1; ``block_edges`` (depth-aware) replaces both
  when ``edges`` = 1.

Where this departs from the paper, and why:

* The paper sums Li at the left ends of the steps, from the surface toward the camera;
  here samples sit at l_n = (n + u) dl with u = 1/2, or a random u per pixel with
  ``jitter`` = 1 (no banding: the step pattern is decorrelated between pixels, and the
  block sum averages it out).
* Marching runs in world space, not in the light's space, so one march serves several
  lights; the lights' contributions are summed in the same loop. The transmittances to the
  light and to the camera share one exponential, and samples a shadow map darkens skip
  the phase function.
* The surface term is attenuated in the surface pass rather than in the march, so the march's
  cost per pixel is only its share of the samples.
* Any medium of warpvol: homogeneous media use closed-form transmittance; heterogeneous
  ones (a grid) accumulate optical depth at every one of the N steps, and march
  ``shadow_steps`` steps toward each light.
* Shadow maps are looked up with 2x2 percentage-closer filtering, and surfaces read them
  from a point half a texel off the surface along its normal (normal-offset shadows).
* Outside the medium's bounds (and beyond the visible surface) nothing scatters, so the
  march covers only the part of the ray inside the media.
* A point or spot light's 1/d^2 is averaged over each sample's cell in closed form
  (``physics.lights.step_mean_irradiance``, as raymarch does): N samples over a long ray
  beside a lamp otherwise miss or alias its peak (point-in-fog at 80x60, M = 4: 0.53 off its
  converged image before, against 2048 steps per pixel).
* Beside a point or spot light the in-scattering peaks like 1/h across the rays (h a ray's
  distance from the light), so neighbours' samples do not stand in for a pixel's own. Within a
  ball around each such light every pixel marches its own ray at equiangular points (at most
  0.1 rad apart as seen from the light; Kulla & Fajardo 2012), and the shared samples take
  what the ball leaves. The split is smooth: the ball takes w(r) = (1 - (r/R)^2)^2 of the
  light's 1/r^2, and the shared samples the rest, 2/R^2 - r^2/R^4 inside and 1/r^2 outside,
  averaged over each sample's cell in closed form (``physics.lights.ball_window``,
  ``segment_mean_outside_window``), so no ray's share jumps at the ball's edge. R is
  ``light_ball`` M x M blocks of pixels at the light's distance (4 by default), and at least
  ``BALL_PERIODS`` = 1 period of the interleaving (M^2 samples along the ray): closer than half a
  period a ray's glow peaks inside one residue class, which the block sum takes from one row of
  the window for M rows running, so the glow came out in steps of M pixels (a lamp 8 away in
  fog 40 in radius, 96 x 72: 0.024 off the closed form on the rays 1 to 5 from it; now 0.002,
  tests/test_light_shafts.py). ``light_ball`` = 0 is the paper's sharing throughout.

At depth discontinuities the block sum adds samples of neighbouring rays of other
lengths: a pixel on a near column next to the far wall borrows the wall pixels' longer
samples, and vice versa, which leaves a halo up to M/2 pixels wide. Its error is measured
in results/light-shafts-edges (edge pixels against the others). Beyond the paper, ``edges`` = 1
(the default; 0: the paper's sum, as the paper's tables are measured)
replaces the separable sum by a depth-aware one (``block_edges``): a pixel whose M x M window
holds neighbours whose surface lies beyond ``edge_tolerance`` of its own depth leaves their
samples out and marches their residue classes along its own ray instead: it still has all N
samples and borrows none of a ray of another length. Only edge pixels pay (their missing
classes' samples), and every pixel M^2 depth reads. (Rescaling the classes kept for those
left out, which this replaced, left an edge pixel the classes at one part of every M^2-sample
period along its ray: they alias whatever peaks along it, as a lamp's glow beside a pole or
under its arm, into dark and bright lines.)

Leaves out (``frame.leaves_out``): the sky's light (the background) scattered once in the
medium or reflected by surfaces, and, with ``multiple_scattering`` = 0, multiple scattering.

With ``multiple_scattering`` = n > 0 (the default) the light scattered more than once is
added too: solved on an n^3 lattice of ``ms_directions`` directions (``warpvol.scattering``,
stages ``multiple`` and ``multiple_view``) and read at each of a pixel's interleaved samples as sigma_s R(x); 0 is the paper's model.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ... import device as dev
from ...geometry.camera import RasterView, camera_view, pixel_ray, view_ray
from ...geometry.intersect import ray_box
from ...geometry.mesh import Surfaces, surface_hit
from ...geometry.raster import NO_HIT, key_hit, rasterise_visible, triangle_at
from ...geometry.shadowmap import ShadowedLights, ShadowMap, texel_ray, texels
from ...media.volume import Media, homogeneous_optical_depth, in_scatter_at, scattering_at, sigma_t_at
from ...physics.constants import INF, RAY_EPS
from ...physics.lights import (DIRECTIONAL, Emitter, angle_point, angle_samples, angle_share, ball_chord,
                               ball_window, step_angle, step_mean_outside_window)
from ...physics.transmittance import transmittance_rgb
from ...pipeline import FLAG, Bias, Quality, Setting
from ...scattering import BIASES as MS_BIASES
from ...scattering import SETTINGS as MS_SETTINGS
from ...scattering import ScatteredLight, scattered_light, scattered_on_surface
from ...shading import light_arriving, marched_optical_depth, surface_through_maps
from ...upload import EXTINCTION_BIAS, EXTINCTION_SETTINGS, LIGHT_VOLUME_BIAS, LIGHT_VOLUME_SETTINGS, pinhole
from .buffers import tiled
from .parameters import ShaftSettings, SurfacePass, shaft_settings, surface_pass
from .stages import ShaftStages
from .view_geometry import far_distance, slice_plane

dev.kernel_module(__name__)

#: A point or spot light's ball is at least this many periods of the interleaving (M^2 samples
#: along the ray) in radius: farther out the glow's peak along a ray, 2h wide at a distance h
#: from the light, spans a whole period, so every residue class of a window shares it.
BALL_PERIODS = 1.0

NAME = "light_shafts"
SETTINGS = {
    "steps": Setting(64, 1, 1 << 16, "N: samples along each view ray, over a whole M x M block when interleaved"),
    "block": Setting(4, 1, 32, "M: interleaving block size (1 = every pixel takes all N samples)"),
    "shadow_map_res": Setting(256, 4, 8192, "texels per side of each shadow map (cube maps: per face)"),
    "depth_bias": Setting(0.02, 0.0, 1.0e3, "shadow-map depth bias, scene units"),
    "jitter": Setting(1, 0, 1, "1: random sample offset per pixel (no banding); 0: step midpoints", names=FLAG),
    "scattering": Setting(1, 0, 1, "0: surfaces only (the paper's 'no scattering' row)", names=FLAG),
    "shadow_steps": Setting(32, 1, 1 << 16, "steps toward a light through grid media (the others: closed form)"),
    "seed": Setting(0, 0, 2**31 - 1, "random seed of the jitter"),
    "spacing": Setting(1, 0, 1, "0: the paper's dl = s / N per ray; 1: dl = (media segment) / N, shared by neighbours",
                       names=("paper", "media")),
    "raster": Setting(1, 0, 1, "1: shadow maps and the visible surface by rasterising triangles; 0: by BVH ray casts",
                      names=("rays", "raster")),
    "raster_tiles": Setting(-1, -1, 1, "1: one rasteriser thread per 16 x 16-pixel piece of a triangle (balanced "
                            "for GPUs); 0: one per triangle; -1: pieces on CUDA, triangles on the CPU",
                            names=("auto", "triangles", "pieces")),
    "edges": Setting(1, 0, 1, "1: a pixel marches the samples of the neighbours in its block at another depth "
                     "itself (no halo at depth jumps; its error there and its cost: results/light-shafts-edges); "
                     "0: the paper's plain separable sum", names=FLAG),
    "edge_tolerance": Setting(0.1, 0.0, 10.0,
                              "edges = 1: relative depth difference beyond which a neighbour is left out"),
    "light_ball": Setting(4.0, 0.0, 64.0, "radius, in M-pixel blocks at the light's distance, of the ball around each "
                          "point or spot light inside which every pixel marches its own ray at equiangular points "
                          "instead of sharing the block's samples (the light's peak stays in its pixel; at least "
                          "one period of M^2 samples along the ray); 0: the paper's shared samples throughout"),
    **MS_SETTINGS,
    **EXTINCTION_SETTINGS,
    **LIGHT_VOLUME_SETTINGS,
}


@wp.struct
class ShaftTerms:
    """Per pixel, what the march writes for the block sum: the surface term L0 exp(-tau s) (from
    the surface pass; without surfaces, the attenuated background), this pixel's share of the
    interleaved in-scattering sum, and its own in-scattering inside the lights' balls."""
    surface: wp.array(dtype=wp.vec3)
    partial: wp.array(dtype=wp.vec3)
    own: wp.array(dtype=wp.vec3)


@wp.struct
class VisibleSurface:
    """Per pixel, from the visible stage: the surface's distance and face (-1: none), the view
    ray's media segment (t_in, t_end, t_out), and the triangles the faces index."""
    t_hit: wp.array(dtype=float)
    face: wp.array(dtype=int)
    segs: wp.array(dtype=wp.vec3)
    points: wp.array(dtype=wp.vec3)
    indices: wp.array(dtype=int)


@wp.kernel
def view_segments(offset: int, cam: RasterView, m: Media, s: Surfaces, source: int,
                  keys: wp.array(dtype=wp.int64), parent: wp.array(dtype=int), vis: VisibleSurface):
    """Per pixel, what depends on the camera alone, into ``vis``: the visible surface
    (``source`` 1: from the rasterised ``keys`` of the triangles ``vis.points``, ``vis.indices``,
    each from face ``parent``; 2: a ray cast through the BVH; 0: no surfaces), its distance and
    face, and the view ray's segment in the media, (t_in, t_end, t_out) with t_end =
    min(t_out, surface)."""
    tid = wp.tid() + offset
    o, d = pixel_ray(cam, tid)
    hit = bool(False)
    t = float(INF)
    n = wp.vec3(0.0, 1.0, 0.0)
    f = int(-1)
    if source == 1:
        hit, t, n, f = key_hit(keys[tid], vis.points, vis.indices, o, d)
        if hit:
            f = parent[f]  # the face the rasterised piece came from
    elif source == 2:
        hit, t, n, f = surface_hit(s, o, d, INF)
    if source != 0:
        vis.t_hit[tid] = t
        vis.face[tid] = f
    a, b = ray_box(o, d, m.all_min, m.all_max)
    vis.segs[tid] = wp.vec3(wp.max(a, 0.0), wp.min(b, t), b)


@wp.kernel
def shade_visible_surface(offset: int, cam: RasterView, m: Media, s: Surfaces, sl: ShadowedLights,
                          vis: VisibleSurface, sp: SurfacePass, ms: ScatteredLight, radiance: wp.array(dtype=wp.vec3)):
    """The paper's step 1: the radiance the visible surface reflects (direct light through the
    shadow maps and the media), then its part of equation 1, L0 exp(-tau s): attenuated along
    the view ray (heterogeneous media by ``sp.view_steps`` midpoints, as the march). Pixels
    without a surface take the attenuated ``sp.background``."""
    tid = wp.tid() + offset
    o, d = pixel_ray(cam, tid)
    f = vis.face[tid]
    t = wp.where(f >= 0, vis.t_hit[tid], vis.segs[tid][2])  # the surface, or where the view leaves the media
    tau_v = marched_optical_depth(m, o, d, 0.0, t, sp.view_steps)
    L = wp.cw_mul(sp.background, transmittance_rgb(tau_v))
    if f >= 0:
        L = wp.vec3(0.0)
        a, b, c = triangle_at(vis.points, vis.indices, f)
        n = wp.normalize(wp.cross(b - a, c - a))
        n = wp.where(wp.dot(n, d) < 0.0, n, -n)
        p = o + t * d + RAY_EPS * n
        L = surface_through_maps(m, sl, p, n, -d, s.material[f], tau_v, sp.shadow_steps)
        L += wp.cw_mul(transmittance_rgb(tau_v), scattered_on_surface(ms, s, s.material[f], p, n, -d))
    radiance[tid] = L


@wp.func
def ball_radius(light: Emitter, o: wp.vec3, st: ShaftSettings) -> float:
    """The radius of a point or spot light's ball (``ball_window``): ``st.near`` times the light's
    distance from the camera at o, and at least ``st.ball_floor``; 0 for a directional light."""
    if light.kind == DIRECTIONAL:
        return 0.0
    return wp.max(st.near * wp.length(light.position - o), st.ball_floor)


@wp.func
def near_light(m: Media, sl: ShadowedLights, l: int, o: wp.vec3, d: wp.vec3, ta: float, tb: float,
               radius: float, shadow_steps: int, view_steps: int) -> wp.vec3:
    """The in-scattered light of point or spot light l over the part of the view ray [ta, tb]
    inside the light's ball of ``radius``, weighted by ``ball_window``, at equiangular points
    (``physics.lights.angle_point``, at most 0.1 rad apart as seen from the light), per pixel: the
    light's singular peak, which the block sum of interleaved samples would spread over M x M
    pixels. The shared samples take the rest (``step_mean_outside_window``)."""
    light = sl.lights[l]
    chord = ball_chord(light, o, d, radius)
    a = wp.max(ta, chord[0])
    b = wp.min(tb, chord[1])
    acc = wp.vec3(0.0)
    if a >= b:
        return acc
    tc, h, phi = step_angle(light, o, d, a, b)
    n = angle_samples(phi)
    for j in range(n):
        t = wp.where(n > 1, angle_point(a, tc, h, phi, j, n), 0.5 * (a + b))
        x = o + t * d
        wi, e, tau = light_arriving(m, sl, l, x, wp.vec3(0.0), shadow_steps)
        r = wp.length(light.position - x)
        if e[0] > 0.0 or e[1] > 0.0 or e[2] > 0.0:
            if n > 1:
                e = angle_share(light, e, r, h, phi, n, 1.0)
            else:
                e = e * (b - a)
            tau_v = marched_optical_depth(m, o, d, 0.0, t, view_steps)
            e = e * ball_window(r, radius)
            acc += wp.cw_mul(transmittance_rgb(tau_v + tau), wp.cw_mul(in_scatter_at(m, x, wp.dot(d, wi)), e))
    return acc


@wp.func
def own_in_scatter(m: Media, sl: ShadowedLights, o: wp.vec3, d: wp.vec3, ta: float, tb: float,
                   st: ShaftSettings) -> wp.vec3:
    """What a pixel takes from no neighbour: the in-scattering of every point or spot light inside
    its ball (``near_light``), which the shared samples leave (``add_sample``)."""
    own = wp.vec3(0.0)
    for l in range(sl.lights.shape[0]):
        own += near_light(m, sl, l, o, d, ta, tb, ball_radius(sl.lights[l], o, st), st.shadow_steps, st.steps)
    return own


@wp.func
def add_sample(acc: wp.vec3, m: Media, sl: ShadowedLights, ms: ScatteredLight, o: wp.vec3, d: wp.vec3, c0: float,
               w: float, x: wp.vec3, tau_v: wp.vec3, st: ShaftSettings) -> wp.vec3:
    """``acc`` plus one shared sample's terms: at x, in the cell [c0, c0 + w] of the view ray,
    optical depth ``tau_v`` from the camera, each light's in-scattering with a point or spot
    light's 1/d^2 averaged over the cell less what its ball takes per pixel (``near_light``,
    ``step_mean_outside_window``: smooth, so neighbours may share it), then the light scattered
    more than once."""
    total = acc
    for l in range(sl.lights.shape[0]):
        wi, e, tau = light_arriving(m, sl, l, x, wp.vec3(0.0), st.shadow_steps)
        if e[0] > 0.0 or e[1] > 0.0 or e[2] > 0.0:
            light = sl.lights[l]
            e = step_mean_outside_window(light, e, wp.length(light.position - x), o, d, c0, c0 + w,
                                         ball_radius(light, o, st))
            li = wp.cw_mul(in_scatter_at(m, x, wp.dot(d, wi)), e)
            total += wp.cw_mul(transmittance_rgb(tau_v + tau), li) * w
    if ms.lat.n > 0:
        total += wp.cw_mul(transmittance_rgb(tau_v), scattered_light(ms, scattering_at(m, x), x)) * w
    return total


@wp.func
def same_depth(tp: float, tq: float, tolerance: float) -> bool:
    """Two pixels' visible surfaces within ``tolerance`` (relative) of each other, or both none."""
    if tp < INF and tq < INF:
        return wp.abs(tq - tp) <= tolerance * wp.min(tp, tq)
    return tp >= INF and tq >= INF


@wp.func
def window_start(p: int, size: int, block: int) -> int:
    """The first pixel of the M-wide window around p, shifted inside the image at its borders."""
    return wp.clamp(p - block / 2, 0, wp.max(size - block, 0))


@wp.struct
class EdgeWindow:
    """A pixel's M x M window for the depth-aware block sum (``block_sum_depth_aware``): its first
    pixel (x0, y0), the image's width, the visible surfaces' distances and the pixel's own (tp);
    ``on`` = 1 where a neighbour in it lies at another depth, whose residue class the pixel then
    marches itself."""
    t_hit: wp.array(dtype=float)
    tp: float
    x0: int
    y0: int
    width: int
    on: int


@wp.func
def edge_window(t_hit: wp.array(dtype=float), px: int, py: int, width: int, height: int, block: int,
                tolerance: float, edges: int) -> EdgeWindow:
    """(px, py)'s window (``EdgeWindow``); ``on`` only with ``edges`` (the depth-aware sum, M > 1)."""
    e = EdgeWindow()
    e.t_hit = t_hit
    e.x0 = window_start(px, width, block)
    e.y0 = window_start(py, height, block)
    e.width = width
    e.tp = float(0.0)
    e.on = 0
    if edges != 0 and block > 1:
        e.tp = t_hit[py * width + px]
        for j in range(block):
            for i in range(block):
                if not same_depth(e.tp, t_hit[(e.y0 + j) * width + e.x0 + i], tolerance):
                    e.on = 1
    return e


@wp.func
def class_missing(e: EdgeWindow, block: int, tolerance: float, c: int) -> bool:
    """Whether residue class c's pixel in the window lies at another depth than the pixel's own
    (so the block sum leaves its samples out); never where the window is not ``on``."""
    if e.on == 0:
        return False
    i = (c % block - e.x0 % block + block) % block
    j = (c / block - e.y0 % block + block) % block
    return not same_depth(e.tp, e.t_hit[(e.y0 + j) * e.width + e.x0 + i], tolerance)


@wp.func
def homogeneous_samples(m: Media, sl: ShadowedLights, ms: ScatteredLight, o: wp.vec3, d: wp.vec3, ta: float,
                        tb: float, dl: float, k0: int, u: float, st: ShaftSettings, e: EdgeWindow):
    """In closed-form media, the sum of a pixel's samples k = k0, k0 + M^2, ... (cells of length
    ``dl`` from ``ta``, cut at ``tb``; a sample at ``u`` of its cell), and that of the residue
    classes its window leaves out (``class_missing``), in one pass. Returns (its own, the missing)."""
    stride = st.block * st.block
    first = k0
    step = stride
    if e.on != 0:  # every step: the missing classes' samples too
        first = 0
        step = 1
    acc = wp.vec3(0.0)
    missing = wp.vec3(0.0)
    for k in range(first, st.steps, step):
        c0 = ta + float(k) * dl  # this sample's cell, cut at the surface
        if c0 >= tb:
            break
        take = k % stride == k0
        if take or class_missing(e, st.block, st.edge_tolerance, k % stride):
            w = wp.min(1.0, (tb - c0) / dl) * dl
            lk = c0 + u * w
            x = o + lk * d
            tau_v = homogeneous_optical_depth(m, o, d, 0.0, lk)
            if take:
                acc = add_sample(acc, m, sl, ms, o, d, c0, w, x, tau_v, st)
            else:
                missing = add_sample(missing, m, sl, ms, o, d, c0, w, x, tau_v, st)
    return acc, missing


@wp.func
def heterogeneous_samples(m: Media, sl: ShadowedLights, ms: ScatteredLight, o: wp.vec3, d: wp.vec3, ta: float,
                          tb: float, dl: float, k0: int, u: float, st: ShaftSettings, e: EdgeWindow):
    """``homogeneous_samples`` where a medium is a grid: the optical depth from the camera is
    accumulated at every one of the N steps, the lights are summed at this pixel's samples (and
    its window's missing classes') only. Returns (its own, the missing, the optical depth from
    the camera to ``tb``)."""
    stride = st.block * st.block
    acc = wp.vec3(0.0)
    missing = wp.vec3(0.0)
    tau = homogeneous_optical_depth(m, o, d, 0.0, ta)
    for k in range(st.steps):
        c0 = ta + float(k) * dl
        if c0 >= tb:
            break
        w = wp.min(1.0, (tb - c0) / dl) * dl
        lk = c0 + u * w
        x = o + lk * d
        sig = sigma_t_at(m, x, True)
        take = k % stride == k0
        if take or class_missing(e, st.block, st.edge_tolerance, k % stride):
            tau_v = tau + homogeneous_optical_depth(m, o, d, ta, lk) + sig * (u * w)
            if take:
                acc = add_sample(acc, m, sl, ms, o, d, c0, w, x, tau_v, st)
            else:
                missing = add_sample(missing, m, sl, ms, o, d, c0, w, x, tau_v, st)
        tau += sig * w
    return acc, missing, tau


@wp.kernel
def march_shafts(offset: int, cam: RasterView, m: Media, sl: ShadowedLights, segs: wp.array(dtype=wp.vec3),
                 t_hit: wp.array(dtype=float), background: wp.vec3, st: ShaftSettings, ms: ScatteredLight,
                 out: ShaftTerms):
    """This pixel's share of the in-scattering sum (its samples k = k0, k0 + M^2, ...) into
    ``out.partial``, and into ``out.own`` what it takes from no neighbour: each point or spot
    light's in-scattering inside the light's ball (``near_light``; the shared samples leave it),
    and, at a depth edge (``st.edges``), the residue classes of the neighbours in its window at
    another depth, which the depth-aware block sum leaves out: without them, the classes kept
    sit at one part of every M^2-sample period along the ray and alias what peaks along it (a
    lamp beside a pole or under its arm).
    With surfaces, the surface term was attenuated by the surface pass; without, the background
    is attenuated here into ``out.surface``."""
    tid = wp.tid() + offset
    px = tid % cam.width
    py = tid / cam.width
    o, d = view_ray(cam, px, py)
    seg = segs[tid]  # from the visible stage: (t_in, up to the surface, t_out)
    ta = seg[0]
    tb = seg[1]
    b = seg[2]
    acc = wp.vec3(0.0)
    background_done = bool(False)
    own = wp.vec3(0.0)
    if ta < tb and st.scattering == 1:
        t_end = tb  # where the samples are spread: up to the surface (paper) or through the media
        if st.spacing == 1:
            t_end = b
        dl = (t_end - ta) / float(st.steps)
        k0 = px % st.block + st.block * (py % st.block)
        stride = st.block * st.block  # the interleaving's period
        if st.near > 0.0:
            # a ray passing a lamp within half a period of the interleaving (M^2 samples) has its
            # glow's peak in one residue class, which the block sum takes from one row of the
            # window for M rows running: the glow held in steps of M pixels. The ball marches it.
            pixel = st
            pixel.ball_floor = BALL_PERIODS * float(stride) * dl
            st = pixel
        own = own_in_scatter(m, sl, o, d, ta, tb, st)
        u = 0.5
        if st.jitter == 1:
            rng = wp.rand_init(st.seed, tid)
            u = wp.randf(rng)
        hetero = m.het_majorant[0] > 0.0 or m.het_majorant[1] > 0.0 or m.het_majorant[2] > 0.0
        # the classes of the neighbours at another depth (the depth-aware sum leaves them out) are
        # marched here, in the same pass
        e = edge_window(t_hit, px, py, cam.width, cam.height, st.block, st.edge_tolerance, st.edges)
        missing = wp.vec3(0.0)
        if not hetero:
            acc, missing = homogeneous_samples(m, sl, ms, o, d, ta, tb, dl, k0, u, st, e)
        else:
            acc, missing, tau = heterogeneous_samples(m, sl, ms, o, d, ta, tb, dl, k0, u, st, e)
            if st.has_depth == 0:  # the background through the optical depth this march summed
                tau += homogeneous_optical_depth(m, o, d, ta, tb)
                out.surface[tid] = wp.cw_mul(background, transmittance_rgb(tau))
                background_done = True
        own += missing
    if st.has_depth == 0 and not background_done:
        out.surface[tid] = wp.cw_mul(background, transmittance_rgb(marched_optical_depth(m, o, d, 0.0, b, st.steps)))
    out.partial[tid] = acc
    out.own[tid] = own


@wp.kernel
def block_sum_rows(offset: int, values: wp.array(dtype=wp.vec3), width: int, block: int,
                   out: wp.array(dtype=wp.vec3)):
    """Sum of the ``block`` pixels of a row around each pixel (the window kept inside the row)."""
    tid = wp.tid() + offset
    px = tid % width
    row = tid - px
    x0 = wp.clamp(px - block / 2, 0, wp.max(width - block, 0))
    acc = wp.vec3(0.0)
    for k in range(block):
        acc += values[row + x0 + k]
    out[tid] = acc


@wp.kernel
def block_sum_cols(offset: int, rows: wp.array(dtype=wp.vec3), surface: wp.array(dtype=wp.vec3),
                   own: wp.array(dtype=wp.vec3), width: int, height: int, block: int, image: wp.array(dtype=wp.vec3)):
    """Column-wise sum of the row sums (the M x M block sum), plus the pixel's surface term and
    its own in-scattering (the lights' balls)."""
    tid = wp.tid() + offset
    px = tid % width
    py = tid / width
    y0 = wp.clamp(py - block / 2, 0, wp.max(height - block, 0))
    acc = surface[tid] + own[tid]
    for k in range(block):
        acc += rows[(y0 + k) * width + px]
    image[tid] = acc


@wp.kernel
def block_sum_depth_aware(offset: int, values: wp.array(dtype=wp.vec3), surface: wp.array(dtype=wp.vec3),
                          own: wp.array(dtype=wp.vec3), t_hit: wp.array(dtype=float), width: int, height: int,
                          block: int, tolerance: float, image: wp.array(dtype=wp.vec3)):
    """The M x M block sum over the neighbours whose visible surface lies within ``tolerance``
    (relative) of this pixel's (``same_depth``): where depth is smooth, every neighbour and the
    plain sum; at a jump, the residue classes of the neighbours left out were marched along this
    pixel's own ray (``march_shafts``, in ``own``), so it borrows no samples of rays of another
    length (the halo of ``block_sum_rows``/``cols``) and still has all N. Not separable: M^2 reads."""
    tid = wp.tid() + offset
    px = tid % width
    py = tid / width
    x0 = window_start(px, width, block)
    y0 = window_start(py, height, block)
    tp = t_hit[tid]
    acc = wp.vec3(0.0)
    for j in range(block):
        row = (y0 + j) * width + x0
        for i in range(block):
            if same_depth(tp, t_hit[row + i], tolerance):
                acc += values[row + i]
    image[tid] = surface[tid] + own[tid] + acc


@wp.kernel
def add_images(offset: int, a: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3), c: wp.array(dtype=wp.vec3),
               out: wp.array(dtype=wp.vec3)):
    tid = wp.tid() + offset
    out[tid] = a[tid] + b[tid] + c[tid]


@wp.kernel
def shadow_hit_points(offset: int, sm: ShadowMap, depth: wp.array(dtype=float), points: wp.array(dtype=wp.vec3)):
    """Where each texel's ray meets a surface (the map's depth surface in world space)."""
    tid = wp.tid() + offset
    o, d = texel_ray(sm, tid)
    t = depth[sm.offset + tid]
    points[tid] = wp.where(t < INF, o + t * d, wp.vec3(INF))


@wp.kernel
def sample_lit_slice(offset: int, m: Media, sl: ShadowedLights, corner: wp.vec3, edge_u: wp.vec3, edge_v: wp.vec3,
                     res: int, view: wp.vec3, shadow_steps: int, out: wp.array(dtype=wp.vec3)):
    """Radiance scattered per unit length toward a camera looking along ``view``, sum_l sigma_s p E v T,
    on a plane (the same phase angle as the march: cos = view . wi)."""
    tid = wp.tid() + offset
    x = corner + (float(tid % res) + 0.5) / float(res) * edge_u + (float(tid / res) + 0.5) / float(res) * edge_v
    li = wp.vec3(0.0)
    for l in range(sl.lights.shape[0]):
        wi, e, tau = light_arriving(m, sl, l, x, wp.vec3(0.0), shadow_steps)
        li += wp.cw_mul(in_scatter_at(m, x, wp.dot(view, wi)), wp.cw_mul(e, transmittance_rgb(tau)))
    out[tid] = li


class LightShafts(ShaftStages):
    """Shadow-mapped single scattering with interleaved sampling (see the module docstring)."""

    NAME = NAME
    EXAMPLES = ("fog-box", "hazy-sun")
    TINY = {"steps": 8, "block": 2, "shadow_map_res": 16, "shadow_steps": 6}
    CENSUS = ("hazy-sun", {})
    SETTINGS = SETTINGS
    QUALITY = Quality(knob="steps", start=16, top=4096, order=1, tied={"shadow_steps": 0.5},
                      biases=(Bias("block", exact=1), Bias("shadow_map_res", factor=4, order=1), *MS_BIASES,
                              EXTINCTION_BIAS, LIGHT_VOLUME_BIAS))
    LEAVES_OUT = ()

    def _visible(self):
        scene, cam, u, buf = self.scene, self.scene.camera, self.uploads, self.buffers
        npix = cam.width * cam.height
        view = camera_view(pinhole(cam))
        self.segs = buf.scratch("segs", npix, wp.vec3)
        keys = buf.no_keys
        points, indices, parent = buf.no_points, buf.no_index, buf.no_index
        t_hit, face = self.shadows.depth, buf.no_index  # no surfaces: nothing to keep but the segments
        if scene.surfaces:
            t_hit = self.t_hit = buf.scratch("t_hit", npix, float)
            face = self.face = buf.scratch("face", npix, int)
            points, indices, parent = buf.raster_mesh(scene, u._surfaces)
        if scene.surfaces and self.settings["raster"]:
            keys = buf.scratch("keys", npix, wp.int64, fill=NO_HIT)
            rasterise_visible(points, indices, view, far_distance(scene), keys,
                              tiled(self.settings["raster_tiles"], self.device), self.device)
        source = 0 if not scene.surfaces else (1 if self.settings["raster"] else 2)
        vis = VisibleSurface()
        vis.t_hit, vis.face, vis.segs, vis.points, vis.indices = t_hit, face, self.segs, points, indices
        dev.launch(view_segments, npix, [view, u.media.struct, u.surfaces, source, keys, parent, vis], self.device)

    def _surface(self):
        scene, cam, u = self.scene, self.scene.camera, self.uploads
        npix = cam.width * cam.height
        self.shadows.when_skipped()
        self.radiance = self.buffers.scratch("radiance", npix, wp.vec3)
        mesh = u._surfaces.mesh
        vis = VisibleSurface()
        vis.t_hit, vis.face, vis.segs = self.t_hit, self.face, self.segs
        vis.points, vis.indices = mesh.points, mesh.indices
        dev.launch(shade_visible_surface, npix, [camera_view(pinhole(cam)), u.media.struct, u.surfaces,
                                                 self.shadows.lights(), vis,
                                                 surface_pass(self.settings, scene.background),
                                                 self.multiple.struct(), self.radiance],
                   self.device, work=self.pixel_work(1.0, self._view_samples()))

    def _march(self):
        scene, u, cfg = self.scene, self.uploads, self.settings
        cam = scene.camera
        npix = cam.width * cam.height
        has_depth = bool(scene.surfaces)
        self.shadows.when_skipped()
        st = shaft_settings(cfg, self.effective_block(), cam, has_depth)
        self.terms = out = ShaftTerms()
        # with surfaces, the surface term is the surface pass's radiance, attenuated there
        out.surface = self.radiance if has_depth else self.buffers.scratch("surface", npix, wp.vec3)
        out.partial = self.buffers.scratch("partial", npix, wp.vec3)
        out.own = self.buffers.scratch("own", npix, wp.vec3)
        t_hit = self.t_hit if has_depth else self.shadows.depth  # without surfaces: no edges, not read
        dev.launch(march_shafts, npix, [camera_view(pinhole(cam)), u.media.struct, self.shadows.lights(), self.segs,
                                        t_hit, wp.vec3(*scene.background), st, self.multiple.struct(), out],
                   self.device, work=self.pixel_work(st.steps / st.block**2, self._view_samples()))
        if st.block == 1 or not cfg["scattering"] or not scene.media:
            self.image = wp.empty(npix, dtype=wp.vec3, device=self.device)  # the frame's own: not reused
            dev.launch(add_images, npix, [out.surface, out.partial, out.own, self.image], self.device)

    def _block_rows(self):
        cam = self.scene.camera
        self.rows = self.buffers.scratch("rows", cam.width * cam.height, wp.vec3)
        dev.launch(block_sum_rows, cam.width * cam.height, [self.terms.partial, cam.width, self.effective_block(),
                                                            self.rows], self.device)

    def _block_cols(self):
        cam, terms = self.scene.camera, self.terms
        self.image = wp.empty(cam.width * cam.height, dtype=wp.vec3, device=self.device)
        dev.launch(block_sum_cols, cam.width * cam.height, [self.rows, terms.surface, terms.own, cam.width, cam.height,
                                                            self.effective_block(), self.image], self.device)

    def _block_edges(self):
        cam, terms = self.scene.camera, self.terms
        self.image = wp.empty(cam.width * cam.height, dtype=wp.vec3, device=self.device)
        dev.launch(block_sum_depth_aware, cam.width * cam.height,
                   [terms.partial, terms.surface, terms.own, self.t_hit, cam.width, cam.height, self.effective_block(),
                    self.settings["edge_tolerance"], self.image], self.device)

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """Intermediate arrays for looking inside (``viz``): ``depth``, the distance to the visible
        surface per pixel (H x W, INF where none); per light, the shadow map's depth
        surface as world points (``shadow_points``, (texels, 3), INF where a ray escaped) and
        its distances (``shadow_distance``); and ``lit_slice``, the in-scattered radiance toward
        the camera on the vertical plane through the camera's target facing the camera
        ((resolution, resolution, 3), with the plane's ``lit_slice_corners``, 4 x 3)."""
        cam, shadows = self.scene.camera, self.shadows
        out = {"shadow_points": [], "shadow_distance": []}
        if self.scene.surfaces and self.t_hit is not None:
            out["depth"] = self.t_hit.numpy().reshape(cam.height, cam.width)
        structs = shadows.structs(occluders=bool(self.scene.surfaces)) if shadows.maps is not None else []
        for sm in structs:
            count = texels(sm.kind, sm.res)
            if count == 0:
                continue
            pts = wp.empty(count, dtype=wp.vec3, device=self.device)
            dev.launch(shadow_hit_points, count, [sm, shadows.depth, pts], self.device)
            out["shadow_points"].append(pts.numpy())
            out["shadow_distance"].append(shadows.depth.numpy()[sm.offset:sm.offset + count])
        corner, edge_u, edge_v, view = slice_plane(self.scene)
        lit = wp.empty(resolution * resolution, dtype=wp.vec3, device=self.device)
        dev.launch(sample_lit_slice, resolution * resolution,
                   [self.uploads.media.struct, shadows.lights(), wp.vec3(*corner), wp.vec3(*edge_u), wp.vec3(*edge_v),
                    resolution, wp.vec3(*view), self.settings["shadow_steps"], lit], self.device)
        out["lit_slice"] = lit.numpy().reshape(resolution, resolution, 3)
        out["lit_slice_corners"] = np.array([corner, corner + edge_u, corner + edge_u + edge_v, corner + edge_v])
        return out


TECHNIQUE = LightShafts
