"""Illumination networks: multiple scattering in particle clouds by iterating on global lines.

Szirmay-Kalos, Sbert, Umenhoffer, "Real-time Multiple Scattering in Participating Media with
Illumination Networks", EGSR 2005 (1024 particles, 128 directions, 26 FPS
on a GeForce 6800 GT). The cloud is N spheres; light is exchanged only along D sample
directions, between particles that see each other along them. Stages:

* ``network`` (reads the medium): the visibility network V (N x D). D directions spread
  evenly on the sphere (Fibonacci); for each, every particle is projected orthographically
  onto an M x M window over the cloud's bounding sphere (radius R), and one radix sort of
  all N*D (direction, pixel, depth) keys lists the particles of each pixel front to back
  (the paper's depth peeling, done by Warp's sort). Consecutive particles of a list give
  V[p, i] = vp, the particle p sees upstream along direction i, and vp's segment opacity
  alpha = 1 - exp(-tau_vp |x_p - x_vp|.w_i), tau_vp = sigma_t times the number of spheres
  that contain vp's centre (the medium's extinction there). M follows the paper's rule
  D (R tau)^2 / pi >= M^2 with tau the cloud's mean extinction (``window = 0``). That rule
  is an upper bound: at its top a thin cloud's columns hold one to three particles, most
  links see past the cloud and light crosses it in a few iterations. ``column = K`` takes
  instead the largest M under the rule whose occupied columns hold K particles or more on
  average, counted on the cloud's own projection along three of the D directions
  (``column_window``): it depends on how the particles lie, not on the cloud's scale.
  Beyond the paper (its future work): for an animated cloud, ``refresh = k`` re-peels only
  k directions per frame, round robin, and keeps the other directions' links from earlier
  frames (positions, extinction and direct light are always current).
* ``direct`` (reads the lights): each particle's irradiance from each light, averaged over
  its sphere: the inverse square's ball mean (bounded for a light inside it) times the
  transmittance to the light through the union of spheres (overlaps add), averaged over
  ``light_samples`` points of the sphere: a thick particle is lit on its rim, not at its
  centre. The transmittance comes from the shared light pass (media/lightpass.py): the
  cloud rendered once from each light into depth slices (``light_pass = 1``, as Umenhoffer & Szirmay-Kalos 2005
  does) or a Fourier opacity map (2), O(N x footprint) per light instead of every sphere
  against every light ray, and checked against the exact chord sums on 64 particles (the
  exact answer is used instead when the map is off by more than ``light_tolerance``);
  ``light_pass = 0`` is the exact answer throughout (BVH ray queries). With one sample:
  from the centre through the other spheres, times its own sphere's mean self-shadowing
  (the escape probability 3/(8 tau^3) [2 tau^2 - 1 + (1 + 2 tau) e^(-2 tau)], tau =
  sigma_t r).
* ``emission``: E[vp, i] = alpha a sum_lights c_l p(w_light . w_i) E_light T_light, the
  light the segment of vp scatters into direction i. The paper snaps the light to the
  nearest sample direction; we evaluate the phase function at the light's own direction.
  With ``phase_norm = 1`` (the default) c_l = 1 / ((4 pi / D) sum_i p(w_light . w_i)), so
  the D directions carry exactly the scattered energy, (4 pi / D) sum_i c_l p = 1; a lobe
  narrower than the directions' spacing otherwise loses it (between directions) or
  multiplies it (on one). ``phase_norm = 0``: c_l = 1, the paper's.
* ``iterate``: the paper's update (section 3.3), ``iterations`` times per frame:

      I[p, i] = (1 - alpha) I[vp, i] + E[vp, i] + alpha a (4 pi / D) sum_d I[vp, d] P(w_d, w_i)

  and the sky radiance (the scene background) where no particle is seen. The sum is one
  batched matrix product S = I P over all particles (N D^2 multiply-adds per channel) whose
  epilogue forms what each particle sends on, Q = (1 - alpha) I + E + alpha a S, row by row;
  the update is then a gather of Q (one read per link instead of six scattered ones). The phase matrix is tabulated once (D x D), so any phase function
  works: the scene's ``hg`` is true Henyey-Greenstein, its ``cornette_shanks`` the formula
  the paper prints (and calls Henyey-Greenstein). The paper's weights 4 pi / D p(w_d . w_i)
  (``phase_norm = 0``) conserve energy only while the lobe is wide against the directions'
  spacing: for HG g = 0.95 at D = 128 the diagonal weight alone, 4 pi / D p(1) =
  (1 + g) / (D (1 - g)^2), is 6, the iteration's gain far above 1, and it diverges. The
  default (``phase_norm = 1``) scales the tabulated matrix symmetrically to a doubly
  stochastic one, P' = diag(x) P diag(x) (symmetric Sinkhorn-Knopp in float64 at set-up):
  every row sums to 1 (what scatters out of incoming direction d is conserved), every
  column too (so the scattering gain in the max norm is the albedo, never above it), and
  P' stays symmetric (reciprocity). As g -> 1 P' tends to the identity, light passing
  straight on. One iteration is then a map of max-norm gain at most the largest
  1 - alpha (1 - a) over the links (<= 1), and per scattering event at most the albedo.
  The solution is kept between frames: a
  moved light warm-starts from the last one (as the paper does; ``warm = 0`` restarts
  from zero). The stage settles once the relative L2 change of an iteration falls below
  ``tolerance`` and then stays cached until its inputs change.
* ``splat`` (reads the camera): each particle's radiance toward the camera, in-scattered
  from the D incoming radiances plus its direct light with the phase function at the
  camera direction, composited front to back over 8 x 8 pixel tiles (particles sorted
  by tile, then depth). A particle's footprint is its sphere's own opacity along the pixel
  ray, 1 - exp(-sigma_t chord): smooth, zero at the rim, and exact for the transmittance
  of overlapping spheres. The background shows through. A pixel stops once its
  transmittance falls below 1e-5 (what lies behind changes it by less than that fraction).

I and E are (3N, D) arrays, channel c of particle p in row 3p + c (rows padded to a multiple
of 4, columns to 16), so the gather reads one particle's three channels from neighbouring
rows. ``half = 1`` stores them as float16 (as the paper does), scaled by a power of two so
the largest source is at most 1: the iteration is a contraction of the sources, so no
entry comes near the float16 limit of 65504.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import warp as wp

from .. import device as dev
from ..geometry.camera import RasterView, camera_view, pixel_ray
from ..geometry.intersect import ray_sphere, sphere_chord
from ..geometry.tiles import TileLists, bin_spheres, pixel_tile
from ..media.lightpass import REPRESENTATIONS, LightPass
from ..media.particles import ParticleBuffers, Particles, particle_sigma_t
from ..physics.constants import INV_4PI, PI
from ..physics.lights import DIRECTIONAL, Emitter
from ..physics.phase import PhaseParams, PhaseFn, phase_eval, phase_fn, phase_struct, phase_toward
from ..physics.sampling import orthonormal_basis
from ..physics.sphere import fibonacci_directions
from ..physics.transmittance import step_integral_rgb, transmittance_rgb
from ..pipeline import Bias, Quality, Setting, SettingsError, Stage, Technique
from ..upload import SceneUploads, check_particle_scene, particle_buffers, pinhole

dev.kernel_module(__name__)

NAME = "illumination_network"
ONE_SHOT_CAP = 2000  # iterations a one-shot render may take to converge
SETTINGS = {
    "directions": Setting(128, 1, 4096, "sample directions D"),
    "direction_seed": Setting(0, 0, 1 << 30, "0: the Fibonacci set of D directions as laid out; k: the set turned by "
                                             "a random rotation drawn from seed k (target_error compares two)"),
    "window": Setting(0, 0, 4096, "window resolution M per direction; 0: the paper's rule D (R tau)^2 / pi >= M^2"),
    "column": Setting(0.0, 0.0, 1.0e6, "window = 0: the largest M (up to the paper's rule) whose occupied pixel "
                                       "columns hold at least this many particles on average; 0: the paper's rule"),
    "window_at": Setting(0, 0, 4096, "window = 0: the rule taken at this many directions; 0: at D (target_error holds "
                                     "the window of the default D while it raises D)"),
    "iterations": Setting(1, 0, 1 << 20, "iterations per frame (the paper: 1)"),
    "tolerance": Setting(1e-4, 0.0, 1.0, "settle once an iteration changes I by under this (relative L2); 0: never"),
    "warm": Setting(1, 0, 1, "1: start from the previous solution when the lights change; 0: from zero"),
    "half": Setting(0, 0, 1, "1: store I and E as float16, as the paper does"),
    "phase_norm": Setting(1, 0, 1, "1: the phase matrix scaled doubly stochastic (rows and columns sum to 1; energy "
                                   "conserving for any lobe) and each light's emission normalised over the D "
                                   "directions; 0: the paper's weights 4 pi / D (diverges for peaked lobes, "
                                   "e.g. HG g >= 0.9 at D = 128)"),
    "light_samples": Setting(16, 1, 1024, "points of a sphere whose transmittance to a light is averaged (1: centre)"),
    "light_pass": Setting(1, 0, 2, "transmittance to the lights: 0 exact (BVH ray queries), 1 depth slices, "
                                   "2 Fourier opacity map (media/lightpass.py)",
                          names=REPRESENTATIONS),
    "light_slices": Setting(32, 1, 1024, "depth slices S of the light pass"),
    "light_terms": Setting(16, 1, 256, "Fourier terms K of the light pass"),
    "light_texels": Setting(0, 0, 1024, "light-pass texels per face side; 0: 4 R / r (half a median radius)"),
    "light_tolerance": Setting(0.1, 0.0, 10.0, "fall back to exact when the map's relative RMSE against it, "
                                               "measured on 64 particles, is above this; 0: never check"),
    "splat_steps": Setting(0, 0, 4096, "0: splat spheres sorted by depth; S: march S steps through overlapping ones"),
    "refresh": Setting(0, 0, 4096, "when the medium changes, re-peel this many directions (round robin; 0: all)"),
}

ROWS = 4  # rows of I per thread of the matrix product
vec16 = wp.types.vector(length=16, dtype=float)
DEPTH_BITS = wp.constant(wp.int64(1 << 31))


@wp.struct
class DirectLight:
    """Per (particle p, light l) at p L + l: irradiance E_l T_l, travel direction w_l (0: from
    every side) and emission weight c_l (``light_weights``)."""
    direct: wp.array(dtype=wp.vec3)
    travel: wp.array(dtype=wp.vec3)
    weight: wp.array(dtype=float)
    count: int  # lights L


@wp.kernel
def particle_extinction(offset: int, P: Particles, tau: wp.array(dtype=wp.vec3)):
    """sigma_t of the medium at each particle's centre: the sum over spheres containing it."""
    p = wp.tid() + offset
    tau[p] = particle_sigma_t(P, P.centres[p])


@wp.kernel
def project_particles(offset: int, pos: wp.array(dtype=wp.vec3), dirs: wp.array(dtype=wp.vec3),
                      which: wp.array(dtype=int), centre: wp.vec3, R: float, M: int, keys: wp.array(dtype=wp.int64),
                      values: wp.array(dtype=int)):
    """Key (direction, pixel) << 32 | depth for particle p in direction i = which[j]
    (thread j N + p)."""
    tid = wp.tid() + offset
    n = pos.shape[0]
    i = which[tid / n]
    p = tid % n
    w = dirs[i]
    e1, e2 = orthonormal_basis(w)
    x = pos[p] - centre
    scale = float(M) / (2.0 * R)
    u = wp.clamp(int(wp.floor((wp.dot(x, e1) + R) * scale)), 0, M - 1)
    v = wp.clamp(int(wp.floor((wp.dot(x, e2) + R) * scale)), 0, M - 1)
    depth = wp.clamp((wp.dot(x, w) + R) / (2.0 * R), 0.0, 1.0)
    cell = (wp.int64(i) * wp.int64(M) + wp.int64(v)) * wp.int64(M) + wp.int64(u)
    keys[tid] = cell * DEPTH_BITS * wp.int64(2) + wp.int64(depth * float(DEPTH_BITS - wp.int64(1)))
    values[tid] = p


@wp.kernel
def clear_directions(offset: int, which: wp.array(dtype=int), D: int, V: wp.array(dtype=int),
                     alpha: wp.array(dtype=wp.vec3)):
    """Forget the links of directions which[j] before they are peeled again (thread j N + p)."""
    tid = wp.tid() + offset
    n = V.shape[0] / D
    k = (tid % n) * D + which[tid / n]
    V[k] = -1
    alpha[k] = wp.vec3(0.0)


@wp.kernel
def link_network(offset: int, keys: wp.array(dtype=wp.int64), values: wp.array(dtype=int),
                 pos: wp.array(dtype=wp.vec3), dirs: wp.array(dtype=wp.vec3), tau: wp.array(dtype=wp.vec3), M: int,
                 V: wp.array(dtype=int), alpha: wp.array(dtype=wp.vec3)):
    """Sorted entry k: its particle sees the previous entry of the same pixel list upstream."""
    k = wp.tid() + offset
    D = dirs.shape[0]
    cell = keys[k] / (DEPTH_BITS * wp.int64(2))
    i = int(cell / (wp.int64(M) * wp.int64(M)))
    p = values[k]
    vp = int(-1)
    if k > 0:
        if keys[k - 1] / (DEPTH_BITS * wp.int64(2)) == cell:
            vp = values[k - 1]
    V[p * D + i] = vp
    if vp >= 0:
        dist = wp.max(wp.dot(pos[p] - pos[vp], dirs[i]), 0.0)
        alpha[vp * D + i] = wp.vec3(1.0) - transmittance_rgb(tau[vp] * dist)


@wp.kernel
def light_weights(offset: int, dirs: wp.array(dtype=wp.vec3), travel: wp.array(dtype=wp.vec3), ph: PhaseParams,
                  table: wp.array(dtype=float), normalise: int, lights: wp.array(dtype=Emitter), share: int,
                  out: wp.array(dtype=float)):
    """Thread p L + l: c = 1 / ((4 pi / D) sum_i p(w_l . w_i)) with ``normalise`` (the D
    directions then carry exactly what the particle scatters of light l), else 1. With
    ``share``, a directional light's c (the same travel direction for every particle) is
    copied from particle 0's, which a launch over the first L threads computed."""
    tid = wp.tid() + offset
    L = lights.shape[0]
    if share != 0 and lights[tid % L].kind == DIRECTIONAL:
        if tid >= L:
            out[tid] = out[tid % L]
        return
    D = dirs.shape[0]
    c = float(1.0)
    if normalise != 0:
        total = float(0.0)
        for i in range(D):
            total += phase_toward(ph, table, travel[tid], dirs[i])
        if total > 0.0:
            c = float(D) / (4.0 * PI * total)
    out[tid] = c


@wp.kernel
def emission_network(offset: int, dirs: wp.array(dtype=wp.vec3), dl: DirectLight,
                     albedo: wp.array(dtype=wp.vec3), alpha: wp.array(dtype=wp.vec3), ph: PhaseParams,
                     table: wp.array(dtype=float), inv_scale: float, E: wp.array2d(dtype=Any)):
    """E[vp, i] = alpha a sum_l c_l p(w_l . w_i) E_l T_l, channel c of vp in row 3 vp + c
    (c_l from ``light_weights``)."""
    tid = wp.tid() + offset
    D = dirs.shape[0]
    p = tid / D
    i = tid % D
    s = wp.vec3(0.0)
    for l in range(dl.count):
        k = p * dl.count + l
        s += (dl.weight[k] * phase_toward(ph, table, dl.travel[k], dirs[i])) * dl.direct[k]
    e = wp.cw_mul(wp.cw_mul(alpha[tid], albedo[p]), s) * inv_scale
    for c in range(3):
        E[3 * p + c, i] = E.dtype(e[c])


@wp.kernel
def phase_matrix(offset: int, dirs: wp.array(dtype=wp.vec3), ph: PhaseParams, table: wp.array(dtype=float), Dp: int,
                 out: wp.array(dtype=float)):
    """out[d Dp + i] = p(w_d . w_i) for d, i < D; zero in the padding."""
    tid = wp.tid() + offset
    d = tid / Dp
    i = tid % Dp
    D = dirs.shape[0]
    v = float(0.0)
    if d < D and i < D:
        v = phase_eval(ph, table, wp.dot(dirs[d], dirs[i]))
    out[tid] = v


@wp.kernel
def scatter_matmul(offset: int, I: wp.array2d(dtype=Any), P: wp.array2d(dtype=vec16), E: wp.array2d(dtype=Any),
                   alpha: wp.array(dtype=wp.vec3), albedo: wp.array(dtype=wp.vec3), n: int, D: int,
                   Q: wp.array2d(dtype=float)):
    """S = I P, thread (row block, column block) accumulating 4 rows x 16 columns, and in the
    same pass what particle vp sends on along each direction i (row 3 vp + c):
    Q = (1 - alpha) I + E + alpha a S. The update is then a gather of Q alone."""
    tid = wp.tid() + offset
    nb = P.shape[1]
    r = (tid / nb) * 4
    b = tid % nb
    a0 = vec16()
    a1 = vec16()
    a2 = vec16()
    a3 = vec16()
    for d in range(P.shape[0]):
        pd = P[d, b]
        a0 += float(I[r, d]) * pd
        a1 += float(I[r + 1, d]) * pd
        a2 += float(I[r + 2, d]) * pd
        a3 += float(I[r + 3, d]) * pd
    c0 = b * 16
    for k in range(4):
        row = r + k
        vp = row / 3
        c = row % 3
        if vp < n:
            acc = a0
            if k == 1:
                acc = a1
            elif k == 2:
                acc = a2
            elif k == 3:
                acc = a3
            al = albedo[vp][c]
            for j in range(16):
                i = c0 + j
                if i < D:
                    a = alpha[vp * D + i][c]
                    Q[row, i] = (1.0 - a) * float(I[row, i]) + float(E[row, i]) + a * al * acc[j]


@wp.kernel
def gather_update(offset: int, V: wp.array(dtype=int), Q: wp.array2d(dtype=float), sky: wp.vec3, D: int,
                  out: wp.array2d(dtype=Any)):
    """The paper's update: I[p, i] = Q[vp, i] from the upstream particle vp = V[p, i], the sky
    if there is none; 16 directions i of particle p per thread."""
    tid = wp.tid() + offset
    blocks = (D + 15) / 16
    p = tid / blocks
    i0 = (tid % blocks) * 16
    for i in range(i0, wp.min(i0 + 16, D)):
        vp = V[p * D + i]
        for c in range(3):
            v = sky[c]
            if vp >= 0:
                v = Q[3 * vp + c, i]
            out[3 * p + c, i] = out.dtype(v)


@wp.kernel
def change_norms(offset: int, I_new: wp.array2d(dtype=Any), I_old: wp.array2d(dtype=Any), D: int,
                 out: wp.array(dtype=float)):
    """out += (sum (new - old)^2, sum new^2) over the first D columns (thread r Dp + i: row r, column i;
    atomics into two numbers: launched in one piece)."""
    tid = wp.tid() + offset
    r = tid / I_new.shape[1]
    i = tid % I_new.shape[1]
    if i < D:
        a = float(I_new[r, i])
        b = float(I_old[r, i])
        wp.atomic_add(out, 0, (a - b) * (a - b))
        wp.atomic_add(out, 1, a * a)


@wp.kernel
def rescale(offset: int, I: wp.array2d(dtype=Any), factor: float):
    tid = wp.tid() + offset
    r = tid / I.shape[1]
    i = tid % I.shape[1]
    I[r, i] = I.dtype(float(I[r, i]) * factor)


@wp.kernel
def outgoing_radiance(offset: int, P: Particles, eye: wp.vec3, dirs: wp.array(dtype=wp.vec3),
                      I: wp.array2d(dtype=Any), dl: DirectLight, pf: PhaseFn, normalise: int, scale: float,
                      out: wp.array(dtype=wp.vec3)):
    """a (sum_d I[p, d] p(w_d . w_eye) 4 pi / D + sum_l p(w_l . w_eye) E_l T_l): the source
    radiance of particle p toward the eye; ``normalise``: the D weights sum to 1 instead."""
    p = wp.tid() + offset
    D = dirs.shape[0]
    to_eye = eye - P.centres[p]
    w = wp.vec3(0.0, 0.0, 1.0)
    if wp.length_sq(to_eye) > 0.0:
        w = wp.normalize(to_eye)
    s = wp.vec3(0.0)
    total = float(0.0)
    for d in range(D):
        f = phase_eval(pf.phase, pf.table, wp.dot(dirs[d], w))
        total += f
        s += f * wp.vec3(float(I[3 * p, d]), float(I[3 * p + 1, d]), float(I[3 * p + 2, d]))
    norm = 4.0 * PI / float(D)
    if normalise != 0 and total > 0.0:
        norm = 1.0 / total
    s = s * (scale * norm)
    for l in range(dl.count):
        s += phase_toward(pf.phase, pf.table, dl.travel[p * dl.count + l], w) * dl.direct[p * dl.count + l]
    out[p] = wp.cw_mul(P.albedo[p], s)


@wp.kernel
def composite(offset: int, cam: RasterView, P: Particles, radiance: wp.array(dtype=wp.vec3), tl: TileLists,
              background: wp.vec3, image: wp.array(dtype=wp.vec3)):
    """Front to back over the pixel's tile: each sphere adds T (1 - e^-sigma chord) L_p."""
    tid = wp.tid() + offset
    o, d = pixel_ray(cam, tid)
    tile = pixel_tile(cam, tid, tl.tiles_x)
    L = wp.vec3(0.0)
    T = wp.vec3(1.0)
    for k in range(tl.first[tile], tl.last[tile]):
        p = tl.values[k]
        c = sphere_chord(o, d, 0.0, 1.0e30, P.centres[p], P.radius[p])
        if c > 0.0:
            t = transmittance_rgb(P.sigma_t[p] * c)
            L += wp.cw_mul(wp.cw_mul(T, wp.vec3(1.0) - t), radiance[p])
            T = wp.cw_mul(T, t)
            if wp.max(T[0], wp.max(T[1], T[2])) < 1.0e-5:  # what lies behind adds < 1e-5 of it
                break
    image[tid] = L + wp.cw_mul(T, background)


@wp.kernel
def composite_march(offset: int, cam: RasterView, P: Particles, radiance: wp.array(dtype=wp.vec3), tl: TileLists,
                    steps: int, background: wp.vec3, image: wp.array(dtype=wp.vec3)):
    """Overlapping spheres integrated together: ``steps`` steps over the span of the spheres
    the pixel ray meets, each with the summed sigma_t and source sum sigma_k L_k / sigma of the
    spheres containing its midpoint, integrated exactly over the step. Unlike the sorted
    splat, light from where spheres interleave is attenuated only by what lies in front."""
    tid = wp.tid() + offset
    o, d = pixel_ray(cam, tid)
    tile = pixel_tile(cam, tid, tl.tiles_x)
    t0 = float(1.0e30)
    t1 = float(0.0)
    for k in range(tl.first[tile], tl.last[tile]):
        p = tl.values[k]
        a, b = ray_sphere(o, d, P.centres[p], P.radius[p])
        if a < b and b > 0.0:
            t0 = wp.min(t0, wp.max(a, 0.0))
            t1 = wp.max(t1, b)
    L = wp.vec3(0.0)
    T = wp.vec3(1.0)
    if t1 > t0:
        dt = (t1 - t0) / float(steps)
        for q in range(steps):
            x = o + (t0 + (float(q) + 0.5) * dt) * d
            sig = wp.vec3(0.0)
            src = wp.vec3(0.0)
            for k in range(tl.first[tile], tl.last[tile]):
                p = tl.values[k]
                e = x - P.centres[p]
                if wp.dot(e, e) <= P.radius[p] * P.radius[p]:
                    sig += P.sigma_t[p]
                    src += wp.cw_mul(P.sigma_t[p], radiance[p])
            if sig[0] > 0.0 or sig[1] > 0.0 or sig[2] > 0.0:
                f = step_integral_rgb(sig, dt)  # integral of e^(-sig t) over the step
                L += wp.cw_mul(T, wp.cw_mul(src, f))
                T = wp.cw_mul(T, transmittance_rgb(sig * dt))
                if wp.max(T[0], wp.max(T[1], T[2])) < 1.0e-5:
                    break
    image[tid] = L + wp.cw_mul(T, background)


# Concrete float32 and float16 overloads of the generic kernels, declared before the module
# first loads, so it compiles once with all of them (not once more per new overload).
for _t in (wp.float32, wp.float16):
    _a = wp.array2d(dtype=_t)
    wp.overload(emission_network, {"E": _a})
    wp.overload(scatter_matmul, {"I": _a, "E": _a})
    wp.overload(gather_update, {"out": _a})
    wp.overload(change_norms, {"I_new": _a, "I_old": _a})
    wp.overload(rescale, {"I": _a})
    wp.overload(outgoing_radiance, {"I": _a})


def window_rule(directions: int, radius: float, tau: float) -> int:
    """The paper's largest window: M^2 <= D (R tau)^2 / pi, at least 1."""
    return max(1, int(np.floor(np.sqrt(directions * (radius * tau) ** 2 / np.pi))))


def column_counts(pos: np.ndarray, centre, R: float, M: int, dirs: np.ndarray) -> float:
    """Particles per occupied pixel column of an M x M window over the ball (centre, R),
    averaged over the directions ``dirs``: N over the columns the particles fall in."""
    x = np.asarray(pos, np.float64) - np.asarray(centre, np.float64)
    means = []
    for w in np.asarray(dirs, np.float64):
        # the window's axes as project_particles takes them (physics.sampling.orthonormal_basis)
        sign = 1.0 if w[2] >= 0.0 else -1.0
        a = -1.0 / (sign + w[2])
        b = w[0] * w[1] * a
        e1 = np.array([1.0 + sign * w[0] * w[0] * a, sign * b, -sign * w[0]])
        e2 = np.array([b, sign + w[1] * w[1] * a, -w[1]])
        u = np.clip(np.floor((x @ e1 + R) * M / (2.0 * R)), 0, M - 1).astype(np.int64)
        v = np.clip(np.floor((x @ e2 + R) * M / (2.0 * R)), 0, M - 1).astype(np.int64)
        means.append(len(x) / len(np.unique(v * M + u)))
    return float(np.mean(means))


def column_window(pos: np.ndarray, centre, R: float, per_column: float, dirs: np.ndarray, largest: int) -> int:
    """The largest window M (1 .. ``largest``) whose occupied columns hold at least
    ``per_column`` particles on average along ``dirs`` (``column_counts``): links then join
    chains of about that many particles instead of mostly seeing past the cloud. The count
    falls as M grows (finer columns), so M is found by bisection."""
    if len(pos) < per_column:  # one column holds them all: M = 1 is as coarse as a window gets
        return 1
    lo, hi = 1, max(int(largest), 1)  # column_counts(lo) >= per_column holds throughout
    if column_counts(pos, centre, R, hi, dirs) >= per_column:
        return hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if column_counts(pos, centre, R, mid, dirs) >= per_column:
            lo = mid
        else:
            hi = mid
    return lo


def doubly_stochastic(P: np.ndarray, tol: float = 1e-9, max_iter: int = 10000) -> np.ndarray:
    """diag(x) P diag(x) for a symmetric non-negative P (float64): every row and column sums
    to 1. Symmetric Sinkhorn-Knopp, x <- x / sqrt(row sums), from x = 1 / sqrt(P 1), to a
    largest row-sum error of ``tol`` (or ``max_iter`` steps: a matrix without total support
    may not converge). The result is then divided by its largest row or column sum, so the
    sums are <= 1 whatever happened (the iteration's gain bound), and symmetrised."""
    P = np.asarray(P, np.float64)
    sums = P.sum(1)
    x = 1.0 / np.sqrt(np.where(sums > 0, sums, 1.0))
    for _ in range(max_iter):
        r = x * (P @ x)
        if np.abs(r[sums > 0] - 1.0).max(initial=0.0) < tol:
            break
        x = x / np.sqrt(np.where(r > 0, r, 1.0))
    B = x[:, None] * P * x[None, :]
    B = 0.5 * (B + B.T)
    top = max(B.sum(0).max(initial=0.0), B.sum(1).max(initial=0.0))
    return B / top if top > 0 else B


def _pad(n: int, k: int) -> int:
    return -(-n // k) * k


class IlluminationNetwork(Technique):
    """Visibility network, emission, iteration and splatting (see the module docstring)."""

    NAME = NAME
    SETTINGS = SETTINGS
    # directions: the converged answer's quadrature, order 1 (measured); each level averages two turned sets
    QUALITY = Quality(knob="directions", start=32, top=2048, order=1, biases=(Bias("light_pass", exact=0),
                                                          Bias("light_samples", factor=4, order=1)))
    QUALITY_SEED = "direction_seed"
    # the window is the model's, not a discretisation with a limit: as M grows a window column
    # holds fewer particles, the links fall away and multiple scattering with them (the image mean
    # falls as M grows: results/illumination-network-convergence). By the paper's rule it grows
    # with D and moves the answer; held at the default D's, the answer settles (order 1 in D)
    QUALITY_HOLD = {"window_at": SETTINGS["directions"].default}
    LEAVES_OUT = ()
    GATHERS_SKY = True

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        check_particle_scene(NAME, scene)
        if scene.surfaces:
            raise SettingsError(f"{NAME}: renders particle clouds under lights and sky; scene {scene.name!r} has "
                                f"{len(scene.surfaces)} surfaces (allowed: none)")
        self.uploads = SceneUploads(self, medium=False)
        # network stage: the cloud, its layout and the visibility network
        self._layout: tuple | None = None  # (N, D, direction_seed, window, half, phase_norm) the network was built for
        self._n = 0  # particles N
        self.D = self.Dp = self.rows = 0  # directions, padded to 16; rows of I (3N padded to ROWS)
        self._particles: ParticleBuffers | None = None
        self.particles: Particles | None = None
        self.centre: np.ndarray | None = None  # the cloud's bounding ball (centre, R)
        self.R = 1.0
        self.M = 0  # window resolution
        self._next_direction = 0  # refresh: the next direction to re-peel
        self.dirs = self.V = self.alpha = self.tau = None
        self.phase: PhaseParams | None = None
        self.table = self.P = None
        self.p_max = 0.0
        # direct and emission stages
        self.direct = self.travel = self.light_weight = None
        self.light_pass: LightPass | None = None  # its map, measured error and fallback
        self._light_args = None
        # iterate stage
        self.I = self.I_next = self.E = self.S = None
        self.scale = 1.0
        self.change = float("inf")  # relative L2 change of the last iteration
        self.history: list[float] = []  # change per iteration since the last restart
        self.converged = False
        # splat stage
        self.radiance = self.image = None

    # --- stages -------------------------------------------------------------------------

    def stages(self):
        return self.uploads.stages() + [
            Stage("network", self._network, reads=("medium",),
                  settings=("directions", "direction_seed", "window", "column", "window_at", "half", "phase_norm",
                            "refresh")),
            Stage("direct", self._direct, reads=("lights",),
                  settings=("light_samples", "light_pass", "light_slices", "light_terms", "light_texels",
                            "light_tolerance"), after=("network", "lights")),
            Stage("emission", self._emission, after=("network", "direct"), settings=("half", "phase_norm", "warm")),
            Stage("iterate", self._iterate, reads=("background",), settings=("iterations", "tolerance", "warm"),
                  after=("network", "emission"), settled=self.converged),
            Stage("splat", self._splat, reads=("camera", "background"), settings=("splat_steps", "phase_norm"),
                  after=("iterate", "direct")),
        ]

    def _network(self):
        """Particles to the device, per-particle extinction, phase matrix, and V with alpha:
        every direction, or with ``refresh = k`` and an unchanged layout the next k."""
        s, device = self.settings, self.device
        self._particles = cloud = particle_buffers(self.scene.media, device)
        pos, radius, sigma = cloud.centres, cloud.radius, cloud.sigma_t
        n = len(pos)
        D = s["directions"]
        layout = (n, D, s["direction_seed"], s["window"], s["column"], s["window_at"], s["half"], s["phase_norm"])
        partial = bool(s["refresh"]) and self._layout == layout
        self._layout = layout
        self._n = n
        self.D, self.Dp = D, _pad(D, 16)
        self.rows = _pad(3 * max(n, 1), ROWS)
        self.particles = P = self._particles.struct
        self.centre, self.R = self._particles.centre, self._particles.R
        if partial:  # the paper's future work: re-peel k directions a frame, round robin
            which = (self._next_direction + np.arange(min(s["refresh"], D))) % D
            self._next_direction = int((which[-1] + 1) % D)
        else:
            # mean extinction of the bounding ball: total sigma_t volume / ball volume
            tau_mean = float((sigma.mean(1) * radius**3).sum()) / self.R**3 if n else 0.0
            dirs = fibonacci_directions(D, s["direction_seed"])
            self.M = s["window"] or window_rule(s["window_at"] or D, self.R, tau_mean)
            if not s["window"] and s["column"] > 0:  # no finer than the paper's rule, and chains of `column`
                self.M = column_window(pos, self.centre, self.R, s["column"], dirs[:: max(D // 3, 1)][:3], self.M)
            self.dirs = wp.array(dirs, dtype=wp.vec3, device=device)
            self.V = wp.full(n * D, -1, dtype=int, device=device)
            self.alpha = wp.zeros(n * D, dtype=wp.vec3, device=device)
            which = np.arange(D)
            self._next_direction = 0
        self.tau = wp.zeros(n, dtype=wp.vec3, device=device)
        if n:
            dev.launch(particle_extinction, n, [P, self.tau], device)
            k = len(which)
            which = wp.array(which.astype(np.int32), dtype=int, device=device)
            if partial:
                dev.launch(clear_directions, n * k, [which, D, self.V, self.alpha], device)
            keys = wp.empty(2 * n * k, dtype=wp.int64, device=device)
            values = wp.empty(2 * n * k, dtype=int, device=device)
            dev.launch(project_particles, n * k, [P.centres, self.dirs, which, wp.vec3(*self.centre), self.R, self.M,
                                                  keys, values], device)
            wp.utils.radix_sort_pairs(keys, values, n * k)
            dev.launch(link_network, n * k, [keys, values, P.centres, self.dirs, self.tau, self.M, self.V, self.alpha],
                       device)
        if partial:
            self.converged = False
            return
        self._phase_matrix()
        dtype = wp.float16 if s["half"] else wp.float32
        if self.I is None or self.I.shape != (self.rows, self.Dp) or self.I.dtype != dtype:
            self.I = wp.zeros((self.rows, self.Dp), dtype=dtype, device=device)
            self.I_next = wp.zeros_like(self.I)
            self.E = wp.zeros_like(self.I)
            self.S = wp.zeros((self.rows, self.Dp), dtype=float, device=device)  # I P, always float32
            self.history = []
        self.converged = False

    def _phase_matrix(self):
        """P[d, i] = weight p(w_d . w_i), blocked 16 columns to a vector (padding zero):
        the paper's weight 4 pi / D, or (``phase_norm``) the doubly stochastic scaling."""
        medium = self.scene.media[0]
        self.phase, table = phase_struct(medium.phase)
        self.table = wp.array(table if len(table) else np.zeros(1, np.float32), dtype=float, device=self.device)
        D, Dp = self.D, self.Dp
        flat = wp.empty(Dp * Dp, dtype=float, device=self.device)
        dev.launch(phase_matrix, Dp * Dp, [self.dirs, self.phase, self.table, Dp, flat], self.device)
        P = flat.numpy().reshape(Dp, Dp).astype(np.float64)
        self.p_max = float(P.max())
        if self.settings["phase_norm"]:
            P[:D, :D] = doubly_stochastic(P[:D, :D])
        else:
            P *= 4.0 * np.pi / D
        self.P = wp.array(P.astype(np.float32).reshape(Dp, Dp // 16, 16), dtype=vec16, device=self.device)

    def _direct(self):
        """Each particle's light through the shared light pass (media/lightpass.py): a map per
        light, O(N x footprint), read at ``light_samples`` points of each sphere. Without lights
        (or particles) the direct light is one zero, which the emission reads as none."""
        s = self.settings
        n, L = self._n, len(self.scene.lights)
        self.direct = wp.zeros(max(n * L, 1), dtype=wp.vec3, device=self.device)
        self.travel = wp.zeros(max(n * L, 1), dtype=wp.vec3, device=self.device)
        if not (n and L):
            return
        args = (REPRESENTATIONS[s["light_pass"]], s["light_slices"], s["light_terms"], s["light_texels"],
                s["light_tolerance"])
        if self.light_pass is None or self._light_args != args:  # kept, so a moved light starts where it ended
            self.light_pass = LightPass(self.device, args[0], slices=args[1], terms=args[2], texels=args[3],
                                        tolerance=args[4], check_particles=64)
            self._light_args = args
        self.light_pass.build(self._particles, self.uploads.lights, s["light_samples"])
        self.light_pass.direct(self._particles, self.uploads.lights, s["light_samples"], self.direct, self.travel)

    def _emission(self):
        n, D, L = self._n, self.D, len(self.scene.lights)
        # one scale for E, I and the sky: the largest source at most 1 in float16
        big = max(self._emission_bound(), float(np.max(self.scene.background)), 0.0)
        scale = float(2.0 ** np.ceil(np.log2(big))) if self.settings["half"] and big > 0 else 1.0
        if scale != self.scale:
            dev.launch(rescale, self.rows * self.Dp, [self.I, self.scale / scale], self.device)
            self.scale = scale
        self.E.zero_()
        if n:
            self.light_weight = wp.empty(max(n * L, 1), dtype=float, device=self.device)
            if L:
                w_args = [self.dirs, self.travel, self.phase, self.table, self.settings["phase_norm"],
                          self.uploads.lights]
                dev.launch(light_weights, L, [*w_args, 0, self.light_weight], self.device)
                dev.launch(light_weights, n * L, [*w_args, 1, self.light_weight], self.device, min_split=256)
            dev.launch(emission_network, n * D, [self.dirs, self._direct_light(), self.particles.albedo, self.alpha,
                                                 self.phase, self.table, 1.0 / self.scale, self.E], self.device)
        if not self.settings["warm"]:
            self.I.zero_()
            self.history = []
        self.converged = False

    def _direct_light(self) -> DirectLight:
        dl = DirectLight()
        dl.direct, dl.travel, dl.weight = self.direct, self.travel, self.light_weight
        dl.count = len(self.scene.lights)
        return dl

    def _emission_bound(self) -> float:
        """An upper bound of E: lights x the largest direct irradiance x the largest weighted
        phase value (alpha and the albedo are at most 1); normalised, c_l p <= D / (4 pi)
        (one term of a sum that is D / (4 pi))."""
        if not self.scene.lights or not self._n:
            return 0.0
        w = self.D / (4.0 * np.pi) if self.settings["phase_norm"] else max(self.p_max, float(INV_4PI))
        return len(self.scene.lights) * float(self.direct.numpy().max()) * w

    def _iterate(self):
        """The frame's iterations; a one-shot render (``warpvol.render``) iterates until an
        iteration changes I by under ``tolerance``, at most ``ONE_SHOT_CAP`` times (a warning if
        it stops there)."""
        s = self.settings
        count = s["iterations"]
        if self.one_shot and s["tolerance"] > 0.0:
            count = max(count, ONE_SHOT_CAP)
        for _ in range(count):
            self.step()
            if s["tolerance"] > 0.0 and self.change < s["tolerance"]:
                self.converged = True
                break
        if self.one_shot and s["tolerance"] > 0.0 and not self.converged and self._n:
            warnings.warn(f"{NAME}: not converged after {count} iterations (last change {self.change:.3g}, "
                          f"tolerance {s['tolerance']:.3g}): the image is unfinished", RuntimeWarning, stacklevel=2)

    def step(self, measure: bool | None = None) -> float:
        """One iteration of the network; returns (and, with a tolerance, measures) the
        relative L2 change, else NaN."""
        n, D, device = self._n, self.D, self.device
        if n:
            S = self.S
            dev.launch(scatter_matmul, self.rows // ROWS * (self.Dp // 16),
                       [self.I, self.P, self.E, self.alpha, self.particles.albedo, n, D, S], device, min_split=64)
            sky = wp.vec3(*(np.asarray(self.scene.background, np.float64) / self.scale))
            dev.launch(gather_update, n * (-(-D // 16)), [self.V, S, sky, D, self.I_next], device)
        if measure is None:
            measure = self.settings["tolerance"] > 0.0
        change = float("nan")
        if measure:
            norms = wp.zeros(2, dtype=float, device=device)
            dev.launch(change_norms, 3 * n * self.Dp, [self.I_next, self.I, D, norms], device, split=False)
            a, b = norms.numpy()
            change = float(np.sqrt(a / b)) if b > 0 else 0.0
        self.I, self.I_next = self.I_next, self.I
        self.change = change
        self.history.append(change)
        return change

    def _splat(self):
        cam, device, n = self.scene.camera, self.device, self._n
        W, H = cam.width, cam.height
        self.image = wp.empty(W * H, dtype=wp.vec3, device=device)
        pc = camera_view(pinhole(cam))
        P = self.particles
        self.radiance = wp.zeros(max(n, 1), dtype=wp.vec3, device=device)
        if n:
            dev.launch(outgoing_radiance, n, [P, pc.origin, self.dirs, self.I, self._direct_light(),
                                              phase_fn(self.phase, self.table), self.settings["phase_norm"],
                                              self.scale, self.radiance],
                       device, min_split=512)
            z_far = float(np.linalg.norm(self.centre - np.asarray(cam.origin)) + self.R)
            tl = bin_spheres(pc, P.centres, P.radius, z_far, device)
        else:
            tl = bin_spheres(pc, wp.empty(0, dtype=wp.vec3, device=device), wp.empty(0, dtype=float, device=device),
                             1.0, device)
        bg = wp.vec3(*self.scene.background)
        if self.settings["splat_steps"]:
            dev.launch(composite_march, W * H, [pc, P, self.radiance, tl, self.settings["splat_steps"], bg, self.image],
                       device, work=self.settings["splat_steps"])
        else:
            dev.launch(composite, W * H, [pc, P, self.radiance, tl, bg, self.image], device)

    def output(self):
        return self.image

    # --- looking inside -------------------------------------------------------------------

    def radiance_network(self) -> np.ndarray:
        """I as (N, D, 3) float32 in scene units: incoming radiance at p travelling along w_i."""
        n, D = self._n, self.D
        I = self.I.numpy()[: 3 * n, :D].astype(np.float32) * self.scale
        return np.moveaxis(I.reshape(n, 3, D), 1, -1)

    def set_radiance_network(self, radiance: np.ndarray) -> None:
        """Load I from (N, D, 3) radiance in scene units: ``radiance_network``'s inverse."""
        n, D = self._n, self.D
        host = np.zeros(self.I.shape, np.float32)
        host[: 3 * n, :D] = np.moveaxis(np.asarray(radiance, np.float32), -1, 1).reshape(3 * n, D) / self.scale
        self.I.assign(host)

    def diagnostics(self) -> dict:
        """``window``: the window resolution M used; ``iterations``: iterations the last frames
        took (the convergence history's length); ``direct``: the direct light per particle
        (N x lights x 3); ``light_texels``: the light pass's texels per face side; ``light_refined``: how often its
        map was refined to meet ``light_tolerance``; ``light_error``: its last map's measured
        error (None: not checked); ``light_fell_back``: whether it fell back to exact transmittance."""
        return {"window": self.M, "iterations": len(self.history), "direct": self.direct.numpy(),
                "light_texels": self.light_pass.M if self.light_pass is not None else 0,
                "light_refined": len(self.light_pass.refined) if self.light_pass is not None else 0,
                "light_error": self.light_pass.error if self.light_pass is not None else None,
                "light_fell_back": bool(self.light_pass is not None and self.light_pass.fell_back)}

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """``positions`` (N, 3), ``directions`` (D, 3), ``visibility`` (N, D) int (-1: sky),
        ``alpha`` (N, D, 3) (vp's segment opacity), ``radiance`` (N, D, 3) (the network I),
        ``outgoing`` (N, 3) (toward the camera of the last frame), ``window`` M, ``bounds``
        (centre, R); ``for_view`` adds ``view_direction``, the sample direction nearest the
        first light's travel direction (the one whose edges a view draws); ``resolution`` is
        unused (every array is the network's own size)."""
        n, D = self._n, self.D
        extra = {}
        if for_view:
            dirs = self.dirs.numpy()
            travel = self.travel.numpy()[0] if self.scene.lights and n else np.array([0.0, -1.0, 0.0])
            extra["view_direction"] = int(np.argmax(dirs @ travel)) if np.any(travel) else 0
        return {**extra,
            "positions": self.particles.centres.numpy(), "directions": self.dirs.numpy(),
            "visibility": self.V.numpy().reshape(n, D), "alpha": self.alpha.numpy().reshape(n, D, 3),
            "radiance": self.radiance_network(),
            "outgoing": self.radiance.numpy()[:n] if self.radiance is not None else None,
            "window": self.M, "bounds": (tuple(self.centre), self.R), "radius": self.particles.radius.numpy(),
        }


TECHNIQUE = IlluminationNetwork
