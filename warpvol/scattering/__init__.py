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
lattice's box and the sky where one misses it (``reflected_from_outside``). Everything
converges to the all-orders answer as the nodes and directions rise (error ~ 1/n, 1/D), up to the light leaking through surfaces
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

Modules: ``lattice`` (the nodes: their spacing, coordinates and cells, and where the lattice
lies in a scene), ``kernels`` (the solve's kernels and what a march reads), this one (the
settings and ``MultipleScattering``, the stages a technique adds).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .. import device as dev
from ..physics.sphere import fibonacci_directions
from ..pipeline import FLAG, Bias, Frame, Setting, SettingsError, Stage
from ..scene.model import MediumKind
from ..media.volume import Media
from ..upload import MediaBuffers
from .kernels import (Ends, ScatteredLight, add_order, bake_scattering, characteristics, light_source, phase_matrix,
                      reflect_at_ends, reflected_field, reflected_from_outside, scatter, scattered_light,
                      scattered_on_surface, surface_starts, toward_eye, transport)
from .lattice import LATTICE_PAD, Lattice, Spacing, enclosed, focus, graded_spacing
from .near import NearLights
from .near import empty as near_empty

__all__ = ["BIASES", "SETTINGS", "Lattice", "MultipleScattering", "ScatteredLight", "Spacing", "check_settings",
           "leaves_out", "reflected_field", "reflected_from_outside", "scattered_light", "scattered_on_surface"]

SETTINGS = {
    "multiple_scattering": Setting(8, 0, 64, "nodes per axis of the lattice light scattered more than once is "
                                               "solved on (orders 2 and up); 0: single scattering only, the "
                                               "paper's model"),
    "ms_directions": Setting(16, 6, 256, "directions of the multiple-scattering lattice's radiance (a Fibonacci "
                                          "set); error ~ 1/directions"),
    "ms_near": Setting(1, 0, 1, "on: a point light inside homogeneous fog has the light it scatters first within a "
                                "window around it carried in closed form, the rest on the lattice (a "
                                "first-collision split); off: all of it on the lattice", names=FLAG),
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

MAX_ORDERS = 64  # source iterations before the geometric tail, at most
SETTLED = 0.01  # the ratio of successive orders counts as settled when it changes by less than this
TAIL_SETTLED = 0.01  # ... or when the tail's uncertainty from that change is under this part of the energy
MAX_RATIO = 0.995  # rho above this is taken as this in the tail (albedo 1 in an unbounded medium)
EYE_CELLS = 1.5  # within this many cells of the eye a march takes R with its own direction to the eye


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
        self.ratios: list[float] = []  # each order's energy over the last's (channels' mean), as iterated
        self.sigma_s = None

    @classmethod
    def over(cls, technique, uploads, media: bool = True) -> "MultipleScattering":
        """The solver over a technique's scene uploads (``upload.SceneUploads``): its surfaces, its
        lights and, with ``media``, its media struct, each read when a stage runs."""
        return cls(technique, lambda: uploads.surfaces, lambda: uploads.lights,
                   (lambda: uploads.media.struct) if media else None)

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
                  settings=("multiple_scattering", "ms_directions", "ms_near", *sky), after=after, needed=needed),
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
        lat.exact = int(lat.graded == 0 and all(mm.type == MediumKind.HOMOGENEOUS for mm in self.t.scene.media))
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
        self.near = NearLights(scene if self.t.settings["ms_near"] else None, m, lights.shape[0],
                               lambda p: self._cell_at(lat, p), device)
        window = wp.array(self.near.rho, dtype=float, device=device)
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
        dev.launch(light_source, n3, [m, surfaces, lights, lat, sigma_t, self.sigma_s, M, shadow_steps, window, source],
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
        self.ratios = []
        # the windowed lights' first order: the march reads it itself, the next orders and the surfaces take it
        near_first = self.near.first_order(lat, size)
        for k in range(1, MAX_ORDERS + 1):
            dev.launch(transport, size, [m, lat, sigma_t, source, ends.length, starts, 1, L], device, work=march)
            dev.launch(add_order, size, [L, one, total], device)
            if k == 1 and near_first is not None:
                dev.launch(add_order, size, [near_first, one, L], device)
            energy = L.numpy().reshape(-1, 3).sum(axis=0, dtype=np.float64)
            total_energy = total_energy + energy
            self.orders = k
            if previous is not None:
                r = np.where(previous > 0.0, energy / np.maximum(previous, 1e-300), 0.0)
                self.ratios.append(float(np.mean(r)))
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
        self.L = total  # what the view reads: the windowed lights' first order is the march's own
        if near_first is not None:  # the surfaces read it on the lattice
            self.field = wp.clone(total)
            dev.launch(add_order, size, [near_first, one, self.field], device)
        else:
            self.field = total
        self._m = m

    def _cell_at(self, lat: Lattice, p: np.ndarray) -> float:
        """The lattice's widest cell around p (``lattice.cell_size`` on the host: p held to the
        lattice's bounds, as there)."""
        sp = lat.spacing
        lo, hi = np.array(lat.lo, np.float64), np.array(lat.hi, np.float64)
        s, alpha, c = (np.array(v, np.float64) for v in (sp.s, sp.alpha, sp.c))
        even = (hi - lo) / (lat.n - 1)
        graded = s * alpha * np.sqrt(1.0 + ((np.clip(p, lo, hi) - c) / s) ** 2)
        return float(np.max(np.where(alpha > 0.0, graded, even)))

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
            sl.lat, sl.values, sl.field = self.lattice, self.view, self.field
            eye = np.asarray(self.t.scene.camera.origin, np.float64)
            sl.near = self.near.field
            sl.m, sl.view_field, sl.eye = self._m, self.L, wp.vec3(*eye)
            sl.eye_reach = EYE_CELLS * self._cell_at(self.lattice, eye)
            # the sky on surfaces beyond the field, unless the technique gathers the sky itself
            sl.sky = wp.vec3(0.0) if self.t.gathers_sky else wp.vec3(*self.t.scene.background)
        else:
            sl.lat = Lattice()
            sl.lat.n, sl.lat.graded, sl.lat.exact, sl.lat.spacing = 0, 0, 0, Spacing()
            sl.values = sl.field = sl.lat.directions = wp.zeros(1, dtype=wp.vec3, device=self.t.device)
            sl.near = near_empty(self.t.device)
            sl.m, sl.view_field, sl.eye, sl.eye_reach = Media(), sl.values, wp.vec3(0.0), 0.0
        return sl

    def diagnostics(self) -> dict:
        if not self.n:
            return {}
        return {"ms_orders": self.orders, "ms_tail_ratio": [float(r) for r in self.ratio],
                "ms_order_ratios": [round(r, 4) for r in self.ratios],
                "ms_near_lights": int(np.count_nonzero(self.near.rho)) if getattr(self, "near", None) else 0}
