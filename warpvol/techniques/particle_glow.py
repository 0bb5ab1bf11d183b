"""Particle glow: glowing light through visible particles (the glowy-light paper).

The paper marches each view ray and adds, at every step, the light of a *nearby particle*
to the light at the step, so that a lamp's glow and its shafts look grainy, "jittered
through particles", and soften at their edges. It is empirical; every constant is a
setting defaulting to the paper's value. Per step i at R_i (section 4, equation 1):

    I = I_o + (1 - (1 - d)^0.4) I_s

* ``I_o``, the direct sample: the light scattered at R_i toward the eye, sigma_s p E T V,
  T the media's transmittance to the light, V the light's shadow map (step 1 of the paper's
  list; the shadow maps ``geometry/shadowmap.py`` builds for light_shafts too). As in raymarch,
  a point light's 1/d^2 is averaged over the step, and a step beside the light is split into
  equal angles seen from it (``shading.step_in_scatter_through_maps``): the lamp's core does not
  depend on the number of steps (results/defaults).
* ``d`` (d-bar), the particle density of R_i's unit cell: a texture of ``texture_res``^3
  cells of side ``cell`` that tiles space, each d = CDF(x | mu, sigma) of a value x drawn
  once per cell, uniformly in (0, ``density_x``]. Equation 2 prints a *normal* CDF; the
  text (and figure 4's captions, "log-normal distribution function with mu = 2, sigma =
  0.1", which figure 5 renders) names the log-normal: ``density_cdf`` 0 (default) is the
  log-normal Phi((ln x - mu) / sigma), 1 the normal Phi((x - mu) / sigma) as printed. The
  paper does not say what x is; reading it as a per-cell random variable whose CDF sets the
  density reproduces figure 5's contrast (mu = 2: sparse, mu = 0: dense).
* The nearby particle C_i = R_i + D_i dir (equations 3-4), D_i = k_c (1 - d) in cells
  (k_c = 7; the paper's "unit space" read as the cell), ``dir`` from a texture of
  uniformly distributed unit directions tiling space the same way. Both textures are
  fixed in the world (seeded by ``seed``), so the grain stays put as the camera moves.
  Section 5 takes "the first and second closest particles": ``glow`` = 2 adds a second at
  4/3 the distance (the ratio of the mean distances to a point's nearest and second nearest
  neighbour in a Poisson field of particles) along an independent direction from the
  texture, and I_s is the two particles' mean: the neighbourhood's light estimated from two
  samples instead of one, of about the same size (their sum would double the glow the paper's
  constants were tuned for; results/particle-glow-ground-truth measures both).
  ``glow`` = 1, the default, is equations 3-4's one.
* ``I_s``, the nearby particle's radiance from Sun et al. 2005's surface radiance model
  (appendix B, equation 9), the particle a Lambertian patch facing R_i (normal -dir) with
  BRDF k_d = albedo / pi: I0 k_d [exp(-T) cos(theta_s) / D^2 + beta^2 G_0(T, theta_s) /
  (2 pi T)], T = beta D, D the particle's distance to the light, beta = ((1 - d) + c1) c2
  (equation 5; c1 = 0.05 keeps beta > 0, c2 = 0.03, per scene unit), shadowed by the light's
  map at C_i ("get the light intensity at the desired point", step 3.4). G_0 is tabulated
  once (``physics.airlight.g_table``). A directional light is a point light at the
  media's boundary along its direction (I0 = E D^2). ``specular`` = k_s > 0 adds the term
  the paper dropped (appendix B, equation 8) with a Phong lobe of exponent ``shininess`` and
  its G_n: the glints of figure 7.
* How I and I_s add up along the ray, the paper does not say ("return the sum"). Here
  sigma_s (I_o-source + w I_s) is the source of the radiative transfer equation: each step
  adds T_cam sigma_s (p E T V + w I_s) (1 - exp(-sigma_t dt)) / sigma_t, so the image does not
  depend on the number of steps, and with ``glow`` = 0 (or a density of 0 everywhere) it is
  the single-scattering march through shadow maps. The weight's two printings, 1 - (1 -
  d)^0.4 (equation 1) and 1 - d^0.4 (the text after it): equation 1, ``exponent`` = 0.4.

A 1/D^2 that would diverge at the light (a light at a march point) is the mean of 1/D^2
over a ball of half a step (``ball_mean_inverse_square``), as a step samples that much.
Surfaces are lit directly through the shadow maps (normal offset).

Stages: medium, surfaces, lights (uploads), textures (density and directions), tables
(G_0, and G_n for the specular term), shadow_maps (surfaces and lights; not built without
surfaces), march.

Leaves out (``frame.leaves_out``): the sky's light (the background) scattered once in the
medium or reflected by surfaces, and, with ``multiple_scattering`` = 0, multiple scattering.

With ``multiple_scattering`` = n > 0 (the default) the light scattered more than once is
added too: solved on an n^3 lattice of ``ms_directions`` directions (``warpvol.scattering``,
stages ``multiple`` and ``multiple_view``) and read at every step as sigma_s R(x) in place of the glow I_s, which imitates it; 0 is the paper's model, the glow.
"""

from __future__ import annotations


import numpy as np
import warp as wp

from .. import device as dev
from ..geometry.camera import RasterView, camera_view, pixel_ray
from ..geometry.intersect import ray_box
from ..geometry.mesh import Surfaces
from ..geometry.shadowmap import ShadowedLights, shadow_visibility
from ..media.volume import Media, coefficients_at
from ..physics.airlight import g_table, surface_radiance
from ..physics.constants import PI
from ..physics.lights import DIRECTIONAL, SPOT, ball_mean_inverse_square, spot_falloff
from ..physics.transmittance import step_integral_rgb, transmittance_rgb
from ..pipeline import Bias, Quality, Setting, Stage, Technique
from ..scattering import BIASES as MS_BIASES
from ..scattering import SETTINGS as MS_SETTINGS
from ..scattering import MultipleScattering, ScatteredLight, scattered_light, scattered_on_surface
from ..scattering import check_settings as check_ms_settings
from ..scattering import leaves_out as ms_leaves_out
from ..scene.procedural import density_texture, direction_texture
from ..shading import LightDepthVolume, camera_segment, step_in_scatter_through_maps, surface_through_maps
from ..upload import (EXTINCTION_BIAS, EXTINCTION_SETTINGS, LIGHT_VOLUME_BIAS, LIGHT_VOLUME_SETTINGS, SceneUploads,
                      pinhole, shadowed_lights)

dev.kernel_module(__name__)

NAME = "particle_glow"
SETTINGS = {
    "steps": Setting(64, 1, 1 << 16, "march steps along each view ray's media segment (a step beside a point "
                                     "light is split into equal angles seen from it)"),
    "shadow_map_res": Setting(256, 4, 8192, "texels per side of each shadow map (cube maps: per face)"),
    "depth_bias": Setting(0.02, 0.0, 1.0e3, "shadow-map depth bias, scene units"),
    "shadow_steps": Setting(32, 1, 1 << 16, "steps toward a light through grid media (the others: closed form)"),
    "glow": Setting(1, 0, 2, "how many nearby particles glow at each step: none (the direct sample I_o alone, a "
                             "single-scattering march through shadow maps), the nearest (equations 3-4) or the first "
                             "and second nearest (section 5), their light averaged; the glow imitates multiple scattering, so it is added "
                             "only where multiple_scattering = 0 (the paper's model)", names=("off", "nearest", "two")),
    "k_c": Setting(7.0, 0.0, 1.0e4, "equation 3: the nearby particle lies up to k_c cells from the march point"),
    "c1": Setting(0.05, 0.0, 1.0e3, "equation 5: beta = ((1 - d) + c1) c2; c1 keeps beta > 0 where d = 1"),
    "c2": Setting(0.03, 0.0, 1.0e6, "equation 5: beta's scale, per scene unit"),
    "exponent": Setting(0.4, 0.0, 100.0, "equation 1: I_s weighs 1 - (1 - d)^exponent"),
    "mu": Setting(0.5, -100.0, 100.0, "the density distribution's mu (log-normal: of ln x)"),
    "sigma": Setting(0.5, 1.0e-6, 100.0, "the density distribution's sigma (log-normal: of ln x)"),
    "density_cdf": Setting(0, 0, 1, "0: log-normal CDF (the text); 1: normal CDF (equation 2 as printed)",
                           names=("lognormal", "normal")),
    "density_x": Setting(10.0, 1.0e-6, 1.0e6, "each cell's x is drawn uniformly in (0, density_x]; d = CDF(x) "
                                            "(10: figure 5's mu = 2, sigma = 0.1 sparse, mu = 0 dense)"),
    "cell": Setting(0.0, 0.0, 1.0e6, "side of a density cell, scene units; 0: the media's bounding diagonal / 64"),
    "texture_res": Setting(32, 1, 256, "cells per side of the density and direction textures (they tile space)"),
    "seed": Setting(0, 0, 2**31 - 1, "seed of the density texture"),
    "direction_seed": Setting(1, 0, 2**31 - 1, "seed of the direction texture"),
    "anchor": Setting(0, 0, 1, "where the nearby particle is placed from: 0 the march point R_i (equation 4, the "
                               "paper); 1 the centre of R_i's cell (the particle fixed in the world: no shimmer "
                               "as the march points slide with the camera)", names=("march", "cell")),
    "specular": Setting(0.0, 0.0, 1.0e3, "k_s of the specular term the paper dropped (appendix B, equation 8); 0: off"),
    "shininess": Setting(20.0, 1.0, 1.0e4, "Phong exponent n of the specular term"),
    **MS_SETTINGS,
    **EXTINCTION_SETTINGS,
    **LIGHT_VOLUME_SETTINGS,
}


@wp.struct
class Glow:
    steps: int
    shadow_steps: int
    glow: int
    k_c: float
    c1: float
    c2: float
    cell: float
    res: int  # texture cells per side
    anchor: int  # 0: C_i from the march point; 1: from its cell's centre
    k_s: float
    shininess: float
    density: wp.array(dtype=float)  # res^3 cells: d in [0, 1]
    weight: wp.array(dtype=float)  # res^3 cells: I_s's weight 1 - (1 - d)^exponent
    direction: wp.array(dtype=wp.vec3)  # res^3 unit vectors
    g0: wp.array2d(dtype=float)  # G_0 e^T (physics.airlight.g_table)
    gn: wp.array2d(dtype=float)  # G_n e^T for the specular lobe (n = shininess)
    lo: wp.vec3  # the media's bounds: a directional light enters there
    hi: wp.vec3


@wp.func
def cell_of(gs: Glow, x: wp.vec3) -> int:
    """The texture cell holding x; the textures repeat every ``res`` cells along each axis."""
    R = gs.res
    i = int(wp.floor(x[0] / gs.cell)) % R
    j = int(wp.floor(x[1] / gs.cell)) % R
    k = int(wp.floor(x[2] / gs.cell)) % R
    i = wp.where(i < 0, i + R, i)
    j = wp.where(j < 0, j + R, j)
    k = wp.where(k < 0, k + R, k)
    return (k * R + j) * R + i


@wp.func
def particle_radiance(gs: Glow, sl: ShadowedLights, c: wp.vec3, normal: wp.vec3, beta: float, r_ball: float,
                      albedo: wp.vec3) -> wp.vec3:
    """I_s: what the particle at c (a Lambertian patch facing ``normal``, BRDF albedo / pi,
    plus k_s Phong) sends back, by Sun et al.'s surface radiance model, per light, shadowed
    by the light's map at c."""
    L = wp.vec3(0.0)
    for l in range(sl.lights.shape[0]):
        light = sl.lights[l]
        wi = wp.vec3(0.0)
        dist = float(0.0)
        inv_d2 = float(0.0)
        strength = light.strength
        directional = light.kind == DIRECTIONAL
        if directional:  # a point light where the light enters the media, I0 = E D^2
            wi = -light.direction
            a, b = ray_box(c, wi, gs.lo, gs.hi)
            dist = wp.max(b, 0.0)
        else:
            to = light.position - c
            dist = wp.length(to)
            wi = wp.where(dist > 0.0, to / wp.max(dist, 1.0e-30), normal)
            if light.kind == SPOT:
                strength = light.strength * spot_falloff(light, wp.dot(-wi, light.direction))
            if dist > 8.0 * r_ball:  # the ball's mean of 1/D^2 is 1/D^2 within 0.3% there
                inv_d2 = 1.0 / (dist * dist)
            else:
                inv_d2 = ball_mean_inverse_square(r_ball, dist)
            dist = wp.max(dist, r_ball)
        if strength[0] > 0.0 or strength[1] > 0.0 or strength[2] > 0.0:
            v = shadow_visibility(sl.maps[l], sl.depth, c)
            if v > 0.0:
                cos_s = wp.dot(normal, wi)
                d2 = wp.where(directional, dist * dist, 1.0)  # directional: I0 / E = D^2
                diffuse = surface_radiance(gs.g0, beta, dist, inv_d2, cos_s, 1.0) * d2
                if directional:
                    diffuse += wp.exp(-beta * dist) * wp.max(cos_s, 0.0)
                s = diffuse * albedo / PI
                if gs.k_s > 0.0:  # the viewer (R_i) lies along the normal: the mirror direction is the normal
                    spec = surface_radiance(gs.gn, beta, dist, inv_d2, cos_s, gs.shininess) * d2
                    if directional:
                        spec += wp.exp(-beta * dist) * wp.pow(wp.max(cos_s, 0.0), gs.shininess)
                    s += wp.vec3(gs.k_s * spec)
                L += v * wp.cw_mul(s, strength)
    return L


#: The second nearest particle lies SECOND_NEAREST times as far as the nearest: the ratio of their
#: mean distances in a Poisson field of particles, Gamma(7/3) / (Gamma(2) Gamma(4/3)) = 4/3.
SECOND_NEAREST = 4.0 / 3.0


@wp.func
def nearby_glow(gs: Glow, sl: ShadowedLights, x: wp.vec3, sig: wp.vec3, sig_s: wp.vec3, r_ball: float) -> wp.vec3:
    """sigma_s w I_s at the march point x: the light of the ``glow`` nearest particles (one or
    two, averaged) of x's texture cell, the nearest at D = k_c (1 - d) cells along the cell's
    direction (equations 3-4), the second SECOND_NEAREST times as far along the direction of the
    cell half the texture away (an independent draw)."""
    cell = cell_of(gs, x)
    dbar = gs.density[cell]
    w = gs.weight[cell]
    out = wp.vec3(0.0)
    if w > 0.0:
        base = x
        if gs.anchor != 0:
            base = (wp.vec3(wp.floor(x[0] / gs.cell), wp.floor(x[1] / gs.cell), wp.floor(x[2] / gs.cell)) +
                    wp.vec3(0.5)) * gs.cell
        beta = ((1.0 - dbar) + gs.c1) * gs.c2
        albedo = wp.cw_div(sig_s, wp.max(sig, wp.vec3(1.0e-30)))
        n3 = gs.res * gs.res * gs.res
        reach = gs.k_c * (1.0 - dbar) * gs.cell
        for j in range(gs.glow):
            dirn = gs.direction[(cell + j * (n3 / 2)) % n3]
            c = base + (reach * wp.where(j == 0, 1.0, SECOND_NEAREST)) * dirn
            out += w * wp.cw_mul(sig_s, particle_radiance(gs, sl, c, -dirn, beta, r_ball, albedo))
    return out / float(wp.max(gs.glow, 1))


@wp.kernel
def march_glow(offset: int, cam: RasterView, m: Media, s: Surfaces, sl: ShadowedLights, gs: Glow,
               background: wp.vec3, ms: ScatteredLight, image: wp.array(dtype=wp.vec3)):
    """Per pixel: the march of section 4 over the media segment in front of the nearest
    surface, equation 1 at every step, then the surface (lit through the shadow maps) or the
    background, attenuated."""
    tid = wp.tid() + offset
    o, d = pixel_ray(cam, tid)
    hit, t_surf, n, face, ta, tb = camera_segment(m, s, o, d)
    tr = wp.vec3(1.0)
    L = wp.vec3(0.0)
    if ta < tb:
        dt = (tb - ta) / float(gs.steps)
        for k in range(gs.steps):
            x = o + (ta + (float(k) + 0.5) * dt) * d
            sig, sig_s = coefficients_at(m, x)  # each medium looked up once a step
            if sig[0] > 0.0 or sig[1] > 0.0 or sig[2] > 0.0:
                src = wp.vec3(0.0)
                for l in range(sl.lights.shape[0]):  # I_o: the direct sample, over the step
                    src += step_in_scatter_through_maps(m, sl, l, o, d, ta + float(k) * dt, dt, sig_s, gs.shadow_steps)
                if ms.lat.n > 0:  # the light scattered more than once, solved (in place of the glow)
                    src += scattered_light(ms, sig_s, x)
                elif gs.glow != 0 and sl.lights.shape[0] > 0:  # I_s: the nearby particles' light
                    src += nearby_glow(gs, sl, x, sig, sig_s, 0.5 * dt)
                L += wp.cw_mul(wp.cw_mul(tr, src), step_integral_rgb(sig, dt))
                tr = wp.cw_mul(tr, transmittance_rgb(sig * dt))
    if hit:
        nf = wp.where(wp.dot(n, d) < 0.0, n, -n)
        p = o + t_surf * d
        Ls = surface_through_maps(m, sl, p, nf, -d, s.material[face], wp.vec3(0.0), gs.shadow_steps)
        L += wp.cw_mul(tr, Ls + scattered_on_surface(ms, s, s.material[face], p, nf, -d))
    else:
        L += wp.cw_mul(tr, background)
    image[tid] = L


class ParticleGlow(Technique):
    """the glowy-light paper: a march with a nearby particle's light at every step (module docstring)."""

    NAME = NAME
    EXAMPLES = ("dusty-lamp", "smoke-grid")
    TINY = {"steps": 12, "shadow_map_res": 16, "shadow_steps": 6, "specular": 0.3}
    CENSUS = ("dusty-lamp", {})
    SETTINGS = SETTINGS
    QUALITY = Quality(knob="steps", start=8, top=8192, order=2, tied={"shadow_steps": 0.25},
                      biases=(Bias("shadow_map_res", factor=4, order=1), *MS_BIASES, EXTINCTION_BIAS,
                              LIGHT_VOLUME_BIAS))
    LEAVES_OUT = ()

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        self.uploads = SceneUploads(self)
        self.multiple = MultipleScattering.over(self, self.uploads)
        self.density = self.weight = self.direction = None
        self.g0 = self.gn = None
        self.sl: ShadowedLights | None = None
        self.light_volume = LightDepthVolume(self, lambda: self.uploads.media.struct, lambda: self.uploads.lights)
        self.image = None

    def check_settings(self, settings):
        check_ms_settings(NAME, settings)

    def leaves_out(self) -> list[str]:
        if self.settings["multiple_scattering"] == 0 and self.settings["glow"]:
            return ["multiple scattering (the glow imitates some of it)", *super().leaves_out()]
        return [*ms_leaves_out(self.settings), *super().leaves_out()]

    def stages(self):
        return self.uploads.stages() + [
            *self.multiple.stages(after=("medium", "surfaces", "lights")),
            Stage("textures", self._textures, settings=("mu", "sigma", "density_cdf", "density_x", "texture_res", "seed",
                                                        "direction_seed", "exponent")),
            Stage("tables", self._tables, settings=("specular", "shininess")),
            Stage("shadow_maps", self._shadow_maps, reads=("lights",), settings=("shadow_map_res", "depth_bias"),
                  after=("surfaces", "lights")),
            self.light_volume.stage(),
            Stage("march", self._march, reads=("camera", "background"),
                  settings=("steps", "shadow_steps", "glow", "k_c", "c1", "c2", "cell", "anchor", "multiple_scattering",
                            "shadow_grid", "specular", "shininess", "texture_res"),
                  after=("medium", "textures", "tables", "shadow_maps", "multiple_view", "light_volume")),
        ]

    def _textures(self):
        s = self.settings
        d = density_texture(s["texture_res"], s["mu"], s["sigma"], s["density_x"], s["density_cdf"] == 0, s["seed"])
        self.density = wp.array(d, dtype=float, device=self.device)
        self.weight = wp.array((1.0 - np.maximum(1.0 - d.astype(np.float64), 0.0) ** s["exponent"]).astype(np.float32),
                               dtype=float, device=self.device)
        self.direction = wp.array(direction_texture(s["texture_res"], s["direction_seed"]), dtype=wp.vec3,
                                  device=self.device)

    def _tables(self):
        self.g0 = wp.array(g_table(1), dtype=float, device=self.device)
        n = self.settings["shininess"] if self.settings["specular"] > 0.0 else 1.0
        self.gn = self.g0 if n == 1.0 else wp.array(g_table(float(n)), dtype=float, device=self.device)

    def _shadow_maps(self):
        s = self.settings
        self.sl = shadowed_lights(self.scene, self.uploads.lights, self.uploads.surfaces, s["shadow_map_res"],
                                  s["depth_bias"], self.device)

    def glow_struct(self) -> Glow:
        s = self.settings
        gs = Glow()
        gs.steps, gs.shadow_steps, gs.glow = s["steps"], s["shadow_steps"], s["glow"]
        gs.k_c, gs.c1, gs.c2 = s["k_c"], s["c1"], s["c2"]
        media = self.uploads.media.struct
        diag = float(np.linalg.norm(np.asarray(media.all_max, np.float64) - np.asarray(media.all_min, np.float64)))
        gs.cell = s["cell"] or (diag / 64.0 if np.isfinite(diag) and diag > 0.0 else 1.0)
        gs.res, gs.anchor = s["texture_res"], s["anchor"]
        gs.k_s, gs.shininess = s["specular"], s["shininess"]
        gs.density, gs.weight, gs.direction, gs.g0, gs.gn = self.density, self.weight, self.direction, self.g0, self.gn
        gs.lo, gs.hi = media.all_min, media.all_max
        return gs

    def _march(self):
        scene, u = self.scene, self.uploads
        npix = scene.camera.width * scene.camera.height
        self.image = wp.empty(npix, dtype=wp.vec3, device=self.device)
        sl = self.light_volume.attach(self.sl)
        dev.launch(march_glow, npix, [camera_view(pinhole(scene.camera)), u.media.struct, u.surfaces, sl,
                                      self.glow_struct(), wp.vec3(*scene.background), self.multiple.struct(),
                                      self.image], self.device, work=self.pixel_work(self.settings["steps"]))

    def diagnostics(self) -> dict:
        """``density``: the particle-density texture d (texels), as sampled by the march; with
        multiple scattering, the orders iterated and the tail's ratio (``scattering``); the grids
        the media were baked into (``extinction_grid``, ``SceneUploads.diagnostics``)."""
        return {"density": self.density.numpy(), **self.multiple.diagnostics(), **self.uploads.diagnostics()}

    def output(self):
        return self.image


TECHNIQUE = ParticleGlow
