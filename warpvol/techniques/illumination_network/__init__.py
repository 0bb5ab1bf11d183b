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
  from zero); another cloud or direction set (count, directions, ``direction_seed``) starts
  from zero, as the last solution's columns belong to other directions. The stage settles once the relative L2 change of an iteration falls below
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

import numpy as np
import warp as wp

from ... import device as dev
from ...geometry.camera import camera_view
from ...geometry.tiles import bin_spheres
from ...media.lightpass import REPRESENTATIONS, LightPass
from ...media.particles import ParticleBuffers, Particles
from ...physics.constants import INV_4PI
from ...physics.phase import PhaseParams, phase_fn, phase_struct
from ...physics.sphere import fibonacci_directions
from ...pipeline import FLAG, Bias, Quality, Setting, SettingsError, Stage, Technique
from ...upload import SceneUploads, check_particle_scene, particle_buffers, pinhole
from .kernels import (ROWS, DirectLight, change_norms, composite, composite_march, emission_network, gather_update,
                      light_weights, outgoing_radiance, particle_extinction, rescale, scatter_matmul)
from .network import pad, peel
from .weights import tabulate_weights
from .window import network_window

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
    "warm": Setting(1, 0, 1, "1: start from the previous solution when the lights change; 0: from zero", names=FLAG),
    "half": Setting(0, 0, 1, "1: store I and E as float16, as the paper does", names=FLAG),
    "phase_norm": Setting(1, 0, 1, "1: the phase matrix scaled doubly stochastic (rows and columns sum to 1; energy "
                                   "conserving for any lobe) and each light's emission normalised over the D "
                                   "directions; 0: the paper's weights 4 pi / D (diverges for peaked lobes, "
                                   "e.g. HG g >= 0.9 at D = 128)", names=FLAG),
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


class IlluminationNetwork(Technique):
    """Visibility network, emission, iteration and splatting (see the module docstring)."""

    NAME = NAME
    EXAMPLES = ("particle-cloud",)
    TINY = {"directions": 8, "iterations": 3, "light_samples": 1}
    CENSUS = ("particle-cloud", {})
    SETTINGS = SETTINGS
    # directions: the converged answer's quadrature, order 1 (measured); each level averages two turned sets
    QUALITY = Quality(knob="directions", start=32, top=2048, order=1, biases=(Bias("light_pass", exact=0),
                                                          Bias("light_samples", factor=4, order=1)))
    QUALITY_SEED = "direction_seed"
    # the window is the model's, not a discretisation with a limit: as M grows a window column
    # holds fewer particles, the links fall away and multiple scattering with them (the image mean
    # falls as M grows: results/illumination-network-convergence). By the paper's rule it grows
    # with D and moves the answer; held at the default D's, the answer settles (order 1 in D).
    # Each of a search's renders is solved from zero (warm = 0), as a fresh Renderer's: a warm
    # start from the level before would stop within the tolerance of that level's answer
    QUALITY_HOLD = {"window_at": SETTINGS["directions"].default, "warm": 0}
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
        self.table = self.phase_weights = None  # the phase table, and the D x D weights of the iteration
        self.p_max = 0.0
        # direct and emission stages
        self.direct = self.travel = self.light_weight = None
        self.light_pass: LightPass | None = None  # its map, measured error and fallback
        self._light_args = None
        # iterate stage
        self.I = self.I_next = self.E = self.S = None
        self._solved_for = ()  # the layout (particles, directions, seed, ...) I was last solved on
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
        n, D = len(cloud.centres), s["directions"]
        layout = (n, D, s["direction_seed"], s["window"], s["column"], s["window_at"], s["half"], s["phase_norm"])
        partial = bool(s["refresh"]) and self._layout == layout
        self._layout = layout
        self._n = n
        self.D, self.Dp = D, pad(D, 16)
        self.rows = pad(3 * max(n, 1), ROWS)
        self.particles = cloud.struct
        self.centre, self.R = cloud.centre, cloud.R
        if partial:  # the paper's future work: re-peel k directions a frame, round robin
            which = (self._next_direction + np.arange(min(s["refresh"], D))) % D
            self._next_direction = int((which[-1] + 1) % D)
        else:
            which = self._directions(cloud)
        self.tau = wp.zeros(n, dtype=wp.vec3, device=device)
        if n:
            dev.launch(particle_extinction, n, [self.particles, self.tau], device)
            peel(self.particles, self.tau, self.dirs, which, self.centre, self.R, self.M, self.V, self.alpha, device,
                 clear=partial)
        if partial:
            self.converged = False
            return
        self._phase_matrix()
        dtype = wp.float16 if s["half"] else wp.float32
        if self.I is None or self.I.shape != (self.rows, self.Dp) or self.I.dtype != dtype:
            self.I = wp.zeros((self.rows, self.Dp), dtype=dtype, device=device)
            self.I_next = wp.zeros_like(self.I)
            self.E = wp.zeros_like(self.I)
            self.S = wp.zeros((self.rows, self.Dp), dtype=float, device=device)  # I W, always float32
            self.history = []
        elif layout[:3] != self._solved_for[:3]:  # other particles or directions: the last solution is not a start
            self.I.zero_()
            self.history = []
        self._solved_for = layout
        self.converged = False

    def _directions(self, cloud: ParticleBuffers) -> np.ndarray:
        """A network laid out anew: the D directions, the window M (``window.network_window``)
        and V and alpha without links; returns the directions to peel (all of them)."""
        s, n, D, device = self.settings, self._n, self.D, self.device
        # mean extinction of the bounding ball: total sigma_t volume / ball volume
        tau_mean = float((cloud.sigma_t.mean(1) * cloud.radius**3).sum()) / self.R**3 if n else 0.0
        dirs = fibonacci_directions(D, s["direction_seed"])
        self.M = network_window(s["window"], s["column"], s["window_at"], cloud.centres, self.centre, self.R, tau_mean,
                                dirs)
        self.dirs = wp.array(dirs, dtype=wp.vec3, device=device)
        self.V = wp.full(n * D, -1, dtype=int, device=device)
        self.alpha = wp.zeros(n * D, dtype=wp.vec3, device=device)
        self._next_direction = 0
        return np.arange(D)

    def _phase_matrix(self):
        """The medium's phase function, and the weights the iteration applies
        (``weights.tabulate_weights``): the paper's 4 pi / D, or (``phase_norm``) doubly stochastic."""
        self.phase, table = phase_struct(self.scene.media[0].phase)
        self.table = wp.array(table if len(table) else np.zeros(1, np.float32), dtype=float, device=self.device)
        self.phase_weights, self.p_max = tabulate_weights(self.dirs, self.phase, self.table, self.Dp,
                                                          self.settings["phase_norm"], self.device)

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
                       [self.I, self.phase_weights, self.E, self.alpha, self.particles.albedo, n, D, S], device,
                       min_split=64)
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
        error (None: not checked); ``light_fell_back``: whether it fell back to exact transmittance;
        ``linked``: the share of (particle, direction) pairs with an upstream particle."""
        return {"window": self.M, "iterations": len(self.history), "direct": self.direct.numpy(),
                "linked": float((self.V.numpy() >= 0).mean()) if getattr(self, "V", None) is not None else 0.0,
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
