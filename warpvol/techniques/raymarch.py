"""Raymarch: the deterministic single-scattering baseline every technique is compared with.

Per pixel centre, the camera ray is marched from where it enters the media to the nearest
surface (or where it leaves them) in ``steps`` equal steps, or steps of ``step_length``.
Each step evaluates sigma_t and the in-scattered direct light S at its midpoint and adds
T S (1 - exp(-sigma_t dt)) / sigma_t, the exact integral over a step of constant
coefficients (Hillaire 2015), so thin and thick steps both conserve energy. Light reaches
a point through the media (in closed form where one exists: homogeneous shapes, particles
and RBFs, one walk along the ray; grids marched with ``shadow_steps`` midpoint steps) and
past surfaces (a shadow ray). A point or spot light's 1/d^2 is averaged over each step in
closed form, and a step that subtends more than 0.1 rad at the light (beside it) is split into
equal angles seen from the light (equiangular points, Kulla & Fajardo 2012), each with its own
phase function, shadow and falloff: a coarse march no longer misses the light's peak (the fog-box
rows of results/multiple-scattering).
Surfaces are lit directly. The sky (the background radiance) is a light
too. With the multiple-scattering lattice on (the default) the lattice carries it, every order
of it, in the media and on the surfaces its field reaches, and lights the surfaces beyond the
field (a floor past a cloud) with the sky seen along their normal (``shading.sky_along_normal``,
as every marcher's lattice does: on haze under a sky it came closer to the reference than 8
gathered directions). Without the lattice, surfaces gather it from ``sky_samples``
directions over the sphere (``upload.sky_lights``) as pi f L_sky sum_k cos_k T_k / sum_k cos_k,
and its single scattering at every step from those directions, sum_k sigma_s p_k T_k / sum_k sigma_s p_k times
sigma_s L_sky: exact where nothing shadows the point, the error of the shadowed part falling as
the directions grow, at the price of a march toward each direction at every step (the cost that
the lattice removes; results/defaults). Each sky direction's transmittance is marched with an
eighth of ``shadow_steps``.

With ``shadow_grid`` = n > 0 (the default 32), the optical depth toward each light is baked once
on an n^3 lattice over the heterogeneous media (stage ``light_volume``, which reads the medium and
the lights only; ``shading.bake_light_depth``, shared with light_shafts and particle_glow) and
looked up trilinearly while marching, the froxel-style shortcut of
real-time fog: the march then costs one lookup per light per step instead of
``shadow_steps`` density samples, at the price of blurring shadow edges to a cell.
Surfaces still occlude through a shadow ray.

With ``multiple_scattering`` = n > 0 (the default) the light scattered more than once is
added too: solved on an n^3 lattice of ``ms_directions`` directions (``warpvol.scattering``,
stages ``multiple`` and ``multiple_view``) and read at every step as sigma_s R(x), one
trilinear lookup, and on the visible surface; 0 is single scattering.

An RBF medium whose Gaussians overlap (``extinction_grid``, shared with light_shafts and
particle_glow: ``upload.extinction_cells``) is baked into a grid once per medium change, so a
step reads 8 samples where it would sum every Gaussian in reach; its bias against the exact
sum falls as (cell / radius)^2 and ``target_error`` measures it.

Stages: medium, surfaces, lights (uploads), light_volume, multiple, multiple_view, march.
"""

from __future__ import annotations

import warp as wp

from .. import device as dev
from ..geometry.camera import RasterView, camera_view, view_ray
from ..geometry.intersect import inside_box
from ..geometry.mesh import Surfaces, occluded
from ..media.volume import Media, coefficients_at, in_scatter_at, in_scatter_sample, scattering_at
from ..physics.constants import INF, RAY_EPS
from ..physics.lights import (Emitter, angle_point, angle_samples, angle_share, light_incident, step_angle,
                              step_mean_irradiance)
from ..physics.transmittance import step_integral_rgb, transmittance_rgb
from ..pipeline import Bias, Quality, Setting, SettingsError, Stage, Technique
from ..scattering import BIASES as MS_BIASES
from ..scattering import SETTINGS as MS_SETTINGS
from ..scattering import MultipleScattering, ScatteredLight, scattered_light, scattered_on_surface
from ..scattering import check_settings as check_ms_settings
from ..scattering import leaves_out as ms_leaves_out
from ..shading import (baked_light_depth, bakes_light_depth, camera_segment, light_depth_volume, light_transmittance,
                       reflected, sky_reflected, sky_scattered, surface_direct)
from ..upload import (EXTINCTION_BIAS, EXTINCTION_SETTINGS, LIGHT_VOLUME_BIAS, LIGHT_VOLUME_SETTINGS, SceneUploads,
                      light_structs, lights_array, pinhole, sky_light_structs)

dev.kernel_module(__name__)

NAME = "raymarch"
SETTINGS = {
    "steps": Setting(64, 1, 1 << 20, "steps along each camera ray (used when step_length = 0)"),
    "step_length": Setting(0.0, 0.0, 1.0e6, "step length in scene units; 0 = use steps"),
    "shadow_steps": Setting(32, 1, 1 << 20, "steps along each ray toward a light through grid media (the others: closed form)"),
    "sky_samples": Setting(8, 0, 4096, "directions the sky's light (the background) is gathered from, each marched "
                                       "like a light, on surfaces and at every step, when the multiple-scattering "
                                       "lattice is off (multiple_scattering = 0; on, the lattice carries the sky); "
                                       "0: left out"),
    **MS_SETTINGS,
    **EXTINCTION_SETTINGS,
    **LIGHT_VOLUME_SETTINGS,
}


@wp.struct
class MarchSettings:
    steps: int
    step_length: float
    shadow_steps: int
    shadow_grid: int  # nodes per axis of the baked transmittance lattice; 0: none
    baked_lights: int  # the lights baked (the scene's, then the sky's directions where they are marched per step)
    grid_lo: wp.vec3
    grid_hi: wp.vec3


@wp.struct
class Sky:
    """The sky as a light: its directions (``upload.sky_lights``; empty: left out), where they
    start in the baked lattice (after the scene's lights) and its radiance (the background)."""

    directions: wp.array(dtype=Emitter)
    first: int
    radiance: wp.vec3


@wp.func
def light_at(m: Media, s: Surfaces, l: int, x: wp.vec3, wi: wp.vec3, dist: float, st: MarchSettings,
             baked: wp.array(dtype=wp.vec3), steps: int) -> wp.vec3:
    """Transmittance from light l (the scene's lights, then the sky's directions, as baked) to
    x: past the surfaces, and through the media marched or read from the baked lattice."""
    rng = wp.uint32(0)  # unused: transmittance is marched, not estimated
    if st.shadow_grid > 0 and l < st.baked_lights and inside_box(x, st.grid_lo, st.grid_hi):
        if occluded(s, x, wi, dist):
            return wp.vec3(0.0)
        return transmittance_rgb(baked_light_depth(baked, l, st.shadow_grid, st.grid_lo, st.grid_hi, x))
    return light_transmittance(m, s, x, wi, dist, 0, rng, steps)


@wp.func
def sky_steps(st: MarchSettings) -> int:
    """Steps toward each sky direction: an eighth of ``shadow_steps`` (at least 4). The sky is
    a sum over many directions, each of which blurs into the rest, so a coarser march serves."""
    return wp.max(st.shadow_steps / 8, 4)


@wp.func
def sky_in_scatter(m: Media, s: Surfaces, sky: Sky, x: wp.vec3, d: wp.vec3, st: MarchSettings,
                   baked: wp.array(dtype=wp.vec3)) -> wp.vec3:
    """The sky's light scattered at x toward -d: sigma_s L_sky int p T dw, the integral as
    sum_k sigma_s p_k T_k / sum_k sigma_s p_k over the sky's directions (baked after the
    scene's ``first`` lights), exact where nothing shadows x."""
    num = wp.vec3(0.0)
    den = wp.vec3(0.0)
    for k in range(sky.directions.shape[0]):
        wi = -sky.directions[k].direction
        ph = in_scatter_at(m, x, wp.dot(d, wi))
        num += wp.cw_mul(ph, light_at(m, s, sky.first + k, x, wi, INF, st, baked, sky_steps(st)))
        den += ph
    return wp.cw_mul(wp.cw_mul(sky_scattered(num, den), scattering_at(m, x)), sky.radiance)


@wp.func
def sky_on_surface(m: Media, s: Surfaces, sky: Sky, p: wp.vec3, n: wp.vec3, wo: wp.vec3, face: int,
                   st: MarchSettings, baked: wp.array(dtype=wp.vec3)) -> wp.vec3:
    """The sky's light reflected at p: pi f L_sky sum_k cos_k T_k / sum_k cos_k over the sky's
    directions above the surface (exact for an unshadowed diffuse surface)."""
    acc = wp.vec3(0.0)
    csum = float(0.0)
    mat = s.material[face]
    for k in range(sky.directions.shape[0]):
        wi = -sky.directions[k].direction
        c = wp.dot(n, wi)
        if c > 0.0:
            csum += c
            tl = light_at(m, s, sky.first + k, p + RAY_EPS * n, wi, INF, st, baked, sky_steps(st))
            acc += reflected(mat, n, wo, wi, c, wp.vec3(1.0), tl)  # the sky's radiance once, after the sum
    return sky_reflected(wp.cw_mul(acc, sky.radiance), csum)


@wp.kernel
def march_single_scattering(offset: int, cam: RasterView, m: Media, s: Surfaces, lights: wp.array(dtype=Emitter),
                            sky: Sky, st: MarchSettings, baked: wp.array(dtype=wp.vec3), ms: ScatteredLight,
                            image: wp.array(dtype=wp.vec3)):
    """Per pixel: the march over the scene's lights and the sky's directions (none: the sky's
    light left out) and the light scattered more than once (``ms``; none: left out), then the
    surface or the background, attenuated."""
    tid = wp.tid() + offset
    px = tid % cam.width
    py = tid / cam.width
    o, d = view_ray(cam, px, py)
    rng = wp.uint32(0)  # unused: transmittance is marched, not estimated
    hit, t_surf, n, face, ta, tb = camera_segment(m, s, o, d)
    tr = wp.vec3(1.0)
    L = wp.vec3(0.0)
    if ta < tb:
        steps = st.steps
        if st.step_length > 0.0:
            steps = wp.clamp(int(wp.ceil((tb - ta) / st.step_length)), 1, 1 << 20)
        dt = (tb - ta) / float(steps)
        for k in range(steps):
            x = o + (ta + (float(k) + 0.5) * dt) * d
            sig, sig_s = coefficients_at(m, x)  # each medium looked up once a step
            if sig[0] > 0.0 or sig[1] > 0.0 or sig[2] > 0.0:
                inscatter = wp.vec3(0.0)
                t_mid = ta + (float(k) + 0.5) * dt
                t0 = t_mid - 0.5 * dt
                for l in range(lights.shape[0]):
                    tc, h, phi = step_angle(lights[l], o, d, t0, t0 + dt)
                    na = angle_samples(phi)  # 1 but beside a point or spot light
                    for j in range(na):
                        xj = x
                        if na > 1:
                            xj = o + angle_point(t0, tc, h, phi, j, na) * d
                        wi, dist, e = light_incident(lights[l], xj)
                        if dist > 0.0:
                            if na == 1:
                                e = step_mean_irradiance(lights[l], e, dist, o, d, t0, t0 + dt)
                            else:
                                e = angle_share(lights[l], e, dist, h, phi, na, dt)
                            tl = light_at(m, s, l, xj, wi, dist, st, baked, st.shadow_steps)
                            ph = in_scatter_sample(m, xj, sig_s, na == 1, wp.dot(d, wi))
                            inscatter += wp.cw_mul(wp.cw_mul(ph, e), tl)
                if sky.directions.shape[0] > 0 and ms.lat.n == 0:  # else the lattice carries the sky
                    inscatter += sky_in_scatter(m, s, sky, x, d, st, baked)
                if ms.lat.n > 0:
                    inscatter += scattered_light(ms, sig_s, x)
                f = step_integral_rgb(sig, dt)
                L += wp.cw_mul(wp.cw_mul(tr, inscatter), f)
                tr = wp.cw_mul(tr, transmittance_rgb(sig * dt))
    if hit:
        nf = wp.where(wp.dot(n, d) < 0.0, n, -n)
        p = o + t_surf * d
        Ls = surface_direct(m, s, lights, p, nf, -d, s.material[face], 0, rng, st.shadow_steps)
        Ls += scattered_on_surface(ms, s, s.material[face], p, nf, -d)
        if sky.directions.shape[0] > 0:  # the lattice off (on, it lights the surfaces with the sky)
            Ls += sky_on_surface(m, s, sky, p, nf, -d, face, st, baked)
        L += wp.cw_mul(tr, Ls)
    else:
        L += wp.cw_mul(tr, sky.radiance)
    image[tid] = L


class Raymarch(Technique):
    """Fixed-step single-scattering ray march (see the module docstring)."""

    NAME = NAME
    EXAMPLES = ("fog-box", "smoke-grid", "hazy-sun")
    TINY = {"steps": 12, "shadow_steps": 6}
    CENSUS = ("smoke-grid", {})
    SETTINGS = SETTINGS
    QUALITY = Quality(knob="steps", start=8, top=1024, order=2, tied={"shadow_steps": 1},
                      biases=(Bias("sky_samples", factor=4, order=1, when="sky"), LIGHT_VOLUME_BIAS,
                              *MS_BIASES, EXTINCTION_BIAS))
    LEAVES_OUT = ()

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        self.uploads = SceneUploads(self)
        self.multiple = MultipleScattering.over(self, self.uploads)
        self.baked = wp.zeros(1, dtype=wp.vec3, device=device)
        self.image = None

    def leaves_out(self) -> list[str]:
        return [*ms_leaves_out(self.settings), *super().leaves_out()]

    @property
    def gathers_sky(self) -> bool:
        """The sky's directions are gathered only without the lattice: with it, the lattice
        carries the sky's light (all orders, the media's shadows on it included) and lights the
        surfaces beyond its field."""
        return self.settings["sky_samples"] > 0 and self.multiple.n == 0

    def diagnostics(self) -> dict:
        return {**self.multiple.diagnostics(), **self.uploads.diagnostics()}

    def check_settings(self, settings):
        check_ms_settings(NAME, settings)
        if settings["shadow_grid"] == 1:
            raise SettingsError(f"{NAME}: setting shadow_grid=1 has no interior (allowed: 0 or 2..512)")

    def _march_settings(self) -> MarchSettings:
        st = MarchSettings()
        st.steps, st.step_length = self.settings["steps"], self.settings["step_length"]
        st.shadow_steps = self.settings["shadow_steps"]
        st.shadow_grid = self.settings["shadow_grid"] if self._bakes() else 0
        st.baked_lights = len(self._baked_lights())
        st.grid_lo, st.grid_hi = wp.vec3(0.0), wp.vec3(0.0)
        if st.shadow_grid:
            st.grid_lo, st.grid_hi = self.uploads.media.struct.het_min, self.uploads.media.struct.het_max
        return st

    def _bakes(self) -> bool:
        """A baked volume pays only where transmittance is marched: heterogeneous media, some light."""
        return bakes_light_depth(self.scene, self.settings["shadow_grid"], len(self._baked_lights()))

    def _baked_lights(self) -> list:
        """What the light volume bakes, in this order: the scene's lights, and the sky's directions
        where the march gathers them (the lattice off; on, it carries the sky)."""
        return light_structs(self.scene) + self._sky()

    def _sky(self) -> list:
        """The sky's directions, where the march gathers them (the lattice off)."""
        if not self.scene.media or self.multiple.n > 0:
            return []
        return sky_light_structs(self.scene.background, self.settings["sky_samples"])

    def stages(self):
        return self.uploads.stages() + [
            Stage("light_volume", self._bake, reads=("medium", "lights", "background"),
                  settings=("shadow_grid", "shadow_steps", "sky_samples", "multiple_scattering"),
                  after=("medium", "lights"), needed=self._bakes()),
            *self.multiple.stages(after=("medium", "surfaces", "lights")),
            Stage("march", self._march, reads=("camera", "background"), settings=tuple(SETTINGS),
                  after=("medium", "surfaces", "lights", "light_volume", "multiple_view")),
        ]

    def _bake(self):
        """The light volume: it reads shadow_grid and shadow_steps (not the march's own settings)."""
        lights = lights_array(self._baked_lights(), self.device)
        self.baked = light_depth_volume(self.uploads.media.struct, lights, self.settings["shadow_grid"],
                                        self.settings["shadow_steps"], self.device)

    def _march(self):
        scene, u = self.scene, self.uploads
        npix = scene.camera.width * scene.camera.height
        self.image = wp.empty(npix, dtype=wp.vec3, device=self.device)
        sky = Sky()
        sky.directions = lights_array(self._sky(), self.device)
        sky.first = len(scene.lights)
        sky.radiance = wp.vec3(*scene.background)
        dev.launch(march_single_scattering, npix, [camera_view(pinhole(scene.camera)), u.media.struct, u.surfaces,
                                                   u.lights, sky, self._march_settings(), self.baked,
                                                   self.multiple.struct(), self.image],
                   self.device, work=self.pixel_work(self.settings["steps"]))

    def output(self):
        return self.image


TECHNIQUE = Raymarch
