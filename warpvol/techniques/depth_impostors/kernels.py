"""The depth impostors' Warp code, one kernel module (one compile): the impostors of the template
blocks (``make_impostors``), what lights the cloud and the shading of texels, one-particle instances
and surfaces (``shade_texels``, ``shade_particles``, ``scattered_particles``, ``shade_surfaces``), and
the front-to-back ``gather`` of the instances per pixel tile, with the structs they pass."""

from __future__ import annotations

import warp as wp

from ... import device as dev
from ...geometry.camera import RasterView, pixel_ray
from ...geometry.intersect import ray_sphere
from ...geometry.mesh import Surfaces, occluded, surface_hit
from ...geometry.tiles import TileLists, pixel_tile
from ...media.lightpass import LightMap, optical_depth_to_light
from ...media.particles import Blocks, Particles
from ...physics.constants import INF, RAY_EPS
from ...physics.lights import Emitter, light_incident
from ...physics.phase import PhaseParams, PhaseFn, phase_eval, phase_toward
from ...physics.transmittance import transmittance_rgb
from ...scattering import ScatteredLight, scattered_light
from ...shading import reflected, sky_reflected, sky_scattered

dev.kernel_module(__name__)


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

    light_map: LightMap
    lights: wp.array(dtype=Emitter)
    sky_map: LightMap
    sky: wp.array(dtype=Emitter)
    particles: Particles


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
def in_scatter(m: LightMap, P: Particles, lights: wp.array(dtype=Emitter), ph: PhaseParams,
               table: wp.array(dtype=float), x: wp.vec3, w_out: wp.vec3, widen: float, sky: int) -> wp.vec3:
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
        L = in_scatter(cl.light_map, cl.particles, cl.lights, pf.phase, pf.table, x, w, widen, 0)
        if cl.sky.shape[0] > 0:
            L += in_scatter(cl.sky_map, cl.particles, cl.sky, pf.phase, pf.table, x, w, 0.0, 1)
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
                tr = transmittance_rgb(optical_depth_to_light(cl.light_map, cl.particles, -1, l, cl.lights[l], x))
                L += reflected(mat, n, -d, wi, cos_l, e, tr)
        acc = wp.vec3(0.0)
        csum = float(0.0)
        for l in range(cl.sky.shape[0]):
            wi, dist, e = light_incident(cl.sky[l], x)
            cos_l = wp.dot(n, wi)
            if cos_l > 0.0:
                csum += cos_l
                if not occluded(s, x + RAY_EPS * n, wi, dist):
                    tr = transmittance_rgb(optical_depth_to_light(cl.sky_map, cl.particles, -1, l, cl.sky[l], x))
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
    L = in_scatter(sh.cl.light_map, sh.cl.particles, sh.cl.lights, sh.pf.phase, sh.pf.table, x, -d, sh.widen, 0)
    if sh.cl.sky.shape[0] > 0:
        L += in_scatter(sh.cl.sky_map, sh.cl.particles, sh.cl.sky, sh.pf.phase, sh.pf.table, x, -d, 0.0, 1)
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
                    res = imp.res
                    h = 0.5 * float(res) / R
                    taps, ax, ay = bilinear_taps(res, (u + R) * h - 0.5, (v + R) * h - 0.5)
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
