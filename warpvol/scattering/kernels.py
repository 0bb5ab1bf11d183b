"""The multiple-scattering solve's kernels (the coefficients at the nodes, the phase matrix, the
characteristics, the lights' source, transport, scattering, the view's bake) and what a march
reads of the result (``scattered_light``, ``scattered_on_surface``)."""

from __future__ import annotations

import warp as wp

from .. import device as dev
from ..geometry.intersect import ray_box
from ..geometry.mesh import Surfaces, surface_hit
from ..media.grid import lattice_at_vec3, lattice_cell, trilinear_weights
from ..media.volume import Media, coefficients_at, medium_sigma_t
from ..physics.brdf import Material
from ..physics.constants import INF, INV_PI, PI
from ..physics.lights import DIRECTIONAL, Emitter, ball_mean_inverse_square, light_incident
from ..physics.phase import phase_eval
from ..physics.sampling import orthonormal_basis
from ..physics.transmittance import step_integral_rgb, transmittance_rgb
from ..shading import light_transmittance, reflected, sky_along_normal, surface_direct
from .near import NearField, far_part, near_in_scatter, near_on_surface
from .lattice import (LATTICE_PAD, Lattice, cell_size, cell_step, corner_weight, hat_volume, hat_weight, inside_margin,
                      lattice_coords, lattice_sample, node_index, node_position, support_corner)

dev.kernel_module(__name__)


NEAR_LIGHT_CELLS = 2.0  # nodes this many cells (per axis) from a point or spot light average its source over their hat
NEAR_DIRECTIONS = 96  # directions from the light over such a node's hat
NEAR_STEPS = 12  # midpoints along each through the hat
GOLDEN_ANGLE = 2.399963229728653  # pi (3 - sqrt 5): the Fibonacci set's turn


@wp.struct
class ScatteredLight:
    """What a march reads: R(x), the multiply scattered radiance weighted by the phase function
    toward the camera (``scattered_light``); n = 0: none (single scattering)."""

    lat: Lattice
    values: wp.array(dtype=wp.vec3)
    field: wp.array(dtype=wp.vec3)  # L_{>=1}(x, w_d), n^3 x D, for surfaces
    sky: wp.vec3  # the sky's radiance where the technique does not light surfaces with it itself, else 0
    near: NearField  # the windowed point lights' once-scattered light (``near.py``)
    m: Media  # the media (their phase functions, for R toward the eye near it)
    view_field: wp.array(dtype=wp.vec3)  # what ``values`` is baked from: L_{>=1} less the near field
    eye: wp.vec3
    eye_reach: float  # within this of the eye R is taken at the point itself (0: nowhere)


@wp.func
def toward_eye_at(sl: ScatteredLight, x: wp.vec3, baked: wp.vec3) -> wp.vec3:
    """R(x) with the direction to the eye from x itself: sum_d p(w_d . wo) L(x, w_d) / sum_d p,
    L trilinear per direction, the media's phase functions mixed by their sigma_s at x (none
    there: ``baked``)."""
    wo = sl.eye - x
    if wp.length(wo) <= 0.0:
        return baked
    wo = wp.normalize(wo)
    D = sl.lat.directions.shape[0]
    num = wp.vec3(0.0)
    weight = wp.vec3(0.0)
    for i in range(sl.m.count):
        sig = wp.cw_mul(medium_sigma_t(sl.m, i, x), sl.m.albedo[i])
        if wp.max(sig) > 0.0:
            s = wp.vec3(0.0)
            den = float(0.0)
            for d in range(D):
                ph = phase_eval(sl.m.phase[i], sl.m.phase_table, wp.dot(sl.lat.directions[d], wo))
                s += ph * lattice_sample(sl.view_field, d, D, sl.lat, x)
                den += ph
            num += wp.cw_mul(sig, s / wp.max(den, 1.0e-30))
            weight += sig
    if wp.max(weight) <= 0.0:
        return baked
    return wp.cw_div(num, wp.max(weight, wp.vec3(1.0e-30)))


@wp.func
def scattered_light(sl: ScatteredLight, sigma_s: wp.vec3, x: wp.vec3) -> wp.vec3:
    """sigma_s(x) R(x): the in-scattered radiance of the light scattered once or more at x toward
    the camera, per unit length (added to a march's in-scattering); zero without the term.
    R is baked at the nodes with each node's own direction to the eye; within ``eye_reach`` of
    the eye (a cell and a half), where that direction turns across a cell (the nodes either side
    of a camera inside fog see it in opposite directions, and their blend darkened the fog in
    front of it by a quarter), R is taken at x itself, blended into the baked value over the
    reach's outer half."""
    if sl.lat.n == 0:
        return wp.vec3(0.0)
    R = lattice_sample(sl.values, 0, 1, sl.lat, x)
    if sl.eye_reach > 0.0:
        dist = wp.length(x - sl.eye)
        if dist < sl.eye_reach:
            w = wp.clamp(2.0 - 2.0 * dist / sl.eye_reach, 0.0, 1.0)
            R = (1.0 - w) * R + w * toward_eye_at(sl, x, R)
    return wp.cw_mul(sigma_s, R) + near_in_scatter(sl.near, sl.eye, sigma_s, x)


@wp.func
def reflected_field(field: wp.array(dtype=wp.vec3), lat: Lattice, mat: Material, p: wp.vec3, n: wp.vec3,
                    wo: wp.vec3) -> wp.vec3:
    """sum_d f(wo, -w_d) cos L(p, w_d) 4 pi / D over the directions arriving from above the
    surface (normal n facing wo): what it reflects toward wo of a lattice's radiance field.

    L(p, w_d) is trilinear over the nodes of p's cell in front of the surface's tangent plane
    (the weights of those behind it, inside a solid or beyond a wall where the field is not the
    one arriving here, are dropped and the rest renormalised); all eight where none is in front."""
    N = lat.n
    q, t = lattice_cell(N, lattice_coords(lat, p))
    sy = N
    sz = N * N
    plain0, plain1 = trilinear_weights(t)
    w0 = wp.vec4(corner_weight(lat, q, plain0[0], p, n), corner_weight(lat, q + 1, plain0[1], p, n),
                 corner_weight(lat, q + sy, plain0[2], p, n), corner_weight(lat, q + sy + 1, plain0[3], p, n))
    w1 = wp.vec4(corner_weight(lat, q + sz, plain1[0], p, n), corner_weight(lat, q + sz + 1, plain1[1], p, n),
                 corner_weight(lat, q + sz + sy, plain1[2], p, n), corner_weight(lat, q + sz + sy + 1, plain1[3], p, n))
    total = w0[0] + w0[1] + w0[2] + w0[3] + w1[0] + w1[1] + w1[2] + w1[3]
    if total <= 1.0e-6:  # no node in front: the plain trilinear weights
        w0 = plain0
        w1 = plain1
        total = 1.0
    out = wp.vec3(0.0)
    D = lat.directions.shape[0]
    dw = 4.0 * PI / (float(D) * total)
    for d in range(D):
        wi = -lat.directions[d]
        c = wp.dot(n, wi)
        if c > 0.0:
            L = (field[q * D + d] * w0[0] + field[(q + 1) * D + d] * w0[1] + field[(q + sy) * D + d] * w0[2] +
                 field[(q + sy + 1) * D + d] * w0[3] + field[(q + sz) * D + d] * w1[0] +
                 field[(q + sz + 1) * D + d] * w1[1] + field[(q + sz + sy) * D + d] * w1[2] +
                 field[(q + sz + sy + 1) * D + d] * w1[3])
            out += reflected(mat, n, wo, wi, c, L * dw, wp.vec3(1.0))
    return out


@wp.func
def reflected_from_outside(field: wp.array(dtype=wp.vec3), lat: Lattice, mat: Material, p: wp.vec3, n: wp.vec3,
                           wo: wp.vec3, sky: wp.vec3) -> wp.vec3:
    """What a surface at p, a cell or more outside the lattice, reflects toward wo,
    sum_d f_r cos L 4 pi / D: where the direction meets the lattice's box, L is the field where
    it enters the box (no medium lies outside it, so the radiance leaving it along -w_d arrives
    unchanged; surfaces between are not tested); where it misses the box, a sky of radiance
    ``sky``."""
    D = lat.directions.shape[0]
    dw = 4.0 * PI / float(D)
    out = wp.vec3(0.0)
    for d in range(D):
        wi = -lat.directions[d]
        c = wp.dot(n, wi)
        if c > 0.0:
            a, b = ray_box(p, wi, lat.lo, lat.hi)
            L = sky
            if a <= b and b > 0.0:
                L = lattice_sample(field, d, D, lat, p + wp.max(a, 0.0) * wi)
            out += reflected(mat, n, wo, wi, c, L * dw, wp.vec3(1.0))
    return out


@wp.func
def scattered_on_surface(sl: ScatteredLight, s: Surfaces, mat: Material, p: wp.vec3, n: wp.vec3,
                         wo: wp.vec3) -> wp.vec3:
    """What a surface at p (normal n facing wo) reflects toward wo of the light the media have
    scattered and the surfaces have reflected: within a cell of the lattice, of the field at p
    (``reflected_field`` of L_{>=1}); farther out, of the light leaving the lattice toward p and
    of the sky unless the technique gathers it there itself (``reflected_from_outside``; it read
    the sky alone, and a floor a cell below a lit fog lost the fog's light). Zero without the
    term."""
    if sl.lat.n == 0:
        return wp.vec3(0.0)
    if inside_margin(sl.lat.lo, sl.lat.hi, wp.max(cell_size(sl.lat, p)), p):
        # the windowed lights' first scattering from their tables at p (Lambertian), the rest of
        # the field from the nodes: interpolated, a light's L1 (1/r toward it) read twice its light
        # a third of a cell away
        near = wp.cw_mul(mat.diffuse, near_on_surface(sl.near, p, n)) * INV_PI
        return reflected_field(sl.view_field, sl.lat, mat, p, n, wo) + near
    return reflected_from_outside(sl.field, sl.lat, mat, p, n, wo, sl.sky)


@wp.kernel
def bake_scattering(offset: int, m: Media, lat: Lattice, sigma_t: wp.array(dtype=wp.vec3),
                    sigma_s: wp.array(dtype=wp.vec3)):
    """sigma_t (all media) and each medium's sigma_s at every node (medium-major). A node on the
    lattice's boundary, which lies a pad outside the media's bounds, takes them from just inside:
    the media end at their bounds, and nodes holding none would halve the coefficients over the
    last cell (a third of an 8^3 lattice's volume)."""
    q = wp.tid() + offset
    n3 = lat.n * lat.n * lat.n
    inset = 2.0 * LATTICE_PAD * wp.max(lat.hi - lat.lo)
    x = wp.min(wp.max(node_position(lat, q), lat.lo + wp.vec3(inset)), lat.hi - wp.vec3(inset))
    tot = wp.vec3(0.0)
    for i in range(m.count):
        sig = medium_sigma_t(m, i, x)
        tot += sig
        sigma_s[i * n3 + q] = wp.cw_mul(sig, m.albedo[i])
    sigma_t[q] = tot


@wp.kernel
def phase_matrix(offset: int, m: Media, directions: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
    """Row (medium i, direction d) of P: p_i(w_d . w_d') over d', scaled to sum to 1."""
    row = wp.tid() + offset
    D = directions.shape[0]
    i = row / D
    d = row % D
    total = float(0.0)
    for e in range(D):
        total += phase_eval(m.phase[i], m.phase_table, wp.dot(directions[d], directions[e]))
    for e in range(D):
        out[row * D + e] = phase_eval(m.phase[i], m.phase_table, wp.dot(directions[d], directions[e])) / total


@wp.struct
class Ends:
    """Where each characteristic (direction d, node q; q fastest) ends: its length, the point and
    the normal (facing the node) of the surface there, the surface's face (-1: none, the
    lattice's boundary; -2: a surface more than a cell outside the lattice, whose light is taken
    once, not iterated) and the radiance arriving from there before any scattering (``start``)."""

    length: wp.array(dtype=float)
    point: wp.array(dtype=wp.vec3)
    normal: wp.array(dtype=wp.vec3)
    face: wp.array(dtype=int)
    start: wp.array(dtype=wp.vec3)


@wp.kernel
def characteristics(offset: int, m: Media, s: Surfaces, lights: wp.array(dtype=Emitter), lat: Lattice,
                    sky: wp.vec3, shadow_steps: int, ends: Ends):
    """How far back along w_d node q sees, to the lattice's boundary or the first surface, and
    the radiance arriving from there before any scattering in the media: the sky, or what the
    surface reflects toward w_d of the lights' direct light (and, outside the lattice, where the
    iteration cannot reach it, of the sky: Lambertian, its visibility taken along the normal)."""
    tid = wp.tid() + offset
    n3 = lat.n * lat.n * lat.n
    q = tid % n3
    x = node_position(lat, q)
    w = lat.directions[tid / n3]
    back = -w
    a, b = ray_box(x, back, lat.lo, lat.hi)
    t = wp.max(b, 0.0)
    hit, t_hit, nrm, face = surface_hit(s, x, back, INF)
    start = sky
    ends.face[tid] = -1
    if hit:  # inside the lattice or beyond it (where no medium is)
        t = wp.min(t, t_hit)
        p = x + t_hit * back
        nf = wp.where(wp.dot(nrm, w) > 0.0, nrm, -nrm)
        rng = wp.uint32(0)  # unused: transmittance is marched
        mat = s.material[face]
        start = surface_direct(m, s, lights, p, nf, w, mat, 0, rng, shadow_steps)
        ends.point[tid] = p
        ends.normal[tid] = nf
        ends.face[tid] = face
        if not inside_margin(lat.lo, lat.hi, wp.min(cell_size(lat, p)), p):
            ends.face[tid] = -2
            if wp.max(sky) > 0.0:
                start += sky_along_normal(m, s, mat, p, nf, sky, shadow_steps)
    ends.length[tid] = t
    ends.start[tid] = start


@wp.kernel
def surface_starts(offset: int, ends: Ends):
    """Keep of each characteristic's start only what a surface sends (the sky's set to 0)."""
    tid = wp.tid() + offset
    if ends.face[tid] == -1:
        ends.start[tid] = wp.vec3(0.0)


@wp.kernel
def reflect_at_ends(offset: int, s: Surfaces, lat: Lattice, ends: Ends, L: wp.array(dtype=wp.vec3),
                    out: wp.array(dtype=wp.vec3)):
    """The radiance a characteristic starts with in the next order: what the surface at its end
    reflects toward w_d of the field L (``reflected_field``); zero where it ends on no surface
    or more than a cell outside the lattice (its light taken once, in the start)."""
    tid = wp.tid() + offset
    n3 = lat.n * lat.n * lat.n
    face = ends.face[tid]
    out[tid] = wp.vec3(0.0)
    if face >= 0:
        out[tid] = reflected_field(L, lat, s.material[face], ends.point[tid], ends.normal[tid],
                                   lat.directions[tid / n3])


@wp.func
def near_light(lat: Lattice, node: wp.vec3, light: Emitter) -> bool:
    """Whether a point or spot light lies within NEAR_LIGHT_CELLS cells of the node on every axis."""
    if light.kind == DIRECTIONAL:
        return False
    u = lattice_coords(lat, light.position)
    return (wp.abs(u[0] - node[0]) < NEAR_LIGHT_CELLS and wp.abs(u[1] - node[1]) < NEAR_LIGHT_CELLS and
            wp.abs(u[2] - node[2]) < NEAR_LIGHT_CELLS)


@wp.func
def hat_cap(lat: Lattice, node: wp.vec3, light: Emitter, x: wp.vec3):
    """What every direction of ``hat_light_direction`` shares for one node (at x) and light: the
    hat's corners, the cosine of the cap of directions from the light that holds the hat's
    bounding sphere (-1: the light is inside it, the whole sphere), the cap's axis and the node's
    distance to the light."""
    lo = support_corner(lat, node, -1.0)
    hi = support_corner(lat, node, 1.0)
    radius = wp.length(wp.max(x - lo, hi - x))
    to = x - light.position
    dist = wp.length(to)
    axis = wp.vec3(0.0, 1.0, 0.0)
    if dist > 0.0:
        axis = to / dist
    cos_max = float(-1.0)
    if dist > radius:
        cos_max = wp.sqrt(1.0 - (radius / dist) * (radius / dist))
    return lo, hi, cos_max, axis, dist


@wp.func
def hat_light_direction(lat: Lattice, node: wp.vec3, light: Emitter, lo: wp.vec3, hi: wp.vec3, cos_max: float,
                        axis: wp.vec3, dist: float, volume: float, sig: wp.vec3, log_tr: wp.vec3, k: int):
    """Direction k of NEAR_DIRECTIONS from the light over the node's hat (a Fibonacci set on the cap
    of ``hat_cap``) and the light it carries into the hat, per unit solid angle and hat volume:
    int hat(p + r w) I(w) T e^(-sigma (r - d)) dr (omega / K) / int hat dV, sigma the extinction at
    the node, d its distance to the light and T = e^log_tr the node's own shadow ray's
    transmittance, midpoints along the chord. The two factors are joined in the exponent: apart,
    a point nearer the light than the node in dense fog (sigma a cell over 88) overflowed
    e^(sigma (d - r)) to inf, and inf times the node's underflowed T made NaN."""
    z = 1.0 - (float(k) + 0.5) / float(NEAR_DIRECTIONS) * (1.0 - cos_max)
    r = wp.sqrt(wp.max(1.0 - z * z, 0.0))
    phi = GOLDEN_ANGLE * float(k)
    t, b = orthonormal_basis(axis)
    w = z * axis + (r * wp.cos(phi)) * t + (r * wp.sin(phi)) * b
    p = light.position
    t0, t1 = ray_box(p, w, lo, hi)
    t0 = wp.max(t0, 0.0)
    acc = wp.vec3(0.0)
    if t1 > t0 and volume > 0.0:
        dr = (t1 - t0) / float(NEAR_STEPS)
        for j in range(NEAR_STEPS):
            rr = t0 + (float(j) + 0.5) * dr
            y = p + rr * w
            hw = hat_weight(lat, node, y)
            if hw > 0.0:
                wi, dd, e = light_incident(light, y)
                fall = wp.vec3(wp.exp(wp.min(log_tr[0] - sig[0] * (rr - dist), 0.0)),
                               wp.exp(wp.min(log_tr[1] - sig[1] * (rr - dist), 0.0)),
                               wp.exp(wp.min(log_tr[2] - sig[2] * (rr - dist), 0.0)))
                acc += (hw * dd * dd) * wp.cw_mul(e, fall)
        acc = acc * (dr * 2.0 * PI * (1.0 - cos_max) / (float(NEAR_DIRECTIONS) * volume))
    return w, acc


@wp.func
def log_or_floor(t: float) -> float:
    """log t, or -1e30 (e^ of it: 0) where t is 0."""
    return wp.where(t > 0.0, wp.log(wp.max(t, 1.0e-38)), -1.0e30)


@wp.func
def total_scattering(sigma_s: wp.array(dtype=wp.vec3), phase_count: int, n3: int, q: int) -> wp.vec3:
    out = wp.vec3(0.0)
    for i in range(phase_count):
        out += sigma_s[i * n3 + q]
    return out


@wp.func
def source_weight(lat: Lattice, sigma_s: wp.array(dtype=wp.vec3), phase_count: int, n3: int, q: int,
                  i: int) -> wp.vec3:
    """What medium i's phase function weighs in node q's source: its sigma_s; on an ``exact``
    lattice (sources per unit sigma_s) its share of the node's sigma_s, or an equal share where
    the node holds no medium (the source just outside a sphere of fog, read inside its edge)."""
    sig = sigma_s[i * n3 + q]
    if lat.exact == 0:
        return sig
    total = total_scattering(sigma_s, phase_count, n3, q)
    if wp.max(total) <= 0.0:
        return wp.vec3(1.0 / float(phase_count))
    return wp.cw_div(sig, wp.max(total, wp.vec3(1.0e-30)))


@wp.func
def add_scattered(m: Media, lat: Lattice, sigma_s: wp.array(dtype=wp.vec3), phase_count: int, n3: int, q: int,
                  w: wp.vec3, et: wp.vec3, q_out: wp.array(dtype=wp.vec3)):
    """Onto node q's source toward every direction: light et travelling along w, scattered by each
    medium's phase function, weighted as ``source_weight`` says."""
    D = lat.directions.shape[0]
    for i in range(phase_count):
        sig = source_weight(lat, sigma_s, phase_count, n3, q, i)
        if wp.max(sig) > 0.0:
            se = wp.cw_mul(sig, et)
            for d in range(D):
                ph = phase_eval(m.phase[i], m.phase_table, wp.dot(w, lat.directions[d]))
                q_out[d * n3 + q] = q_out[d * n3 + q] + ph * se


@wp.kernel
def light_source(offset: int, m: Media, s: Surfaces, lights: wp.array(dtype=Emitter), lat: Lattice,
                 sigma_t: wp.array(dtype=wp.vec3), sigma_s: wp.array(dtype=wp.vec3), phase_count: int,
                 shadow_steps: int, window: wp.array(dtype=float), q_out: wp.array(dtype=wp.vec3)):
    """Q_1 of the lights at node q for every direction (direction-major): sum_l sigma_s
    p(-w_l . w_d) E_l T_l. The trilinear interpolant's integral is the nodes' values times their
    hats' volumes, so a node near a point or spot light takes the source averaged over its hat
    (``hat_light_direction``: the 1/d^2 peak is integrable, a node's own value is not, and half
    the light a thick fog scatters first lies within a cell of the light), each direction from
    the light scattered by its own angle; farther nodes, and every node of a graded lattice
    (whose hats are not those of even cells; measured, they dim the image), take 1/d^2 averaged
    over a ball of half a cell. A light with a window (``window`` > 0, its radius; ``near.py``)
    leaves the windowed part of its source to the near field: the remainder, smooth and bounded,
    is taken at the node."""
    q = wp.tid() + offset
    D = lat.directions.shape[0]
    n3 = lat.n * lat.n * lat.n
    x = node_position(lat, q)
    node = node_index(lat.n, q)
    rng = wp.uint32(0)  # unused: transmittance is marched
    for d in range(D):
        q_out[d * n3 + q] = wp.vec3(0.0)
    for l in range(lights.shape[0]):
        wi, dist, e = light_incident(lights[l], x)
        rho = window[l]
        if rho > 0.0:
            e = e * (dist * dist) * far_part(dist, rho)
        elif lat.graded == 0 and near_light(lat, node, lights[l]):
            tr = light_transmittance(m, s, x, wi, dist, 0, rng, shadow_steps)
            if wp.max(tr) > 0.0:
                lo, hi, cos_max, axis, d_light = hat_cap(lat, node, lights[l], x)
                volume = hat_volume(lat, node)
                log_tr = wp.vec3(log_or_floor(tr[0]), log_or_floor(tr[1]), log_or_floor(tr[2]))
                for k in range(NEAR_DIRECTIONS):
                    w, carried = hat_light_direction(lat, node, lights[l], lo, hi, cos_max, axis, d_light, volume,
                                                     sigma_t[q], log_tr, k)
                    if wp.max(carried) > 0.0:
                        add_scattered(m, lat, sigma_s, phase_count, n3, q, w, carried, q_out)
            continue
        elif lights[l].kind != DIRECTIONAL:
            cell = 0.5 * wp.length(cell_size(lat, x))  # the half cell 1/d^2 is averaged over: finite at the light
            e = e * (dist * dist) * ball_mean_inverse_square(cell, dist)
        if wp.max(e) > 0.0:
            et = wp.cw_mul(e, light_transmittance(m, s, x, wi, dist, 0, rng, shadow_steps))
            if wp.max(et) > 0.0:
                add_scattered(m, lat, sigma_s, phase_count, n3, q, -wi, et, q_out)


@wp.func
def transport_step(m: Media, lat: Lattice, sigma_t: wp.array(dtype=wp.vec3), source: wp.array(dtype=wp.vec3),
                   base: int, with_source: int, xm: wp.vec3, dt: float, L: wp.vec3, tr: wp.vec3):
    """One step of a characteristic, coefficients at its midpoint xm: (L, tr) after it. Where the
    lattice is ``exact`` the media's own sigma_t and sigma_s at xm (a sphere's edge stays sharp,
    not blurred over a cell) times the interpolated source per unit sigma_s."""
    u = lattice_coords(lat, xm)
    sig = wp.vec3(0.0)
    scale = wp.vec3(1.0)
    if lat.exact != 0:
        sig, scale = coefficients_at(m, xm)
    else:
        sig = lattice_at_vec3(sigma_t, 0, 1, lat.n, u)
    if with_source != 0:
        src = wp.cw_mul(scale, lattice_at_vec3(source, base, 1, lat.n, u))
        L += wp.cw_mul(wp.cw_mul(tr, src), step_integral_rgb(sig, dt))
    return L, wp.cw_mul(tr, transmittance_rgb(sig * dt))


@wp.kernel
def transport(offset: int, m: Media, lat: Lattice, sigma_t: wp.array(dtype=wp.vec3), source: wp.array(dtype=wp.vec3),
              lengths: wp.array(dtype=float), starts: wp.array(dtype=wp.vec3), with_source: int,
              out: wp.array(dtype=wp.vec3)):
    """L(x, w_d) = int T Q ds back along w_d (one cell a step, exact per step; Q direction-major,
    ``with_source`` = 0: none) plus the radiance the characteristic starts with, attenuated
    (``starts``); written node-major. Threads run node-fastest, so neighbouring threads march
    side by side through the same cells."""
    tid = wp.tid() + offset
    D = lat.directions.shape[0]
    n3 = lat.n * lat.n * lat.n
    q = tid % n3
    d = tid / n3
    x = node_position(lat, q)
    back = -lat.directions[d]
    t_end = lengths[tid]
    L = wp.vec3(0.0)
    tr = wp.vec3(1.0)
    t = float(0.0)
    if lat.graded == 0 and t_end > 0.0:  # evenly spaced: equal steps of about a cell
        steps = wp.max(int(wp.ceil(t_end / cell_step(cell_size(lat, x), back))), 1)
        dt = t_end / float(steps)
        t = t_end
        for k in range(steps):
            L, tr = transport_step(m, lat, sigma_t, source, d * n3, with_source, x + ((float(k) + 0.5) * dt) * back,
                                   dt, L, tr)
    while t < t_end:  # graded: steps of the local cell
        dt = wp.min(cell_step(cell_size(lat, x + t * back), back), t_end - t)
        if t_end - t - dt < 1.0e-3 * dt:
            dt = t_end - t
        L, tr = transport_step(m, lat, sigma_t, source, d * n3, with_source, x + (t + 0.5 * dt) * back, dt, L, tr)
        t += dt
    out[q * D + d] = L + wp.cw_mul(tr, starts[tid])


@wp.kernel
def scatter(offset: int, lat: Lattice, sigma_s: wp.array(dtype=wp.vec3), P: wp.array(dtype=float), phase_count: int,
            L: wp.array(dtype=wp.vec3), add: int, q_out: wp.array(dtype=wp.vec3)):
    """Q(x, w_d) = sum_i sigma_s,i(x) sum_d' P_i[d, d'] L(x, w_d') (L node-major, Q
    direction-major; ``add``: onto q_out)."""
    tid = wp.tid() + offset
    D = lat.directions.shape[0]
    n3 = lat.n * lat.n * lat.n
    q = tid / D
    d = tid % D
    acc = wp.vec3(0.0)
    for i in range(phase_count):
        sig = source_weight(lat, sigma_s, phase_count, n3, q, i)
        if wp.max(sig) > 0.0:
            row = (i * D + d) * D
            s = wp.vec3(0.0)
            for e in range(D):
                s += P[row + e] * L[q * D + e]
            acc += wp.cw_mul(sig, s)
    if add != 0:
        acc += q_out[d * n3 + q]
    q_out[d * n3 + q] = acc


@wp.kernel
def add_order(offset: int, L: wp.array(dtype=wp.vec3), scale: wp.vec3, total: wp.array(dtype=wp.vec3)):
    tid = wp.tid() + offset
    total[tid] = total[tid] + wp.cw_mul(L[tid], scale)


@wp.kernel
def toward_eye(offset: int, m: Media, lat: Lattice, sigma_s: wp.array(dtype=wp.vec3), phase_count: int,
               L: wp.array(dtype=wp.vec3), eye: wp.vec3, out: wp.array(dtype=wp.vec3)):
    """R(x) = sum_d p(w_d . wo) L(x, w_d) / sum_d p(w_d . wo), wo toward the eye; the media's
    phase functions mixed by their sigma_s at the node (none there: isotropic)."""
    q = wp.tid() + offset
    D = lat.directions.shape[0]
    n3 = lat.n * lat.n * lat.n
    x = node_position(lat, q)
    wo = eye - x
    if wp.length(wo) > 0.0:
        wo = wp.normalize(wo)
    num = wp.vec3(0.0)
    weight = wp.vec3(0.0)
    for i in range(phase_count):
        sig = sigma_s[i * n3 + q]
        if wp.max(sig) > 0.0:
            s = wp.vec3(0.0)
            den = float(0.0)
            for d in range(D):
                ph = phase_eval(m.phase[i], m.phase_table, wp.dot(lat.directions[d], wo))
                s += ph * L[q * D + d]
                den += ph
            num += wp.cw_mul(sig, s / wp.max(den, 1.0e-30))
            weight += sig
    if wp.max(weight) > 0.0:
        out[q] = wp.cw_div(num, wp.max(weight, wp.vec3(1.0e-30)))
    else:
        s = wp.vec3(0.0)
        for d in range(D):
            s += L[q * D + d]
        out[q] = s / float(D)
