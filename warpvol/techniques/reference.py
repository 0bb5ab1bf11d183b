"""Reference: an unbiased volumetric path tracer, the ground truth for every technique.

Per camera sample it follows a path through media and off surfaces:

* Distance sampling by superposition: the first collision is the earliest of each medium
  component's own, sampled exactly for homogeneous shapes, particle spheres and RBF
  Gaussians and by delta tracking (Woodcock et al. 1965) in grids (``media/volume.py``).
* In-scattered direct light along every segment by next-event estimation to one light, chosen
  in proportion to its unshadowed irradiance integrated along the segment,
  combining two samples with the power heuristic (Veach 1997): equiangular sampling toward
  a point or spot light (Kulla & Fajardo 2012), whose pdf cancels the 1/d^2 of a light
  inside the medium, and the segment's first real collision, the one the path goes on from
  (pdf sigma_t T: it lands where the medium is, and its weight stays bounded however loose
  the majorant). Transmittance toward the camera and the light is exact in homogeneous,
  particle and RBF media and ratio-tracked (Novak et al. 2014) in grids; there, where the
  collision's pdf is not known exactly, a point light's second sample is exponential
  sampling of the majorant. Surfaces occlude through a ``wp.Mesh`` query.
* Lambertian + normalised Phong surfaces with direct light and cosine-sampled bounces;
  escaping rays see the background.
* Where a point or spot light is near (within ``LAMP_DEPTH`` of the majorant's optical depth,
  in a path's first ``LAMP_EVENTS`` events), a share ``lamp_share`` of the continuations, in the
  media and off surfaces, is aimed at a light, uniform in the angle to it, and weighed against
  the phase function's or the cosine lobe's own directions by one-sample MIS (balance
  heuristic): a lamp's glow, seen from a scattering point, grows like 1/angle toward it, and the
  rare direction that passed close to the lamp was a firefly (street lamp in haze: noise at equal
  time 0.31 -> 0.17 of the mean away from the lamp's core, 80x60 at 256 spp).
* ``max_bounces`` counts scattering events (volume or surface): 1 is single scattering,
  -1 unlimited (Russian roulette on the throughput after ``ROULETTE_AFTER`` events, survival
  at most 0.995 an event). Mitsuba's max_depth is one more.
  The background is a light too: after the last event the path's sampled continuation
  still adds the background if it escapes (``sky_after_last``), so single scattering
  includes the sky's light scattered once, as Mitsuba's environment emitter does.

If extinction differs between R, G and B, each channel is traced on its own (three
launches), so distance sampling stays exact per channel. Per-pixel sums go to float64.

A ``@wp.func`` receives the RNG state by value: its draws do not advance the caller's
state. Every call that draws therefore gets a fresh stream, ``wp.rand_init(wp.randi(rng), STREAM)``,
drawn inline by the caller, so no two estimates that are multiplied share random numbers (a
product of correlated estimates is biased). The sharing on purpose: a segment's direct light
uses the path's free flight as a sample (exact media), or draws from the free flight's stream
(tracked grids: its majorant sample is then delta tracking's first tentative collision); the
two are only summed.
"""

from __future__ import annotations

import numpy as np
import warp as wp
from tqdm import tqdm

from .. import device as dev
from ..geometry.camera import RasterView, camera_view, view_ray_at
from ..geometry.mesh import Surfaces, surface_hit
from ..media.volume import (Media, depths_and_extinction, exact_media, free_flight, in_scatter_at, media_span,
                            transmittance_estimate)
from ..physics.brdf import brdf_eval
from ..physics.constants import INF, PI, RAY_EPS, STREAM
from ..physics.lights import DIRECTIONAL, Emitter, light_incident
from ..physics.phase import phase_eval, phase_sample, phase_sample_pdf
from ..physics.sampling import (angle_uniform_direction, angle_uniform_pdf, cosine_direction, equiangular_pdf,
                                equiangular_sample, exponential_pdf, power_heuristic, sample_exponential)
from ..physics.transmittance import transmittance_rgb
from ..pipeline import FLAG, Quality, Setting, Stage, Technique
from ..shading import light_transmittance, surface_direct
from ..upload import SceneUploads, pinhole

dev.kernel_module(__name__)

NAME = "reference"
SETTINGS = {
    "spp": Setting(64, 1, 1 << 24, "samples per pixel"),
    "max_bounces": Setting(-1, -1, 1 << 20, "scattering events per path; 1 = single scattering, -1 = unlimited"),
    "pixel_area": Setting(1, 0, 1, "1: sample the pixel's area (box filter); 0: its centre, as real-time techniques do",
                          names=FLAG),
    "seed": Setting(0, 0, 2**31 - 1, "random seed"),
    "lamp_share": Setting(0.75, 0.0, 0.95, "the share of continuations near a point or spot light aimed at it "
                          "(one-sample MIS with the phase function's and surfaces' own directions; the lamp's "
                          "glow seen from afar without fireflies); 0: never aimed"),
}


#: Russian roulette on the throughput starts after this many scattering events. Starting earlier is
#: faster per path on the built-in scenes, but a point light in a homogeneous box then needs several
#: times the samples to the same noise and target_error's two-run estimate underrates the error:
#: the paths' weights get heavy tails.
ROULETTE_AFTER = wp.constant(5)


#: The setting ``lamp_share`` (0.75 by default) is the share of scattering events (in the media
#: and on surfaces) whose next direction is aimed at a point or spot light, uniform in the angle
#: to it (``angle_uniform_direction``); the rest are drawn from the phase function or the cosine
#: lobe, and the two are weighed by one-sample MIS with the balance heuristic, so a
#: continuation's weight is at most 1 / (1 - lamp_share). The light a lamp scatters in the fog
#: around it is seen from afar as a glow whose radiance grows like 1/alpha toward it (alpha the
#: angle to it): drawn from the phase function alone, the rare direction that passes close to
#: the lamp brought a firefly (0.25 and 0.5 left more noise than 0.75 on the street lamp).
#: ... at the first LAMP_EVENTS events of a path only (as many as come before Russian roulette:
#: weights up to 1 / (1 - lamp_share) are multiplied at most this many times; on the street
#: lamp, 2 events kept under half of the gain), and only where the lamp lies within LAMP_DEPTH
#: of the medium's majorant optical depth (deeper, its glow is dimmed, and in a dense medium the
#: aimed directions only multiply weights: sigma_t 1e6 around a lamp then gave fireflies).
LAMP_EVENTS = wp.constant(5)
LAMP_DEPTH = wp.constant(4.0)


@wp.struct
class Span:
    """The stretch o + t d, t in [ta, tb), of a path segment inside the media."""

    o: wp.vec3
    d: wp.vec3
    ta: float
    tb: float


@wp.struct
class PathSettings:
    max_events: int
    channel: int  # -1: grey extinction, trace RGB together; else the one channel traced
    pixel_area: int
    spp: int  # samples per pixel in this launch
    slots: int  # threads that share a pixel's samples
    seed: int
    survival: float  # Russian roulette: the most a path survives an event with (after ROULETTE_AFTER events)
    lamp_share: float  # the setting lamp_share


@wp.func
def scatter_sample(m: Media, s: Surfaces, light: Emitter, o: wp.vec3, d: wp.vec3, ta: float, t: float,
                   c: int, rng: wp.uint32) -> wp.vec3:
    """Unbiased estimate of T(ta, t) sigma_s(x) p(x) E_light(x) at x = o + t d."""
    x = o + t * d
    wi, dist, e = light_incident(light, x)
    if dist <= 0.0:
        return wp.vec3(0.0)
    fs = in_scatter_at(m, x, wp.dot(d, wi))
    if fs[0] <= 0.0 and fs[1] <= 0.0 and fs[2] <= 0.0:
        return wp.vec3(0.0)
    tl = light_transmittance(m, s, x, wi, dist, c, wp.rand_init(wp.randi(rng), STREAM), 0)
    if tl[0] <= 0.0 and tl[1] <= 0.0 and tl[2] <= 0.0:
        return wp.vec3(0.0)
    tc = transmittance_estimate(m, o, d, ta, t, c, wp.rand_init(wp.randi(rng), STREAM))
    return wp.cw_mul(wp.cw_mul(fs, e), wp.cw_mul(tl, tc))


@wp.func
def segment_irradiance(light: Emitter, o: wp.vec3, d: wp.vec3, ta: float, tb: float) -> float:
    """The light's unshadowed irradiance integrated along the segment [ta, tb] (grey): for a
    point or spot light I (theta_b - theta_a) / h, the integral of I / r^2 over a line at
    distance h (cone ignored); for a directional light E (tb - ta). What picking a light
    for the segment's next-event estimate is proportional to."""
    e = (light.strength[0] + light.strength[1] + light.strength[2]) / 3.0
    if light.kind == DIRECTIONAL:
        return e * (tb - ta)
    delta = wp.dot(light.position - o, d)
    h = wp.max(wp.length(light.position - (o + delta * d)), 1.0e-7)
    return e * (wp.atan2(tb - delta, h) - wp.atan2(ta - delta, h)) / h


@wp.func
def pick_light(lights: wp.array(dtype=Emitter), span: Span, rng: wp.uint32):
    """One light for the segment, in proportion to ``segment_irradiance``, by one pass of weighted
    reservoir sampling: light l replaces the choice with probability w_l / (the sum of weights so
    far), which leaves each light chosen with w_l / total. Returns (the light, -1 where none
    reaches the segment; total; its weight w_l; the generator's state after the draws)."""
    total = float(0.0)
    chosen = int(-1)
    w_chosen = float(0.0)
    for l in range(lights.shape[0]):
        w = segment_irradiance(lights[l], span.o, span.d, span.ta, span.tb)
        total += w
        if w > 0.0 and wp.randf(rng) * total < w:
            chosen = l
            w_chosen = w
    return chosen, total, w_chosen, rng


@wp.func
def equiangular_frame(light: Emitter, span: Span):
    """Equiangular sampling's frame for a point or spot light over the segment (Kulla & Fajardo
    2012): (delta, the foot of the light on the line; h, its distance from the line; the angles
    th_a, th_b the segment's ends make at the light; whether the segment subtends an angle at
    all). A directional light: (0, 1, 0, 0, False)."""
    delta = float(0.0)
    h = float(1.0)
    th_a = float(0.0)
    th_b = float(0.0)
    equiangular = False
    if light.kind != DIRECTIONAL:
        delta = wp.dot(light.position - span.o, span.d)
        h = wp.max(wp.length(light.position - (span.o + delta * span.d)), 1.0e-7)
        th_a = wp.atan2(span.ta - delta, h)
        th_b = wp.atan2(span.tb - delta, h)
        equiangular = th_b - th_a > 1.0e-12
    return delta, h, th_a, th_b, equiangular


@wp.func
def segment_direct(m: Media, s: Surfaces, lights: wp.array(dtype=Emitter), span: Span, t_ff: float, i_ff: int,
                   exact: bool, c: int, rng: wp.uint32) -> wp.vec3:
    """Direct light scattered toward -d from the media on [ta, tb] from one light, chosen in
    proportion to ``segment_irradiance`` and weighted by one over that probability: each light
    costs transmittances through the media, so a scene with 8 lights pays for one per segment,
    mostly the one the segment passes closest to.

    Two strategies, combined with the power heuristic: equiangular sampling toward a point
    or spot light, and the segment's free flight (t_ff, i_ff), the first real collision that
    the path itself goes on from (i_ff < 0: none), whose pdf is sigma_t(t) T(ta, t). Its
    estimate albedo_i p_i E T_light (medium i_ff chosen with sigma_i / sigma_t) stays bounded
    however loose the majorant, and it lands where the medium is (a Gaussian's core, not its
    thin tails). Its pdf is exact when every medium is (``exact``: ``exact_media``); with a tracked grid
    only an estimate of T is known, so a point light's second strategy there is exponential
    sampling of the majorant, whose pdf is exact."""
    o = span.o
    d = span.d
    ta = span.ta
    tb = span.tb
    L = wp.vec3(0.0)
    mu = m.majorant[c]
    chosen, total, w_chosen, rng = pick_light(lights, span, rng)
    if chosen < 0:
        return L
    light = lights[chosen]
    point_like = light.kind != DIRECTIONAL
    delta, h, th_a, th_b, equiangular = equiangular_frame(light, span)
    # the free flight's optical depth from ta and sigma_t, for its MIS weight against equiangular
    # sampling in exact media (taken with the equiangular sample's in one walk)
    tau_f = wp.vec3(0.0)
    sig_f = wp.vec3(0.0)
    if exact and equiangular:
        t = wp.clamp(equiangular_sample(h, delta, th_a, th_b, wp.randf(rng)), ta, tb)
        pdf_e = equiangular_pdf(h, delta, th_a, th_b, t)
        x = o + t * d
        wi, dist, e = light_incident(light, x)
        t_f = wp.where(i_ff >= 0, t_ff, ta)
        tau_e, tf, fs, sig_e, sf = depths_and_extinction(m, o, d, ta, t, t_f, wp.dot(d, wi))
        tau_f = tf
        sig_f = sf
        if dist > 0.0 and wp.max(fs) > 0.0:
            tc = transmittance_rgb(tau_e)
            pdf_f = sig_e[c] * tc[c]
            tl = light_transmittance(m, s, x, wi, dist, c, wp.rand_init(wp.randi(rng), STREAM), 0)
            w = power_heuristic(pdf_e, pdf_f)
            L += wp.cw_mul(wp.cw_mul(fs, e), wp.cw_mul(tl, tc)) * (w / pdf_e)
    elif equiangular:
        t = wp.clamp(equiangular_sample(h, delta, th_a, th_b, wp.randf(rng)), ta, tb)
        pdf_e = equiangular_pdf(h, delta, th_a, th_b, t)
        pdf_m = exponential_pdf(mu, t - ta)
        w = power_heuristic(pdf_e, pdf_m)
        L += scatter_sample(m, s, light, o, d, ta, t, c, wp.rand_init(wp.randi(rng), STREAM)) * (w / pdf_e)
    if exact or not point_like:
        # the free flight: weight 1 where there is no equiangular sample to share with (a
        # directional light, in grids too; a point light on the segment's line)
        if i_ff >= 0:
            x = o + t_ff * d
            wi, dist, e = light_incident(light, x)
            w = float(1.0)
            if equiangular:
                pdf_e = equiangular_pdf(h, delta, th_a, th_b, t_ff)
                pdf_f = sig_f[c] * wp.exp(-tau_f[c])
                w = power_heuristic(pdf_f, pdf_e)
            fs = m.albedo[i_ff] * phase_eval(m.phase[i_ff], m.phase_table, wp.dot(d, wi))
            if dist > 0.0 and w > 0.0 and wp.max(fs) > 0.0:
                tl = light_transmittance(m, s, x, wi, dist, c, wp.rand_init(wp.randi(rng), STREAM), 0)
                L += wp.cw_mul(wp.cw_mul(fs, e), tl) * w
    elif mu > 0.0:
        t = ta + sample_exponential(wp.randf(rng), mu)
        if t < tb:
            pdf_m = exponential_pdf(mu, t - ta)
            pdf_e = float(0.0)
            if equiangular:
                pdf_e = equiangular_pdf(h, delta, th_a, th_b, t)
            if pdf_m > 0.0:
                w = power_heuristic(pdf_m, pdf_e)
                L += scatter_sample(m, s, light, o, d, ta, t, c, wp.rand_init(wp.randi(rng), STREAM)) * (w / pdf_m)
    return L * (total / w_chosen)


@wp.func
def lamp_weight(light: Emitter, x: wp.vec3, mu: float) -> float:
    """How strongly a continuation from x is aimed at ``light``: its mean intensity over the
    squared distance, 0 for a directional light and beyond LAMP_DEPTH of the majorant ``mu``."""
    if light.kind == DIRECTIONAL:
        return 0.0
    rel = light.position - x
    r2 = wp.dot(rel, rel)
    if mu * mu * r2 > LAMP_DEPTH * LAMP_DEPTH:
        return 0.0
    return (light.strength[0] + light.strength[1] + light.strength[2]) / (3.0 * wp.max(r2, 1.0e-12))


@wp.func
def lamps_total(lights: wp.array(dtype=Emitter), x: wp.vec3, mu: float, events: int) -> float:
    """The sum of ``lamp_weight`` over the lights; 0 past LAMP_EVENTS events."""
    total = float(0.0)
    if events <= LAMP_EVENTS:
        for l in range(lights.shape[0]):
            total += lamp_weight(lights[l], x, mu)
    return total


@wp.func
def toward_lamp(lights: wp.array(dtype=Emitter), x: wp.vec3, mu: float, total: float, rng: wp.uint32) -> wp.vec3:
    """A direction from x aimed at one point or spot light, chosen with ``lamp_weight`` / total,
    uniform in the angle to it (``angle_uniform_direction``)."""
    pick = wp.randf(rng) * total
    w = wp.vec3(0.0, 0.0, 1.0)
    for l in range(lights.shape[0]):
        lw = lamp_weight(lights[l], x, mu)
        if lw > 0.0 and pick >= 0.0 and pick < lw:
            w = angle_uniform_direction(wp.normalize(lights[l].position - x), wp.randf(rng), wp.randf(rng))
        pick -= lw
    return w


@wp.func
def lamps_pdf(lights: wp.array(dtype=Emitter), x: wp.vec3, mu: float, total: float, w: wp.vec3) -> float:
    """The density at w of ``toward_lamp``: each light's angle-uniform density, weighted as chosen."""
    pdf = float(0.0)
    for l in range(lights.shape[0]):
        lw = lamp_weight(lights[l], x, mu)
        if lw > 0.0:
            pdf += lw / total * angle_uniform_pdf(wp.normalize(lights[l].position - x), w)
    return pdf


@wp.func
def aim_at_lamps(lights: wp.array(dtype=Emitter), x: wp.vec3, mu: float, events: int, share: float, wi: wp.vec3,
                 rng: wp.uint32):
    """The continuation from x with a ``share`` of it aimed at the lamps (``toward_lamp``), where
    one is near (``lamps_total`` > 0; ``share`` > 0): (the direction, ``wi`` as drawn by the
    phase function or the cosine lobe or one aimed; the lamps' part of the mixture's density
    there, share x ``lamps_pdf``; whether the mixture applies; the generator's state after)."""
    total = float(0.0)
    if share > 0.0:
        total = lamps_total(lights, x, mu, events)
    if total <= 0.0:
        return wi, 0.0, False, rng
    w = wi
    if wp.randf(rng) < share:
        w = toward_lamp(lights, x, mu, total, wp.rand_init(wp.randi(rng), STREAM))
    return w, share * lamps_pdf(lights, x, mu, total, w), True, rng


@wp.func
def sky_after_last(m: Media, s: Surfaces, o: wp.vec3, d: wp.vec3, background: wp.vec3, c: int,
                   rng: wp.uint32) -> wp.vec3:
    """After a path's last scattering event (``max_bounces``), its continuation d still counts
    if it escapes to the background: the sky is a light, and light from it that scattered
    max_bounces times belongs in the image. Zero past a surface; through the media an
    unbiased transmittance estimate."""
    if background[0] <= 0.0 and background[1] <= 0.0 and background[2] <= 0.0:
        return wp.vec3(0.0)
    return wp.cw_mul(light_transmittance(m, s, o, d, INF, c, rng, 0), background)


@wp.func
def make_span(o: wp.vec3, d: wp.vec3, ta: float, tb: float) -> Span:
    span = Span()
    span.o = o
    span.d = d
    span.ta = ta
    span.tb = tb
    return span


@wp.func
def channel_only(L: wp.vec3, channel: int) -> wp.vec3:
    """L with only ``channel`` kept (-1: all three, grey extinction traced them together)."""
    if channel >= 0:
        mask = wp.vec3(0.0)
        mask[channel] = 1.0
        return wp.cw_mul(L, mask)
    return L


@wp.func
def jittered_ray(cam: RasterView, st: PathSettings, px: int, py: int, rng: wp.uint32):
    """The camera ray through pixel (px, py): its centre, or a uniform point of it with
    ``pixel_area``; and the generator's state after."""
    jx = float(0.5)
    jy = float(0.5)
    if st.pixel_area != 0:
        jx = wp.randf(rng)
        jy = wp.randf(rng)
    o, d = view_ray_at(cam, float(px) + jx, float(py) + jy)
    return o, d, rng


@wp.func
def trace_path(cam: RasterView, m: Media, s: Surfaces, lights: wp.array(dtype=Emitter), background: wp.vec3,
               st: PathSettings, px: int, py: int, rng: wp.uint32) -> wp.vec3:
    """One camera path through pixel (px, py) (its centre, or a uniform point of it with
    ``pixel_area``): each segment's next collision by free flight through the media in front of
    the nearest surface, the direct light scattered on that segment (``segment_direct``), then
    a scattering event (phase sampled, throughput times albedo) or the surface's direct light and
    a BRDF bounce, until ``max_events`` events or the path leaves; the background counts where it
    escapes. Returns the path's radiance estimate for the traced channel (all three with grey
    extinction)."""
    o, d, rng = jittered_ray(cam, st, px, py, rng)
    c = wp.max(st.channel, 0)
    mu = m.majorant[c]
    exact = exact_media(m)
    beta = wp.vec3(1.0)
    L = wp.vec3(0.0)
    events = int(0)
    while True:
        hit, t_surf, n, face = surface_hit(s, o, d, INF)
        a, b = media_span(m, o, d)
        ta = wp.max(a, 0.0)
        tb = wp.min(b, t_surf)
        in_media = ta < tb and mu > 0.0
        # the next real collision: the earliest of the media components' own (exact or tracked);
        # the segment's direct light reuses it as one of its samples
        collided = bool(False)
        t = ta
        i = int(-1)
        if in_media:
            segment = wp.randi(rng)
            t, i = free_flight(m, o, d, ta, tb, c, wp.rand_init(segment, STREAM))
            collided = i >= 0
            # where the direct light takes the free flight as a sample (exact media) its own
            # draws must not be the free flight's (which light it picks would then depend on
            # where the flight stopped); where it does not (tracked grids) it shares them on
            # purpose: its majorant sample is then delta tracking's first tentative collision,
            # and the two estimates, only summed, vary less together (random scene 6, a grid
            # and a point light: half the variance)
            if exact:
                segment = wp.randi(rng)
            L += wp.cw_mul(beta, segment_direct(m, s, lights, make_span(o, d, ta, tb), t, i, exact, c,
                                                wp.rand_init(segment, STREAM)))
        if collided:
            events += 1
            x = o + t * d
            u1 = wp.randf(rng)
            u2 = wp.randf(rng)
            wi, weight, pdf = phase_sample(m.phase[i], m.phase_table, d, u1, u2)
            wi, lamp_pdf, aimed, rng = aim_at_lamps(lights, x, mu, events, st.lamp_share, wi, rng)
            if aimed:  # one-sample MIS with directions aimed at the lamps (lamp_share)
                c_wi = wp.dot(d, wi)
                mix = (1.0 - st.lamp_share) * phase_sample_pdf(m.phase[i], m.phase_table, c_wi) + lamp_pdf
                weight = phase_eval(m.phase[i], m.phase_table, c_wi) / mix
            beta = wp.cw_mul(beta, m.albedo[i]) * weight
            o = x
            d = wi
            if events >= st.max_events:  # the last event: only the sky may still reach it
                L += wp.cw_mul(beta, sky_after_last(m, s, o, d, background, c, wp.rand_init(wp.randi(rng), STREAM)))
                break
        elif hit:
            events += 1
            p = o + t_surf * d
            nf = wp.where(wp.dot(n, d) < 0.0, n, -n)
            mat = s.material[face]
            L += wp.cw_mul(beta, surface_direct(m, s, lights, p, nf, -d, mat, c, wp.rand_init(wp.randi(rng), STREAM), 0))
            # cosine-weighted bounce: weight f cos / pdf = pi f
            u1 = wp.randf(rng)
            u2 = wp.randf(rng)
            wi = cosine_direction(nf, u1, u2)
            bounce = PI
            wi, lamp_pdf, aimed, rng = aim_at_lamps(lights, p, mu, events, st.lamp_share, wi, rng)
            if aimed:  # one-sample MIS with directions aimed at the lamps (lamp_share)
                cos_n = wp.max(wp.dot(nf, wi), 0.0)
                mix = (1.0 - st.lamp_share) * cos_n / PI + lamp_pdf
                bounce = wp.where(cos_n > 0.0, cos_n / mix, 0.0)  # below the surface: the path ends dark
            beta = wp.cw_mul(beta, brdf_eval(mat, nf, -d, wi)) * bounce
            if bounce <= 0.0:
                break
            o = p + RAY_EPS * nf
            d = wi
            if events >= st.max_events:  # the last event: only the sky may still reach it
                L += wp.cw_mul(beta, sky_after_last(m, s, o, d, background, c, wp.rand_init(wp.randi(rng), STREAM)))
                break
        else:
            L += wp.cw_mul(beta, background)
            break
        if events > ROULETTE_AFTER:
            # survive in proportion to the throughput, at most ``SURVIVAL`` per event
            q = wp.min(wp.max(beta[0], wp.max(beta[1], beta[2])), st.survival)
            if wp.randf(rng) >= q:
                break
            beta = beta / q
    return channel_only(L, st.channel)


@wp.kernel
def trace_paths(offset: int, cam: RasterView, m: Media, s: Surfaces, lights: wp.array(dtype=Emitter),
                background: wp.vec3, st: PathSettings, accum: wp.array(dtype=wp.vec3d)):
    """Thread (slot, pixel) traces its share of the pass's ``st.spp`` samples of the pixel
    (``st.slots`` threads share a pixel) and adds their sum to ``accum[thread]`` in float64."""
    tid = wp.tid() + offset
    npix = cam.width * cam.height
    p = tid % npix
    slot = tid / npix
    px = p % cam.width
    py = p / cam.width
    rng = wp.rand_init(st.seed, tid)
    count = st.spp / st.slots + wp.where(slot < st.spp % st.slots, 1, 0)
    total = wp.vec3(0.0)
    for k in range(count):
        total += trace_path(cam, m, s, lights, background, st, px, py, wp.rand_init(wp.randi(rng), STREAM))
    accum[tid] = accum[tid] + wp.vec3d(wp.float64(total[0]), wp.float64(total[1]), wp.float64(total[2]))


#: Russian roulette's cap on survival per event once it starts: a path in a bright, dense
#: medium (albedo -> 1) ends after about 1 / (1 - SURVIVAL) more events while its weight
#: grows by 1 / SURVIVAL per event (0.95 gave furnace paths weights of 100 and more: heavy tails).
SURVIVAL = 0.995

#: Paths from which a CPU pass is split over the cores: a path costs from a few microseconds
#: (a ray that escapes) to a millisecond (rbf-thick-fog: 1000 RBFs, 8 lights), so 2048 of them
#: outweigh handing out the chunks (~1 ms) where device.MIN_SPLIT's simple threads would
#: leave a 32x24 image at 8 spp (6144 paths, 4 s) on one core.
SPLIT_PATHS = 2048

#: Threads a launch should keep in flight: a GPU wants hundreds of thousands (pixels x sample
#: slots); the CPU splits one thread per pixel over its cores (``device.launch`` by work).
IN_FLIGHT = {"cpu": 1, "cuda": 1 << 18}


class Reference(Technique):
    """The volumetric path tracer (see the module docstring). Stages: uploads, then trace."""

    NAME = NAME
    EXAMPLES = ("fog-box",)
    TINY = {"spp": 2}
    CENSUS = ("fog-box", {"spp": 16})
    SETTINGS = SETTINGS
    QUALITY = Quality(knob="spp", start=16, top=1 << 20, order=0.5)
    QUALITY_SEED = "seed"  # the error estimate: two runs of independent samples
    LEAVES_OUT = ()
    GATHERS_SKY = True

    def leaves_out(self) -> list[str]:
        n = self.settings["max_bounces"]
        return [f"light scattered more than {n} time{'s' if n != 1 else ''} (max_bounces = {n})"] if n >= 0 else []

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        self.uploads = SceneUploads(self)
        self.image = None

    def stages(self):
        return self.uploads.stages() + [
            Stage("trace", self._trace, reads=("camera", "background"), settings=tuple(SETTINGS),
                  after=("medium", "surfaces", "lights")),
        ]

    def _trace(self):
        scene, u, settings = self.scene, self.uploads, self.settings
        npix = scene.camera.width * scene.camera.height
        spp = settings["spp"]
        channels = [-1] if u.media.grey else [0, 1, 2]
        # passes of about 2^20 paths keep the progress bar moving and sums well-conditioned;
        # a pass is pixels x slots threads, slots enough to fill the device
        per_pass = max(1, min(spp, (1 << 20) // max(npix, 1)))
        in_flight = IN_FLIGHT["cuda" if str(self.device).startswith("cuda") else "cpu"]
        slots = max(1, min(per_pass, in_flight // max(npix, 1)))
        accum = wp.zeros(npix * slots, dtype=wp.vec3d, device=self.device)
        passes = [(ch, k) for ch in channels for k in range(0, spp, per_pass)]
        st = PathSettings()
        st.max_events = settings["max_bounces"] if settings["max_bounces"] >= 0 else 1 << 30
        st.pixel_area = settings["pixel_area"]
        st.survival = SURVIVAL
        st.lamp_share = settings["lamp_share"]
        cam = camera_view(pinhole(scene.camera))
        bar = tqdm(passes, desc=f"reference {spp} spp", unit="pass", delay=1.0, disable=not self.progress, leave=False)
        for i, (ch, k) in enumerate(bar):
            st.channel = ch
            st.spp = min(per_pass, spp - k)
            st.slots = min(slots, st.spp)
            st.seed = (settings["seed"] * 1_000_003 + i) % (2**31)
            dev.launch(trace_paths, npix * st.slots, [cam, u.media.struct, u.surfaces, u.lights,
                                                      wp.vec3(*scene.background), st, accum], self.device,
                       work=st.spp / st.slots, min_split=SPLIT_PATHS)
        self.image = (accum.numpy().reshape(slots, npix, 3).sum(0) / spp).astype(np.float32)

    def diagnostics(self) -> dict:
        """``grey``: whether the media are grey (one launch for all three channels; else one a
        channel, three times the paths)."""
        return {"grey": bool(self.uploads.media.grey)}

    def output(self):
        return self.image


TECHNIQUE = Reference
