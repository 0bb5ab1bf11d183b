"""The near field of point lights in homogeneous fog: a first-collision split.

Light scattered once around a point light falls off like 1/r (its radiance toward the light
like 1/(r theta)): a trilinear lattice of cells wider than that region cannot hold it, and a few
fixed directions carry what a lamp's neighbourhood scatters as beams (ray effects). As transport
codes do with a point source (the first-collision source, e.g. Alcouffe's "first collision
source method" for S_N codes), the light's first scattering is split by a window around the
light, w(r) = (1 - (r / rho)^2)^2 inside the radius rho, 0 beyond:

* the smooth remainder, the source times (1 - w) (bounded at the light: 2 / rho^2 times
  I sigma_s p), stays on the lattice as every other source;
* the windowed part's once-scattered radiance L1(r, nu) (nu the cosine between the
  radiance's direction and the direction from the light) is integrated here in closed
  geometry, an unbounded medium of the light's own coefficients: equiangular quadrature along
  the ray (Kulla & Fajardo, EGSR 2012), whose Jacobian cancels the 1/d^2 of the light;
* what a march needs of it is the light it scatters toward the eye, sigma_s G(r, mu) with
  G(r, mu) = int p(w . wo) L1 dw = int L1(r, nu) K(nu, mu) dnu, K the phase function
  integrated over the azimuth about the direction from the light (mu: the cosine between it
  and wo). G is a table per light over (log r, mu), read bilinearly a march step
  (``near_in_scatter``); L1 joins the lattice's first order at its nodes (``near_at_nodes``), so
  the orders after it (and the surfaces) take it as every other radiance.

The window is taken where the light lies inside homogeneous media only and the window's
ball lies inside them (its radius is also held to the distance to the media's boundary and to
every surface, as the closed geometry sees neither), and at least a cell of the lattice wide;
elsewhere the light's source stays on the lattice as before.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .. import device as dev
from ..media.volume import Media, coefficients_at
from ..physics.constants import PI
from ..physics.phase import phase_eval
from ..scene.model import LightKind, MediumKind
from .lattice import Lattice, hat_weight, node_index, node_position, support_corner

dev.kernel_module(__name__)

NEAR_R = 64  # the tables' radii, log-spaced over [R_MIN rho, rho + NEAR_REACH mean free paths]
NEAR_NU = 64  # directions of L1 about the direction from the light, midpoints in theta = acos(nu)
NEAR_MU = 33  # directions toward the eye, mu in [-1, 1]
NEAR_STEPS = 64  # equiangular midpoints along each ray
NEAR_PHI = 64  # azimuths of the phase kernel K
R_MIN = 1.0e-3  # the tables' first radius, in units of rho (closer: clamped)
NEAR_REACH = 8.0  # the tables' reach past the window, mean free paths; beyond, 1/r^2 e^(-sigma_t r)
WINDOW_CELLS = 2.0  # the window's radius in the lattice's widest cell at the light
#: The window may shrink to this many cells (to stay inside its medium and off the surfaces);
#: below it the light keeps its whole source on the lattice.
MIN_WINDOW_CELLS = 0.5
#: Surfaces smaller than this part of the window's full reach (their box's diagonal) do not limit
#: it: the closed geometry then leaves out their shadow inside the window (a street lamp's arm
#: 0.125 over the lamp shades a twelfth of its light), where without the window the lattice held
#: half the light scattered twice around the lamp.
SMALL_SURFACE = 1.0
HAT_POINTS = 4  # midpoints a side of a node's hat where L1 is averaged over it


@wp.struct
class NearField:
    """What a march reads of the windowed lights (``count`` of them; 0: none)."""

    count: int
    position: wp.array(dtype=wp.vec3)
    rho: wp.array(dtype=float)  # the window's radius
    r_max: wp.array(dtype=float)  # the tables' last radius
    sigma_t: wp.array(dtype=wp.vec3)  # the medium's at the light (the tables' fall-off beyond r_max)
    view: wp.array(dtype=wp.vec3)  # G, light-major, NEAR_R x NEAR_MU
    surface: wp.array(dtype=wp.vec3)  # E, the irradiance on a surface, light-major, NEAR_R x NEAR_MU


@wp.func
def window(r: float, rho: float) -> float:
    """w(r) = (1 - (r / rho)^2)^2 inside rho, 0 beyond: the part of a light's first scattering
    taken here (smooth, so the remainder 1 - w is smooth on the lattice)."""
    if r >= rho:
        return 0.0
    z = 1.0 - (r / rho) * (r / rho)
    return z * z


@wp.func
def far_part(r: float, rho: float) -> float:
    """(1 - w(r)) / r^2, the remainder's fall-off (bounded: 2 / rho^2 at the light)."""
    if rho <= 0.0:
        return 1.0 / wp.max(r * r, 1.0e-30)
    if r >= rho:
        return 1.0 / (r * r)
    z = (r / rho) * (r / rho)
    return (2.0 - z) / (rho * rho)


@wp.func
def radius_at(rho: float, r_max: float, i: float) -> float:
    """Table radius i (fractional), log-spaced from R_MIN rho to r_max."""
    r0 = R_MIN * rho
    return r0 * wp.exp(i / float(NEAR_R - 1) * wp.log(r_max / r0))


@wp.func
def radius_index(rho: float, r_max: float, r: float) -> float:
    r0 = R_MIN * rho
    return wp.log(wp.max(r, r0) / r0) / wp.log(r_max / r0) * float(NEAR_R - 1)


@wp.func
def theta_of(j: int) -> float:
    return (float(j) + 0.5) * PI / float(NEAR_NU)


@wp.kernel
def near_radiance(offset: int, m: Media, light: wp.vec3, intensity: wp.vec3, medium: int, rho: float,
                  r_max: float, out: wp.array(dtype=wp.vec3)):
    """L1(r_i, nu_j) of the windowed source (unit light at the origin; the medium's
    coefficients are those at the light): int_0^inf e^(-sigma_t s) sigma_s p(w . y^) I w(|y|)
    e^(-sigma_t |y|) / |y|^2 ds along y = x - s w, equiangular in the angle seen from the
    light, where ds / |y|^2 = dtheta / h."""
    tid = wp.tid() + offset
    i = tid / NEAR_NU
    j = tid % NEAR_NU
    r = radius_at(rho, r_max, float(i))
    nu = wp.cos(theta_of(j))
    sig_t, sig_s = coefficients_at(m, light)
    h = wp.max(r * wp.sqrt(wp.max(1.0 - nu * nu, 0.0)), 1.0e-6 * r)  # the ray's distance from the light
    closest = r * nu  # s where the ray passes closest to the light
    out[tid] = wp.vec3(0.0)
    if h < rho:
        half = wp.sqrt(rho * rho - h * h)
        s0 = wp.max(closest - half, 0.0)
        s1 = closest + half
        if s1 > s0:
            th0 = wp.atan2(s0 - closest, h)
            th1 = wp.atan2(s1 - closest, h)
            dth = (th1 - th0) / float(NEAR_STEPS)
            acc = wp.vec3(0.0)
            for k in range(NEAR_STEPS):
                th = th0 + (float(k) + 0.5) * dth
                s = closest + h * wp.tan(th)
                dy = wp.sqrt(h * h + (s - closest) * (s - closest))
                ph = phase_eval(m.phase[medium], m.phase_table, (closest - s) / dy)
                tau = (s + dy) * sig_t
                fall = wp.vec3(wp.exp(-tau[0]), wp.exp(-tau[1]), wp.exp(-tau[2]))
                acc += (ph * window(dy, rho)) * fall
            out[tid] = wp.cw_mul(wp.cw_mul(acc, sig_s), intensity) * (dth / h)


@wp.kernel
def azimuth_kernel(offset: int, m: Media, medium: int, cosine: int, out: wp.array(dtype=float)):
    """K(nu_j, mu_k) sin(theta_j) dtheta = int_0^2pi k(nu mu + sqrt(1 - nu^2) sqrt(1 - mu^2)
    cos phi) dphi sin(theta_j) pi / NEAR_NU: the weight of L1(., nu_j) in G(., mu_k), k the
    medium's phase function; with ``cosine``, k the clamped cosine max(0, .), the weight in the
    irradiance E(., mu_k) on a surface whose normal makes cos mu with the direction to the light
    (L1 travels at cos nu to the direction from the light, so it arrives at that cosine to the
    normal)."""
    tid = wp.tid() + offset
    j = tid / NEAR_MU
    k = tid % NEAR_MU
    th = theta_of(j)
    nu = wp.cos(th)
    mu = -1.0 + 2.0 * float(k) / float(NEAR_MU - 1)
    a = wp.sin(th) * wp.sqrt(wp.max(1.0 - mu * mu, 0.0))
    acc = float(0.0)
    for f in range(NEAR_PHI):
        phi = (float(f) + 0.5) * 2.0 * PI / float(NEAR_PHI)
        c = wp.clamp(nu * mu + a * wp.cos(phi), -1.0, 1.0)
        if cosine != 0:
            acc += wp.max(c, 0.0)
        else:
            acc += phase_eval(m.phase[medium], m.phase_table, c)
    out[tid] = acc * (2.0 * PI / float(NEAR_PHI)) * wp.sin(th) * (PI / float(NEAR_NU))


@wp.kernel
def near_view(offset: int, L1: wp.array(dtype=wp.vec3), K: wp.array(dtype=float), base: int,
              out: wp.array(dtype=wp.vec3)):
    """G(r_i, mu_k) = sum_j L1(r_i, nu_j) K_jk (``azimuth_kernel``; with its cosine: the irradiance E)."""
    tid = wp.tid() + offset
    i = tid / NEAR_MU
    k = tid % NEAR_MU
    acc = wp.vec3(0.0)
    for j in range(NEAR_NU):
        acc += L1[i * NEAR_NU + j] * K[j * NEAR_MU + k]
    out[base + tid] = acc


@wp.func
def table_at(values: wp.array(dtype=wp.vec3), base: int, cols: int, u: float, v: float) -> wp.vec3:
    """Bilinear lookup of a row-major (NEAR_R x cols) table at fractional (row u, column v),
    clamped to its edges."""
    u = wp.clamp(u, 0.0, float(NEAR_R - 1))
    v = wp.clamp(v, 0.0, float(cols - 1))
    i0 = wp.min(int(u), NEAR_R - 2)
    j0 = wp.min(int(v), cols - 2)
    a = u - float(i0)
    b = v - float(j0)
    p = base + i0 * cols + j0
    return ((1.0 - a) * ((1.0 - b) * values[p] + b * values[p + 1]) +
            a * ((1.0 - b) * values[p + cols] + b * values[p + cols + 1]))


@wp.func
def beyond(r: float, r_max: float, sigma_t: wp.vec3) -> wp.vec3:
    """Past the tables' reach the windowed light is a point source seen through the fog:
    (r_max / r)^2 e^(-sigma_t (r - r_max)) of its value at r_max."""
    if r <= r_max:
        return wp.vec3(1.0)
    f = (r_max / r) * (r_max / r)
    return wp.vec3(f * wp.exp(-sigma_t[0] * (r - r_max)), f * wp.exp(-sigma_t[1] * (r - r_max)),
                   f * wp.exp(-sigma_t[2] * (r - r_max)))


@wp.func
def near_in_scatter(nf: NearField, eye: wp.vec3, sigma_s: wp.vec3, x: wp.vec3) -> wp.vec3:
    """sigma_s(x) sum_l G_l(r, mu): the windowed lights' once-scattered light scattered toward
    the eye at x, per unit length."""
    out = wp.vec3(0.0)
    for l in range(nf.count):
        to = x - nf.position[l]
        r = wp.length(to)
        wo = eye - x
        mu = float(0.0)
        if r > 0.0 and wp.length(wo) > 0.0:
            mu = wp.dot(to / r, wp.normalize(wo))
        v = (mu + 1.0) * 0.5 * float(NEAR_MU - 1)
        g = table_at(nf.view, l * NEAR_R * NEAR_MU, NEAR_MU, radius_index(nf.rho[l], nf.r_max[l], r), v)
        out += wp.cw_mul(g, beyond(r, nf.r_max[l], nf.sigma_t[l]))
    return wp.cw_mul(sigma_s, out)


@wp.func
def near_on_surface(nf: NearField, p: wp.vec3, n: wp.vec3) -> wp.vec3:
    """sum_l E_l(r, mu): the irradiance at p, on a surface of normal n, of the windowed lights'
    once-scattered light, mu the cosine between n and the direction to the light (``azimuth_kernel``
    with its cosine). Read from the
    tables at p itself, not interpolated from the lattice's nodes, where a light's L1 grows like
    1/r toward it (a ceiling a third of a cell above a lamp read twice its light)."""
    out = wp.vec3(0.0)
    for l in range(nf.count):
        to = nf.position[l] - p
        r = wp.length(to)
        mu = float(1.0)
        if r > 0.0:
            mu = wp.dot(to / r, n)
        v = (mu + 1.0) * 0.5 * float(NEAR_MU - 1)
        e = table_at(nf.surface, l * NEAR_R * NEAR_MU, NEAR_MU, radius_index(nf.rho[l], nf.r_max[l], r), v)
        out += wp.cw_mul(e, beyond(r, nf.r_max[l], nf.sigma_t[l]))
    return out


@wp.func
def near_radiance_at(L1: wp.array(dtype=wp.vec3), position: wp.vec3, rho: float, r_max: float, sigma_t: wp.vec3,
                     y: wp.vec3, w: wp.vec3) -> wp.vec3:
    """L1 of one windowed light at y toward w, bilinear in (log r, theta)."""
    to = y - position
    r = wp.length(to)
    nu = float(1.0)
    if r > 0.0:
        nu = wp.dot(to / r, w)
    v = wp.acos(wp.clamp(nu, -1.0, 1.0)) / PI * float(NEAR_NU) - 0.5
    return wp.cw_mul(table_at(L1, 0, NEAR_NU, radius_index(rho, r_max, r), v), beyond(r, r_max, sigma_t))


@wp.kernel
def near_at_nodes(offset: int, lat: Lattice, position: wp.vec3, rho: float, r_max: float, sigma_t: wp.vec3,
                  L1: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    """Onto the lattice's first order (node-major, node q direction d): L1 of one windowed
    light. The interpolant's integral is the nodes' values times their hats' volumes, so a node
    whose hat reaches into the window, where L1 grows like 1/r, takes L1 averaged over its hat
    (HAT_POINTS midpoints a side, weighted by the hat); the rest its value at the node."""
    tid = wp.tid() + offset
    D = lat.directions.shape[0]
    q = tid / D
    w = lat.directions[tid % D]
    node = node_index(lat.n, q)
    x = node_position(lat, q)
    lo = support_corner(lat, node, -1.0)
    hi = support_corner(lat, node, 1.0)
    gap = wp.max(wp.max(lo - position, position - hi), wp.vec3(0.0))
    L = wp.vec3(0.0)
    if wp.length(gap) < rho:
        acc = wp.vec3(0.0)
        total = float(0.0)
        step = (hi - lo) / float(HAT_POINTS)
        for a in range(HAT_POINTS):
            for b in range(HAT_POINTS):
                for c in range(HAT_POINTS):
                    y = lo + wp.cw_mul(step, wp.vec3(float(a) + 0.5, float(b) + 0.5, float(c) + 0.5))
                    hw = hat_weight(lat, node, y)
                    if hw > 0.0:
                        acc += hw * near_radiance_at(L1, position, rho, r_max, sigma_t, y, w)
                        total += hw
        if total > 0.0:
            L = acc / total
    else:
        L = near_radiance_at(L1, position, rho, r_max, sigma_t, x, w)
    out[tid] = out[tid] + L


def empty(device) -> NearField:
    nf = NearField()
    nf.count = 0
    nf.position = nf.sigma_t = nf.view = nf.surface = wp.zeros(1, dtype=wp.vec3, device=device)
    nf.rho = nf.r_max = wp.zeros(1, dtype=float, device=device)
    return nf


class NearLights:
    """The windowed lights of one solve: their windows (``rho``: one per uploaded light, 0 where
    the light keeps its whole source on the lattice), their L1 tables and what a march reads
    (``field``: the lights' positions, windows and G tables). ``scene`` None: no windows (the
    setting ``ms_near`` off)."""

    def __init__(self, scene, media: Media, count: int, cell_at, device):
        self.device = device
        self.rho = np.zeros(max(count, 1), np.float32)
        self.L1: list = []
        self.at: list = []  # (medium index, position, rho, r_max, sigma_t) of each windowed light
        for li, light in enumerate(scene.lights if scene is not None else []):
            found = _window_for(scene, light, cell_at(np.asarray(light.position, np.float64)))
            if found is None:
                continue
            rho, medium, sigma_t = found
            r_max = rho + NEAR_REACH / max(float(np.min(sigma_t)), 1.0e-6)
            L1 = wp.empty(NEAR_R * NEAR_NU, dtype=wp.vec3, device=device)
            dev.launch(near_radiance, NEAR_R * NEAR_NU,
                       [media, wp.vec3(*light.position), wp.vec3(*light.strength), medium, rho, r_max, L1], device,
                       work=float(NEAR_STEPS))
            self.rho[li] = rho
            self.L1.append(L1)
            self.at.append((medium, np.asarray(light.position, np.float32), rho, r_max,
                            np.asarray(sigma_t, np.float32)))
        self.field = self._field(media) if self.at else empty(device)

    def _field(self, media: Media) -> NearField:
        """What a march reads, uploaded once a solve: the G tables (the azimuth kernel of each
        light's medium times its L1 table) and each light's position, window and reach."""
        d = self.device
        nf = NearField()
        nf.count = len(self.at)
        nf.view = wp.empty(nf.count * NEAR_R * NEAR_MU, dtype=wp.vec3, device=d)
        nf.surface = wp.empty(nf.count * NEAR_R * NEAR_MU, dtype=wp.vec3, device=d)
        K = wp.empty(NEAR_NU * NEAR_MU, dtype=float, device=d)
        C = wp.empty(NEAR_NU * NEAR_MU, dtype=float, device=d)
        dev.launch(azimuth_kernel, NEAR_NU * NEAR_MU, [media, 0, 1, C], d, work=float(NEAR_PHI))
        for k, (medium, *_) in enumerate(self.at):
            dev.launch(azimuth_kernel, NEAR_NU * NEAR_MU, [media, medium, 0, K], d, work=float(NEAR_PHI))
            dev.launch(near_view, NEAR_R * NEAR_MU, [self.L1[k], K, k * NEAR_R * NEAR_MU, nf.view], d,
                       work=float(NEAR_NU))
            dev.launch(near_view, NEAR_R * NEAR_MU, [self.L1[k], C, k * NEAR_R * NEAR_MU, nf.surface], d,
                       work=float(NEAR_NU))
        nf.position = wp.array([a[1] for a in self.at], dtype=wp.vec3, device=d)
        nf.rho = wp.array([a[2] for a in self.at], dtype=float, device=d)
        nf.r_max = wp.array([a[3] for a in self.at], dtype=float, device=d)
        nf.sigma_t = wp.array([a[4] for a in self.at], dtype=wp.vec3, device=d)
        return nf

    def first_order(self, lat: Lattice, size: int) -> wp.array | None:
        """The windowed lights' L1 at the lattice's nodes (node-major, ``size`` = n^3 D), or None
        where no light has a window."""
        if not self.at:
            return None
        L = wp.zeros(size, dtype=wp.vec3, device=self.device)
        for k, (medium, pos, rho, r_max, sig) in enumerate(self.at):
            dev.launch(near_at_nodes, size, [lat, wp.vec3(*pos), rho, r_max, wp.vec3(*sig), self.L1[k], L],
                       self.device, work=8.0)
        return L


def _window_for(scene, light, cell: float):
    """(rho, medium index, sigma_t) of a point light's window, or None where its source stays
    whole on the lattice: not a point light, the media not all homogeneous, not exactly one
    medium at the light, or less than MIN_WINDOW_CELLS of room to the medium's boundary or a
    surface (surfaces smaller than SMALL_SURFACE times the window's reach are not counted)."""
    if light.type != LightKind.POINT or not scene.media:
        return None
    if any(mm.type != MediumKind.HOMOGENEOUS for mm in scene.media):
        return None
    p = np.asarray(light.position, np.float64)
    inside = [(i, _room(mm, p)) for i, mm in enumerate(scene.media)]
    inside = [(i, room) for i, room in inside if room > 0.0]
    if len(inside) != 1:
        return None
    medium, room = inside[0]
    sigma_t = np.broadcast_to(np.asarray(scene.media[medium].sigma_t, np.float64), (3,))
    if np.min(sigma_t) <= 0.0:
        return None
    reach = WINDOW_CELLS * cell
    for sf in scene.surfaces:
        v = np.asarray(sf.vertices, np.float64)
        if np.linalg.norm(np.ptp(v, axis=0)) < SMALL_SURFACE * reach:
            continue  # a lamp's arm or a post: its shadow within the window is left out
        room = min(room, _distance_to_mesh(v, np.asarray(sf.faces), p))
    rho = min(reach, room)
    if rho < MIN_WINDOW_CELLS * cell:
        return None
    return float(rho), medium, sigma_t


def _room(mm, p: np.ndarray) -> float:
    """How far p lies inside a homogeneous medium's shape (<= 0: outside)."""
    c = np.asarray(mm.center, np.float64)
    if mm.shape == "sphere":
        return float(mm.radius - np.linalg.norm(p - c))
    half = 0.5 * np.asarray(mm.size, np.float64)
    return float(np.min(half - np.abs(p - c)))


def _distance_to_mesh(vertices: np.ndarray, faces: np.ndarray, p: np.ndarray) -> float:
    """A lower bound of the distance from p to a triangle mesh: to each triangle's bounding box."""
    tri = vertices[faces]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    gap = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    return float(np.min(np.linalg.norm(gap, axis=1))) if len(gap) else np.inf
