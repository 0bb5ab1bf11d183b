"""The multiple-scattering lattice's nodes: n^3 of them on the corners of a box, spread evenly
or graded (``graded_spacing``) per axis; coordinates, cell widths and trilinear lookups (``Warp``
functions the solve and the marches call), and where the lattice lies in a scene: the media's
bounds cut back to the walls that enclose the lights (``enclosed``) and the region that
matters most to the image (``focus``)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..media.grid import lattice_at_vec3
from ..scene.model import LightKind, MediumKind


LATTICE_PAD = 1.0e-4  # the lattice's bounds pass the media's by this part of their extent


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
def inside_margin(lo: wp.vec3, hi: wp.vec3, margin: float, p: wp.vec3) -> bool:
    return (p[0] >= lo[0] - margin and p[1] >= lo[1] - margin and p[2] >= lo[2] - margin and
            p[0] <= hi[0] + margin and p[1] <= hi[1] + margin and p[2] <= hi[2] + margin)


@wp.func
def corner_weight(lat: Lattice, q: int, w: float, p: wp.vec3, n: wp.vec3) -> float:
    """A trilinear weight w of node q, or 0 where the node lies behind the plane through p
    with normal n."""
    return wp.where(wp.dot(node_position(lat, q) - p, n) >= 0.0, w, 0.0)


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
def cell_step(width: wp.vec3, w: wp.vec3) -> float:
    """The length along w that crosses one cell of these widths on no axis more than once."""
    return wp.min(wp.min(width[0] / wp.max(wp.abs(w[0]), 1.0e-6), width[1] / wp.max(wp.abs(w[1]), 1.0e-6)),
                  width[2] / wp.max(wp.abs(w[2]), 1.0e-6))


def light_positions(scene) -> list[np.ndarray]:
    """Where the point and spot lights are (directional lights have no position)."""
    return [np.asarray(li.position, np.float64) for li in scene.lights if li.type in (LightKind.POINT, LightKind.SPOT)]


def _first_hit(vertices: np.ndarray, faces: np.ndarray, o: np.ndarray, d: np.ndarray) -> tuple[float, int]:
    """Distance along o + t d to the nearest triangle (Moller-Trumbore over all of them) and its
    index, or (inf, -1)."""
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
    if not np.any(hit):
        return np.inf, -1
    k = int(np.argmin(np.where(hit, t, np.inf)))
    return float(t[k]), k


#: How far inside an enclosing wall the lattice stops, as a fraction of the enclosure's size.
WALL_INSET = 0.005
#: A surface is an enclosing wall only where it spans this part of the surfaces' bounding box on
#: both of the other axes: a lamp's arm just above it (a street lamp) is no wall, and cutting the
#: lattice there left the fog above the lamp without nodes (a band twice the physical light).
WALL_SPAN = 0.9


def enclosed(scene, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lattice's bounds, the media's cut back to the walls that enclose the lights: where a
    ray from the point and spot lights' centroid along an axis meets a surface at the surfaces'
    bounding box and the media reach past it (a Cornell box around Gaussians whose tails pass
    its walls), the bound stops just inside that wall. Nodes beyond a wall would hold the dark
    outside and, interpolated across the wall, darken the light inside (trilinear lookups do
    not know about surfaces); an open side (the Cornell box's front) keeps the media's bound, and
    so does a side whose first surface spans less than WALL_SPAN of the surfaces' box (no wall)."""
    lights = light_positions(scene)
    if not lights or not scene.surfaces:
        return lo, hi
    vertices = np.concatenate([np.asarray(sf.vertices, np.float64) for sf in scene.surfaces])
    offsets = np.cumsum([0] + [len(sf.vertices) for sf in scene.surfaces[:-1]])
    faces = np.concatenate([np.asarray(sf.faces, np.int64) + k for sf, k in zip(scene.surfaces, offsets)])
    owner = np.concatenate([np.full(len(sf.faces), i) for i, sf in enumerate(scene.surfaces)])
    spans = [np.ptp(np.asarray(sf.vertices, np.float64), axis=0) for sf in scene.surfaces]
    box_lo, box_hi = vertices.min(axis=0), vertices.max(axis=0)
    inset = WALL_INSET * float(np.max(box_hi - box_lo))
    o = np.mean(lights, axis=0)
    lo, hi = lo.copy(), hi.copy()
    for a in range(3):
        for sign, face in ((-1.0, box_lo[a]), (1.0, box_hi[a])):
            d = np.zeros(3)
            d[a] = sign
            t, k = _first_hit(vertices, faces, o, d)
            if not np.isfinite(t) or abs(o[a] + sign * t - face) > inset:
                continue  # open, or the first surface that way is not the enclosure's wall
            others = [b for b in range(3) if b != a]
            if np.any(spans[owner[k]][others] < WALL_SPAN * (box_hi - box_lo)[others]):
                continue  # a small surface near the bound (a lamp's arm), not a wall
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
    if not scene.media or any(mm.type != MediumKind.HOMOGENEOUS for mm in scene.media):
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
