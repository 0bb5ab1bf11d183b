"""The illumination network's Warp code, one kernel module (one compile): building the network
(``particle_extinction``, ``project_particles``, ``clear_directions``, ``link_network``), the
emission (``light_weights``, ``emission_network``), the phase matrix (``phase_matrix``), the
iteration (``scatter_matmul``, ``gather_update``, ``change_norms``, ``rescale``) and the splat
(``outgoing_radiance``, ``composite``, ``composite_march``), with the float32 and float16
overloads of the generic ones."""

from __future__ import annotations

from typing import Any

import warp as wp

from ... import device as dev
from ...geometry.camera import RasterView, pixel_ray
from ...geometry.intersect import ray_sphere, sphere_chord
from ...geometry.tiles import TileLists, pixel_tile
from ...media.particles import Particles, particle_sigma_t
from ...physics.constants import PI
from ...physics.lights import DIRECTIONAL, Emitter
from ...physics.phase import PhaseParams, PhaseFn, phase_eval, phase_toward
from ...physics.sampling import orthonormal_basis
from ...physics.transmittance import step_integral_rgb, transmittance_rgb

dev.kernel_module(__name__)

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
def scatter_matmul(offset: int, I: wp.array2d(dtype=Any), W: wp.array2d(dtype=vec16), E: wp.array2d(dtype=Any),
                   alpha: wp.array(dtype=wp.vec3), albedo: wp.array(dtype=wp.vec3), n: int, D: int,
                   Q: wp.array2d(dtype=float)):
    """S = I W (W the phase weights, 16 columns to a vector), thread (row block, column block)
    accumulating 4 rows x 16 columns, and in the same pass what particle vp sends on along each
    direction i (row 3 vp + c): Q = (1 - alpha) I + E + alpha a S. The update is then a gather
    of Q alone."""
    tid = wp.tid() + offset
    nb = W.shape[1]
    r = (tid / nb) * 4
    b = tid % nb
    a0 = vec16()
    a1 = vec16()
    a2 = vec16()
    a3 = vec16()
    for d in range(W.shape[0]):
        pd = W[d, b]
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
