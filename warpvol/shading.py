"""Direct lighting shared by the techniques: what a light delivers to a point in a medium
or on a surface, through the media and past the surfaces in between.

The sky (the scene's background as light from every direction) is a quadrature over K
directions, normalised so that it is exact where nothing shadows the point:
``sky_scattered`` for a medium (sum_k p_k T_k / sum_k p_k, the phase function's integral
being 1) and ``sky_reflected`` for a surface (pi sum_k cos_k f_k T_k / sum_k cos_k, the
cosine's integral over the hemisphere being pi). Each technique sums its own T_k.

Transmittance to a light is either estimated without bias (``march_steps`` = 0: exact for
media with a closed form, ratio tracking for grids) or marched deterministically with
``march_steps`` midpoint steps through the grids (homogeneous, particle and RBF media exact),
or read from a lattice of the optical depth toward each light baked once over the heterogeneous
media (``bake_light_depth``, the froxel-style shortcut of real-time fog: a lookup a step instead
of a march, shadow edges blurred to a cell).
"""

import warp as wp

from . import device as dev
from .geometry.intersect import inside_box, ray_box
from .geometry.mesh import Surfaces, occluded, surface_hit
from .geometry.shadowmap import ShadowedLights, shadow_visibility, texel_world_size
from .media.volume import (Media, exact_media, exact_optical_depth, grid_sigma_t_at, in_scatter_sample,
                           transmittance_estimate)
from .physics.brdf import Material, brdf_eval
from .physics.constants import INF, PI, RAY_EPS, STREAM
from .physics.lights import (Emitter, angle_point, angle_samples, angle_share, light_incident, step_angle,
                             step_mean_irradiance)
from .media.grid import lattice_trilinear_vec3
from .physics.transmittance import transmittance_rgb
from .pipeline import Stage

dev.kernel_module(__name__)


@wp.func
def marched_optical_depth(m: Media, o: wp.vec3, d: wp.vec3, t0: float, t1: float, steps: int) -> wp.vec3:
    """Optical depth over [t0, t1]: every medium with a closed form exact (homogeneous shapes,
    particles, RBFs: one walk along the ray, not a density sum per step), grids by the midpoint
    rule in ``steps`` steps over the heterogeneous media's box."""
    tau = exact_optical_depth(m, o, d, t0, t1)
    if exact_media(m):
        return tau
    a, b = ray_box(o, d, m.het_min, m.het_max)
    a = wp.max(a, t0)
    b = wp.min(b, t1)
    if a < b:
        dt = (b - a) / float(steps)
        for k in range(steps):
            tau += grid_sigma_t_at(m, o + (a + (float(k) + 0.5) * dt) * d) * dt
    return tau


@wp.func
def light_transmittance(m: Media, s: Surfaces, x: wp.vec3, wi: wp.vec3, dist: float, c: int,
                        rng: wp.uint32, march_steps: int) -> wp.vec3:
    """Fraction of the light that reaches x from distance ``dist`` along wi (0 if a surface blocks it)."""
    if occluded(s, x, wi, dist):
        return wp.vec3(0.0)
    if march_steps > 0:
        return transmittance_rgb(marched_optical_depth(m, x, wi, 0.0, dist, march_steps))
    return transmittance_estimate(m, x, wi, 0.0, dist, c, rng)


@wp.func
def sky_along_normal(m: Media, s: Surfaces, mat: Material, p: wp.vec3, n: wp.vec3, sky: wp.vec3,
                     march_steps: int) -> wp.vec3:
    """The light of a uniform sky of radiance ``sky`` that a surface at p (normal n) reflects, as a
    Lambertian rho L, dimmed by what lies along its normal (one shadow ray for the hemisphere:
    exact for an unshadowed diffuse surface, the sky's own directions are not gathered)."""
    rng = wp.uint32(0)  # unused: transmittance is marched
    up = light_transmittance(m, s, p + RAY_EPS * n, n, INF, 0, rng, march_steps)
    return wp.cw_mul(wp.cw_mul(mat.diffuse, sky), up)


@wp.func
def camera_segment(m: Media, s: Surfaces, o: wp.vec3, d: wp.vec3):
    """What a camera ray o + t d meets: the first surface (hit, t_surf, its normal and face) and
    the span [ta, tb) of the media's box in front of it (empty where ta >= tb)."""
    hit, t_surf, n, face = surface_hit(s, o, d, INF)
    a, b = ray_box(o, d, m.all_min, m.all_max)
    return hit, t_surf, n, face, wp.max(a, 0.0), wp.min(b, t_surf)


@wp.func
def reflected(mat: Material, n: wp.vec3, wo: wp.vec3, wi: wp.vec3, cos_l: float, e: wp.vec3, tr: wp.vec3) -> wp.vec3:
    """What a surface (normal n, material mat) reflects toward wo of a light's irradiance e
    (at normal incidence) arriving along wi through transmittance tr: f(wo, wi) e tr cos_l,
    cos_l = n . wi > 0. Each technique finds e and tr its own way and sums this over its lights."""
    return cos_l * wp.cw_mul(wp.cw_mul(brdf_eval(mat, n, wo, wi), e), tr)


@wp.func
def surface_direct(m: Media, s: Surfaces, lights: wp.array(dtype=Emitter), p: wp.vec3, n: wp.vec3, wo: wp.vec3,
                   mat: Material, c: int, rng: wp.uint32, march_steps: int) -> wp.vec3:
    """Radiance reflected toward wo by direct light; ``n`` faces wo."""
    L = wp.vec3(0.0)
    start = p + RAY_EPS * n
    for l in range(lights.shape[0]):
        wi, dist, e = light_incident(lights[l], p)
        cos_l = wp.dot(n, wi)
        if cos_l > 0.0 and (e[0] > 0.0 or e[1] > 0.0 or e[2] > 0.0):
            tr = light_transmittance(m, s, start, wi, dist, c, wp.rand_init(wp.randi(rng), STREAM), march_steps)
            L += reflected(mat, n, wo, wi, cos_l, e, tr)
    return L



@wp.func
def light_arriving(m: Media, sl: ShadowedLights, l: int, x: wp.vec3, n: wp.vec3, shadow_steps: int):
    """(wi, E v, tau): the direction to light l, the irradiance it sends to x past the surfaces
    (shadow-map visibility v), and the optical depth of the media on the way, left for the caller
    to put into one exponential with its own. On a surface, ``n`` is its normal and the map is
    read half a texel off it (normal offset); in the medium n = 0."""
    wi, dist, e = light_incident(sl.lights[l], x)
    if dist <= 0.0:
        return wi, wp.vec3(0.0), wp.vec3(0.0)
    p = x
    if n[0] != 0.0 or n[1] != 0.0 or n[2] != 0.0:
        p = x + (0.5 * texel_world_size(sl.maps[l], x)) * n
    v = shadow_visibility(sl.maps[l], sl.depth, p)
    if v <= 0.0:
        return wi, wp.vec3(0.0), wp.vec3(0.0)
    if sl.baked_n > 0 and inside_box(x, sl.baked_lo, sl.baked_hi):
        return wi, e * v, baked_light_depth(sl.baked, l, sl.baked_n, sl.baked_lo, sl.baked_hi, x)
    return wi, e * v, marched_optical_depth(m, x, wi, 0.0, dist, shadow_steps)


@wp.kernel
def bake_light_depth(offset: int, m: Media, lights: wp.array(dtype=Emitter), n: int, lo: wp.vec3, hi: wp.vec3,
                     steps: int, out: wp.array(dtype=wp.vec3)):
    """The media's optical depth from each node of an n^3 lattice over [lo, hi] to each light
    (marched with ``steps`` steps through grids, closed form otherwise; no surfaces): light l's
    nodes from l n^3, x fastest."""
    tid = wp.tid() + offset
    cell = tid % (n * n * n)
    l = tid / (n * n * n)
    ijk = wp.vec3(float(cell % n), float((cell / n) % n), float(cell / (n * n)))
    x = lo + wp.cw_mul(hi - lo, ijk / float(n - 1))
    wi, dist, e = light_incident(lights[l], x)
    out[tid] = marched_optical_depth(m, x, wi, 0.0, dist, steps)


@wp.func
def baked_light_depth(baked: wp.array(dtype=wp.vec3), l: int, n: int, lo: wp.vec3, hi: wp.vec3,
                      x: wp.vec3) -> wp.vec3:
    """Light l's optical depth at x, trilinear in the lattice ``bake_light_depth`` filled."""
    return lattice_trilinear_vec3(baked, l * n * n * n, 1, n, lo, hi, x)


def light_depth_volume(m: Media, lights: wp.array, n: int, steps: int, device) -> wp.array:
    """``bake_light_depth`` over the media's heterogeneous box for every light of ``lights``."""
    out = wp.empty(max(1, lights.shape[0] * n**3), dtype=wp.vec3, device=device)
    if lights.shape[0]:
        dev.launch(bake_light_depth, lights.shape[0] * n**3, [m, lights, n, m.het_min, m.het_max, steps, out], device,
                   work=steps)
    return out


def bakes_light_depth(scene, n: int, lights: int) -> bool:
    """Whether a light volume of n nodes a side pays: some of ``lights`` to bake, and a medium
    whose optical depth is marched or walked (not homogeneous)."""
    return n > 0 and lights > 0 and any(m.type != "homogeneous" for m in scene.media)


class LightDepthVolume:
    """The light volume of a marcher that reads its lights through ``ShadowedLights``
    (light_shafts, particle_glow): its stage ``light_volume`` bakes the scene's lights
    (``light_depth_volume``, ``shadow_grid`` nodes a side, ``shadow_steps`` through grids) and
    ``attach`` gives it to the lights' struct, which marches instead where it does not pay.
    ``media`` and ``lights``: callables giving the uploaded ``Media`` struct and lights array."""

    def __init__(self, technique, media, lights):
        self.t, self._media, self._lights = technique, media, lights
        self.depth = None

    @property
    def on(self) -> bool:
        return bakes_light_depth(self.t.scene, self.t.settings["shadow_grid"], len(self.t.scene.lights))

    def stage(self) -> Stage:
        return Stage("light_volume", self._bake, reads=("medium", "lights"), settings=("shadow_grid", "shadow_steps"),
                     after=("medium", "lights"), needed=self.on)

    def _bake(self):
        s = self.t.settings
        self.depth = light_depth_volume(self._media(), self._lights(), s["shadow_grid"], s["shadow_steps"], self.t.device)

    def attach(self, sl: ShadowedLights) -> ShadowedLights:
        """``sl`` reading its lights' optical depth from the volume, or marching it (``baked_n`` 0)."""
        baked = self.depth if self.on else None
        sl.baked_n = self.t.settings["shadow_grid"] if baked is not None else 0
        sl.baked_lo, sl.baked_hi = self._media().het_min, self._media().het_max
        sl.baked = baked if baked is not None else wp.zeros(1, dtype=wp.vec3, device=self.t.device)
        return sl


@wp.func
def step_in_scatter_through_maps(m: Media, sl: ShadowedLights, l: int, o: wp.vec3, d: wp.vec3, t0: float, dt: float,
                                 sig_s: wp.vec3, shadow_steps: int) -> wp.vec3:
    """Light l's single scattering toward -d, per unit length, over the march step [t0, t0 + dt]
    of o + t d, past the surfaces by its shadow map and through the media (``light_arriving``):
    at the step's midpoint with the step's mean 1/d^2, or, where the step subtends more than
    ANGLE_STEP at a point or spot light, at equiangular points (``physics.lights.step_angle``),
    each with its own phase function, shadow and falloff, as raymarch's step. ``sig_s``: the
    scattering coefficient at the step's midpoint, looked up already (``coefficients_at``)."""
    light = sl.lights[l]
    tc, h, phi = step_angle(light, o, d, t0, t0 + dt)
    na = angle_samples(phi)  # 1 but beside a point or spot light
    acc = wp.vec3(0.0)
    for j in range(na):
        t = wp.where(na > 1, angle_point(t0, tc, h, phi, j, na), t0 + 0.5 * dt)
        x = o + t * d
        wi, e, tau = light_arriving(m, sl, l, x, wp.vec3(0.0), shadow_steps)
        if e[0] > 0.0 or e[1] > 0.0 or e[2] > 0.0:
            dist = wp.length(light.position - x)
            if na > 1:
                e = angle_share(light, e, dist, h, phi, na, dt)
            else:
                e = step_mean_irradiance(light, e, dist, o, d, t0, t0 + dt)
            ph = in_scatter_sample(m, x, sig_s, na == 1, wp.dot(d, wi))
            acc += wp.cw_mul(wp.cw_mul(ph, e), transmittance_rgb(tau))
    return acc


@wp.func
def surface_through_maps(m: Media, sl: ShadowedLights, p: wp.vec3, n: wp.vec3, wo: wp.vec3, mat: Material,
                         tau_view: wp.vec3, shadow_steps: int) -> wp.vec3:
    """What a surface at p (normal n, facing wo) reflects toward wo of the lights past their
    shadow maps and through the media (``light_arriving``), times exp(-tau_view): the caller's
    optical depth on to the camera, put into the same exponential."""
    L = wp.vec3(0.0)
    for l in range(sl.lights.shape[0]):
        wi, e, tau = light_arriving(m, sl, l, p, n, shadow_steps)
        cos_l = wp.dot(n, wi)
        if cos_l > 0.0:
            L += reflected(mat, n, wo, wi, cos_l, e, transmittance_rgb(tau + tau_view))
    return L


@wp.func
def sky_scattered(num: wp.vec3, den: wp.vec3) -> wp.vec3:
    """The sky's light scattered at a point per unit sky radiance and unit scattering:
    num / den with num = sum_k p_k T_k and den = sum_k p_k over the sky's directions (RGB where
    the phase weight differs per channel); 0 where den is 0 (then so is num)."""
    return wp.vec3(num[0] / wp.max(den[0], 1.0e-30), num[1] / wp.max(den[1], 1.0e-30), num[2] / wp.max(den[2], 1.0e-30))


@wp.func
def sky_reflected(acc: wp.vec3, csum: float) -> wp.vec3:
    """The sky's light a surface reflects: pi acc / csum with acc = sum_k cos_k f_k L T_k and
    csum = sum_k cos_k over the sky's directions above it; 0 where none is above it."""
    if csum > 0.0:
        return acc * (PI / csum)
    return wp.vec3(0.0)
