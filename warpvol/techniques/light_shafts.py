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
  distance from the light), so neighbours' samples do not stand in for a pixel's own. Inside
  a ball around each such light (``light_ball`` = 4: a radius of four M x M blocks of pixels
  at the light's distance) every pixel marches its own ray at equiangular points (at most
  0.1 rad apart as seen from the light; Kulla & Fajardo 2012) and adds it after the block sum;
  the shared samples cover the rest of the ray (the fog-box and light-inside-fog rows of
  results/multiple-scattering). ``light_ball`` = 0 is the paper's sharing throughout.

At depth discontinuities the block sum adds samples of neighbouring rays of other
lengths: a pixel on a near column next to the far wall borrows the wall pixels' longer
samples, and vice versa, which leaves a halo up to M/2 pixels wide. Its error is measured
in results/light-shafts-edges (edge pixels against the others). Beyond the paper, ``edges`` = 1
(the default; 0: the paper's sum, as the paper's tables are measured) replaces the separable
sum by a depth-aware one (``block_edges``): a pixel sums only the
neighbours whose surface lies within ``edge_tolerance`` of its own depth and scales the sum
by M^2 / (neighbours kept), which cuts that error 2.5-8 fold there (5 fold at M = 4) at M^2
reads per pixel.

Leaves out (``frame.leaves_out``): the sky's light (the background) scattered once in the
medium or reflected by surfaces, and, with ``multiple_scattering`` = 0, multiple scattering.

With ``multiple_scattering`` = n > 0 (the default) the light scattered more than once is
added too: solved on an n^3 lattice of ``ms_directions`` directions (``warpvol.scattering``,
stages ``multiple`` and ``multiple_view``) and read at each of a pixel's interleaved samples as sigma_s R(x); 0 is the paper's model.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from .. import device as dev
from ..geometry.camera import RasterView, camera_view, pixel_ray, view_ray
from ..geometry.intersect import ray_box
from ..geometry.mesh import Surfaces, surface_hit
from ..geometry.raster import NO_HIT, key_hit, rasterise_visible, split_long_edges, triangle_at
from ..geometry.shadowmap import (
    ShadowedLights,
    ShadowMap,
    shadow_map_depths,
    texel_ray,
    texels,
)
from ..media.volume import Media, homogeneous_optical_depth, in_scatter_at, scattering_at, sigma_t_at
from ..physics.constants import INF, RAY_EPS
from ..physics.lights import (Emitter, angle_point, angle_samples, angle_share, ball_chord, step_angle,
                              step_mean_irradiance)
from ..physics.transmittance import transmittance_rgb
from ..pipeline import Bias, Quality, Setting, Stage, Technique
from ..scattering import BIASES as MS_BIASES
from ..scattering import SETTINGS as MS_SETTINGS
from ..scattering import MultipleScattering, ScatteredLight, scattered_light, scattered_on_surface
from ..scattering import check_settings as check_ms_settings
from ..scattering import leaves_out as ms_leaves_out
from ..shading import LightDepthVolume, light_arriving, marched_optical_depth, surface_through_maps
from ..upload import (EXTINCTION_BIAS, EXTINCTION_SETTINGS, LIGHT_VOLUME_BIAS, LIGHT_VOLUME_SETTINGS, SceneUploads,
                      pinhole, scene_bounds, shadow_map_structs)

dev.kernel_module(__name__)

NAME = "light_shafts"
SETTINGS = {
    "steps": Setting(64, 1, 1 << 16, "N: samples along each view ray, over a whole M x M block when interleaved"),
    "block": Setting(4, 1, 32, "M: interleaving block size (1 = every pixel takes all N samples)"),
    "shadow_map_res": Setting(256, 4, 8192, "texels per side of each shadow map (cube maps: per face)"),
    "depth_bias": Setting(0.02, 0.0, 1.0e3, "shadow-map depth bias, scene units"),
    "jitter": Setting(1, 0, 1, "1: random sample offset per pixel (no banding); 0: step midpoints"),
    "scattering": Setting(1, 0, 1, "0: surfaces only (the paper's 'no scattering' row)"),
    "shadow_steps": Setting(32, 1, 1 << 16, "steps toward a light through grid media (the others: closed form)"),
    "seed": Setting(0, 0, 2**31 - 1, "random seed of the jitter"),
    "spacing": Setting(1, 0, 1, "0: the paper's dl = s / N per ray; 1: dl = (media segment) / N, shared by neighbours",
                       names=("paper", "media")),
    "raster": Setting(1, 0, 1, "1: shadow maps and the visible surface by rasterising triangles; 0: by BVH ray casts",
                      names=("rays", "raster")),
    "raster_tiles": Setting(-1, -1, 1, "1: one rasteriser thread per 16 x 16-pixel piece of a triangle (balanced "
                            "for GPUs); 0: one per triangle; -1: pieces on CUDA, triangles on the CPU",
                            names=("auto", "triangles", "pieces")),
    "edges": Setting(1, 0, 1, "1: the block sum keeps to neighbours at a similar depth and rescales for the samples it "
                     "leaves out (no halo at depth jumps; its error there and its cost: results/light-shafts-edges); 0: "
                     "the paper's plain separable sum"),
    "edge_tolerance": Setting(0.1, 0.0, 10.0, "edges = 1: relative depth difference beyond which a neighbour is left out"),
    "light_ball": Setting(4.0, 0.0, 64.0, "radius, in M-pixel blocks at the light's distance, of the ball around each "
                          "point or spot light inside which every pixel marches its own ray at equiangular points "
                          "instead of sharing the block's samples (the light's peak stays in its pixel); 0: the "
                          "paper's shared samples throughout"),
    **MS_SETTINGS,
    **EXTINCTION_SETTINGS,
    **LIGHT_VOLUME_SETTINGS,
}


@wp.struct
class ShaftSettings:
    steps: int
    block: int
    jitter: int
    scattering: int
    shadow_steps: int
    seed: int
    spacing: int
    has_depth: int  # 0 when the scene has no surfaces (depth pass skipped)
    near: float  # a point or spot light's ball, marched per pixel: its radius per unit distance from the camera


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
                          vis: VisibleSurface, shadow_steps: int, view_steps: int, background: wp.vec3,
                          ms: ScatteredLight, radiance: wp.array(dtype=wp.vec3)):
    """The paper's step 1: the radiance the visible surface reflects (direct light through the
    shadow maps and the media), then its part of equation 1, L0 exp(-tau s): attenuated along
    the view ray (heterogeneous media by ``view_steps`` midpoints, as the march). Pixels without
    a surface take the attenuated ``background``."""
    tid = wp.tid() + offset
    o, d = pixel_ray(cam, tid)
    f = vis.face[tid]
    t = wp.where(f >= 0, vis.t_hit[tid], vis.segs[tid][2])  # the surface, or where the view leaves the media
    tau_v = marched_optical_depth(m, o, d, 0.0, t, view_steps)
    L = wp.cw_mul(background, transmittance_rgb(tau_v))
    if f >= 0:
        L = wp.vec3(0.0)
        a, b, c = triangle_at(vis.points, vis.indices, f)
        n = wp.normalize(wp.cross(b - a, c - a))
        n = wp.where(wp.dot(n, d) < 0.0, n, -n)
        p = o + t * d + RAY_EPS * n
        L = surface_through_maps(m, sl, p, n, -d, s.material[f], tau_v, shadow_steps)
        L += wp.cw_mul(transmittance_rgb(tau_v), scattered_on_surface(ms, s, s.material[f], p, n, -d))
    radiance[tid] = L


@wp.func
def pixel_ball(light: Emitter, o: wp.vec3, d: wp.vec3, near: float) -> wp.vec2:
    """Where the view ray o + t d crosses light's ball (``ball_chord``), whose radius is ``near``
    (``ShaftSettings.near``) times the light's distance from the camera."""
    return ball_chord(light, o, d, near * wp.length(light.position - o))


@wp.func
def outside_ball(c0: float, w: float, chord: wp.vec2) -> float:
    """The length of the sample cell [c0, c0 + w] outside a light's ball (``ball_chord``)."""
    return w - wp.max(wp.min(c0 + w, chord[1]) - wp.max(c0, chord[0]), 0.0)


@wp.func
def near_light(m: Media, sl: ShadowedLights, l: int, o: wp.vec3, d: wp.vec3, ta: float, tb: float,
               chord: wp.vec2, shadow_steps: int, view_steps: int) -> wp.vec3:
    """The in-scattered light of point or spot light l over the part of the view ray [ta, tb]
    inside the light's ball (``chord``), at equiangular points (``physics.lights.angle_point``,
    at most 0.1 rad apart as seen from the light), per pixel: the light's singular peak, which
    the block sum of interleaved samples would spread over M x M pixels."""
    a = wp.max(ta, chord[0])
    b = wp.min(tb, chord[1])
    acc = wp.vec3(0.0)
    if a >= b:
        return acc
    light = sl.lights[l]
    tc, h, phi = step_angle(light, o, d, a, b)
    n = angle_samples(phi)
    for j in range(n):
        t = wp.where(n > 1, angle_point(a, tc, h, phi, j, n), 0.5 * (a + b))
        x = o + t * d
        wi, e, tau = light_arriving(m, sl, l, x, wp.vec3(0.0), shadow_steps)
        if e[0] > 0.0 or e[1] > 0.0 or e[2] > 0.0:
            if n > 1:
                e = angle_share(light, e, wp.length(light.position - x), h, phi, n, 1.0)
            else:
                e = step_mean_irradiance(light, e, wp.length(light.position - x), o, d, a, b) * (b - a)
            tau_v = marched_optical_depth(m, o, d, 0.0, t, view_steps)
            acc += wp.cw_mul(transmittance_rgb(tau_v + tau), wp.cw_mul(in_scatter_at(m, x, wp.dot(d, wi)), e))
    return acc


@wp.kernel
def march_shafts(offset: int, cam: RasterView, m: Media, sl: ShadowedLights, segs: wp.array(dtype=wp.vec3),
                 background: wp.vec3, st: ShaftSettings, ms: ScatteredLight, surface_out: wp.array(dtype=wp.vec3),
                 partial_out: wp.array(dtype=wp.vec3), own_out: wp.array(dtype=wp.vec3)):
    """This pixel's share of the in-scattering sum (its samples k = k0, k0 + M^2, ...), and into
    ``own_out`` what it takes from no neighbour: each point or spot light's in-scattering inside
    the light's ball (``near_light``; the shared samples skip it). With surfaces, the surface
    term was attenuated by the surface pass; without, the background is attenuated here into
    ``surface_out``."""
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
        for l in range(sl.lights.shape[0]):
            chord = pixel_ball(sl.lights[l], o, d, st.near)
            own += near_light(m, sl, l, o, d, ta, tb, chord, st.shadow_steps, st.steps)
        t_end = tb  # where the samples are spread: up to the surface (paper) or through the media
        if st.spacing == 1:
            t_end = b
        n_steps = st.steps
        dl = (t_end - ta) / float(n_steps)
        stride = st.block * st.block
        k0 = px % st.block + st.block * (py % st.block)
        u = 0.5
        if st.jitter == 1:
            rng = wp.rand_init(st.seed, tid)
            u = wp.randf(rng)
        hetero = m.het_majorant[0] > 0.0 or m.het_majorant[1] > 0.0 or m.het_majorant[2] > 0.0
        if not hetero:
            for k in range(k0, n_steps, stride):
                c0 = ta + float(k) * dl  # this sample's cell, cut at the surface
                if c0 >= tb:
                    break
                w = wp.min(1.0, (tb - c0) / dl) * dl
                lk = c0 + u * w
                x = o + lk * d
                tau_v = homogeneous_optical_depth(m, o, d, 0.0, lk)
                for l in range(sl.lights.shape[0]):
                    chord = pixel_ball(sl.lights[l], o, d, st.near)
                    w_l = outside_ball(c0, w, chord)  # the ball is the pixel's own (near_light)
                    if w_l > 0.0:
                        wi, e, tau = light_arriving(m, sl, l, x, wp.vec3(0.0), st.shadow_steps)
                        if e[0] > 0.0 or e[1] > 0.0 or e[2] > 0.0:
                            e = step_mean_irradiance(sl.lights[l], e, wp.length(sl.lights[l].position - x), o, d,
                                                     c0, c0 + w)  # a point light's 1/d^2 averaged over the cell
                            li = wp.cw_mul(in_scatter_at(m, x, wp.dot(d, wi)), e)
                            acc += wp.cw_mul(transmittance_rgb(tau_v + tau), li) * w_l
                if ms.lat.n > 0:
                    acc += wp.cw_mul(transmittance_rgb(tau_v), scattered_light(ms, scattering_at(m, x), x)) * w
        else:
            # optical depth from the camera, accumulated at every step; lights only at this pixel's
            tau = homogeneous_optical_depth(m, o, d, 0.0, ta)
            for k in range(n_steps):
                c0 = ta + float(k) * dl
                if c0 >= tb:
                    break
                w = wp.min(1.0, (tb - c0) / dl) * dl
                lk = c0 + u * w
                x = o + lk * d
                sig = sigma_t_at(m, x, True)
                if k % stride == k0:
                    tau_v = tau + homogeneous_optical_depth(m, o, d, ta, lk) + sig * (u * w)
                    for l in range(sl.lights.shape[0]):
                        chord = pixel_ball(sl.lights[l], o, d, st.near)
                        w_l = outside_ball(c0, w, chord)
                        if w_l > 0.0:
                            wi, e, tau_l = light_arriving(m, sl, l, x, wp.vec3(0.0), st.shadow_steps)
                            if e[0] > 0.0 or e[1] > 0.0 or e[2] > 0.0:
                                e = step_mean_irradiance(sl.lights[l], e, wp.length(sl.lights[l].position - x), o,
                                                         d, c0, c0 + w)
                                li = wp.cw_mul(in_scatter_at(m, x, wp.dot(d, wi)), e)
                                acc += wp.cw_mul(transmittance_rgb(tau_v + tau_l), li) * w_l
                    if ms.lat.n > 0:
                        acc += wp.cw_mul(transmittance_rgb(tau_v), scattered_light(ms, scattering_at(m, x), x)) * w
                tau += sig * w
            if st.has_depth == 0:  # the background through the optical depth this march summed
                tau += homogeneous_optical_depth(m, o, d, ta, tb)
                surface_out[tid] = wp.cw_mul(background, transmittance_rgb(tau))
                background_done = True
    if st.has_depth == 0 and not background_done:
        surface_out[tid] = wp.cw_mul(background, transmittance_rgb(marched_optical_depth(m, o, d, 0.0, b, st.steps)))
    partial_out[tid] = acc
    own_out[tid] = own


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
    (relative) of this pixel's, scaled by M^2 / (neighbours kept): the samples of the residue
    classes left out are replaced by the mean of those kept. Where depth is smooth every
    neighbour is kept and this is the plain sum; at a jump, a pixel no longer borrows samples
    of rays of another length (the halo of ``block_sum_rows``/``cols``). Not separable: M^2 reads."""
    tid = wp.tid() + offset
    px = tid % width
    py = tid / width
    x0 = wp.clamp(px - block / 2, 0, wp.max(width - block, 0))
    y0 = wp.clamp(py - block / 2, 0, wp.max(height - block, 0))
    tp = t_hit[tid]
    acc = wp.vec3(0.0)
    kept = int(0)
    for j in range(block):
        row = (y0 + j) * width + x0
        for i in range(block):
            tq = t_hit[row + i]
            same = tp >= INF and tq >= INF
            if tp < INF and tq < INF:
                same = wp.abs(tq - tp) <= tolerance * wp.min(tp, tq)
            if same:
                acc += values[row + i]
                kept += 1
    image[tid] = surface[tid] + own[tid] + acc * (float(block * block) / float(wp.max(kept, 1)))


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
def sample_lit_slice(offset: int, m: Media, sl: ShadowedLights, corner: wp.vec3, edge_u: wp.vec3, edge_v: wp.vec3, res: int,
                     view: wp.vec3, shadow_steps: int, out: wp.array(dtype=wp.vec3)):
    """Radiance scattered per unit length toward a camera looking along ``view``, sum_l sigma_s p E v T,
    on a plane (the same phase angle as the march: cos = view . wi)."""
    tid = wp.tid() + offset
    x = corner + (float(tid % res) + 0.5) / float(res) * edge_u + (float(tid / res) + 0.5) / float(res) * edge_v
    li = wp.vec3(0.0)
    for l in range(sl.lights.shape[0]):
        wi, e, tau = light_arriving(m, sl, l, x, wp.vec3(0.0), shadow_steps)
        li += wp.cw_mul(in_scatter_at(m, x, wp.dot(view, wi)), wp.cw_mul(e, transmittance_rgb(tau)))
    out[tid] = li


class LightShafts(Technique):
    """Shadow-mapped single scattering with interleaved sampling (see the module docstring)."""

    NAME = NAME
    SETTINGS = SETTINGS
    QUALITY = Quality(knob="steps", start=16, top=4096, order=1, tied={"shadow_steps": 0.5},
                      biases=(Bias("block", exact=1), Bias("shadow_map_res", factor=4, order=1), *MS_BIASES,
                              EXTINCTION_BIAS, LIGHT_VOLUME_BIAS))
    LEAVES_OUT = ()

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        self.uploads = SceneUploads(self)
        self.multiple = MultipleScattering(self, lambda: self.uploads.surfaces, lambda: self.uploads.lights,
                                           lambda: self.uploads.media.struct)
        self.maps = None
        self.light_volume = LightDepthVolume(self, lambda: self.uploads.media.struct, lambda: self.uploads.lights)
        self.depth = wp.full(1, INF, dtype=float, device=device)
        self._no_keys = wp.full(1, NO_HIT, dtype=wp.int64, device=device)  # "ray cast instead"
        self._no_index = wp.full(1, -1, dtype=int, device=device)
        self._no_points = wp.zeros(1, dtype=wp.vec3, device=device)
        self.segs = self.face = None
        self._arrays = {}
        self._raster_source = self._raster_mesh = None
        self.t_hit = self.radiance = None
        self.surface = self.partial = self.own = self.rows = self.image = None

    def check_settings(self, settings):
        check_ms_settings(NAME, settings)

    def leaves_out(self) -> list[str]:
        return [*ms_leaves_out(self.settings), *super().leaves_out()]

    def diagnostics(self) -> dict:
        return {**self.multiple.diagnostics(), **self.uploads.diagnostics()}

    def effective_block(self) -> int:
        """M, limited to the image so a window always holds all M^2 residue classes."""
        cam = self.scene.camera
        return max(1, min(self.settings["block"], cam.width, cam.height))

    def stages(self):
        scene = self.scene
        occluders = bool(scene.surfaces)
        interleaved = self.effective_block() > 1 and self.settings["scattering"] == 1 and bool(scene.media)
        depth_aware = self.settings["edges"] == 1 and occluders  # depth comes from the surface pass
        return self.uploads.stages() + [
            Stage("shadow_maps", self._shadow_maps, reads=("lights",),
                  settings=("shadow_map_res", "depth_bias", "raster", "raster_tiles"),
                  after=("surfaces", "lights"), needed=occluders and bool(scene.lights)),
            Stage("visible", self._visible, reads=("camera",), settings=("raster", "raster_tiles"),
                  after=("medium", "surfaces")),
            *self.multiple.stages(after=("medium", "surfaces", "lights")),
            self.light_volume.stage(),
            Stage("surface", self._surface, reads=("camera", "background"),
                  settings=("shadow_steps", "steps", "multiple_scattering", "shadow_grid"),
                  after=("medium", "surfaces", "lights", "shadow_maps", "visible", "multiple_view", "light_volume"),
                  needed=occluders),
            Stage("march", self._march, reads=("camera", "background"),
                  settings=("steps", "block", "jitter", "scattering", "shadow_steps", "seed", "spacing",
                            "multiple_scattering", "light_ball", "shadow_grid"),
                  after=("medium", "lights", "shadow_maps", "visible", "surface", "multiple_view", "light_volume")),
            Stage("block_rows", self._block_rows, settings=("block",), after=("march",),
                  needed=interleaved and not depth_aware),
            Stage("block_cols", self._block_cols, settings=("block",), after=("block_rows",),
                  needed=interleaved and not depth_aware),
            Stage("block_edges", self._block_edges, settings=("block", "edge_tolerance"), after=("march",),
                  needed=interleaved and depth_aware),
        ]

    def _map_structs(self, occluders: bool) -> list[ShadowMap]:
        return shadow_map_structs(self.scene, self.settings["shadow_map_res"], self.settings["depth_bias"], occluders)

    def _mesh_arrays(self):
        """(points, indices, face of each triangle) of the triangles the rasteriser takes: the
        surfaces with no edge longer than 1/32 of the scene's diagonal (``split_long_edges``),
        rebuilt when the surfaces are uploaded again."""
        buffers = self.uploads._surfaces
        if self._raster_source is not buffers:
            lo, hi = scene_bounds(self.scene)
            pts, parent = split_long_edges(buffers.mesh.points.numpy(), buffers.mesh.indices.numpy(),
                                           float(np.linalg.norm(hi - lo)) / 32.0)
            self._raster_mesh = (wp.array(pts, dtype=wp.vec3, device=self.device),
                                 wp.array(np.arange(len(pts), dtype=np.int32), dtype=int, device=self.device),
                                 wp.array(parent, dtype=int, device=self.device))
            self._raster_source = buffers
        return self._raster_mesh

    def _tiled(self) -> bool:
        mode = self.settings["raster_tiles"]
        return mode == 1 or (mode == -1 and str(self.device).startswith("cuda"))

    def _shadow_maps(self):
        structs = self._map_structs(occluders=True)
        if self.settings["raster"]:
            points, indices, _ = self._mesh_arrays()
            self.depth = shadow_map_depths(structs, self.device, points, indices, tiled=self._tiled())
        else:
            self.depth = shadow_map_depths(structs, self.device, surfaces=self.uploads.surfaces)
        self.maps = wp.array(structs, dtype=ShadowMap, device=self.device)

    def _no_shadow_maps(self):
        if not (self.scene.surfaces and self.scene.lights):  # no shadow pass: every map says "lit"
            self.maps = wp.array(self._map_structs(occluders=False) or [ShadowMap()], dtype=ShadowMap,
                                 device=self.device)

    def _shadowed_lights(self) -> ShadowedLights:
        sl = ShadowedLights()
        sl.lights, sl.maps, sl.depth = self.uploads.lights, self.maps, self.depth
        return self.light_volume.attach(sl)

    def _scratch(self, name: str, n: int, dtype, fill=None):
        """An intermediate array kept from frame to frame (allocating and first touching ~6 MB per
        frame costs milliseconds on the CPU); ``fill`` resets it."""
        arr = self._arrays.get(name)
        if arr is None or arr.shape[0] != n:
            arr = self._arrays[name] = wp.empty(n, dtype=dtype, device=self.device)
        if fill is not None:
            arr.fill_(fill)
        return arr

    def _visible(self):
        scene, cam, u = self.scene, self.scene.camera, self.uploads
        npix = cam.width * cam.height
        view = camera_view(pinhole(cam))
        self.segs = self._scratch("segs", npix, wp.vec3)
        keys = self._no_keys
        points, indices, parent = self._no_points, self._no_index, self._no_index
        t_hit, face = self.depth, self._no_index  # no surfaces: nothing to keep but the segments
        if scene.surfaces:
            t_hit = self.t_hit = self._scratch("t_hit", npix, float)
            face = self.face = self._scratch("face", npix, int)
            points, indices, parent = self._mesh_arrays()
        if scene.surfaces and self.settings["raster"]:
            keys = self._scratch("keys", npix, wp.int64, fill=NO_HIT)
            lo, hi = scene_bounds(scene)
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            t_far = float(np.max(np.linalg.norm(corners - np.asarray(cam.origin, float), axis=1)))
            rasterise_visible(points, indices, view, t_far, keys, self._tiled(), self.device)
        source = 0 if not scene.surfaces else (1 if self.settings["raster"] else 2)
        vis = VisibleSurface()
        vis.t_hit, vis.face, vis.segs, vis.points, vis.indices = t_hit, face, self.segs, points, indices
        dev.launch(view_segments, npix, [view, u.media.struct, u.surfaces, source, keys, parent, vis], self.device)

    def _surface(self):
        scene, cam, u = self.scene, self.scene.camera, self.uploads
        npix = cam.width * cam.height
        self._no_shadow_maps()
        self.radiance = self._scratch("radiance", npix, wp.vec3)
        mesh = u._surfaces.mesh
        vis = VisibleSurface()
        vis.t_hit, vis.face, vis.segs = self.t_hit, self.face, self.segs
        vis.points, vis.indices = mesh.points, mesh.indices
        dev.launch(shade_visible_surface, npix, [camera_view(pinhole(cam)), u.media.struct, u.surfaces,
                                                 self._shadowed_lights(), vis, self.settings["shadow_steps"],
                                                 self.settings["steps"], wp.vec3(*scene.background),
                                                 self.multiple.struct(), self.radiance],
                   self.device, work=self.pixel_work(1.0, self._view_samples()))

    def _march(self):
        scene, u, cfg = self.scene, self.uploads, self.settings
        cam = scene.camera
        npix = cam.width * cam.height
        has_depth = bool(scene.surfaces)
        self._no_shadow_maps()
        if has_depth:
            self.surface = self.radiance  # attenuated by the surface pass
        else:
            self.surface = self._scratch("surface", npix, wp.vec3)
        st = ShaftSettings()
        st.steps, st.block, st.jitter = cfg["steps"], self.effective_block(), cfg["jitter"]
        st.scattering, st.shadow_steps, st.seed = cfg["scattering"], cfg["shadow_steps"], cfg["seed"]
        st.spacing = cfg["spacing"]
        st.has_depth = int(has_depth)
        pixel = 2.0 * math.tan(math.radians(cam.fov_y) / 2.0) / cam.height  # a pixel's width per unit distance
        st.near = cfg["light_ball"] * st.block * pixel
        self.partial = self._scratch("partial", npix, wp.vec3)
        self.own = self._scratch("own", npix, wp.vec3)
        dev.launch(march_shafts, npix, [camera_view(pinhole(cam)), u.media.struct, self._shadowed_lights(), self.segs,
                                        wp.vec3(*scene.background), st, self.multiple.struct(), self.surface,
                                        self.partial, self.own], self.device,
                   work=self.pixel_work(st.steps / st.block**2, self._view_samples()))
        if st.block == 1 or not cfg["scattering"] or not scene.media:
            self.image = wp.empty(npix, dtype=wp.vec3, device=self.device)  # the frame's own: not reused
            dev.launch(add_images, npix, [self.surface, self.partial, self.own, self.image], self.device)

    def _view_samples(self) -> int:
        """Density samples along a pixel's view ray: one a step in heterogeneous media (their
        optical depth is marched), none where every medium has a closed form."""
        return self.settings["steps"] if any(m.type != "homogeneous" for m in self.scene.media) else 0

    def _block_rows(self):
        cam = self.scene.camera
        self.rows = self._scratch("rows", cam.width * cam.height, wp.vec3)
        dev.launch(block_sum_rows, cam.width * cam.height, [self.partial, cam.width, self.effective_block(), self.rows],
                   self.device)

    def _block_cols(self):
        cam = self.scene.camera
        self.image = wp.empty(cam.width * cam.height, dtype=wp.vec3, device=self.device)
        dev.launch(block_sum_cols, cam.width * cam.height, [self.rows, self.surface, self.own, cam.width, cam.height,
                                                            self.effective_block(), self.image], self.device)

    def _block_edges(self):
        cam = self.scene.camera
        self.image = wp.empty(cam.width * cam.height, dtype=wp.vec3, device=self.device)
        dev.launch(block_sum_depth_aware, cam.width * cam.height,
                   [self.partial, self.surface, self.own, self.t_hit, cam.width, cam.height, self.effective_block(),
                    self.settings["edge_tolerance"], self.image], self.device)

    def output(self):
        return self.image

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """Intermediate arrays for looking inside (``viz``): ``depth``, the distance to the visible
        surface per pixel (H x W, INF where none); per light, the shadow map's depth
        surface as world points (``shadow_points``, (texels, 3), INF where a ray escaped) and
        its distances (``shadow_distance``); and ``lit_slice``, the in-scattered radiance toward
        the camera on the vertical plane through the camera's target facing the camera
        ((resolution, resolution, 3), with the plane's ``lit_slice_corners``, 4 x 3)."""
        cam = self.scene.camera
        out = {"shadow_points": [], "shadow_distance": []}
        if self.scene.surfaces and self.t_hit is not None:
            out["depth"] = self.t_hit.numpy().reshape(cam.height, cam.width)
        structs = self._map_structs(occluders=bool(self.scene.surfaces)) if self.maps is not None else []
        for sm in structs:
            count = texels(sm.kind, sm.res)
            if count == 0:
                continue
            pts = wp.empty(count, dtype=wp.vec3, device=self.device)
            dev.launch(shadow_hit_points, count, [sm, self.depth, pts], self.device)
            out["shadow_points"].append(pts.numpy())
            out["shadow_distance"].append(self.depth.numpy()[sm.offset:sm.offset + count])
        target, origin = np.asarray(cam.target, float), np.asarray(cam.origin, float)
        view = (target - origin) / np.linalg.norm(target - origin)
        right = np.cross(view, cam.up)
        right /= np.linalg.norm(right)
        lo, hi = scene_bounds(self.scene)
        half = 0.5 * float(np.max(hi - lo))
        up = np.asarray(cam.up, float) / np.linalg.norm(cam.up)
        corner = target - half * right - half * up
        edge_u, edge_v = 2 * half * right, 2 * half * up
        lit = wp.empty(resolution * resolution, dtype=wp.vec3, device=self.device)
        dev.launch(sample_lit_slice, resolution * resolution,
                   [self.uploads.media.struct, self._shadowed_lights(), wp.vec3(*corner),
                    wp.vec3(*edge_u), wp.vec3(*edge_v), resolution, wp.vec3(*view), self.settings["shadow_steps"],
                    lit], self.device)
        out["lit_slice"] = lit.numpy().reshape(resolution, resolution, 3)
        out["lit_slice_corners"] = np.array([corner, corner + edge_u, corner + edge_u + edge_v, corner + edge_v])
        return out


TECHNIQUE = LightShafts
