"""The light map's layout, shared by the light pass (``lightpass``) and its block pass
(``blockpass``): a light's faces (orthographic for a directional light, perspective or a cube for
a point or spot light), their texels, and how a segment of uniform extinction on a texel's ray
deposits into a texel in each representation (depth slices or Fourier terms). The module
docstring of ``lightpass`` says what the representations are and how the map is read."""

from __future__ import annotations

import warp as wp

from ..physics.constants import PI

EXACT = wp.constant(0)
SLICES = wp.constant(1)
FOURIER = wp.constant(2)
REPRESENTATIONS = ("exact", "slices", "fourier")


@wp.struct
class LightFace:
    """One face of a light's map: orthographic (a directional light) or perspective."""
    origin: wp.vec3  # orthographic: centre of the near plane; perspective: the light
    forward: wp.vec3  # unit: the face's axis, the way the light travels
    right: wp.vec3
    up: wp.vec3
    half: float  # orthographic: half width (scene units); perspective: tan of the half angle
    near: float  # depth range along a texel ray (scene units; distance from the light)
    far: float
    ortho: int
    first: int  # the face's first texel; texel k holds values C k .. C k + C - 1


@wp.struct
class LightMap:
    """Every light's faces and texels; ``kind`` EXACT (no map), SLICES or FOURIER."""
    kind: int
    M: int  # texels per face side
    C: int  # values per texel: S + 1 slices, or 2 K + 1 Fourier terms
    faces: wp.array(dtype=LightFace)
    first_face: wp.array(dtype=int)  # per light
    face_count: wp.array(dtype=int)  # per light: 1, or 6 for a cube
    data: wp.array(dtype=wp.vec3)


@wp.func
def face_ray(f: LightFace, u: float, v: float):
    """Origin and unit direction of the face's ray through (u, v) in [-1, 1]^2."""
    if f.ortho != 0:
        return f.origin + f.half * (u * f.right + v * f.up), f.forward
    return f.origin, wp.normalize(f.forward + f.half * (u * f.right + v * f.up))


@wp.func
def face_coords(f: LightFace, x: wp.vec3) -> wp.vec3:
    """(u, v, t) of x on the face: its texel-plane coordinates and its depth along the ray."""
    rel = x - f.origin
    if f.ortho != 0:
        return wp.vec3(wp.dot(rel, f.right) / f.half, wp.dot(rel, f.up) / f.half, wp.dot(rel, f.forward))
    z = wp.max(wp.dot(rel, f.forward), 1.0e-20)
    return wp.vec3(wp.dot(rel, f.right) / (z * f.half), wp.dot(rel, f.up) / (z * f.half), wp.length(rel))


@wp.func
def light_face(m: LightMap, light: int, x: wp.vec3) -> int:
    """The face of ``light`` that sees x: its only one, or the cube face of x's major axis."""
    first = m.first_face[light]
    if m.face_count[light] == 1:
        return first
    rel = x - m.faces[first].origin
    a = int(0)
    if wp.abs(rel[1]) > wp.abs(rel[a]):
        a = 1
    if wp.abs(rel[2]) > wp.abs(rel[a]):
        a = 2
    return first + 2 * a + wp.where(rel[a] < 0.0, 1, 0)


@wp.func
def deposit(m: LightMap, texel: int, t0: float, t1: float, sigma: wp.vec3, near: float, far: float,
            out: wp.array(dtype=wp.vec3)):
    """Add a segment [t0, t1] of uniform extinction ``sigma`` on the texel's ray to ``out``:
    its share of each slice interval, or its closed-form Fourier terms."""
    base = texel * m.C
    span = far - near
    z0 = wp.clamp((t0 - near) / span, 0.0, 1.0)
    z1 = wp.clamp((t1 - near) / span, 0.0, 1.0)
    if z1 <= z0:
        return
    if m.kind == SLICES:
        S = m.C - 1
        a = z0 * float(S)
        b = z1 * float(S)
        k = wp.min(int(a), S - 1)
        while k < S and float(k) < b:
            lo = wp.max(a, float(k))
            hi = wp.min(b, float(k + 1))
            if hi > lo:
                out[base + k + 1] += sigma * ((hi - lo) * span / float(S))
            k += 1
    else:
        w = sigma * (2.0 * span)
        out[base] += w * (z1 - z0)
        for k in range(1, (m.C - 1) // 2 + 1):
            ang = 2.0 * PI * float(k)
            out[base + 2 * k - 1] += w * ((wp.sin(ang * z1) - wp.sin(ang * z0)) / ang)
            out[base + 2 * k] += w * ((wp.cos(ang * z0) - wp.cos(ang * z1)) / ang)


@wp.func
def texel_area(f: LightFace, M: int, u: float, v: float, t: float) -> float:
    """Area of a texel's footprint across its ray at depth t (scene units^2)."""
    side = 2.0 * f.half / float(M)
    if f.ortho != 0:
        return side * side
    rho2 = f.half * f.half * (u * u + v * v)
    return side * side / wp.pow(1.0 + rho2, 1.5) * t * t


@wp.func
def item_and_face(m: LightMap, tid: int):
    """Thread tid = i F + f of a launch over items and the map's F faces: (i, f, face f)."""
    F = m.faces.shape[0]
    return tid / F, tid % F, m.faces[tid % F]
