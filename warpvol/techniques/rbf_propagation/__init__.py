"""RBF propagation: extinction volume, opacity propagation, ray march.

Giroud & Biri, "Illuminating and Rendering Heterogeneous Participating Media in Real Time
Using Opacity Propagation", GRAPP 2011 (it builds on Kaplanyan 2009's light
propagation volumes, 800x600 on a GTX 280): an RBF medium injected into an extinction
volume (EV), optical depth propagated from each light through it into an opacity
propagation volume (OPV) by a 6-neighbour gathering wavefront (equations 6-7), and a
fixed-step ray march that reads both (equations 5, 9-10; equation 8's per-step blend
L = (1 - K_t) L + K_t L_in is replaced by the step's exact integral). Stages:

* ``inject`` (reads the medium): sigma_t at the centres of an n^3 grid over a box that
  holds the media (see ``volume_bounds``: the surfaces' box when it is a room around them,
  as the paper's Cornell box, else the media's own bounds; no axis degenerate). Each RBF adds itself to the cells within its
  cut-off radius only (one thread per RBF, atomic adds), so the cost grows with the number
  of RBFs times the cells one covers, never RBFs x cells. The cut-off is the reference's,
  ``CUTOFF`` = 5 sigma: beyond it a Gaussian has fallen to exp(-12.5) = 3.7e-6 of its
  peak, so injection adds no error beyond sampling at cell centres. Other media kinds are
  sampled at the cell centres.
* ``propagate`` (reads the lights): per light, every cell gathers optical depth from its
  six neighbours, weighted by W_i = max(<SX, d_i>, 0) (equation 7; its factor (1 - Kt(X))
  is common to the six weights and cancels in the normalised mean). Two rules:

  - ``rule = 0``, the paper's equation 6 as printed: T(X) = K(X) + sum W_i T_i / sum W_i,
    with K = sigma_t. It adds an extinction coefficient per cell, not an optical depth:
    T is off by the factor 1/(path length per cell) and is not in physical units.
  - ``rule = 1``, corrected: the upwind discretisation of <w, grad T> = sigma_t,
    T(X) = (sum (W_i / h_i) T_i + sigma_t(X)) / sum (W_i / h_i), which is optical depth:
    on a ray along an axis it adds sigma_t h per cell, on a diagonal sigma_t h / |w|_1.

  The cell holding a point light starts at K(X) (paper) or sigma_t |X - S| (corrected);
  outside the grid T = 0, which the corrected rule places on the grid's face, half a cell
  from the first centre, so a beam along an axis through a homogeneous grid gets exactly
  sigma_t times the distance. ``wavefront = 0`` sweeps the whole grid ``iterations`` times
  (Jacobi, as the paper's fragment shader; 0 = 3n sweeps, enough for the wave to cross
  the grid); ``wavefront = 1`` (the paper's future work) updates only the shell of cells
  at Manhattan distance k from the light at step k, in place, so each cell is computed
  once: a launch covers the shell only (2 n^2 threads per light, each taking a pair of
  indices on two axes and solving the third: O(n^3) in all, not O(n^4)). Only the
  shells that hold a grid cell are launched, from each light's nearest to its farthest
  cell: at most 3(n - 1) + 1 launches wherever the light is (a light outside the grid
  counts from its cell clamped to one cell outside the grid, which shifts every cell's
  distance by the same amount, so the order of the shells is unchanged).
* ``march`` (reads the camera): from the camera to the nearest surface in fixed steps of
  the grid's diagonal / ``steps``: sigma_t from the EV, optical depth to each light from the
  OPV (both trilinear), inverse-square falloff and the phase function, integrated exactly
  over each step (beyond the paper: a step that subtends more than 0.1 rad at a point or spot
  light is split into equal angles seen from the light, each with its share of the step's
  1/d^2, ``physics.lights.angle_point``: at the default step the pixel nearest the light was
  under half its value, results/multiple-scattering's fog-box rows). Equation 8 blends each
  step as L = (1 - K_t) L + K_t L_in; the march instead adds T_cam sigma_s p L_in (1 -
  exp(-sigma_t dt)) / sigma_t and scales T_cam by exp(-sigma_t dt), the exact integral over a
  step of constant coefficients, so the image does not depend on the step; surfaces shaded with Phong (Lambert + normalised Phong) and attenuated by
  both optical depths (equation 10). Surfaces do not occlude lights (as in the paper). A
  surface point outside the volume reads the OPV where its path to the light enters the
  volume (no medium lies outside it), or nothing when that path misses the volume.

The EV and OPV store RGB (an RGB sigma_t propagates per channel), one OPV entry per light
and cell. A cell's lights lie side by side, as the paper packs four lights in the RGBA of one
texel: the march finds a sample's trilinear corners and weights once (``cell_corners``) and
reads the EV and every light's optical depth there (``cell_blend``), so a light adds its
eight neighbouring reads, its falloff and its phase function to a step, not a lookup of
its own. The first medium's albedo and phase function serve the whole volume.

Leaves out (``frame.leaves_out``): the sky's light (the background) scattered once in the
medium or reflected by surfaces, and, with ``multiple_scattering`` = 0, multiple scattering.

With ``multiple_scattering`` = n > 0 (the default) the light scattered more than once is
added too: solved on an n^3 lattice of ``ms_directions`` directions (``warpvol.scattering``,
stages ``multiple`` and ``multiple_view``) and read at every step of the march as sigma_s R(x); 0 is the paper's
model.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import warp as wp

from ... import device as dev
from ...geometry.camera import RasterView, camera_view, pixel_ray
from ...geometry.intersect import inside_box, ray_box
from ...geometry.mesh import Surfaces, surface_hit
from ...media.grid import grid_corners, trilinear_blend
from ...media.rbf import CUTOFF
from ...media.volume import sample_extinction
from ...physics.constants import INF
from ...physics.lights import DIRECTIONAL, Emitter, angle_point, angle_samples, angle_share, light_incident, step_angle
from ...physics.phase import phase_eval
from ...physics.transmittance import step_integral_rgb, transmittance_rgb
from ...pipeline import FLAG, Quality, Setting, Stage, Technique
from ...scattering import BIASES as MS_BIASES
from ...scattering import SETTINGS as MS_SETTINGS
from ...scattering import MultipleScattering, ScatteredLight, scattered_light, scattered_on_surface
from ...scattering import check_settings as check_ms_settings
from ...scattering import leaves_out as ms_leaves_out
from ...scene.model import MediumKind
from ...shading import reflected
from ...upload import MediaBuffers, SceneUploads, pinhole
from .volumes import Volume, Volumes, grid_volume, march_inputs
from .wavefront import shell_plan, solve_axes

dev.kernel_module(__name__)

NAME = "rbf_propagation"
SETTINGS = {
    "grid": Setting(20, 1, 512, "cells per axis of the extinction and opacity volumes"),
    "steps": Setting(64, 1, 1 << 16, "ray-march steps across the grid's diagonal"),
    "rule": Setting(1, 0, 1, "0: the paper's equation 6 as printed; 1: corrected, optical depth in physical units",
                    names=("printed", "corrected")),
    "wavefront": Setting(1, 0, 1, "1: update only the wavefront shell per step; 0: sweep the whole grid", names=FLAG),
    "iterations": Setting(0, 0, 1 << 16, "whole-grid sweeps when wavefront = 0 (0: 3 x grid)"),
    **MS_SETTINGS,
}


@wp.func
def cell_centre(v: Volume, i: int, j: int, k: int) -> wp.vec3:
    return v.lo + wp.cw_mul(v.h, wp.vec3(float(i) + 0.5, float(j) + 0.5, float(k) + 0.5))


@wp.func
def cell_index(v: Volume, i: int, j: int, k: int) -> int:
    return (k * v.n[1] + j) * v.n[0] + i


@wp.func
def cell_corners(v: Volume, x: wp.vec3):
    """Where a trilinear lookup at x reads, found once for the EV and every light's OPV (they
    share the grid): (the lower corner's cell, the cell steps to the upper corner along x, y
    and z, the upper corner's weights, whether x is in the grid)."""
    a, b, t = grid_corners(v.n, v.lo, v.hi, x)
    step = wp.vec3i(b[0] - a[0], (b[1] - a[1]) * v.n[0], (b[2] - a[2]) * v.n[0] * v.n[1])
    return cell_index(v, a[0], a[1], a[2]), step, t, inside_box(x, v.lo, v.hi)


@wp.func
def cell_blend(values: wp.array(dtype=wp.vec3), stride: int, k: int, first: int, step: wp.vec3i,
               t: wp.vec3) -> wp.vec3:
    """The trilinear blend at the corners ``cell_corners`` found, of entry k of ``stride`` per
    cell: the EV is one entry per cell; the OPV holds a cell's lights side by side (entry l of
    ``lights``), as the paper packs four lights in a texel's RGBA, so one sample's lights
    read neighbouring memory."""
    c0 = first * stride + k
    dx = step[0] * stride
    dy = step[1] * stride
    dz = step[2] * stride
    return trilinear_blend(values[c0], values[c0 + dx], values[c0 + dy], values[c0 + dx + dy], values[c0 + dz],
                           values[c0 + dx + dz], values[c0 + dy + dz], values[c0 + dx + dy + dz], t)


@wp.func
def volume_lookup(values: wp.array(dtype=wp.vec3), stride: int, k: int, v: Volume, x: wp.vec3) -> wp.vec3:
    """Entry k of ``stride`` per cell (the EV: 1 and 0; the OPV: the lights and the light),
    trilinear between cell centres, clamped at the outer half cells; 0 outside the grid."""
    first, step, t, inside = cell_corners(v, x)
    if not inside:
        return wp.vec3(0.0)
    return cell_blend(values, stride, k, first, step, t)


@wp.kernel
def inject_rbfs(offset: int, centres: wp.array(dtype=wp.vec3), radii: wp.array(dtype=float),
                amplitudes: wp.array(dtype=float), peak: wp.vec3, v: Volume, ev: wp.array(dtype=wp.vec3)):
    """One thread per RBF: add peak a exp(-|x - c|^2 / (2 r^2)) to the cells within its cut-off."""
    tid = wp.tid() + offset
    c = centres[tid]
    radius = radii[tid]
    r_cut = CUTOFF * radius
    inv = 0.5 / (radius * radius)
    peak = peak * amplitudes[tid]
    a = wp.cw_div(c - wp.vec3(r_cut) - v.lo, v.h)
    b = wp.cw_div(c + wp.vec3(r_cut) - v.lo, v.h)
    i0 = wp.max(int(wp.floor(a[0])), 0)
    j0 = wp.max(int(wp.floor(a[1])), 0)
    k0 = wp.max(int(wp.floor(a[2])), 0)
    i1 = wp.min(int(wp.floor(b[0])), v.n[0] - 1)
    j1 = wp.min(int(wp.floor(b[1])), v.n[1] - 1)
    k1 = wp.min(int(wp.floor(b[2])), v.n[2] - 1)
    for k in range(k0, k1 + 1):
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                d = cell_centre(v, i, j, k) - c
                d2 = wp.dot(d, d)
                if d2 < r_cut * r_cut:
                    wp.atomic_add(ev, cell_index(v, i, j, k), peak * wp.exp(-d2 * inv))


@wp.func
def light_flow(light: Emitter, x: wp.vec3) -> wp.vec3:
    """Unit direction light travels at x (S -> X), zero at the light itself."""
    if light.kind == DIRECTIONAL:
        return light.direction
    d = x - light.position
    l2 = wp.dot(d, d)
    if l2 > 1.0e30:  # a light far away: |d|^2 overflows float32, so scale d down first
        d = d / wp.max(wp.abs(d[0]), wp.max(wp.abs(d[1]), wp.abs(d[2])))
        l2 = wp.dot(d, d)
    if l2 <= 0.0:
        return wp.vec3(0.0)
    return d / wp.sqrt(l2)


@wp.func
def anchor_offset(light: Emitter, g: wp.vec3i, v: Volume, i: int, j: int, k: int) -> wp.vec3i:
    """Cell offset from the light's cell ``g`` (point, spot; clamped to [-1, n] per axis, see
    ``light_cells``) or, for a directional light, from the grid's most upwind corner, in the
    light's travel sense (non-negative on used axes)."""
    if light.kind == DIRECTIONAL:
        w = light.direction
        oi = wp.where(w[0] > 0.0, i, wp.where(w[0] < 0.0, v.n[0] - 1 - i, 0))
        oj = wp.where(w[1] > 0.0, j, wp.where(w[1] < 0.0, v.n[1] - 1 - j, 0))
        ok = wp.where(w[2] > 0.0, k, wp.where(w[2] < 0.0, v.n[2] - 1 - k, 0))
        return wp.vec3i(oi, oj, ok)
    return wp.vec3i(wp.abs(i - g[0]), wp.abs(j - g[1]), wp.abs(k - g[2]))


@wp.func
def axis_offset(light: Emitter, g: wp.vec3i, v: Volume, axis: int, i: int) -> int:
    """``anchor_offset`` along one axis, for index ``i`` on it."""
    if light.kind == DIRECTIONAL:
        w = light.direction[axis]
        return wp.where(w > 0.0, i, wp.where(w < 0.0, v.n[axis] - 1 - i, 0))
    return wp.abs(i - g[axis])


@wp.func
def update_cell(l: int, cell: wp.vec3i, a: wp.vec3i, wave: int, ev: wp.array(dtype=wp.vec3), v: Volume,
                light: Emitter, rule: int, tau_in: wp.array(dtype=wp.vec3), tau_out: wp.array(dtype=wp.vec3)):
    """One propagation step of light ``l`` at ``cell`` (i, j, k), ``a`` its offset from the light
    (``anchor_offset``): equation 6 (rule 0) or its corrected form, read from ``tau_in``."""
    i = cell[0]
    j = cell[1]
    k = cell[2]
    cells = v.n[0] * v.n[1] * v.n[2]
    c = cell_index(v, i, j, k)
    x = cell_centre(v, i, j, k)
    sig = ev[c]
    w = light_flow(light, x)
    lights = tau_out.shape[0] / cells  # the OPV: cells x lights, a cell's lights side by side
    wsum = float(0.0)
    acc = wp.vec3(0.0)
    for axis in range(3):
        comp = w[axis]
        use = comp != 0.0
        if wave != 0 and a[axis] == 0 and light.kind != DIRECTIONAL:
            use = False  # in the light's own slab that neighbour lies on the next shell, not upwind
        if use:
            step = wp.where(comp > 0.0, 1, -1)
            ni = i
            nj = j
            nk = k
            if axis == 0:
                ni = i - step
            if axis == 1:
                nj = j - step
            if axis == 2:
                nk = k - step
            weight = wp.abs(comp)
            if rule == 1:
                weight = weight / v.h[axis]
            t_n = wp.vec3(0.0)  # outside the grid: no medium, no optical depth
            if ni >= 0 and nj >= 0 and nk >= 0 and ni < v.n[0] and nj < v.n[1] and nk < v.n[2]:
                t_n = tau_in[cell_index(v, ni, nj, nk) * lights + l]
            elif rule == 1:
                weight = 2.0 * weight  # T = 0 holds on the grid's face, half a cell away
            acc += weight * t_n
            wsum += weight
    out = wp.vec3(0.0)
    own = light.kind != DIRECTIONAL and a[0] + a[1] + a[2] == 0
    if own or wsum <= 0.0:  # the light's own cell
        out = sig
        if rule == 1 and light.kind != DIRECTIONAL:
            out = sig * wp.length(x - light.position)
    elif rule == 1:
        out = (acc + sig) / wsum
    else:
        out = sig + acc / wsum
    tau_out[c * lights + l] = out


@wp.kernel
def propagate_optical_depth(offset: int, ev: wp.array(dtype=wp.vec3), v: Volume, lights: wp.array(dtype=Emitter),
                            light_cell: wp.array(dtype=wp.vec3i), rule: int, tau_in: wp.array(dtype=wp.vec3),
                            tau_out: wp.array(dtype=wp.vec3)):
    """A whole-grid Jacobi sweep: one propagation step for every (light, cell)."""
    tid = wp.tid() + offset
    cells = v.n[0] * v.n[1] * v.n[2]
    l = tid / cells
    c = tid % cells
    i = c % v.n[0]
    j = (c / v.n[0]) % v.n[1]
    k = c / (v.n[0] * v.n[1])
    a = anchor_offset(lights[l], light_cell[l], v, i, j, k)
    update_cell(l, wp.vec3i(i, j, k), a, 0, ev, v, lights[l], rule, tau_in, tau_out)


@wp.kernel
def propagate_shell(offset: int, ev: wp.array(dtype=wp.vec3), v: Volume, lights: wp.array(dtype=Emitter),
                    light_cell: wp.array(dtype=wp.vec3i), shell_base: wp.array(dtype=int),
                    solve_axis: wp.array(dtype=int), rule: int, shell: int, tau: wp.array(dtype=wp.vec3)):
    """The wavefront's step ``shell``, in place: the cells at offset ``shell_base[light] +
    shell`` from each light. A thread takes one pair of indices on the two axes other than
    ``solve_axis[light]`` and one of the (at most two) indices on that axis that put the cell
    on the shell, so a launch is 2 n^2 threads per light, not n^3."""
    tid = wp.tid() + offset
    nm = wp.max(v.n[0], wp.max(v.n[1], v.n[2]))
    per = 2 * nm * nm
    l = tid / per
    r = tid % per
    side = r % 2
    u = (r / 2) % nm
    w = (r / 2) / nm
    s = solve_axis[l]
    p = (s + 1) % 3
    q = (s + 2) % 3
    if u >= v.n[p] or w >= v.n[q]:
        return
    light = lights[l]
    g = light_cell[l]
    rest = shell_base[l] + shell - axis_offset(light, g, v, p, u) - axis_offset(light, g, v, q, w)
    if rest < 0:
        return
    x = int(0)
    if light.kind == DIRECTIONAL:  # solve_axis is one the light travels along: one index
        if side == 1:
            return
        x = wp.where(light.direction[s] > 0.0, rest, v.n[s] - 1 - rest)
    else:  # |x - g| = rest
        if side == 1 and rest == 0:
            return
        x = wp.where(side == 0, g[s] - rest, g[s] + rest)
    if x < 0 or x >= v.n[s]:
        return
    i = wp.where(s == 0, x, wp.where(p == 0, u, w))
    j = wp.where(s == 1, x, wp.where(p == 1, u, w))
    k = wp.where(s == 2, x, wp.where(p == 2, u, w))
    a = anchor_offset(light, g, v, i, j, k)
    update_cell(l, wp.vec3i(i, j, k), a, 1, ev, v, light, rule, tau, tau)


@wp.kernel
def march_exact_optical_depth(offset: int, ev: wp.array(dtype=wp.vec3), v: Volume, lights: wp.array(dtype=Emitter),
                              per_cell: int, out: wp.array(dtype=wp.vec3)):
    """Optical depth from each cell centre to each light through the EV, marched in
    ``per_cell`` midpoint steps per cell width (the yardstick for the propagation rules)."""
    tid = wp.tid() + offset
    cells = v.n[0] * v.n[1] * v.n[2]
    l = tid / cells
    c = tid % cells
    x = cell_centre(v, c % v.n[0], (c / v.n[0]) % v.n[1], c / (v.n[0] * v.n[1]))
    wi, dist, e = light_incident(lights[l], x)
    a, b = ray_box(x, wi, v.lo, v.hi)
    t1 = wp.min(b, dist)
    tau = wp.vec3(0.0)
    if t1 > 0.0:
        dt = wp.min(v.h[0], wp.min(v.h[1], v.h[2])) / float(per_cell)
        # t1 <= sqrt(3) n h on a cubic grid, so the cap binds only for flat cells, where the
        # thinnest cell would otherwise set the work (n per_cell / thinness steps)
        cap = 2 * wp.max(v.n[0], wp.max(v.n[1], v.n[2])) * per_cell
        steps = int(wp.min(wp.ceil(t1 / dt), float(cap)))
        dt = t1 / float(steps)
        for s in range(steps):
            tau += volume_lookup(ev, 1, 0, v, x + (float(s) + 0.5) * dt * wi) * dt
    out[tid] = tau


@wp.func
def surface_optical_depth(opv: wp.array(dtype=wp.vec3), lights: int, l: int, v: Volume, p: wp.vec3, wi: wp.vec3,
                          dist: float) -> wp.vec3:
    """Optical depth from a surface point p to a light (direction wi, distance dist) from the
    OPV. On the volume (within a rounding tolerance) it is read at p, clamped in; outside, no
    medium lies between p and the volume, so it is read where the segment p -> light enters
    the volume, and is 0 when the segment misses the volume. (Clamping an outside point to
    the nearest face instead would stretch the face's shadows over every surface beyond it.)"""
    pc = wp.vec3(wp.clamp(p[0], v.lo[0], v.hi[0]), wp.clamp(p[1], v.lo[1], v.hi[1]), wp.clamp(p[2], v.lo[2], v.hi[2]))
    if wp.length(p - pc) <= 1.0e-4 * wp.length(v.hi - v.lo):
        return volume_lookup(opv, lights, l, v, pc)
    a, b = ray_box(p, wi, v.lo, v.hi)
    ta = wp.max(a, 0.0)
    if ta > wp.min(b, dist):
        return wp.vec3(0.0)
    q = p + ta * wi
    q = wp.vec3(wp.clamp(q[0], v.lo[0], v.hi[0]), wp.clamp(q[1], v.lo[1], v.hi[1]), wp.clamp(q[2], v.lo[2], v.hi[2]))
    return volume_lookup(opv, lights, l, v, q)


@wp.kernel
def march_volumes(offset: int, cam: RasterView, s: Surfaces, lights: wp.array(dtype=Emitter), vols: Volumes,
                  steps: int, background: wp.vec3, ms: ScatteredLight, image: wp.array(dtype=wp.vec3)):
    tid = wp.tid() + offset
    o, d = pixel_ray(cam, tid)
    ev = vols.ev
    opv = vols.opv
    v = vols.v
    albedo = vols.albedo
    phase = vols.phase
    phase_table = vols.phase_table
    hit, t_surf, n, face = surface_hit(s, o, d, INF)
    a, b = ray_box(o, d, v.lo, v.hi)
    ta = wp.max(a, 0.0)
    tb = wp.min(b, t_surf)
    n_lights = lights.shape[0]
    L = wp.vec3(0.0)
    tr = wp.vec3(1.0)
    if ta < tb:
        dt = wp.length(v.hi - v.lo) / float(steps)  # a fixed step, as in the paper
        count = int(wp.ceil((tb - ta) / dt))
        for q in range(count):
            t0 = ta + float(q) * dt
            seg = wp.min(dt, tb - t0)
            x = o + (t0 + 0.5 * seg) * d
            first, step, t, inside = cell_corners(v, x)  # once for the EV and every light
            sig = wp.vec3(0.0)
            if inside:
                sig = cell_blend(ev, 1, 0, first, step, t)
            if sig[0] > 0.0 or sig[1] > 0.0 or sig[2] > 0.0:
                li = wp.vec3(0.0)
                for l in range(n_lights):
                    tc, h, phi = step_angle(lights[l], o, d, t0, t0 + seg)
                    na = angle_samples(phi)  # 1 but beside a point or spot light
                    if na == 1:
                        wi, dist, e = light_incident(lights[l], x)
                        tl = transmittance_rgb(cell_blend(opv, n_lights, l, first, step, t))
                        li += phase_eval(phase, phase_table, wp.dot(d, wi)) * wp.cw_mul(e, tl)
                    else:  # equal angles seen from the light, each its share of the step's 1/d^2
                        for j in range(na):
                            xj = o + angle_point(t0, tc, h, phi, j, na) * d
                            wi, dist, e = light_incident(lights[l], xj)
                            if dist > 0.0:
                                e = angle_share(lights[l], e, dist, h, phi, na, seg)
                                tl = transmittance_rgb(volume_lookup(opv, n_lights, l, v, xj))
                                li += phase_eval(phase, phase_table, wp.dot(d, wi)) * wp.cw_mul(e, tl)
                f = step_integral_rgb(sig, seg)
                sig_s = wp.cw_mul(sig, albedo)
                src = wp.cw_mul(sig_s, li) + scattered_light(ms, sig_s, x)
                L += wp.cw_mul(wp.cw_mul(tr, src), f)
                tr = wp.cw_mul(tr, transmittance_rgb(sig * seg))
    if hit:
        nf = wp.where(wp.dot(n, d) < 0.0, n, -n)
        p = o + t_surf * d
        for l in range(n_lights):  # equation 10
            wi, dist, e = light_incident(lights[l], p)
            cos_l = wp.dot(nf, wi)
            if cos_l > 0.0:
                tl = transmittance_rgb(surface_optical_depth(opv, n_lights, l, v, p, wi, dist))
                L += wp.cw_mul(tr, reflected(s.material[face], nf, -d, wi, cos_l, e, tl))
        L += wp.cw_mul(tr, scattered_on_surface(ms, s, s.material[face], p, nf, -d))
    else:
        L += wp.cw_mul(tr, background)
    image[tid] = L


class RBFPropagation(Technique):
    """Extinction volume, opacity propagation volume, ray march (see the module docstring)."""

    NAME = NAME
    EXAMPLES = ("rbf-single", "fog-box")
    TINY = {"grid": 6, "steps": 12}
    CENSUS = ("rbf-cornell", {})
    SETTINGS = SETTINGS
    QUALITY = Quality(knob="grid", start=8, top=256, order=1, tied={"steps": 4}, biases=MS_BIASES)
    LEAVES_OUT = ()

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        self.uploads = SceneUploads(self, medium=False)  # the EV replaces the media's own buffers
        self.multiple = MultipleScattering.over(self, self.uploads, media=False)
        self.ev = self.opv = self.image = None
        self.volume = None
        self.launches = 0  # propagation launches of the last propagate stage

    def check_settings(self, settings):
        check_ms_settings(NAME, settings)

    def leaves_out(self) -> list[str]:
        return [*ms_leaves_out(self.settings), *super().leaves_out()]

    def stages(self):
        return self.uploads.stages() + [
            Stage("inject", self._inject, reads=("medium", "surfaces"), settings=("grid",)),  # the density stage
            Stage("propagate", self._propagate, reads=("lights",), settings=("rule", "wavefront", "iterations", "grid"),
                  after=("inject", "lights"), needed=bool(self.scene.lights)),
            *self.multiple.stages(after=("surfaces", "lights")),
            Stage("march", self._march, reads=("camera", "background", "medium"),
                  settings=("steps", "multiple_scattering"),
                  after=("inject", "propagate", "surfaces", "lights", "multiple_view")),
        ]

    def _inject(self):
        n = self.settings["grid"]
        self.volume = v = grid_volume(self.scene, n)
        self.ev = wp.zeros(n**3, dtype=wp.vec3, device=self.device)
        others = [m for m in self.scene.media if m.type != MediumKind.RBF]
        if others:
            buffers = MediaBuffers(dataclasses.replace(self.scene, media=others), self.device)
            dev.launch(sample_extinction, n**3, [buffers.struct, v.lo, v.hi, v.n, self.ev], self.device)
        for m in self.scene.media:
            if m.type == MediumKind.RBF and len(m.centers):
                centres = wp.array(np.asarray(m.centers, np.float32), dtype=wp.vec3, device=self.device)
                # atomics: one chunk keeps the adds race-free on the CPU as on the GPU
                radii, amps = (wp.array(a, dtype=float, device=self.device) for a in m.gaussians())
                dev.launch(inject_rbfs, len(m.centers), [centres, radii, amps, wp.vec3(*m.peak), v, self.ev],
                           self.device, split=False)

    def _propagate(self):
        v, n = self.volume, self.settings["grid"]
        count = len(self.scene.lights) * n**3
        tau = wp.zeros(count, dtype=wp.vec3, device=self.device)
        lights = self.uploads.lights
        cells, base, shells = shell_plan(self.scene.lights, v, n)
        cells = wp.array(cells, dtype=wp.vec3i, device=self.device)
        base = wp.array(base, dtype=int, device=self.device)
        solve = wp.array(solve_axes(self.scene.lights), dtype=int, device=self.device)
        self.launches = 0
        if self.settings["wavefront"]:
            for shell in range(shells):
                dev.launch(propagate_shell, len(self.scene.lights) * 2 * n * n,
                           [self.ev, v, lights, cells, base, solve, self.settings["rule"], shell, tau], self.device)
                self.launches += 1
        else:
            other = wp.zeros_like(tau)
            for _ in range(self.settings["iterations"] or 3 * n):
                dev.launch(propagate_optical_depth, count, [self.ev, v, lights, cells, self.settings["rule"], tau,
                                                            other], self.device)
                self.launches += 1
                tau, other = other, tau
        self.opv = tau

    def _march(self):
        scene, u = self.scene, self.uploads
        cam = scene.camera
        npix = cam.width * cam.height
        if self.opv is None or not scene.lights:
            self.opv = wp.zeros(1, dtype=wp.vec3, device=self.device)
        self.image = wp.empty(npix, dtype=wp.vec3, device=self.device)
        vols = march_inputs(self.ev, self.opv, self.volume, scene.media[0] if scene.media else None, self.device)
        dev.launch(march_volumes, npix, [camera_view(pinhole(cam)), u.surfaces, u.lights, vols,
                                         self.settings["steps"], wp.vec3(*scene.background), self.multiple.struct(),
                                         self.image], self.device, work=self.settings["steps"])

    def output(self):
        return self.image

    def exact_optical_depth(self, per_cell: int = 8) -> np.ndarray:
        """The optical depth from every cell centre to every light through the EV, marched
        finely: (lights, n, n, n, 3), the yardstick for the OPV."""
        n = self.settings["grid"]
        out = wp.empty(len(self.scene.lights) * n**3, dtype=wp.vec3, device=self.device)
        dev.launch(march_exact_optical_depth, out.shape[0], [self.ev, self.volume, self.uploads.lights, per_cell, out],
                   self.device)
        return out.numpy().reshape(len(self.scene.lights), n, n, n, 3)

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """``extinction`` (n, n, n, 3) [z, y, x], ``optical_depth`` (lights, n, n, n, 3), the
        volumes' ``bounds`` (lo, hi), and with ``for_view`` the marched yardstick
        ``optical_depth_exact`` of the same shape (``resolution`` is unused: the grid is the setting's)."""
        n = self.settings["grid"]
        out = {"bounds": (tuple(self.volume.lo), tuple(self.volume.hi)),
               "extinction": self.ev.numpy().reshape(n, n, n, 3)}
        if self.scene.lights and self.opv is not None and self.opv.shape[0] == len(self.scene.lights) * n**3:
            out["optical_depth"] = np.moveaxis(self.opv.numpy().reshape(n, n, n, len(self.scene.lights), 3), 3, 0)
            if for_view:
                out["optical_depth_exact"] = self.exact_optical_depth()
        return out


TECHNIQUE = RBFPropagation
