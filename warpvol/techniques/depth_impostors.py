"""Depth impostors: particle clouds built of blocks, light slices, objects inside clouds.

Umenhoffer & Szirmay-Kalos, "Real-Time Rendering of Cloudy Natural Phenomena with
Hierarchical Depth Impostors", Eurographics 2005 short presentations (8000 particles, one directional light, 8 FPS without blocks and 200 FPS with 40
blocks on a GeForce 6800 GT). A cloud of N particles is built of N / b copies (instances) of
one block of b particles, so a frame renders the block once (b) and then its instances
(N / b) instead of N particles. Single scattering of the scene's lights. Stages:

* ``blocks`` (reads the medium): the particles to the device, and the blocks. A medium made
  by ``generator = {kind = "blocks", ...}`` (``block_size`` b > 1) is K instances of one
  template block: the block's particles about its centroid, and the K centroids. Any other
  particle medium is grouped into blocks of ``cluster`` particles, neighbours along a
  Morton curve (each group its own template and one instance); ``cluster = 1`` (default)
  makes every particle an instance of a one-particle template (the paper's "no blocks").
* ``light`` (reads the lights): the shared light pass (media/lightpass.py) over the cloud:
  per light, the opacity accumulated up to S depths (the paper's light slices, S = 4 in one
  RGBA texture; here ``slices``), read at any point by interpolating between the two
  slices that enclose it. Directional lights get an orthographic pass, point and spot
  lights a perspective one (a cube inside the cloud). ``light_pass = 2``: a Fourier
  opacity map of ``light_terms`` terms instead (Jansen and Bavoil 2010); 0: exact. The sky
  (the scene's background, the paper's "sky color" in figure 2) is light too: from
  ``sky_samples`` directions over the sphere (``upload.sky_lights``), each with its own
  light pass on a quarter of the sun's texels (sky light is soft), exact where ``light_pass`` = 0;
  not built for a black sky. Where every particle is in a block of several
  (``light_blocks`` = 1), a directional light's map (the sun's, the sky's) is made block by
  block, the paper's b + N / b: each template rendered once from the light into a light
  impostor (per cell: the chords' total length and the mean and variance of their depth),
  and each instance splatted from it into the slices, its chords through a texel merged
  into one segment of the same mean and spread. Point and spot lights stay per particle.
* ``templates``: whether the blocks' templates changed; when an animation only moves the
  instances, the impostors stay cached.
* ``impostors`` (reads the camera): each template block's depth impostor for the camera
  direction: T x T texels over the block's bounding disc (``impostor_res``; 0: T = 3 R / r,
  a texel two thirds of a particle radius r across the block's radius R, and no finer than
  two pixels of the largest projected block, D / 2; ``impostor_detail`` scales both), per texel the
  total opacity 1 - prod(1 - alpha_j) = 1 - exp(-sum sigma_t chord_j) (RGB; each sphere's
  chord analytic), the front and back depths (min entry, max exit, from the block's
  centre), and the depth it is shaded at (the chords' centres weighted by what each sends
  toward the viewer: a thick texel is seen at its front). b x T^2 work, once per template, not per instance. A one-particle template needs
  no texture: its opacity along a pixel ray is the sphere's own chord.
* ``shade`` (reads the camera): what each instance's texel scatters toward the camera:
  albedo x sum over lights of p(theta) E T_light, T_light read from the light pass at the
  texel's shading depth (the block's own particles toward the light included: its
  self-shadowing), plus the sky's albedo L_sky sum_k p_k T_k / sum_k p_k. ``widen`` > 0: the
  paper's forward-scattering widening (``particle_light_transmittance``). A one-particle instance: its irradiance averaged over the sphere at
  ``light_samples`` points (``LightPass.direct``).
* ``surfaces`` (reads the surfaces, camera): per pixel the nearest surface (its depth: the
  paper's depth buffer) and its colour lit through the light pass (the cloud's shadow) and
  past the other surfaces.
* ``gather`` (reads the camera, background): instances listed per 8 x 8 pixel tile near
  to far (``bin_spheres``, by their bounding spheres) and composited front to back: an
  instance adds T alpha L and scales T by 1 - alpha; a block's impostor is read in its plane
  within its reach R of its centre, where its spheres are. Objects in clouds (section 2.4): where the surface depth falls in
  a block's [front, back] interval along the pixel ray, its optical depth is scaled by the
  fraction of the interval in front of the surface (uniform density in the block; for a
  one-particle instance the chord is cut exactly). ``object_depth = 0`` is the billboard
  the paper fixes: a block stands at its centre plane, wholly in front of or behind the
  surface. The background (or the surface) shows through.

With ``multiple_scattering`` = n > 0 (the default) the light scattered more than once is
added too: solved on an n^3 lattice of ``ms_directions`` directions (``warpvol.scattering``,
stages ``multiple`` and ``multiple_view``) and read at each shaded texel and one-particle instance as albedo R(x); 0 is the paper's model.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .. import device as dev
from ..geometry.camera import RasterView, camera_view, pixel_ray
from ..geometry.intersect import ray_sphere
from ..geometry.mesh import Surfaces, occluded, surface_hit
from ..geometry.tiles import SPHERE_TILE, TileLists, bin_spheres, pixel_tile
from ..media.lightpass import REPRESENTATIONS, LightMap, LightPass, optical_depth_to_light
from ..media.particles import BlockCloud, Blocks, ParticleBuffers, Particles
from ..physics.constants import INF, RAY_EPS
from ..physics.lights import Emitter, light_incident
from ..physics.phase import PhaseParams, PhaseFn, phase_eval, phase_fn, phase_struct, phase_toward
from ..physics.transmittance import transmittance_rgb
from ..pipeline import Bias, Quality, Setting, Stage, Technique
from ..scattering import BIASES as MS_BIASES
from ..scattering import SETTINGS as MS_SETTINGS
from ..scattering import MultipleScattering, ScatteredLight, scattered_light
from ..scattering import check_settings as check_ms_settings
from ..scattering import leaves_out as ms_leaves_out
from ..scene.procedural import split_blocks
from ..shading import reflected, sky_reflected, sky_scattered
from ..upload import SceneUploads, check_particle_scene, particle_buffers, pinhole, sky_lights

dev.kernel_module(__name__)

NAME = "depth_impostors"
RES_MIN, RES_MAX = 2, 128  # impostor texels a side where impostor_res = 0
LIGHT_WORK = 4.0  # a texel's light-map read and phase for one light, in simple per-pixel threads (device.launch)
SETTINGS = {
    "impostor_res": Setting(0, 0, 512, "texels across a block's depth impostor (T x T); 0: from the block's size "
                                       "(``impostor_detail``)"),
    "impostor_detail": Setting(1.0, 0.125, 16.0, "with impostor_res = 0, T = this x min(3 R / r, D / 2): a texel two "
                                                 "thirds of a particle radius r across (R the block's radius) and no "
                                                 "finer than two pixels of its largest projected diameter D"),
    "cluster": Setting(1, 1, 100000, "a cloud not built of blocks is grouped into blocks of this many particles "
                                     "(neighbours in Morton order); 1: every particle on its own"),
    "slices": Setting(4, 1, 1024, "light-pass depth slices S (the paper: 4, in one RGBA texture)"),
    "light_pass": Setting(1, 0, 2, "0 exact transmittance (BVH ray queries; the sky's too), 1 depth slices, "
                                    "2 Fourier opacity map (the sky: depth slices for 1 and 2)",
                          names=REPRESENTATIONS),
    "light_terms": Setting(8, 1, 256, "Fourier terms K (light_pass = 2)"),
    "light_texels": Setting(0, 0, 1024, "light-pass texels per face side; 0: 4 R / r (half a median radius)"),
    "light_blocks": Setting(1, 0, 1, "1: a cloud built of blocks is splatted into the light pass block by block, "
                                     "from one light impostor per template (section 2, b + N / b work; directional "
                                     "lights and the sky); 0: particle by particle"),
    "light_samples": Setting(4, 1, 1024, "points of a one-particle instance whose light is averaged"),
    "sky_samples": Setting(8, 0, 256, "directions the sky's light (the scene's background) is gathered from, each "
                                       "through its own coarse light pass; 0: no sky light"),
    "widen": Setting(0.0, 0.0, 16.0, "forward-scattering widening (section 2.3): the light at a texel averaged with a "
                                     "ring this many median particle radii across, weighted by the phase function; "
                                     "0: off"),
    "particle_shading": Setting(0, 0, 1, "how a one-particle instance is shaded: sphere, one radiance a particle (its "
                                         "irradiance averaged over light_samples points of the sphere: the paper's "
                                         "particles); chord, each pixel's visible chord through it at the depth its "
                                         "light comes from (large or thick particles, whose lit and shadowed sides "
                                         "differ, and a camera among them)", names=("sphere", "chord")),
    "object_depth": Setting(1, 0, 1, "1: depth impostors (a block's opacity cut where a surface lies inside its "
                                     "depth interval); 0: billboards (a block at its centre plane, as the paper fixes)",
                                     names=("billboards", "impostors")),
    **MS_SETTINGS,
}


@wp.struct
class Impostors:
    """Per texel of every template's impostor: opacity, front and back depth from the centre."""
    alpha: wp.array(dtype=wp.vec3)
    front: wp.array(dtype=float)
    back: wp.array(dtype=float)
    mid: wp.array(dtype=float)  # the depth a texel is shaded at
    res: int  # texels a side for this view, T (at most Blocks.res, the layout's)
    fwd: wp.vec3  # the direction they were made for, and its frame
    right: wp.vec3
    up: wp.vec3


@wp.func
def texel_uv(k: int, T: int, R: float):
    """(u, v) of texel k of a T x T impostor over a disc of radius R, from its centre."""
    u = ((float(k % T) + 0.5) / float(T) * 2.0 - 1.0) * R
    v = ((float(k / T) + 0.5) / float(T) * 2.0 - 1.0) * R
    return u, v


@wp.kernel
def make_impostors(offset: int, B: Blocks, reach: wp.array(dtype=float), imp: Impostors,
                   textured: wp.array(dtype=int)):
    """Thread per (textured template, texel of its T x T impostor): the total opacity of the block's spheres
    along the texel's ray (direction imp.fwd), the nearest entry and farthest exit, and the
    depth the texel is shaded at: the chords' own emission-weighted depths (the mean depth
    of a first collision inside each), averaged with weights what each chord sends toward
    the viewer, e^(-tau in front of it) (1 - e^(-its own tau)): the visible part of a thick
    texel lies at its front, not at its middle."""
    T2 = imp.res * imp.res
    i = wp.tid() + offset
    t = textured[i / T2]
    k = i % T2
    tid = B.texel0[t] + k
    R = reach[t]
    u, v = texel_uv(k, imp.res, R)
    o = u * imp.right + v * imp.up - R * imp.fwd
    r = B.radius[t]
    sig = (B.sigma_t[t][0] + B.sigma_t[t][1] + B.sigma_t[t][2]) / 3.0
    tau = float(0.0)
    lo = float(INF)
    hi = float(-INF)
    wsum = float(0.0)
    dsum = float(0.0)
    j0 = B.first[t]
    j1 = j0 + B.count[t]
    for j in range(j0, j1):
        a, b = ray_sphere(o, imp.fwd, B.offsets[j], r)
        if b > a:
            tau += b - a
            lo = wp.min(lo, a - R)
            hi = wp.max(hi, b - R)
            before = float(0.0)  # chord length of the other spheres in front of this one's entry
            for q in range(j0, j1):
                if q != j:
                    a2, b2 = ray_sphere(o, imp.fwd, B.offsets[q], r)
                    before += wp.max(wp.min(b2, a) - a2, 0.0)
            tj = sig * (b - a)
            w = wp.exp(-sig * before) * (1.0 - wp.exp(-tj))
            # the chord's own emission-weighted depth: a + (b - a) (1 / tau - e^-tau / (1 - e^-tau))
            g = float(0.5)
            if tj > 1.0e-3:
                g = 1.0 / tj - wp.exp(-tj) / (1.0 - wp.exp(-tj))
            wsum += w
            dsum += w * (a + (b - a) * g - R)
    imp.alpha[tid] = wp.vec3(1.0) - transmittance_rgb(B.sigma_t[t] * tau)
    imp.front[tid] = lo
    imp.back[tid] = hi
    imp.mid[tid] = wp.where(wsum > 0.0, dsum / wp.max(wsum, 1.0e-30), 0.5 * (lo + hi))


@wp.func
def particle_light_transmittance(m: LightMap, P: Particles, l: int, light: Emitter, x: wp.vec3, wi: wp.vec3,
                                 widen: float, ph: PhaseParams, table: wp.array(dtype=float)) -> wp.vec3:
    """Transmittance from light l to x; ``widen`` > 0: the paper's forward-scattering widening
    (section 2.3: "the radiance of those pixels of both enclosing slices are taken into
    account, for which the phase function is not negligible"), read as the light at x plus
    the light at six points a distance ``widen`` across the light's ray and as far upstream
    (toward the light), each weighted by the phase function for scattering from there to x
    (the centre by p(0 degrees), the ring by p(45 degrees)), normalised: a shadow's edge
    blurs more the flatter the phase function."""
    tr = transmittance_rgb(optical_depth_to_light(m, P, -1, l, light, x))
    if widen <= 0.0:
        return tr
    w0 = phase_eval(ph, table, 1.0)
    w1 = phase_eval(ph, table, 0.7071068)
    a = wp.where(wp.abs(wi[0]) < 0.9, wp.vec3(1.0, 0.0, 0.0), wp.vec3(0.0, 1.0, 0.0))
    e1 = wp.normalize(wp.cross(wi, a))
    e2 = wp.cross(wi, e1)
    acc = w0 * tr
    for k in range(6):
        ang = float(k) * 1.0471976
        y = x + widen * (wp.cos(ang) * e1 + wp.sin(ang) * e2 + wi)
        acc += w1 * transmittance_rgb(optical_depth_to_light(m, P, -1, l, light, y))
    return acc / (w0 + 6.0 * w1)


@wp.struct
class CloudLight:
    """What lights the cloud: the light pass's map of the scene's lights and of the sky's
    directions (an empty array: no sky), and the particles the maps were made from."""

    m: LightMap
    lights: wp.array(dtype=Emitter)
    m_sky: LightMap
    sky: wp.array(dtype=Emitter)
    P: Particles


@wp.struct
class Shaded:
    """The shade stage's output: each textured instance's texels (from ``first`` of it) and each
    one-particle instance's radiance; with ``chord`` = 1 the one-particle instances are shaded
    in the gather instead, per pixel, from what lights the cloud (``cl``, ``pf``, ``widen``, the
    lattice ``ms``)."""

    texels: wp.array(dtype=wp.vec3)
    first: wp.array(dtype=int)
    particles: wp.array(dtype=wp.vec3)
    chord: int
    cl: CloudLight
    pf: PhaseFn
    ms: ScatteredLight
    widen: float


@wp.struct
class SurfaceLayer:
    """The nearest surface per pixel (distance, INF: none; reflected light) and whether it cuts
    the impostors by depth (``object_depth``)."""

    depth: wp.array(dtype=float)
    colour: wp.array(dtype=wp.vec3)
    object_depth: int


@wp.func
def in_scatter(m: LightMap, P: Particles, lights: wp.array(dtype=Emitter), ph: PhaseParams, table: wp.array(dtype=float),
               x: wp.vec3, w_out: wp.vec3, widen: float, sky: int) -> wp.vec3:
    """Light scattered at x toward w_out per unit albedo: sum_l p E_l T_l(x). ``sky`` = 1:
    the lights are a sky's directions (``upload.sky_lights``), and the sum is divided by
    sum_l p, the quadrature of int p L_sky T dw (exact where nothing shadows x)."""
    L = wp.vec3(0.0)
    psum = float(0.0)
    for l in range(lights.shape[0]):
        wi, dist, e = light_incident(lights[l], x)
        p = phase_eval(ph, table, wp.dot(-wi, w_out))
        psum += p
        if e[0] > 0.0 or e[1] > 0.0 or e[2] > 0.0:
            L += p * wp.cw_mul(e, particle_light_transmittance(m, P, l, lights[l], x, wi, widen, ph, table))
    if sky != 0:
        L = sky_scattered(L, wp.vec3(psum))
    return L


@wp.kernel
def shade_texels(offset: int, B: Blocks, imp: Impostors, cl: CloudLight, pf: PhaseFn, eye: wp.vec3, widen: float,
                 ms: ScatteredLight, inst: wp.array(dtype=int), radiance: wp.array(dtype=wp.vec3)):
    """Thread (textured instance j, texel k): what the texel's segment scatters toward the
    eye, per unit opacity: albedo (sum_l p E_l T_l + the sky's) at its mid-depth point."""
    tid = wp.tid() + offset
    T2 = imp.res * imp.res
    j = tid / T2
    k = tid % T2
    i = inst[j]
    t = B.tpl[i]
    texel = B.texel0[t] + k
    L = wp.vec3(0.0)
    if imp.alpha[texel][0] > 0.0 or imp.alpha[texel][1] > 0.0 or imp.alpha[texel][2] > 0.0:
        u, v = texel_uv(k, imp.res, B.reach[i])
        x = B.centre[i] + u * imp.right + v * imp.up + imp.mid[texel] * imp.fwd
        w = wp.normalize(eye - x)
        L = in_scatter(cl.m, cl.P, cl.lights, pf.phase, pf.table, x, w, widen, 0)
        if cl.sky.shape[0] > 0:
            L += in_scatter(cl.m_sky, cl.P, cl.sky, pf.phase, pf.table, x, w, 0.0, 1)
        L = wp.cw_mul(B.albedo[t], L) + scattered_light(ms, B.albedo[t], x)
    radiance[j * B.res * B.res + k] = L  # the layout's T^2 per instance, as Shaded.first


@wp.kernel
def shade_particles(offset: int, B: Blocks, direct: wp.array(dtype=wp.vec3), travel: wp.array(dtype=wp.vec3),
                    L: int, particle: wp.array(dtype=int), pf: PhaseFn, eye: wp.vec3, sky: int,
                    out: wp.array(dtype=wp.vec3)):
    """One-particle instance i: adds albedo sum_l p(travel_l . w_eye) E_l T_l (sphere means);
    ``sky`` = 1: the lights are a sky's directions, the sum divided by sum_l p."""
    i = wp.tid() + offset
    p = particle[i]
    w = wp.normalize(eye - B.centre[i])
    acc = wp.vec3(0.0)
    psum = float(0.0)
    for l in range(L):
        ph_l = phase_toward(pf.phase, pf.table, travel[p * L + l], w)
        psum += ph_l
        acc += ph_l * direct[p * L + l]
    if sky != 0:
        acc = sky_scattered(acc, wp.vec3(psum))
    out[i] = out[i] + wp.cw_mul(B.albedo[B.tpl[i]], acc)


@wp.kernel
def scattered_particles(offset: int, B: Blocks, ms: ScatteredLight, out: wp.array(dtype=wp.vec3)):
    """Instance i: adds albedo R(centre), the light scattered more than once toward the eye."""
    i = wp.tid() + offset
    out[i] = out[i] + scattered_light(ms, B.albedo[B.tpl[i]], B.centre[i])


@wp.kernel
def shade_surfaces(offset: int, cam: RasterView, s: Surfaces, cl: CloudLight, depth: wp.array(dtype=float),
                   colour: wp.array(dtype=wp.vec3)):
    """Per pixel: the nearest surface's distance along the pixel ray (INF: none) and the
    light it reflects, through the cloud (the light pass) and past the other surfaces; the
    sky's as pi f L_sky sum_k cos_k T_k V_k / sum_k cos_k over its directions (exact for an
    unshadowed diffuse surface)."""
    tid = wp.tid() + offset
    o, d = pixel_ray(cam, tid)
    hit, t, n, face = surface_hit(s, o, d, INF)
    L = wp.vec3(0.0)
    if hit:
        if wp.dot(n, d) > 0.0:
            n = -n
        x = o + t * d
        mat = s.material[face]
        for l in range(cl.lights.shape[0]):
            wi, dist, e = light_incident(cl.lights[l], x)
            cos_l = wp.dot(n, wi)
            if cos_l > 0.0 and not occluded(s, x + RAY_EPS * n, wi, dist):
                tr = transmittance_rgb(optical_depth_to_light(cl.m, cl.P, -1, l, cl.lights[l], x))
                L += reflected(mat, n, -d, wi, cos_l, e, tr)
        acc = wp.vec3(0.0)
        csum = float(0.0)
        for l in range(cl.sky.shape[0]):
            wi, dist, e = light_incident(cl.sky[l], x)
            cos_l = wp.dot(n, wi)
            if cos_l > 0.0:
                csum += cos_l
                if not occluded(s, x + RAY_EPS * n, wi, dist):
                    tr = transmittance_rgb(optical_depth_to_light(cl.m_sky, cl.P, -1, l, cl.sky[l], x))
                    acc += reflected(mat, n, -d, wi, cos_l, e, tr)
        L += sky_reflected(acc, csum)
    depth[tid] = wp.where(hit, t, INF)
    colour[tid] = L


@wp.func
def bilinear_taps(T: int, fx: float, fy: float):
    """The four texels (row-major in a T x T grid, clamped at its edges) a bilinear lookup at
    texel coordinates (fx, fy) blends, and its two weights; the nearest texel is the first
    (rounded) where the weights are below a half."""
    i0 = wp.clamp(int(wp.floor(fx)), 0, T - 1)
    j0 = wp.clamp(int(wp.floor(fy)), 0, T - 1)
    i1 = wp.min(i0 + 1, T - 1)
    j1 = wp.min(j0 + 1, T - 1)
    ax = wp.clamp(fx - float(i0), 0.0, 1.0)
    ay = wp.clamp(fy - float(j0), 0.0, 1.0)
    return wp.vec4i(j0 * T + i0, j0 * T + i1, j1 * T + i0, j1 * T + i1), ax, ay


@wp.func
def blend4(a: wp.array(dtype=wp.vec3), base: int, k: wp.vec4i, ax: float, ay: float) -> wp.vec3:
    """The bilinear blend of a[base + k] for the taps and weights of ``bilinear_taps``."""
    top = wp.lerp(a[base + k[0]], a[base + k[1]], ax)
    return wp.lerp(top, wp.lerp(a[base + k[2]], a[base + k[3]], ax), ay)


@wp.func
def chord_radiance(sh: Shaded, albedo: wp.vec3, sigma: wp.vec3, o: wp.vec3, d: wp.vec3, a: float, b: float) -> wp.vec3:
    """What a pixel's chord [a, b] through a one-particle instance scatters toward the eye per
    unit opacity, shaded at the depth its light comes from: the mean of s under sigma e^(-sigma s)
    over the chord, 1 / sigma - l e^(-sigma l) / (1 - e^(-sigma l)) (the middle where thin,
    the front where thick)."""
    sig = (sigma[0] + sigma[1] + sigma[2]) / 3.0
    l = b - a
    t = 0.5 * l
    tau = sig * l
    if tau > 1.0e-3:
        t = 1.0 / sig - l * wp.exp(-tau) / (1.0 - wp.exp(-tau))
    x = o + (a + t) * d
    L = in_scatter(sh.cl.m, sh.cl.P, sh.cl.lights, sh.pf.phase, sh.pf.table, x, -d, sh.widen, 0)
    if sh.cl.sky.shape[0] > 0:
        L += in_scatter(sh.cl.m_sky, sh.cl.P, sh.cl.sky, sh.pf.phase, sh.pf.table, x, -d, 0.0, 1)
    return wp.cw_mul(albedo, L) + scattered_light(sh.ms, albedo, x)


@wp.kernel
def gather(offset: int, per: int, cam: RasterView, B: Blocks, imp: Impostors, tl: TileLists,
           shaded: Shaded, surf: SurfaceLayer, background: wp.vec3, image: wp.array(dtype=wp.vec3)):
    """Front to back over the pixel's tile: each instance adds T alpha L and scales T by
    1 - alpha, its opacity cut where the surface lies inside it. A textured instance's
    transmittance is 1 - alpha straight from its impostor (no log or exp), except where the
    surface cuts it: there (1 - alpha)^f, f the fraction of its depth interval in front. It
    is read only within the block's reach R of its centre in its plane: its spheres lie
    there, and beyond R the bilinear lookup would smear its last texels outward. A pixel
    whose tile lists nothing shows what lies behind. A thread does ``per`` pixels in a row
    (``device.per_thread``)."""
    first = (wp.tid() + offset) * per
    for tid in range(first, wp.min(first + per, cam.width * cam.height)):
        t_s = surf.depth[tid]
        tile = pixel_tile(cam, tid, tl.tiles_x)
        if tl.first[tile] == tl.last[tile]:  # no instance near this pixel: what lies behind
            image[tid] = wp.where(t_s < INF, surf.colour[tid], background)
            continue
        o, d = pixel_ray(cam, tid)
        L = wp.vec3(0.0)
        Tr = wp.vec3(1.0)
        one = wp.vec3(1.0)
        cos_f = wp.max(wp.dot(d, imp.fwd), 1.0e-6)
        for q in range(tl.first[tile], tl.last[tile]):
            i = tl.values[q]
            t = B.tpl[i]
            c = B.centre[i]
            tr = one
            Lq = wp.vec3(0.0)
            if B.texel0[t] < 0:  # one particle: its chord along the ray, cut at the surface
                a, b = ray_sphere(o, d, c, B.radius[t])
                a = wp.max(a, 0.0)
                if surf.object_depth == 0:
                    if wp.dot(c - o, d) > t_s:
                        b = a
                else:
                    b = wp.min(b, t_s)
                if b > a:
                    tr = transmittance_rgb(B.sigma_t[t] * (b - a))
                    if shaded.chord != 0:
                        Lq = chord_radiance(shaded, B.albedo[t], B.sigma_t[t], o, d, a, b)
                    else:
                        Lq = shaded.particles[i]
            else:
                t_plane = wp.dot(c - o, imp.fwd) / cos_f
                x = o + t_plane * d - c  # in the plane: x . fwd = 0
                u = wp.dot(x, imp.right)
                v = wp.dot(x, imp.up)
                R = B.reach[i]
                if t_plane > 0.0 and u * u + v * v < R * R:  # beyond R no sphere of the block
                    T = imp.res
                    h = 0.5 * float(T) / R
                    taps, ax, ay = bilinear_taps(T, (u + R) * h - 0.5, (v + R) * h - 0.5)
                    base = B.texel0[t]
                    tr = one - blend4(imp.alpha, base, taps, ax, ay)
                    k = taps[wp.where(ay < 0.5, 0, 2) + wp.where(ax < 0.5, 0, 1)]  # the nearest texel
                    t0 = t_plane + imp.front[base + k] / cos_f
                    t1 = t_plane + imp.back[base + k] / cos_f
                    if surf.object_depth == 0:
                        if t_plane > t_s:
                            tr = one
                    elif t_s <= t0:
                        tr = one
                    elif t_s < t1:
                        f = (t_s - t0) / (t1 - t0)
                        tr = wp.vec3(wp.pow(wp.max(tr[0], 1.0e-30), f), wp.pow(wp.max(tr[1], 1.0e-30), f),
                                     wp.pow(wp.max(tr[2], 1.0e-30), f))
                    if tr[0] < 1.0 or tr[1] < 1.0 or tr[2] < 1.0:
                        Lq = blend4(shaded.texels, shaded.first[i], taps, ax, ay)
            if tr[0] < 1.0 or tr[1] < 1.0 or tr[2] < 1.0:
                L += wp.cw_mul(wp.cw_mul(Tr, one - tr), Lq)
                Tr = wp.cw_mul(Tr, tr)
                if wp.max(Tr[0], wp.max(Tr[1], Tr[2])) < 1.0e-5:
                    break
        behind = background
        if t_s < INF:
            behind = surf.colour[tid]
        image[tid] = L + wp.cw_mul(Tr, behind)


def morton_groups(positions: np.ndarray, size: int) -> list[np.ndarray]:
    """Indices of ``positions`` in groups of ``size`` (the last may be smaller), neighbours
    along a Morton (Z-order) curve over their bounding box: compact blocks, found in
    O(N log N)."""
    p = np.asarray(positions, np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    q = np.clip(((p - lo) / np.maximum(hi - lo, 1e-12) * 1023).astype(np.int64), 0, 1023)
    code = np.zeros(len(p), np.int64)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> bit) & 1) << (3 * bit + axis)
    order = np.argsort(code, kind="stable")
    return [order[k:k + size] for k in range(0, len(order), size)]


class DepthImpostors(Technique):
    """Umenhoffer & Szirmay-Kalos 2005: depth impostors of particle blocks, light slices, objects in clouds."""

    NAME = NAME
    SETTINGS = SETTINGS
    QUALITY = Quality(knob="slices", start=2, top=512, order=1, biases=(
        Bias("light_pass", exact=0), Bias("impostor_detail", factor=4, order=1),
        Bias("light_samples", factor=4, order=1), Bias("sky_samples", factor=4, order=1, when="sky"), *MS_BIASES))
    LEAVES_OUT = ()

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        check_particle_scene(NAME, scene)
        self.uploads = SceneUploads(self, medium=False)
        self.multiple = MultipleScattering(self, lambda: self.uploads.surfaces, lambda: self.uploads.lights)
        self._cloud: ParticleBuffers | None = None
        self._template_key: tuple | None = None  # what the impostors were made from
        self.blocks: Blocks | None = None
        self._reach_t = None  # per template bounding radius (device)
        self._textured_t = None  # the templates with a texture (device)
        self._inst_host = None  # per instance on the host: centre, bounding radius, textured or not
        self._textured = None  # instances with a texture (device) and their first radiance texel
        self._first = None
        self._particle_of = None  # one-particle instances: their particle index in the cloud
        self.n_instances = 0
        self.n_textured = 0
        self.texels = 0
        self.phase = self.table = None
        self.light_pass: LightPass | None = None
        self.sky_pass: LightPass | None = None  # the sky's directions (None: a black sky, or sky_samples = 0)
        self.sky = None
        self.impostors: Impostors | None = None
        self.texel_radiance = self.particle_radiance = None
        self.surf_depth = self.surf_colour = None
        self.image = None
        self.gather_tests = 0  # (pixel, instance) pairs the gather looks at: its tiles' lists x their pixels

    def check_settings(self, settings):
        check_ms_settings(NAME, settings)

    def leaves_out(self) -> list[str]:
        shadows = (["the surfaces' shadows on the cloud (the light pass holds the particles alone)"]
                   if self.scene.surfaces and self.scene.lights else [])
        return [*ms_leaves_out(self.settings), *super().leaves_out(), *shadows]

    def stages(self):
        surfaces = bool(self.scene.surfaces)
        return self.uploads.stages() + [
            *self.multiple.stages(after=("surfaces", "lights")),
            Stage("blocks", self._blocks, reads=("medium",),
                  settings=("impostor_res", "impostor_detail", "cluster", "light_pass")),
            Stage("light", self._light, reads=("lights", "background"),
                  settings=("slices", "light_pass", "light_terms", "light_texels", "light_samples", "sky_samples",
                            "light_blocks"),
                  after=("blocks", "lights")),
            Stage("templates", self._templates, after=("blocks",)),
            Stage("impostors", self._impostors, reads=("camera",), settings=("impostor_detail", "impostor_res"),
                  after=("templates",)),
            Stage("shade", self._shade, reads=("camera",),
                  settings=("widen", "multiple_scattering", "light_samples", "sky_samples", "particle_shading"),
                  after=("light", "impostors", "multiple_view")),
            Stage("surfaces_lit", self._surfaces_lit, reads=("camera",), after=("light", "surfaces"),
                  needed=surfaces),
            Stage("gather", self._gather, reads=("camera", "background"),
                  settings=("object_depth", "particle_shading", "widen", "multiple_scattering", "sky_samples"),
                  after=("shade", "surfaces_lit") if surfaces else ("shade",)),
        ]

    # --- stages -------------------------------------------------------------------------

    def _blocks(self):
        device = self.device
        centres, tpl_of, offsets, first, count, t_radius, t_sigma, t_albedo, texel0, particle_of = ([] for _ in range(10))
        n_tex = 0  # textured templates so far

        def template(offs: np.ndarray, m, textured: bool) -> int:
            nonlocal n_tex
            first.append(sum(len(o) for o in offsets))
            offsets.append(np.asarray(offs, np.float64).reshape(-1, 3))
            count.append(len(offsets[-1]))
            t_radius.append(m.radius)
            t_sigma.append(m.sigma_t)
            t_albedo.append(m.albedo)
            texel0.append(n_tex if textured else -1)  # times T^2 once T is known
            n_tex += 1 if textured else 0
            return len(first) - 1

        base = 0
        for m in self.scene.media:
            p = np.asarray(m.positions, np.float32).reshape(-1, 3)
            split = split_blocks(p, int(getattr(m, "block_size", 0)))
            if split is not None:  # K copies of one block
                offs, inst = split
                t = template(offs, m, True)
                centres.append(inst)
                tpl_of.append(np.full(len(inst), t, np.int32))
                particle_of.append(np.full(len(inst), -1, np.int32))
            elif self.settings["cluster"] > 1 and len(p) > 1:  # grouped: each group a template of its own
                for group in morton_groups(p, self.settings["cluster"]):
                    g = p[group].astype(np.float64)
                    c = g.mean(axis=0)
                    t = template(g - c, m, len(g) > 1)
                    centres.append(c[None])
                    tpl_of.append(np.array([t], np.int32))
                    particle_of.append(np.array([base + group[0] if len(g) == 1 else -1], np.int32))
            else:  # every particle an instance of a one-particle template
                t = template(np.zeros((1, 3)), m, False)
                centres.append(p.astype(np.float64))
                tpl_of.append(np.full(len(p), t, np.int32))
                particle_of.append(np.arange(base, base + len(p), dtype=np.int32))
            base += len(p)
        self._cloud = particle_buffers(self.scene.media, device, hash_grid=False, bvh=self.settings["light_pass"] == 0)
        offsets_np = np.concatenate(offsets).astype(np.float64)
        centres = np.concatenate(centres)
        tpl_of = np.concatenate(tpl_of)
        particle_of = np.concatenate(particle_of)
        reach_t = np.array([np.sqrt((offsets_np[f:f + c] ** 2).sum(1)).max() + r
                            for f, c, r in zip(first, count, t_radius)], np.float32)
        textured_t = np.nonzero(np.asarray(texel0) >= 0)[0].astype(np.int32)
        T = self._layout_res(reach_t[textured_t], np.asarray(t_radius, np.float64)[textured_t])
        texel0 = [j * T * T if j >= 0 else -1 for j in texel0]
        texels = n_tex * T * T
        B = Blocks()
        f3 = lambda a: wp.array(np.asarray(a, np.float32).reshape(-1, 3), dtype=wp.vec3, device=device)  # noqa: E731
        B.centre = f3(centres)
        B.tpl = wp.array(tpl_of, dtype=int, device=device)
        B.reach = wp.array(reach_t[tpl_of] if len(tpl_of) else np.zeros(0, np.float32), dtype=float, device=device)
        B.first = wp.array(np.asarray(first, np.int32), dtype=int, device=device)
        B.count = wp.array(np.asarray(count, np.int32), dtype=int, device=device)
        B.offsets = f3(offsets_np)
        B.radius = wp.array(np.asarray(t_radius, np.float32), dtype=float, device=device)
        B.sigma_t = f3(t_sigma)
        B.albedo = f3(t_albedo)
        B.texel0 = wp.array(np.asarray(texel0, np.int32), dtype=int, device=device)
        B.res = T  # the layout's texels a side; Impostors.res: this view's, at most this
        self.blocks = B
        self._reach_t = wp.array(reach_t, dtype=float, device=device)
        self._textured_t = wp.array(textured_t, dtype=int, device=device)
        self._texel_work = float(np.mean(np.asarray(count)[textured_t])) if len(textured_t) else 1.0
        self.texels = texels
        self.n_instances = len(tpl_of)
        has_texture = np.asarray(texel0, np.int64)[tpl_of] >= 0 if len(tpl_of) else np.zeros(0, bool)
        textured = np.nonzero(has_texture)[0].astype(np.int32)
        self.n_textured = len(textured)
        self._inst_host = (centres.astype(np.float64), reach_t[tpl_of].astype(np.float64), has_texture)
        self._textured = wp.array(textured, dtype=int, device=device)
        first_rad = np.full(max(len(tpl_of), 1), 0, np.int32)
        first_rad[textured] = np.arange(len(textured), dtype=np.int32) * T * T
        self._first = wp.array(first_rad, dtype=int, device=device)
        self._particle_of = wp.array(np.maximum(particle_of, 0) if len(particle_of) else np.zeros(1, np.int32),
                                     dtype=int, device=device)
        self.phase, table = phase_struct(self.scene.media[0].phase)
        self.table = wp.array(table if len(table) else np.zeros(1, np.float32), dtype=float, device=device)

    def _templates(self) -> bool:
        """Whether the templates changed: an animation that only moves the instances leaves the
        impostors as they are (returns False, so the impostors stage stays cached). Offsets are
        compared to 1e-6 of the block's size: moving a block in float32 re-rounds them."""
        B = self.blocks
        exact = b"".join(a.numpy().tobytes() for a in (B.first, B.count, B.radius, B.sigma_t, B.texel0))
        exact += np.int64(B.res).tobytes()
        offsets = B.offsets.numpy().astype(np.float64)
        old = self._template_key
        same = (old is not None and old[0] == exact and old[1].shape == offsets.shape
                and np.allclose(old[1], offsets, rtol=0.0, atol=1e-6 * max(float(np.abs(offsets).max()), 1e-12)))
        if not same:
            self._template_key = (exact, offsets)
        return not same

    def _light(self):
        s = self.settings
        self.light_pass = LightPass(self.device, REPRESENTATIONS[s["light_pass"]], slices=s["slices"],
                                    terms=s["light_terms"], texels=s["light_texels"])
        blocks = None  # the block light pass: where every particle is in a block of several
        if s["light_blocks"] and self.n_instances and self.n_textured == self.n_instances:
            blocks = BlockCloud(self.blocks, self._reach_t, self.n_instances)
        self.light_pass.build(self._cloud, self.uploads.lights, s["light_samples"], blocks)
        self.sky = sky_lights(self.scene.background, s["sky_samples"], self.device)
        self.sky_pass = None
        if self.sky is not None:  # soft light: slices on a quarter of the sun's texels; exact with the sun's
            self.sky_pass = LightPass(self.device, "exact" if s["light_pass"] == 0 else "slices", slices=s["slices"],
                                      texels=max(16, (self.light_pass.M or 64) // 4))
            self.sky_pass.build(self._cloud, self.sky, s["light_samples"], blocks)

    def _impostors(self):
        pc = pinhole(self.scene.camera)  # the camera's frame, right and up scaled by the field of view
        imp = Impostors()
        imp.fwd, imp.right, imp.up = pc.forward, wp.normalize(pc.right), wp.normalize(pc.up)
        n = max(self.texels, 1)
        imp.alpha = wp.zeros(n, dtype=wp.vec3, device=self.device)
        imp.front = wp.zeros(n, dtype=float, device=self.device)
        imp.back = wp.zeros(n, dtype=float, device=self.device)
        imp.mid = wp.zeros(n, dtype=float, device=self.device)
        imp.res = self._view_res()
        if self.texels:
            # a texel tests its ray against the block's b spheres, and each sphere it meets against the
            # others in front: split over the cores by that work, not by the texel count
            dev.launch(make_impostors, self._textured_t.shape[0] * imp.res * imp.res,
                       [self.blocks, self._reach_t, imp, self._textured_t], self.device, work=self._texel_work)
        self.impostors = imp

    def _layout_res(self, reach: np.ndarray, radius: np.ndarray) -> int:
        """Texels a side the impostors are laid out for: ``impostor_res``, or where that is 0,
        ``impostor_detail`` x 3 R / r for the textured template of the most particle radii r
        across its radius R (a texel two thirds of a radius wide: finer adds nothing the
        spheres' own edges do not blur), within [RES_MIN, RES_MAX]."""
        fixed = self.settings["impostor_res"]
        if fixed > 0 or not len(reach):
            return max(fixed, 1)
        across = float(np.max(reach / np.maximum(radius, 1e-12)))
        return int(np.clip(np.ceil(self.settings["impostor_detail"] * 3.0 * across), RES_MIN, RES_MAX))

    def _view_res(self) -> int:
        """Texels a side for this view: the layout's, or where ``impostor_res`` is 0, no more
        than ``impostor_detail`` x D / 2 for D the largest projected diameter in pixels of a
        textured instance (2 R / (distance - R) x the focal length in pixels): a texel need not
        be finer than two pixels. An instance around the camera keeps the layout's."""
        T = self.blocks.res
        centres, reach, textured = self._inst_host
        if self.settings["impostor_res"] > 0 or not textured.any():
            return T
        cam = self.scene.camera
        focal = 0.5 * cam.height / np.tan(np.radians(cam.fov_y) / 2.0)
        dist = np.linalg.norm(centres[textured] - np.asarray(cam.origin, np.float64), axis=1)
        R = reach[textured]
        if np.any(dist <= R):
            return T
        D = float(np.max(2.0 * R / (dist - R))) * focal
        return int(np.clip(np.ceil(self.settings["impostor_detail"] * 0.5 * D), RES_MIN, T))

    def _sky_args(self):
        """The sky's map and directions for a kernel (an empty array when there is no sky)."""
        if self.sky is None:
            return self.light_pass.map, wp.empty(0, dtype=Emitter, device=self.device)
        return self.sky_pass.map, self.sky

    def _cloud_light(self) -> CloudLight:
        cl = CloudLight()
        cl.m, cl.lights, cl.P = self.light_pass.map, self.uploads.lights, self._cloud.struct
        cl.m_sky, cl.sky = self._sky_args()
        return cl

    def _shade(self):
        device, T = self.device, self.blocks.res
        eye = wp.vec3(*self.scene.camera.origin)
        self.texel_radiance = wp.zeros(max(self.n_textured * T * T, 1), dtype=wp.vec3, device=device)
        self.particle_radiance = wp.zeros(max(self.n_instances, 1), dtype=wp.vec3, device=device)
        m_sky, sky = self._sky_args()
        ms = self.multiple.struct()
        if ms.lat.n > 0 and not self.settings["particle_shading"]:  # chord: read per pixel in the gather
            dev.launch(scattered_particles, self.n_instances, [self.blocks, ms, self.particle_radiance], device)
        if not len(self.scene.lights) and not sky.shape[0] and ms.lat.n == 0:
            return
        if self.n_textured:
            radii = self._cloud.radius
            widen = self.settings["widen"] * (float(np.median(radii)) if len(radii) else 0.0)
            T = self.impostors.res
            dev.launch(shade_texels, self.n_textured * T * T,
                       [self.blocks, self.impostors, self._cloud_light(), phase_fn(self.phase, self.table), eye, widen,
                        ms, self._textured, self.texel_radiance], device,
                       work=LIGHT_WORK * (len(self.scene.lights) + sky.shape[0]))
        if self.n_instances > self.n_textured and not self.settings["particle_shading"]:
            n = self._cloud.struct.centres.shape[0]
            for lights, lp, is_sky in ((self.uploads.lights, self.light_pass, 0), (sky, self.sky_pass, 1)):
                L = lights.shape[0]
                if not L:
                    continue
                direct = wp.zeros(n * L, dtype=wp.vec3, device=device)
                travel = wp.zeros(n * L, dtype=wp.vec3, device=device)
                lp.direct(self._cloud, lights, self.settings["light_samples"], direct, travel)
                dev.launch(shade_particles, self.n_instances, [self.blocks, direct, travel, L, self._particle_of,
                                                               phase_fn(self.phase, self.table), eye, is_sky,
                                                               self.particle_radiance], device)

    def _surfaces_lit(self):
        cam = self.scene.camera
        n = cam.width * cam.height
        self.surf_depth = wp.empty(n, dtype=float, device=self.device)
        self.surf_colour = wp.empty(n, dtype=wp.vec3, device=self.device)
        dev.launch(shade_surfaces, n, [camera_view(pinhole(cam)), self.uploads.surfaces, self._cloud_light(),
                                       self.surf_depth, self.surf_colour], self.device)

    def _gather(self):
        cam, device = self.scene.camera, self.device
        n = cam.width * cam.height
        view = camera_view(pinhole(cam))
        if not self.scene.surfaces:
            self.surf_depth = wp.full(n, INF, dtype=float, device=device)
            self.surf_colour = wp.zeros(n, dtype=wp.vec3, device=device)
        centres, reach, textured = self._inst_host
        # a textured instance is read in its plane within its reach R of the centre (its
        # spheres lie there; ``gather`` cuts the bilinear lookup's smear beyond R): a disc
        # inside the sphere of radius R, so the sphere's tiles hold it
        eye = np.asarray(cam.origin, np.float64)
        z_far = float(np.max(np.linalg.norm(centres - eye, axis=1) + reach)) if len(centres) else 1.0
        tl = bin_spheres(view, self.blocks.centre, wp.array(reach.astype(np.float32), dtype=float, device=device), z_far,
                         device)
        self.gather_tests = (tl.values.shape[0] // 2) * SPHERE_TILE * SPHERE_TILE
        self.image = wp.empty(n, dtype=wp.vec3, device=device)
        shaded = Shaded()
        shaded.texels, shaded.first, shaded.particles = self.texel_radiance, self._first, self.particle_radiance
        shaded.chord = int(self.settings["particle_shading"])
        shaded.cl, shaded.pf, shaded.ms = self._cloud_light(), phase_fn(self.phase, self.table), self.multiple.struct()
        radii = self._cloud.radius
        shaded.widen = self.settings["widen"] * (float(np.median(radii)) if len(radii) else 0.0)
        surf = SurfaceLayer()
        surf.depth, surf.colour, surf.object_depth = self.surf_depth, self.surf_colour, self.settings["object_depth"]
        per = dev.per_thread(device)
        dev.launch(gather, dev.groups(n, per), [per, view, self.blocks, self.impostors, tl, shaded, surf, wp.vec3(*self.scene.background),
                               self.image], device, min_split=dev.MIN_SPLIT // per)

    def output(self):
        return self.image

    def diagnostics(self) -> dict:
        """``instances``: how many block instances; ``block_centres`` (instances x 3) and
        ``block_reach`` (instances): each one's centre and bounding radius, world units;
        ``light_texels``: the light pass's texels per face side (0 before it is built);
        ``light_refined``: how often its map was refined to meet its tolerance;
        ``light_fell_back``: whether it fell back to exact transmittance;
        ``light_template_texels``: texels a side of each template's light impostor (0: the
        light pass splatted particle by particle); ``impostor_res``: texels a side of the
        camera impostors in this view (``_view_res``); ``gather_tests``: the (pixel, instance)
        pairs the gather looks at (each tile's list times its pixels)."""
        return {"instances": self.n_instances, "block_centres": self.blocks.centre.numpy(),
                "block_reach": self.blocks.reach.numpy(),
                "light_texels": self.light_pass.M if self.light_pass is not None else 0,
                "light_refined": len(self.light_pass.refined) if self.light_pass is not None else 0,
                "light_fell_back": bool(self.light_pass is not None and self.light_pass.fell_back),
                "light_template_texels": self.light_pass.template_texels if self.light_pass is not None else 0,
                "impostor_res": self.impostors.res if self.impostors is not None and self.texels else 0,
                "gather_tests": self.gather_tests}

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """The instances (centres, bounding radii), the first textured template's impostor
        layers (opacity, front and back depth; T x T) with the frame they face and the
        instance that shows them, and the light pass's faces and slices."""
        T = self.impostors.res if self.impostors is not None else 0
        out = {"instances": self.blocks.centre.numpy(), "instance_reach": self.blocks.reach.numpy()}
        if self.texels and self.impostors is not None:
            imp = self.impostors
            out.update(impostor_alpha=imp.alpha.numpy()[:T * T].reshape(T, T, 3),
                       impostor_front=imp.front.numpy()[:T * T].reshape(T, T),
                       impostor_back=imp.back.numpy()[:T * T].reshape(T, T),
                       impostor_frame=np.array([list(imp.fwd), list(imp.right), list(imp.up)], np.float32),
                       impostor_instance=int(self._textured.numpy()[0]) if self.n_textured else -1)
        if self.light_pass is not None:
            out["light_texels"] = self.light_pass.M
            layers = self.light_pass.layers()
            out["light_faces"] = layers["faces"]
            if "slices" in layers:
                out["light_slices"] = layers["slices"]
        return out


TECHNIQUE = DepthImpostors
