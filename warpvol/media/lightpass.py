"""The light pass: what each light sees of a particle cloud, read back at any point.

A particle technique needs, for every particle and light, the transmittance from the light
to the particle through the rest of the cloud. Testing every sphere against every light
ray is O(N^2). The light pass instead renders the cloud once from each light (Szirmay-Kalos et al. 2005:
"rendering the volume from the point of view of the light source"; Umenhoffer & Szirmay-Kalos 2005's light
pass) into a light-space opacity map, O(N x footprint) work, and reads the optical depth
back at any point in O(1). One function, ``LightPass``, builds it; ``sphere_light`` reads it
for every (particle, light).

**Frames.** A directional light gets one orthographic face over the cloud's bounding ball
(centre c, radius R), depth 0 to 2R along the light. A point or spot light outside the ball
gets one perspective face on the cone that holds the ball, depth d - R to d + R from the
light; a light inside the ball (inside the cloud, at a particle's centre) gets a cube of
six 90-degree faces, depth 0 to d + R. Each face has M x M texels; a texel stores the
optical depth along the ray through its centre, in one of two representations:

* ``slices`` (Umenhoffer & Szirmay-Kalos 2005's depth slices): the optical depth at S + 1 depths evenly spaced
  over the face's depth range, tau_k = tau(near + k (far - near) / S). Each sphere adds its
  chord's exact share to every slice interval it crosses (not, as the paper does, all of
  it to the slice of its centre), so the map is exact at the slice depths; between them it
  is interpolated linearly (exact where the density along the texel ray is uniform over a
  slice). Error: O(chord structure finer than a slice).
* ``fourier`` (a Fourier opacity map; Jansen and Bavoil, I3D 2010): the extinction along
  the ray as K cosine and K sine terms over the normalised depth z in [0, 1], a_k =
  2 int sigma cos(2 pi k z) dz, b_k = 2 int sigma sin(2 pi k z) dz (closed forms per
  chord), and tau(z) = a_0 z / 2 + sum_k [a_k sin(2 pi k z) + b_k (1 - cos(2 pi k z))] /
  (2 pi k): exact total depth (at z = 1), smooth in between, clamped to [0, a_0 / 2]
  against the ringing of a truncated series. Error: O(1 / K) at a sphere's edge.

Reading interpolates the four nearest texels bilinearly. A sphere smaller than a texel
(centre-sampled, it could fall between texel centres) deposits its optical volume
sigma_t (4/3) pi r^3 over the four texels around its centre instead (the mean optical depth
over a texel is then right).

``exact`` builds no map: the optical depth is the chord sum along the actual ray through
the spheres it crosses, found by a ``wp.Bvh`` ray query (``particle_optical_depth``). It is
the yardstick the maps are measured against and the fallback when a map's error, measured
on a subset of particles at build (``LightPass.check``), is above a tolerance.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .. import device as dev
from ..geometry.intersect import ray_sphere
from ..physics.constants import PI
from ..physics.lights import DIRECTIONAL, Emitter, light_incident, particle_incident
from ..physics.transmittance import sphere_escape, step_integral, transmittance_rgb
from .blockpass import splat_block_faces
from .lightmap import (EXACT, REPRESENTATIONS, SLICES, LightFace, LightMap, deposit, face_coords,
                       face_ray, item_and_face, light_face, texel_area)
from .particles import BlockCloud, ParticleBuffers, Particles, particle_optical_depth

dev.kernel_module(__name__)

MAX_TEXELS = 1024  # texels per face side, at most
MIN_TEXELS = 64  # and by the rule at least
MAX_BYTES = 128 << 20  # one map's texels at most (a CPU build holds one copy per core)
REFINE_ROUNDS = 3  # a map above its tolerance is refined at most this many times before the exact fallback


@wp.kernel
def splat_spheres(offset: int, P: Particles, m: LightMap, blocked: int, out: wp.array(dtype=wp.vec3)):
    """Thread p F + f: sphere p into face f; every texel whose centre ray crosses it gets the
    chord (texels over the sphere's projected box), or, for a sphere under a texel, its
    optical volume over the four texels around its centre. ``blocked`` = 1: orthographic
    faces are left to ``splat_blocks``."""
    p, fi, f = item_and_face(m, wp.tid() + offset)
    if blocked != 0 and f.ortho != 0:
        return
    c = P.centres[p]
    r = P.radius[p]
    sig = P.sigma_t[p]
    M = m.M
    texel = 2.0 / float(M)
    rel = c - f.origin
    u0 = float(-1.0)
    u1 = float(1.0)
    v0 = float(-1.0)
    v1 = float(1.0)
    cu = float(0.0)
    cv = float(0.0)
    ru = float(1.0)
    tc = float(0.0)
    if f.ortho != 0:
        cu = wp.dot(rel, f.right) / f.half
        cv = wp.dot(rel, f.up) / f.half
        ru = r / f.half
        tc = wp.dot(rel, f.forward)
        u0 = cu - ru
        u1 = cu + ru
        v0 = cv - ru
        v1 = cv + ru
    else:
        z = wp.dot(rel, f.forward)
        dist = wp.length(rel)
        if z + r <= 0.0:
            return
        if dist > r and z - r > 0.0:  # wholly in front: the box of x/z and y/z over the sphere's box
            x = wp.dot(rel, f.right)
            y = wp.dot(rel, f.up)
            u0 = wp.min((x - r) / (z - r), (x - r) / (z + r)) / f.half
            u1 = wp.max((x + r) / (z - r), (x + r) / (z + r)) / f.half
            v0 = wp.min((y - r) / (z - r), (y - r) / (z + r)) / f.half
            v1 = wp.max((y + r) / (z - r), (y + r) / (z + r)) / f.half
            cu = x / (z * f.half)
            cv = y / (z * f.half)
            ru = r / (dist * f.half)  # the sphere's angular radius, roughly, in face units
            tc = dist
    if ru < texel:  # under a texel: its optical volume over the 4 texels around its centre
        fx = (cu + 1.0) * 0.5 * float(M) - 0.5
        fy = (cv + 1.0) * 0.5 * float(M) - 0.5
        i0 = int(wp.floor(fx))
        j0 = int(wp.floor(fy))
        for dj in range(2):
            for di in range(2):
                i = i0 + di
                j = j0 + dj
                if i >= 0 and i < M and j >= 0 and j < M:
                    wx = wp.where(di == 0, 1.0 - (fx - float(i0)), fx - float(i0))
                    wy = wp.where(dj == 0, 1.0 - (fy - float(j0)), fy - float(j0))
                    area = texel_area(f, M, cu, cv, tc)
                    # sigma (4/3 pi r^3) / (area 2r) over the depth interval [tc - r, tc + r]
                    s = sig * (wx * wy * (2.0 / 3.0) * PI * r * r / area)
                    deposit(m, f.first + j * M + i, tc - r, tc + r, s, f.near, f.far, out)
        return
    ia = wp.max(int(wp.ceil((u0 + 1.0) / texel - 0.5)), 0)
    ib = wp.min(int(wp.floor((u1 + 1.0) / texel - 0.5)), M - 1)
    ja = wp.max(int(wp.ceil((v0 + 1.0) / texel - 0.5)), 0)
    jb = wp.min(int(wp.floor((v1 + 1.0) / texel - 0.5)), M - 1)
    for j in range(ja, jb + 1):
        for i in range(ia, ib + 1):
            o, d = face_ray(f, (float(i) + 0.5) * texel - 1.0, (float(j) + 0.5) * texel - 1.0)
            a, b = ray_sphere(o, d, c, r)
            if b > a and b > 0.0:
                deposit(m, f.first + j * M + i, wp.max(a, 0.0), b, sig, f.near, f.far, out)


@wp.kernel
def merge_maps(offset: int, part: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    tid = wp.tid() + offset
    out[tid] = out[tid] + part[tid]


@wp.kernel
def accumulate_slices(offset: int, C: int, data: wp.array(dtype=wp.vec3)):
    """Slice increments to optical depths at the slice depths (a prefix sum per texel)."""
    base = (wp.tid() + offset) * C
    for k in range(1, C):
        data[base + k] = data[base + k] + data[base + k - 1]


@wp.func
def texel_depth(m: LightMap, texel: int, z: float) -> wp.vec3:
    """Optical depth along the texel's ray up to normalised depth z in [0, 1]."""
    base = texel * m.C
    if m.kind == SLICES:
        S = m.C - 1
        s = z * float(S)
        k = wp.min(int(s), S - 1)
        return wp.lerp(m.data[base + k], m.data[base + k + 1], s - float(k))
    total = m.data[base] * 0.5
    tau = total * z
    s1 = wp.sin(2.0 * PI * z)
    c1 = wp.cos(2.0 * PI * z)
    sk = s1
    ck = c1
    for k in range(1, (m.C - 1) // 2 + 1):
        ang = 2.0 * PI * float(k)
        tau += (m.data[base + 2 * k - 1] * sk + m.data[base + 2 * k] * (1.0 - ck)) / ang
        sn = sk * c1 + ck * s1
        ck = ck * c1 - sk * s1
        sk = sn
    return wp.vec3(wp.clamp(tau[0], 0.0, total[0]), wp.clamp(tau[1], 0.0, total[1]), wp.clamp(tau[2], 0.0, total[2]))


@wp.func
def sphere_represented(m: LightMap, f: LightFace, t0: float, t1: float, sigma: wp.vec3, z: float) -> wp.vec3:
    """What a texel's map holds at normalised depth z for one segment [t0, t1] of extinction
    sigma (``deposit`` then ``texel_depth``, for that segment alone): subtracting it takes a
    sphere out of the map exactly, interpolation error included."""
    span = f.far - f.near
    z0 = wp.clamp((t0 - f.near) / span, 0.0, 1.0)
    z1 = wp.clamp((t1 - f.near) / span, 0.0, 1.0)
    if z1 <= z0:
        return wp.vec3(0.0)
    if m.kind == SLICES:
        S = float(m.C - 1)
        s = z * S
        k = wp.min(wp.floor(s), S - 1.0)
        lo = wp.clamp(z1, 0.0, k / S) - wp.clamp(z0, 0.0, k / S)
        hi = wp.clamp(z1, 0.0, (k + 1.0) / S) - wp.clamp(z0, 0.0, (k + 1.0) / S)
        return sigma * (span * wp.lerp(lo, hi, s - k))
    acc = (z1 - z0) * z
    for k in range(1, (m.C - 1) // 2 + 1):
        ang = 2.0 * PI * float(k)
        a_k = (wp.sin(ang * z1) - wp.sin(ang * z0)) / ang
        b_k = (wp.cos(ang * z0) - wp.cos(ang * z1)) / ang
        acc += 2.0 * (a_k * wp.sin(ang * z) + b_k * (1.0 - wp.cos(ang * z))) / ang
    return sigma * (span * acc)


@wp.func
def map_optical_depth(m: LightMap, light: int, x: wp.vec3, own_c: wp.vec3, own_r: float, own_sigma: wp.vec3) -> wp.vec3:
    """Optical depth from ``light`` to x read from its map (bilinear over four texels), less
    the sphere (own_c, own_r, own_sigma) along the same texel rays (own_r = 0: none)."""
    f = m.faces[light_face(m, light, x)]
    uvt = face_coords(f, x)
    if wp.abs(uvt[0]) > 1.0 or wp.abs(uvt[1]) > 1.0:  # off the face, which covers the cloud: nothing in the way
        return wp.vec3(0.0)
    M = m.M
    z = wp.clamp((uvt[2] - f.near) / (f.far - f.near), 0.0, 1.0)
    fx = wp.clamp((uvt[0] + 1.0) * 0.5 * float(M) - 0.5, 0.0, float(M - 1))
    fy = wp.clamp((uvt[1] + 1.0) * 0.5 * float(M) - 0.5, 0.0, float(M - 1))
    i0 = wp.min(int(fx), M - 2)
    j0 = wp.min(int(fy), M - 2)
    if M == 1:
        i0 = 0
        j0 = 0
    ax = fx - float(i0)
    ay = fy - float(j0)
    tau = wp.vec3(0.0)
    texel = 2.0 / float(M)
    for dj in range(2):
        for di in range(2):
            i = wp.min(i0 + di, M - 1)
            j = wp.min(j0 + dj, M - 1)
            w = wp.where(di == 0, 1.0 - ax, ax) * wp.where(dj == 0, 1.0 - ay, ay)
            if w > 0.0:
                t = texel_depth(m, f.first + j * M + i, z)
                if own_r > 0.0:
                    o, d = face_ray(f, (float(i) + 0.5) * texel - 1.0, (float(j) + 0.5) * texel - 1.0)
                    a, b = ray_sphere(o, d, own_c, own_r)
                    if b > a and b > 0.0:
                        t -= sphere_represented(m, f, wp.max(a, 0.0), b, own_sigma, z)
                tau += w * t
    return wp.max(tau, wp.vec3(0.0))


@wp.func
def ball_point(j: int, k: int, r: float) -> wp.vec3:
    """Point j of k spread evenly over a ball of radius r about the origin: golden-spiral
    directions (z = 1 - 2 (j + 1/2) / k) at equal-volume radii r v^(1/3), v = frac(j / phi)
    (an independent low-discrepancy sequence, so radius and direction do not correlate)."""
    u = (float(j) + 0.5) / float(k)
    z = 1.0 - 2.0 * u
    ring = wp.sqrt(wp.max(0.0, 1.0 - z * z))
    phi = 2.39996323 * (float(j) + 0.5)
    v = (float(j) + 0.5) * 0.61803398875
    v = v - wp.floor(v)
    return r * wp.pow(v, 1.0 / 3.0) * wp.vec3(ring * wp.cos(phi), z, ring * wp.sin(phi))


@wp.func
def self_shadow(tau: float, inside: bool) -> float:
    """A particle's mean transmittance of its own sphere (optical radius tau) to the light that
    reaches it: the escape probability for light from outside (exact for a directional light),
    (1 - e^-tau) / tau, exact at the centre, for a point light inside it."""
    if inside:
        return step_integral(tau, 1.0)
    return sphere_escape(tau)


@wp.func
def optical_depth_to_light(m: LightMap, P: Particles, skip: int, l: int, light: Emitter, x: wp.vec3) -> wp.vec3:
    """Optical depth from light l to x through the cloud, leaving out sphere ``skip`` (-1:
    none): from the map (a left-out sphere taken out of it exactly as the map holds it), or,
    ``EXACT``, as chord sums along the ray itself."""
    if m.kind == EXACT:
        wi, dist, e = light_incident(light, x)  # at the light itself: dist 0, no depth
        return particle_optical_depth(P, skip, x, wi, 0.0, dist)
    if skip < 0:
        return map_optical_depth(m, l, x, x, 0.0, wp.vec3(0.0))
    return map_optical_depth(m, l, x, P.centres[skip], P.radius[skip], P.sigma_t[skip])


@wp.func
def sphere_transmittance(m: LightMap, P: Particles, p: int, l: int, light: Emitter, samples: int) -> wp.vec3:
    """Transmittance from light l averaged over particle p's sphere: the mean over
    ``samples`` points of it (``ball_point``; its own sphere included). With one point, from
    the centre through the rest of the cloud times the own sphere's mean (``self_shadow``)."""
    r = P.radius[p]
    x_p = P.centres[p]
    if samples <= 1:
        s = P.sigma_t[p] * r
        to = x_p - light.position
        inside = light.kind != DIRECTIONAL and wp.dot(to, to) < r * r
        own = wp.vec3(self_shadow(s[0], inside), self_shadow(s[1], inside), self_shadow(s[2], inside))
        return wp.cw_mul(transmittance_rgb(optical_depth_to_light(m, P, p, l, light, x_p)), own)
    acc = wp.vec3(0.0)
    for j in range(samples):
        acc += transmittance_rgb(optical_depth_to_light(m, P, -1, l, light, x_p + ball_point(j, samples, r)))
    return acc / float(samples)


@wp.kernel
def sphere_light(offset: int, P: Particles, lights: wp.array(dtype=Emitter), m: LightMap, samples: int,
                 direct: wp.array(dtype=wp.vec3), travel: wp.array(dtype=wp.vec3)):
    """Thread p L + l: light l's irradiance averaged over particle p's sphere, the ball mean
    of the inverse square (``particle_incident``) times ``sphere_transmittance``, and the
    direction the light travels on arrival (zero: from every side, no shadowing)."""
    tid = wp.tid() + offset
    n_l = lights.shape[0]
    p = tid / n_l
    l = tid % n_l
    light = lights[l]
    w, dist, e = particle_incident(light, P.centres[p], P.radius[p])
    tr = wp.vec3(1.0)
    if wp.length_sq(w) > 0.0:
        tr = sphere_transmittance(m, P, p, l, light, samples)
    direct[tid] = wp.cw_mul(e, tr)
    travel[tid] = w


@wp.kernel
def subset_light(offset: int, P: Particles, lights: wp.array(dtype=Emitter), m: LightMap, samples: int,
                 which: wp.array(dtype=int), out: wp.array(dtype=wp.vec3)):
    """``sphere_transmittance`` for the particles ``which`` (thread k L + l)."""
    tid = wp.tid() + offset
    n_l = lights.shape[0]
    l = tid % n_l
    out[tid] = sphere_transmittance(m, P, which[tid / n_l], l, lights[l], samples)


@wp.kernel
def points_depth(offset: int, P: Particles, lights: wp.array(dtype=Emitter), m: LightMap, l: int,
                 points: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    """Optical depth from light l to each point (the whole cloud counted)."""
    tid = wp.tid() + offset
    out[tid] = optical_depth_to_light(m, P, -1, l, lights[l], points[tid])


def _unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing n to an orthonormal frame."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    r = np.cross(n, a)
    r /= np.linalg.norm(r)
    return r, np.cross(n, r)


class LightPass:
    """Builds the light-space map of a particle cloud for its lights and reads it.

    ``representation``: "exact" (no map; BVH ray queries), "slices" (``slices`` = S) or
    "fourier" (``terms`` = K). ``texels``: M per face side, 0 for the rule M = 4 R / r
    (a texel half a median particle radius across at the cloud), from ``MIN_TEXELS`` to
    ``MAX_TEXELS``; either way no more than fits ``MAX_BYTES`` (faces x M^2 x C values).
    ``tolerance`` > 0: after a build, ``check`` measures the map against the exact answer on
    up to ``check_particles`` particles (at the same ``samples`` points of each as the render
    reads); above the tolerance the map is refined (texels per side and slices or terms
    scaled by up to 2 after the error's excess, or the texels alone where both do not fit) up to ``REFINE_ROUNDS`` times within ``MAX_BYTES``, and only
    then falls back to exact. ``refined`` lists each rejected map's (M, C, error), ``error``
    is the last map's and ``fell_back`` says whether exact was taken. A later build of the
    same cloud (its count, radius and bounding ball) and kinds of faces, with its lights moved,
    starts at the resolution the last one ended at.
    """

    def __init__(self, device, representation: str = "slices", slices: int = 16, terms: int = 8, texels: int = 0,
                 tolerance: float = 0.0, check_particles: int = 256):
        if representation not in REPRESENTATIONS:
            raise ValueError(f"light pass representation must be one of {REPRESENTATIONS}, got {representation!r}")
        self.device = device
        self.representation = representation
        self.slices, self.terms, self.texels = int(slices), int(terms), int(texels)
        self.tolerance, self.check_particles = float(tolerance), int(check_particles)
        self.map: LightMap | None = None
        self.M = 0
        self.error: float | None = None  # relative RMSE of the last check
        self.fell_back = False
        self.refined: list[tuple[int, int, float]] = []  # (M, C, error) of each map refined away
        self.checked: np.ndarray | None = None  # the exact transmittances the last check compared with
        self.template_texels = 0  # texels a side of each template's light impostor (0: no block light pass)
        self._blocks: BlockCloud | None = None
        self._data = None
        self._start = None  # (cloud and faces, M, C) where the last checked build ended
        self._buffer = None  # the map's storage, kept between builds

    def build(self, cloud: ParticleBuffers, lights: wp.array, samples: int = 4,
              blocks: BlockCloud | None = None) -> LightMap:
        """The map of ``cloud`` (its bounding ball ``centre``, ``R``) for every light.
        ``blocks``: the same cloud as instances of templates (every particle in one); its
        orthographic faces (directional lights) are then made from one light impostor per
        template and face, splatted once per instance (``blockpass``: b + N / b work), the
        paper's block light pass; other faces per particle."""
        self._blocks = blocks
        kind = REPRESENTATIONS.index(self.representation)
        if (kind == EXACT or self.tolerance > 0.0) and cloud.struct.centres.shape[0] and cloud.bvh is None:
            raise ValueError("the exact light pass (and a map's check against it) needs the cloud's BVH "
                             "(ParticleBuffers(..., bvh=True))")
        n = cloud.struct.centres.shape[0]
        infos = lights.numpy() if lights.shape[0] else []
        radius = cloud.radius if n else np.ones(1, np.float32)
        C = self.slices + 1 if kind == SLICES else 2 * self.terms + 1
        M = self.texels or int(np.clip(np.ceil(4.0 * cloud.R / max(float(np.median(radius)), 1e-9)), MIN_TEXELS,
                                            MAX_TEXELS))
        faces, first_face, face_count = [], [], []
        centre, R = np.asarray(cloud.centre, np.float64), float(cloud.R)
        for info in infos:
            first_face.append(len(faces))
            if int(info["kind"]) == DIRECTIONAL:
                fwd = _unit(info["direction"])
                right, up = _basis(fwd)
                faces.append((centre - R * fwd, fwd, right, up, R, 0.0, 2.0 * R, 1))
            else:
                pos = np.asarray(info["position"], np.float64)
                d = float(np.linalg.norm(centre - pos))
                if d > 1.05 * R:  # outside the ball: one face on the cone that holds it
                    fwd = (centre - pos) / d
                    right, up = _basis(fwd)
                    faces.append((pos, fwd, right, up, R / np.sqrt(d * d - R * R), d - R, d + R, 0))
                else:  # inside: a cube, faces +x -x +y -y +z -z
                    for a in range(3):
                        for sign in (1.0, -1.0):
                            fwd = np.zeros(3)
                            fwd[a] = sign
                            right, up = np.eye(3)[(a + 1) % 3], np.eye(3)[(a + 2) % 3]
                            faces.append((pos, fwd, right, up, 1.0, 0.0, d + R, 0))
            face_count.append(len(faces) - first_face[-1])
        # the same cloud and faces as a build before: start at the resolution it ended at
        key = (kind, n, round(float(R), 6), round(float(np.median(radius)), 6), tuple(f[7] for f in faces))
        if self.tolerance > 0.0 and self._start is not None and self._start[0] == key:
            M, C = max(M, self._start[1]), max(C, self._start[2])
        if kind != EXACT and faces:  # the memory bound: F M^2 C vec3 of 12 bytes
            M = max(1, min(M, int(np.sqrt(MAX_BYTES / (12.0 * C * len(faces))))))
        self.error, self.fell_back, self.refined = None, False, []
        m = self._splat(cloud, kind, faces, first_face, face_count, M, C)
        if kind != EXACT and self.tolerance > 0.0 and n and len(faces):
            self.error = self.check(cloud, lights, samples)
            # above the tolerance: refine while the map fits MAX_BYTES, up to REFINE_ROUNDS times;
            # only then fall back to exact
            while self.error > self.tolerance and len(self.refined) < REFINE_ROUNDS:
                fits = [(m2, c2) for m2, c2 in self._finer(kind, M, C, self.error)
                        if m2 <= MAX_TEXELS and 12.0 * c2 * len(faces) * m2 * m2 <= MAX_BYTES]
                if not fits:
                    break
                self.refined.append((M, C, self.error))
                M, C = fits[0]
                m = self._splat(cloud, kind, faces, first_face, face_count, M, C)
                self.error = self.check(cloud, lights, samples, self.checked)  # the exact side computed once
            if self.error > self.tolerance:
                self.fell_back = True
                m.kind = EXACT
            self._start = (key, M, C)
        return m

    def _finer(self, kind: int, M: int, C: int, error: float) -> list[tuple[int, int]]:
        """The next (M, C) to try after a map of ``error``: texels a side and slices (or terms)
        scaled by f = 1.2 error / tolerance within [1.25, 2] (the map's error falls about as 1 / f,
        first order in both), else the texels alone."""
        f = float(np.clip(1.2 * error / self.tolerance, 1.25, 2.0))
        m2 = int(np.ceil(M * f))
        c2 = int(np.ceil((C - 1) * f)) + 1 if kind == SLICES else 2 * int(np.ceil((C - 1) // 2 * f)) + 1
        return [(m2, c2), (m2, C)]

    def _splat(self, cloud: ParticleBuffers, kind: int, faces: list, first_face: list, face_count: list, M: int,
               C: int) -> LightMap:
        """The map of ``faces`` at M texels a side and C values a texel, splatted from ``cloud``."""
        m = LightMap()
        m.kind = kind
        structs = []
        for k, (o, fwd, right, up, half, near, far, ortho) in enumerate(faces):
            s = LightFace()
            s.origin, s.forward, s.right, s.up = (wp.vec3(*map(float, v)) for v in (o, fwd, right, up))
            s.half, s.near, s.far, s.ortho, s.first = float(half), float(near), float(max(far, near + 1e-6)), int(ortho), k * M * M
            structs.append(s)
        dev_ = self.device
        m.M, m.C = M, C
        m.faces = wp.array(structs, dtype=LightFace, device=dev_) if structs else wp.empty(0, dtype=LightFace, device=dev_)
        m.first_face = wp.array(np.asarray(first_face or [0], np.int32), dtype=int, device=dev_)
        m.face_count = wp.array(np.asarray(face_count or [0], np.int32), dtype=int, device=dev_)
        texels = len(faces) * M * M
        n = cloud.struct.centres.shape[0]
        if kind == EXACT or not texels:
            self._data = wp.zeros(1, dtype=wp.vec3, device=dev_)
        else:
            if self._buffer is None or self._buffer.shape[0] < texels * C:  # kept: a fresh one costs page faults
                self._buffer = wp.empty(texels * C, dtype=wp.vec3, device=dev_)
            self._data = self._buffer[: texels * C]
            self._data.zero_()
            m.data = self._data
            blocks = self._blocks if any(f[7] for f in faces) else None
            self.template_texels = 0
            if n and blocks is not None and blocks.n_instances:
                self.template_texels = splat_block_faces(blocks, cloud.R, float(np.median(cloud.radius)), m,
                                                         len(faces), self._data, merge_maps, dev_)
            if n and (blocks is None or not all(f[7] for f in faces)):
                footprint = (M * float(np.median(cloud.radius)) / max(float(cloud.R), 1e-9)) ** 2  # texels a sphere covers
                dev.launch_private(splat_spheres, n * len(faces), [cloud.struct, m, int(blocks is not None)], self._data,
                                   merge_maps, dev_, work=C * max(1.0, footprint))
            if kind == SLICES:
                dev.launch(accumulate_slices, texels, [C, self._data], dev_)
        m.data = self._data
        self.M, self.map = (M if kind != EXACT else 0), m
        return m

    def exact(self) -> LightMap:
        """A map of kind EXACT with the same lights (no texels): the yardstick."""
        m = LightMap()
        m.kind, m.M, m.C = EXACT, self.map.M, self.map.C
        m.faces, m.first_face, m.face_count, m.data = self.map.faces, self.map.first_face, self.map.face_count, self._data
        return m

    def check(self, cloud: ParticleBuffers, lights: wp.array, samples: int, want: np.ndarray | None = None) -> float:
        """Relative RMSE, sqrt(sum (T_map - T)^2 / sum T^2), of the sphere-averaged
        transmittance over up to ``check_particles`` particles (evenly strided) and every
        light, the map against the exact chord sums at the same ``samples`` points (``want``:
        those exact values, where already computed; ``self.checked`` keeps the last)."""
        n = cloud.struct.centres.shape[0]
        which = np.unique(np.linspace(0, n - 1, min(n, self.check_particles)).astype(np.int32))
        idx = wp.array(which, dtype=int, device=self.device)
        got = self.transmittance(cloud, lights, samples, idx, self.map)
        if want is None:
            want = self.transmittance(cloud, lights, samples, idx, self.exact())
        self.checked = want
        return float(np.sqrt(np.sum((got - want) ** 2) / max(np.sum(want**2), 1e-30)))

    def transmittance(self, cloud: ParticleBuffers, lights: wp.array, samples: int, which: wp.array,
                      m: LightMap | None = None) -> np.ndarray:
        """(len(which), L, 3) sphere-averaged transmittance to each light, from map ``m``."""
        L = lights.shape[0]
        out = wp.zeros(max(which.shape[0] * L, 1), dtype=wp.vec3, device=self.device)
        if which.shape[0] and L:
            dev.launch(subset_light, which.shape[0] * L, [cloud.struct, lights, m or self.map, samples, which, out],
                       self.device, min_split=256)
        return out.numpy()[: which.shape[0] * L].reshape(which.shape[0], L, 3)

    def layers(self) -> dict:
        """For looking inside: every face's frame (origin, forward, right, up, half, near, far,
        ortho; numpy) and, for a slices map, the optical depth at each slice depth as
        (faces, M, M, S + 1, 3)."""
        faces = self.map.faces.numpy() if self.map is not None and self.map.faces.shape[0] else []
        out = {"faces": [{k: np.asarray(f[k]) for k in ("origin", "forward", "right", "up", "half", "near", "far",
                                                           "ortho")} for f in faces]}
        if self.map is not None and self.map.kind == SLICES and len(faces):
            M, C = self.map.M, self.map.C
            out["slices"] = self._data.numpy().reshape(len(faces), M, M, C, 3)
        return out

    def optical_depth(self, cloud: ParticleBuffers, lights: wp.array, light: int, points: np.ndarray,
                      m: LightMap | None = None) -> np.ndarray:
        """(n, 3) optical depth from light ``light`` to each of ``points`` (n, 3), from map ``m``
        (default: the one built)."""
        pts = wp.array(np.asarray(points, np.float32).reshape(-1, 3), dtype=wp.vec3, device=self.device)
        out = wp.zeros(max(pts.shape[0], 1), dtype=wp.vec3, device=self.device)
        if pts.shape[0]:
            dev.launch(points_depth, pts.shape[0], [cloud.struct, lights, m or self.map, int(light), pts, out],
                       self.device)
        return out.numpy()[: pts.shape[0]]

    def direct(self, cloud: ParticleBuffers, lights: wp.array, samples: int, direct: wp.array, travel: wp.array):
        """Every (particle p, light l) at p L + l: irradiance averaged over the sphere into
        ``direct``, the light's travel direction into ``travel`` (``sphere_light``)."""
        n, L = cloud.struct.centres.shape[0], lights.shape[0]
        if n and L:
            dev.launch(sphere_light, n * L, [cloud.struct, lights, self.map, samples, direct, travel], self.device,
                       min_split=256)
