"""Multiple scattering for every marcher: the light scattered more than once, solved order by
order on a lattice of nodes and directions, and read back by a march as one lookup a step.

A marcher computes single scattering exactly (its lights, and the sky where it gathers it).
What it leaves out is the in-scattered radiance of the light that has already scattered,
S_ms(x, wo) = sigma_s(x) int p(w . wo) L_{>=1}(x, w) dw, with L_{>=1} the radiance of all
light scattered one or more times. This module solves for L_{>=1} by source iteration (the
Neumann series of the radiative transfer equation, one order of scattering per pass) on an
n^3 lattice of nodes over the media's bounds and D directions (a Fibonacci set, 4 pi / D sr
each), the discrete-ordinates method (Chandrasekhar 1960; Fattal 2009 for graphics), with
long characteristics:

* order 1's source at node x toward w_d: Q_1 = sum_l sigma_s p(-w_l . w_d) E_l T_l, the
  lights' direct light (shadow rays through the media and past the surfaces), plus the sky's
  light scattered once (the background carried to the node along each w_d, through the media
  and blocked by surfaces). A node within NEAR_LIGHT_CELLS of a point or spot light takes the
  light's source averaged over its hat (``hat_light_direction``), so the interpolant keeps the
  light scattered near the lamp; farther nodes, and graded lattices, 1/d^2 averaged over a ball
  of half a cell (finite at the light);
* transport: L_k(x, w_d) = int_0^t T(x, x - s w_d) Q_k(x - s w_d, w_d) ds, marched back along
  w_d to the lattice's boundary or the first surface, one cell a step, with Q interpolated
  trilinearly and each step integrated exactly for constant coefficients; sigma_t is
  interpolated too, except where every medium is homogeneous (and the nodes even): there the
  step reads the media's own sigma_t and sigma_s and the nodes hold Q per unit sigma_s
  (``Lattice.exact``), so a sphere's edge stays sharp;
* scattering: Q_{k+1}(x, w_d) = sigma_s(x) sum_d' P[d, d'] L_k(x, w_d'), the phase function
  as a D x D matrix whose rows sum to 1 (energy kept exactly at albedo 1, the white furnace);
* order 0 (L_0: the sky and the surfaces' reflected direct light carried to the node, not
  scattered) joins the total where a march does not gather it: the surfaces' part always
  (the fog lit by the walls, a wall lit by another), the sky's unless the technique gathers
  the sky's single scattering itself (``sky_samples`` > 0);
* orders are summed until the ratio rho of successive orders' energies settles (to 1%, or
  until the change moves the tail by under 1% of the energy summed); the rest of the series
  is the geometric tail L_k rho / (1 - rho), as Hillaire (EGSR 2020) sums the orders of
  multiple scattering in an atmosphere.

For the camera, every node holds R(x) = sum_d p(w_d . wo) L_{>=1}(x, w_d) / sum_d p(w_d . wo),
wo toward the camera's eye: a march adds sigma_s(x) R(x) to its in-scattering at each step
(``scattered_light``), trilinearly, one lookup. Moving the camera re-runs only that last
bake. Surfaces are part of the iteration: a characteristic that ends on one starts with what
the surface reflects, of the lights' direct light and of the sky in order 0 and of the
lattice's field L_{k-1} in order k (``reflect_at_ends``), so light goes from the media to a
wall and back, and from wall to wall; a march's visible surface reflects the field too
(``scattered_on_surface``). A surface more than a cell outside the lattice (a floor beyond
the fog) reflects the lights and the sky (seen along its normal, ``shading.sky_along_normal``)
once into the iteration, and in the image the field where each of its directions enters the
lattice's box and the sky where one misses it (``reflected_from_outside``). Everything converges to the all-orders answer as
the nodes and directions rise (error ~ 1/n, 1/D), up to the light leaking through surfaces
thinner than a cell, whose two sides share nodes.

The lattice stops just inside the walls that enclose the lights where the media's bounds pass
them (``enclosed``): nodes behind a wall would blend the dark outside into the light inside.
Where even cells would span more than half a mean free path of media far wider than what
matters (``focus``: the eye and the lamps in fog that fills the world, or the lamps in thick
fog seen from outside), the nodes are graded: node u at c + s sinh(alpha (u - uc)) per axis,
fine around that region and growing geometrically to the media's bounds
(``graded_spacing``); the characteristics then step one local cell at a time.

The setting ``multiple_scattering`` is n (0: single scattering, the papers' own models);
``ms_directions`` is D.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from . import device as dev
from .geometry.intersect import ray_box
from .geometry.mesh import Surfaces, surface_hit
from .physics.brdf import Material
from .media.grid import lattice_at_vec3, lattice_cell, trilinear_weights
from .media.volume import Media, coefficients_at, medium_sigma_t
from .physics.constants import INF, PI
from .physics.lights import DIRECTIONAL, Emitter, ball_mean_inverse_square, light_incident
from .physics.phase import phase_eval
from .physics.sampling import orthonormal_basis
from .physics.sphere import fibonacci_directions
from .physics.transmittance import step_integral_rgb, transmittance_rgb
from .pipeline import Bias, Frame, Setting, SettingsError, Stage
from .shading import light_transmittance, reflected, sky_along_normal, surface_direct
from .upload import MediaBuffers

dev.kernel_module(__name__)

SETTINGS = {
    "multiple_scattering": Setting(8, 0, 64, "nodes per axis of the lattice light scattered more than once is "
                                               "solved on (orders 2 and up); 0: single scattering only, the "
                                               "paper's model"),
    "ms_directions": Setting(16, 6, 256, "directions of the multiple-scattering lattice's radiance (a Fibonacci "
                                          "set); error ~ 1/directions"),
}

#: The finest lattice ``target_error`` takes: 32^3 nodes solve in seconds on two CPU cores, 64^3
#: (the setting's top) in minutes; beyond it target_error reports the lattice's bias instead.
MS_TOP = 32

#: What ``target_error`` measures of the two settings: each doubled, the difference scaled to
#: the whole bias as an error of order 1 (the lattice's interpolation and step are first order
#: where the media have edges).
BIASES = (Bias("multiple_scattering", factor=2, order=1, when="multiple", top=MS_TOP),
          Bias("ms_directions", factor=2, order=1, when="multiple", top=2 * MS_TOP))

#: What a technique leaves out with the term on (and the one it does not have without it).
LEFT_OUT_WITH = (Frame.APPROXIMATED + "multiple scattering and the surfaces' indirect light (and the sky's "
                 "light where the technique does not gather it), on a lattice (multiple_scattering, ms_directions)")
LEFT_OUT_WITHOUT = "multiple scattering"

LATTICE_PAD = 1.0e-4  # the lattice's bounds pass the media's by this part of their extent
NEAR_LIGHT_CELLS = 2.0  # nodes this many cells (per axis) from a point or spot light average its source over their hat
NEAR_DIRECTIONS = 96  # directions from the light over such a node's hat
NEAR_STEPS = 12  # midpoints along each through the hat
GOLDEN_ANGLE = 2.399963229728653  # pi (3 - sqrt 5): the Fibonacci set's turn
MAX_ORDERS = 64  # source iterations before the geometric tail, at most
SETTLED = 0.01  # the ratio of successive orders counts as settled when it changes by less than this
TAIL_SETTLED = 0.01  # ... or when the tail's uncertainty from that change is under this part of the energy
MAX_RATIO = 0.995  # rho above this is taken as this in the tail (albedo 1 in an unbounded medium)


@wp.struct
class Spacing:
    """How the nodes spread over [lo, hi] per axis: evenly where alpha is 0, else node u at
    c + s sinh(alpha (u - uc)), cells of about s alpha near c growing by e^alpha a node away
    from it (``graded_spacing``)."""

    c: wp.vec3
    s: wp.vec3
    alpha: wp.vec3
    uc: wp.vec3


@wp.struct
class Lattice:
    """n^3 nodes on the corners of [lo, hi] (spread by ``spacing``) and D directions: the
    solver's unknowns."""

    n: int
    lo: wp.vec3
    hi: wp.vec3
    spacing: Spacing
    graded: int  # 0: evenly spaced on every axis
    exact: int  # 1: all media homogeneous: steps read their coefficients, the nodes hold sources per unit sigma_s
    directions: wp.array(dtype=wp.vec3)  # unit, the direction the radiance travels


@wp.struct
class ScatteredLight:
    """What a march reads: R(x), the multiply scattered radiance weighted by the phase function
    toward the camera (``scattered_light``); n = 0: none (single scattering)."""

    lat: Lattice
    values: wp.array(dtype=wp.vec3)
    field: wp.array(dtype=wp.vec3)  # L_{>=1}(x, w_d), n^3 x D, for surfaces
    sky: wp.vec3  # the sky's radiance where the technique does not light surfaces with it itself, else 0


@wp.func
def asinh_(z: float) -> float:
    a = wp.abs(z)
    return wp.sign(z) * wp.log(a + wp.sqrt(a * a + 1.0))


@wp.func
def axis_coord(lo: float, hi: float, n: int, c: float, s: float, alpha: float, uc: float, x: float) -> float:
    if alpha == 0.0:
        return (x - lo) / (hi - lo) * float(n - 1)
    return uc + asinh_((x - c) / s) / alpha


@wp.func
def axis_position(lo: float, hi: float, n: int, c: float, s: float, alpha: float, uc: float, u: float) -> float:
    if alpha == 0.0:
        return lo + (hi - lo) * u / float(n - 1)
    return c + s * wp.sinh(alpha * (u - uc))


@wp.func
def lattice_coords(lat: Lattice, x: wp.vec3) -> wp.vec3:
    sp = lat.spacing
    return wp.vec3(axis_coord(lat.lo[0], lat.hi[0], lat.n, sp.c[0], sp.s[0], sp.alpha[0], sp.uc[0], x[0]),
                   axis_coord(lat.lo[1], lat.hi[1], lat.n, sp.c[1], sp.s[1], sp.alpha[1], sp.uc[1], x[1]),
                   axis_coord(lat.lo[2], lat.hi[2], lat.n, sp.c[2], sp.s[2], sp.alpha[2], sp.uc[2], x[2]))


@wp.func
def cell_size(lat: Lattice, x: wp.vec3) -> wp.vec3:
    """The lattice's cell widths around x, per axis: dx/du = s alpha cosh(alpha (u - uc)) =
    s alpha sqrt(1 + ((x - c) / s)^2) where graded, no transcendental function a step."""
    sp = lat.spacing
    p = wp.min(wp.max(x, lat.lo), lat.hi)
    out = wp.vec3(0.0)
    for a in range(3):
        if sp.alpha[a] == 0.0:
            out[a] = (lat.hi[a] - lat.lo[a]) / float(lat.n - 1)
        else:
            z = (p[a] - sp.c[a]) / sp.s[a]
            out[a] = sp.s[a] * sp.alpha[a] * wp.sqrt(1.0 + z * z)
    return out


@wp.func
def lattice_sample(values: wp.array(dtype=wp.vec3), base: int, stride: int, lat: Lattice, x: wp.vec3) -> wp.vec3:
    """Trilinear lookup at x in a lattice's values (node q at ``base + stride q``)."""
    return lattice_at_vec3(values, base, stride, lat.n, lattice_coords(lat, x))


@wp.func
def lattice_position(lat: Lattice, u: wp.vec3) -> wp.vec3:
    """The point at lattice coordinates u (``lattice_coords``' inverse)."""
    sp = lat.spacing
    return wp.vec3(axis_position(lat.lo[0], lat.hi[0], lat.n, sp.c[0], sp.s[0], sp.alpha[0], sp.uc[0], u[0]),
                   axis_position(lat.lo[1], lat.hi[1], lat.n, sp.c[1], sp.s[1], sp.alpha[1], sp.uc[1], u[1]),
                   axis_position(lat.lo[2], lat.hi[2], lat.n, sp.c[2], sp.s[2], sp.alpha[2], sp.uc[2], u[2]))


@wp.func
def node_index(n: int, q: int) -> wp.vec3:
    """Node q's lattice coordinates (i, j, k)."""
    return wp.vec3(float(q % n), float((q / n) % n), float(q / (n * n)))


@wp.func
def node_position(lat: Lattice, q: int) -> wp.vec3:
    return lattice_position(lat, node_index(lat.n, q))


@wp.func
def scattered_light(sl: ScatteredLight, sigma_s: wp.vec3, x: wp.vec3) -> wp.vec3:
    """sigma_s(x) R(x): the in-scattered radiance of the light scattered once or more at x toward
    the camera, per unit length (added to a march's in-scattering); zero without the term."""
    if sl.lat.n == 0:
        return wp.vec3(0.0)
    return wp.cw_mul(sigma_s, lattice_sample(sl.values, 0, 1, sl.lat, x))


@wp.func
def inside_margin(lo: wp.vec3, hi: wp.vec3, margin: float, p: wp.vec3) -> bool:
    return (p[0] >= lo[0] - margin and p[1] >= lo[1] - margin and p[2] >= lo[2] - margin and
            p[0] <= hi[0] + margin and p[1] <= hi[1] + margin and p[2] <= hi[2] + margin)


@wp.func
def corner_weight(lat: Lattice, q: int, w: float, p: wp.vec3, n: wp.vec3) -> float:
    """A trilinear weight w of node q, or 0 where the node lies behind the plane through p
    with normal n."""
    return wp.where(wp.dot(node_position(lat, q) - p, n) >= 0.0, w, 0.0)


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
        return reflected_field(sl.field, sl.lat, mat, p, n, wo)
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
def hat_weight(lat: Lattice, node: wp.vec3, x: wp.vec3) -> float:
    """The trilinear interpolant's weight of the node at lattice coordinates ``node`` at x: its
    hat, 1 at the node falling to 0 a cell away on each axis (0 outside the lattice)."""
    u = lattice_coords(lat, x)
    w = float(1.0)
    top = float(lat.n - 1)
    for a in range(3):
        if u[a] < 0.0 or u[a] > top:
            w = 0.0
        w *= wp.max(1.0 - wp.abs(u[a] - node[a]), 0.0)
    return w


@wp.func
def support_corner(lat: Lattice, node: wp.vec3, side: float) -> wp.vec3:
    """A corner of a node's hat (the neighbouring nodes' positions, or its own on the lattice's
    boundary): side -1 the low corner, +1 the high."""
    top = float(lat.n - 1)
    return lattice_position(lat, wp.vec3(wp.clamp(node[0] + side, 0.0, top), wp.clamp(node[1] + side, 0.0, top),
                                         wp.clamp(node[2] + side, 0.0, top)))


@wp.func
def hat_volume(lat: Lattice, node: wp.vec3) -> float:
    """int hat dV of the node at lattice coordinates ``node``: per axis its two sides'
    int (1 - |v|) dx/du dv, dx/du = s alpha cosh(alpha (u - uc)) where graded (with a = alpha (i - uc),
    s alpha e^(+-a) (e^(+-alpha) - 1 -+ alpha) / (2 alpha^2) and the mirror terms), half a cell a
    side where even; one side only on the lattice's boundary."""
    sp = lat.spacing
    v = float(1.0)
    for k in range(3):
        lo_side = wp.where(node[k] > 0.0, 1.0, 0.0)
        hi_side = wp.where(node[k] < float(lat.n - 1), 1.0, 0.0)
        al = sp.alpha[k]
        if al == 0.0:
            v *= 0.5 * (lo_side + hi_side) * (lat.hi[k] - lat.lo[k]) / float(lat.n - 1)
        else:
            a = al * (node[k] - sp.uc[k])
            up = wp.exp(al) - 1.0 - al  # int_0^1 (1 - v) e^(alpha v) dv alpha^2
            down = wp.exp(-al) - 1.0 + al
            right = 0.5 * (wp.exp(a) * up + wp.exp(-a) * down)
            left = 0.5 * (wp.exp(a) * down + wp.exp(-a) * up)
            v *= sp.s[k] * (lo_side * left + hi_side * right) / al
    return v


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
                        axis: wp.vec3, dist: float, volume: float, sig: wp.vec3, k: int):
    """Direction k of NEAR_DIRECTIONS from the light over the node's hat (a Fibonacci set on the cap
    of ``hat_cap``) and the light it carries into the hat, per unit solid angle and hat volume:
    int hat(p + r w) I(w) e^(-sigma (r - d)) dr (omega / K) / int hat dV, sigma the extinction at
    the node and d its distance to the light (the node's own shadow ray takes the rest),
    midpoints along the chord."""
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
                fall = wp.vec3(wp.exp(-sig[0] * (rr - dist)), wp.exp(-sig[1] * (rr - dist)),
                               wp.exp(-sig[2] * (rr - dist)))
                acc += (hw * dd * dd) * wp.cw_mul(e, fall)
        acc = acc * (dr * 2.0 * PI * (1.0 - cos_max) / (float(NEAR_DIRECTIONS) * volume))
    return w, acc


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
                 shadow_steps: int, q_out: wp.array(dtype=wp.vec3)):
    """Q_1 of the lights at node q for every direction (direction-major): sum_l sigma_s
    p(-w_l . w_d) E_l T_l. The trilinear interpolant's integral is the nodes' values times their
    hats' volumes, so a node near a point or spot light takes the source averaged over its hat
    (``hat_light_direction``: the 1/d^2 peak is integrable, a node's own value is not, and half
    the light a thick fog scatters first lies within a cell of the light), each direction from
    the light scattered by its own angle; farther nodes, and every node of a graded lattice
    (whose hats are not those of even cells; measured, they dim the image), take 1/d^2 averaged
    over a ball of half a cell."""
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
        if lat.graded == 0 and near_light(lat, node, lights[l]):
            tr = light_transmittance(m, s, x, wi, dist, 0, rng, shadow_steps)
            if wp.max(tr) > 0.0:
                lo, hi, cos_max, axis, d_light = hat_cap(lat, node, lights[l], x)
                volume = hat_volume(lat, node)
                for k in range(NEAR_DIRECTIONS):
                    w, carried = hat_light_direction(lat, node, lights[l], lo, hi, cos_max, axis, d_light, volume,
                                                     sigma_t[q], k)
                    if wp.max(carried) > 0.0:
                        add_scattered(m, lat, sigma_s, phase_count, n3, q, w, wp.cw_mul(carried, tr), q_out)
            continue
        if lights[l].kind != DIRECTIONAL:
            cell = 0.5 * wp.length(cell_size(lat, x))  # the half cell 1/d^2 is averaged over: finite at the light
            e = e * (dist * dist) * ball_mean_inverse_square(cell, dist)
        if wp.max(e) > 0.0:
            et = wp.cw_mul(e, light_transmittance(m, s, x, wi, dist, 0, rng, shadow_steps))
            if wp.max(et) > 0.0:
                add_scattered(m, lat, sigma_s, phase_count, n3, q, -wi, et, q_out)


@wp.func
def cell_step(width: wp.vec3, w: wp.vec3) -> float:
    """The length along w that crosses one cell of these widths on no axis more than once."""
    return wp.min(wp.min(width[0] / wp.max(wp.abs(w[0]), 1.0e-6), width[1] / wp.max(wp.abs(w[1]), 1.0e-6)),
                  width[2] / wp.max(wp.abs(w[2]), 1.0e-6))


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


def light_positions(scene) -> list[np.ndarray]:
    """Where the point and spot lights are (directional lights have no position)."""
    return [np.asarray(li.position, np.float64) for li in scene.lights if li.type in ("point", "spot")]


def _first_hit(vertices: np.ndarray, faces: np.ndarray, o: np.ndarray, d: np.ndarray) -> float:
    """Distance along o + t d to the nearest triangle (Moller-Trumbore over all of them), or inf."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    e1, e2 = b - a, c - a
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - a
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
    return float(t[hit].min()) if np.any(hit) else np.inf


#: How far inside an enclosing wall the lattice stops, as a fraction of the enclosure's size.
WALL_INSET = 0.005


def enclosed(scene, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lattice's bounds, the media's cut back to the walls that enclose the lights: where a
    ray from the point and spot lights' centroid along an axis meets a surface at the surfaces'
    bounding box and the media reach past it (a Cornell box around Gaussians whose tails pass
    its walls), the bound stops just inside that wall. Nodes beyond a wall would hold the dark
    outside and, interpolated across the wall, darken the light inside (trilinear lookups do
    not know about surfaces); an open side (the Cornell box's front) keeps the media's bound."""
    lights = light_positions(scene)
    if not lights or not scene.surfaces:
        return lo, hi
    vertices = np.concatenate([np.asarray(sf.vertices, np.float64) for sf in scene.surfaces])
    offsets = np.cumsum([0] + [len(sf.vertices) for sf in scene.surfaces[:-1]])
    faces = np.concatenate([np.asarray(sf.faces, np.int64) + k for sf, k in zip(scene.surfaces, offsets)])
    box_lo, box_hi = vertices.min(axis=0), vertices.max(axis=0)
    inset = WALL_INSET * float(np.max(box_hi - box_lo))
    o = np.mean(lights, axis=0)
    lo, hi = lo.copy(), hi.copy()
    for a in range(3):
        for sign, face in ((-1.0, box_lo[a]), (1.0, box_hi[a])):
            d = np.zeros(3)
            d[a] = sign
            t = _first_hit(vertices, faces, o, d)
            if not np.isfinite(t) or abs(o[a] + sign * t - face) > inset:
                continue  # open, or the first surface that way is not the enclosure's wall
            if sign < 0 and lo[a] < face - inset:  # the media pass the wall (not merely meet it)
                lo[a] = face + inset
            elif sign > 0 and hi[a] > face + inset:
                hi[a] = face - inset
    return lo, hi


#: The lattice grades its nodes on an axis where an even cell would span more than GRADE_CELL mean
#: free paths and the media are wider than GRADE_ABOVE times the region that matters (``focus``):
#: e.g. a light inside fog that fills the world, where an even lattice's cells are wider than
#: everything the camera sees, or a point light in thick fog, whose first scattering lies within
#: a cell of it.
GRADE_ABOVE = 2.0
GRADE_CELL = 0.5
#: With the eye inside the media, an axis is graded only where an even cell is also wider than
#: this many times the focus (the nodes could not resolve what the camera sees at all: a lamp in
#: fog that fills the world, cells 5 times the focus); where even cells come near resolving it,
#: grading measured worse (a box of fog 9 mean free paths wide around the camera: 0.34 graded,
#: 0.13 even).
GRADE_EYE_CELLS = 2.0
#: The focus's reach around the eye and the lights (the camera inside the media) and around the
#: lights alone (the camera outside: it sees the media's near side, lit by what spreads from the
#: lights), in mean free paths.
FOCUS_FREE_PATHS = 0.1
FOCUS_LIGHT_FREE_PATHS = 0.5


def focus(scene, lo: np.ndarray, hi: np.ndarray) -> tuple:
    """The box that matters most to the image, the mean free path's extinction there (the
    thinnest homogeneous medium's) and whether the eye is inside: with the camera's eye inside
    the lattice's bounds [lo, hi], the eye and the point and spot lights FOCUS_FREE_PATHS mean
    free paths around; with it outside, the lights FOCUS_LIGHT_FREE_PATHS around (lights inside
    the bounds only).
    (None, None, 0, False) where the media are not all homogeneous (a grid's or a cloud's own
    size is its set-up) or no box is left."""
    if not scene.media or any(mm.type != "homogeneous" for mm in scene.media):
        return None, None, 0.0, False
    sigma = min(float(np.min(mm.sigma_t)) for mm in scene.media)
    if sigma <= 0.0:
        return None, None, 0.0, False
    eye = np.asarray(scene.camera.origin, np.float64)
    # lights outside the media light them from their surface, no focus of their own
    lights = [p for p in light_positions(scene) if np.all(p >= lo) and np.all(p <= hi)]
    inside = bool(np.all(eye >= lo) and np.all(eye <= hi))
    if inside:
        points, reach = np.array([eye] + lights), FOCUS_FREE_PATHS / sigma
    elif lights:
        points, reach = np.array(lights), FOCUS_LIGHT_FREE_PATHS / sigma
    else:
        return None, None, 0.0, False
    return points.min(axis=0) - reach, points.max(axis=0) + reach, sigma, inside


def graded_spacing(lo: np.ndarray, hi: np.ndarray, n: int, flo, fhi, sigma: float, eye: bool = False):
    """Per axis (c, s, alpha, uc) of ``Spacing``: even (alpha 0) unless an even cell would span
    more than GRADE_CELL mean free paths (1 / sigma) and the media's extent is over GRADE_ABOVE
    times the focus box's (clipped to them), and, the ``eye`` inside the media, the cell over
    GRADE_EYE_CELLS times the focus box; then node u at c + s sinh(alpha (u - uc)), centred
    on the focus box with s its half width, so the focus gets cells of about s alpha and the far
    media cells growing geometrically, and the nodes still span [lo, hi]."""
    zero = np.zeros(3)
    c, s, alpha, uc = zero.copy(), np.ones(3), zero.copy(), zero.copy()
    if flo is None or n < 2:
        return c, s, alpha, uc
    flo, fhi = np.maximum(flo, lo), np.minimum(fhi, hi)
    for a in range(3):
        width = fhi[a] - flo[a]
        cell = (hi[a] - lo[a]) / (n - 1)
        if (width <= 0.0 or hi[a] - lo[a] <= GRADE_ABOVE * width or cell * sigma <= GRADE_CELL
                or (eye and cell <= GRADE_EYE_CELLS * width)):
            continue
        c[a], s[a] = 0.5 * (flo[a] + fhi[a]), 0.5 * width
        a0, a1 = np.arcsinh((lo[a] - c[a]) / s[a]), np.arcsinh((hi[a] - c[a]) / s[a])
        alpha[a] = (a1 - a0) / (n - 1)
        uc[a] = -a0 / alpha[a]
    return c, s, alpha, uc


def check_settings(technique: str, settings: dict) -> None:
    if settings["multiple_scattering"] == 1:
        raise SettingsError(f"{technique}: setting multiple_scattering=1 has no interior (allowed: 0 or 2..64)")


def leaves_out(settings: dict) -> tuple[str, ...]:
    """What a marcher's model leaves out with these settings."""
    return (LEFT_OUT_WITH,) if settings["multiple_scattering"] else (LEFT_OUT_WITHOUT,)


class MultipleScattering:
    """The solver's buffers and stages for one technique (see the module docstring).

    ``media``: a callable giving the technique's ``Media`` struct, or None (the solver then
    uploads the scene's media itself); ``surfaces`` and ``lights``: callables giving the
    uploaded ``Surfaces`` struct and lights array. ``stages()`` are ``multiple`` (the solve:
    reads the medium, lights, surfaces and sky) and ``multiple_view`` (R toward the camera);
    a march lists ``multiple_view`` in its ``after`` and passes ``struct()`` to its kernel."""

    def __init__(self, technique, surfaces, lights, media=None):
        self.t = technique
        self._surfaces, self._lights, self._media = surfaces, lights, media
        self._own_media = None
        self.L = None  # L_{>=1}: n^3 x D
        self.view = None
        self.orders = 0  # orders iterated before the tail
        self.ratio = np.zeros(3)  # the last ratio of successive orders
        self.sigma_s = None

    @property
    def n(self) -> int:
        return self.t.settings["multiple_scattering"] if self.t.scene.media else 0

    @property
    def shadow_steps(self) -> int:
        """Midpoints of the solve's shadow rays through grid media (and of the sky's along a
        surface's normal): two a node."""
        return max(2 * self.n, 16)

    def stages(self, after: tuple[str, ...]) -> list[Stage]:
        needed = self.n > 0
        sky = ("sky_samples",) if "sky_samples" in self.t.settings else ()
        return [
            Stage("multiple", self._solve, reads=("medium", "lights", "surfaces", "background"),
                  settings=("multiple_scattering", "ms_directions", *sky), after=after, needed=needed),
            Stage("multiple_view", self._view, reads=("camera",), settings=("multiple_scattering",),
                  after=("multiple",), needed=needed),
        ]

    def media_struct(self) -> Media:
        if self._media is not None:
            return self._media()
        if self._own_media is None or self._own_media[0] is not self.t.scene.media:
            self._own_media = (self.t.scene.media, MediaBuffers(self.t.scene, self.t.device))
        return self._own_media[1].struct

    def _lattice(self, m: Media) -> Lattice:
        n, D = self.n, self.t.settings["ms_directions"]
        lat = Lattice()
        lat.n = n
        lo, hi = np.array(m.all_min, np.float64), np.array(m.all_max, np.float64)
        pad = LATTICE_PAD * max(float(np.max(hi - lo)), 1.0e-6)
        lo, hi = enclosed(self.t.scene, lo - pad, hi + pad)
        lat.lo, lat.hi = wp.vec3(*lo), wp.vec3(*hi)
        c, s, alpha, uc = graded_spacing(lo, hi, n, *focus(self.t.scene, lo, hi))
        lat.spacing = Spacing()
        lat.spacing.c, lat.spacing.s, lat.spacing.alpha, lat.spacing.uc = (wp.vec3(*v) for v in (c, s, alpha, uc))
        lat.graded = int(np.any(alpha > 0.0))
        # exact coefficients where every medium is homogeneous (cheap to read, and a sphere's edge
        # blurred over a cell dimmed a thick sphere lit from outside by 20%); not on graded lattices,
        # whose far cells, wider than the fog's own features, measured better interpolated
        lat.exact = int(lat.graded == 0 and all(mm.type == "homogeneous" for mm in self.t.scene.media))
        lat.directions = wp.array(fibonacci_directions(D), dtype=wp.vec3, device=self.t.device)
        return lat

    def _solve(self):
        device, scene = self.t.device, self.t.scene
        m = self.media_struct()
        lat = self._lattice(m)
        self.lattice = lat
        n3, D, M = lat.n**3, lat.directions.shape[0], len(scene.media)
        size = n3 * D
        sigma_t = wp.empty(n3, dtype=wp.vec3, device=device)
        self.sigma_s = wp.empty(n3 * M, dtype=wp.vec3, device=device)
        dev.launch(bake_scattering, n3, [m, lat, sigma_t, self.sigma_s], device, work=8.0 * M)
        P = wp.empty(M * D * D, dtype=float, device=device)
        dev.launch(phase_matrix, M * D, [m, lat.directions, P], device, work=2.0 * D)
        lights, surfaces = self._lights(), self._surfaces()
        shadow_steps = self.shadow_steps
        ends = Ends()
        ends.length = wp.empty(size, dtype=float, device=device)
        ends.point = wp.zeros(size, dtype=wp.vec3, device=device)
        ends.normal = wp.zeros(size, dtype=wp.vec3, device=device)
        ends.face = wp.empty(size, dtype=int, device=device)
        ends.start = wp.empty(size, dtype=wp.vec3, device=device)
        dev.launch(characteristics, size, [m, surfaces, lights, lat, wp.vec3(*scene.background), shadow_steps, ends],
                   device, work=4.0 + lights.shape[0])
        reflects = bool(scene.surfaces) and bool(np.any(ends.face.numpy() >= 0))
        source = wp.empty(size, dtype=wp.vec3, device=device)
        dev.launch(light_source, n3, [m, surfaces, lights, lat, sigma_t, self.sigma_s, M, shadow_steps, source],
                   device, work=max(1, lights.shape[0]) * (4.0 * lat.n + D))
        L = wp.empty(size, dtype=wp.vec3, device=device)
        starts = wp.zeros(size, dtype=wp.vec3, device=device)  # what each characteristic starts with, this order
        march = 2.0 * lat.n
        total = wp.zeros(size, dtype=wp.vec3, device=device)
        one = wp.vec3(1.0, 1.0, 1.0)
        sky = any(c > 0.0 for c in scene.background)
        if sky or scene.surfaces:
            # L_0: the sky and the surfaces' reflected direct light; scattered once, it joins Q_1
            dev.launch(transport, size, [m, lat, sigma_t, source, ends.length, ends.start, 0, L], device, work=march)
            dev.launch(scatter, size, [lat, self.sigma_s, P, M, L, 1, source], device, work=M * D)
            if reflects:
                dev.launch(reflect_at_ends, size, [surfaces, lat, ends, L, starts], device, work=D)
            # L_0 joins the total where the march does not gather it itself: always the surfaces'
            # part (the fog lit by the walls, a wall by the others), the sky's unless the
            # technique gathers the sky's single scattering (raymarch's sky_samples)
            if sky and scene.surfaces and self.t.gathers_sky:
                dev.launch(surface_starts, size, [ends], device)
                dev.launch(transport, size, [m, lat, sigma_t, source, ends.length, ends.start, 0, L], device,
                           work=march)
            if scene.surfaces or not self.t.gathers_sky:
                dev.launch(add_order, size, [L, one, total], device)
        previous, ratio, total_energy = None, np.zeros(3), np.zeros(3)
        for k in range(1, MAX_ORDERS + 1):
            dev.launch(transport, size, [m, lat, sigma_t, source, ends.length, starts, 1, L], device, work=march)
            dev.launch(add_order, size, [L, one, total], device)
            energy = L.numpy().reshape(-1, 3).sum(axis=0, dtype=np.float64)
            total_energy = total_energy + energy
            self.orders = k
            if previous is not None:
                r = np.where(previous > 0.0, energy / np.maximum(previous, 1e-300), 0.0)
                # a ratio at the cap (light still spreading, order after order, as early in an
                # albedo-1 medium) is no ratio to extrapolate from: iterate on
                change = np.abs(r - ratio)
                # or the tail's uncertainty from that change, L_k dr / (1 - r)^2, is a small part of the whole
                settled = np.all(r < MAX_RATIO) and (np.all(change <= SETTLED * np.maximum(r, 1e-12)) or np.all(
                    change * energy <= TAIL_SETTLED * (1.0 - r) ** 2 * total_energy))
                done = np.all(energy <= 1.0e-6 * total_energy) or settled
                ratio = r
                if done:
                    break
            previous = energy
            if not np.any(energy > 0.0):
                break
            dev.launch(scatter, size, [lat, self.sigma_s, P, M, L, 0, source], device, work=M * D)
            if reflects:
                dev.launch(reflect_at_ends, size, [surfaces, lat, ends, L, starts], device, work=D)
        self.ratio = np.clip(ratio, 0.0, MAX_RATIO)
        if np.any(self.ratio > 0.0):  # the geometric tail of the orders not iterated
            tail = self.ratio / (1.0 - self.ratio)
            dev.launch(add_order, size, [L, wp.vec3(*tail), total], device)
        self.L = total
        self._m = m

    def _view(self):
        lat = self.lattice
        n3 = lat.n**3
        self.view = wp.empty(n3, dtype=wp.vec3, device=self.t.device)
        eye = wp.vec3(*self.t.scene.camera.origin)
        dev.launch(toward_eye, n3, [self._m, lat, self.sigma_s, len(self.t.scene.media), self.L, eye, self.view],
                   self.t.device, work=2.0 * lat.directions.shape[0])

    def struct(self) -> ScatteredLight:
        sl = ScatteredLight()
        if self.n > 0 and self.view is not None:
            sl.lat, sl.values, sl.field = self.lattice, self.view, self.L
            # the sky on surfaces beyond the field, unless the technique gathers the sky itself
            sl.sky = wp.vec3(0.0) if self.t.gathers_sky else wp.vec3(*self.t.scene.background)
        else:
            sl.lat = Lattice()
            sl.lat.n, sl.lat.graded, sl.lat.exact, sl.lat.spacing = 0, 0, 0, Spacing()
            sl.values = sl.field = sl.lat.directions = wp.zeros(1, dtype=wp.vec3, device=self.t.device)
        return sl

    def diagnostics(self) -> dict:
        return {"ms_orders": self.orders, "ms_tail_ratio": [float(r) for r in self.ratio]} if self.n else {}
