"""Triangulated primitives and .obj reading, in numpy: (vertices (V, 3), faces (F, 3))."""

from __future__ import annotations

import numpy as np


def _orthonormal(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(n, a)
    t /= np.linalg.norm(t)
    return t, np.cross(n, t)


def quad(corner: np.ndarray, edge_u: np.ndarray, edge_v: np.ndarray):
    """A parallelogram corner + [0,1]^2 spanned by edge_u, edge_v, as two triangles."""
    v = np.array([corner, corner + edge_u, corner + edge_u + edge_v, corner + edge_v], np.float64)
    return v, np.array([[0, 1, 2], [0, 2, 3]], np.int32)


def plane(center, normal, size):
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    t, b = _orthonormal(n)
    w, h = size
    corner = np.asarray(center, np.float64) - 0.5 * w * t - 0.5 * h * b
    return quad(corner, w * t, h * b)


def box(center, size):
    c = np.asarray(center, np.float64)
    h = 0.5 * np.asarray(size, np.float64)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
    v = c + corners * h
    # index = 4 * (x > 0) + 2 * (y > 0) + (z > 0)
    f = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
        np.int32,
    )
    return v, f


def sphere(center, radius, rings: int = 24, segments: int = 48):
    """A UV sphere (poles on y); its vertices lie on the exact sphere."""
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    pts = np.stack([st * np.cos(phi), np.broadcast_to(ct, (rings + 1, segments)), st * np.sin(phi)], -1)
    v = np.asarray(center, np.float64) + radius * pts.reshape(-1, 3)
    faces = []
    for i in range(rings):
        for j in range(segments):
            a, b = i * segments + j, i * segments + (j + 1) % segments
            c, d = a + segments, b + segments
            if i > 0:
                faces.append([a, b, d])
            if i < rings - 1:
                faces.append([a, d, c])
    return v, np.array(faces, np.int32)


def read_obj(path: str):
    """Vertices and faces of an .obj file; polygons are fanned into triangles.

    Raises ``ValueError`` naming the line for a vertex that is not three finite numbers or a
    face that refers to a vertex that does not exist.
    """
    verts, faces = [], []
    with open(path) as fh:
        for n, line in enumerate(fh, 1):
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                try:
                    xyz = [float(x) for x in parts[1:4]]
                except ValueError:
                    xyz = []
                if len(xyz) != 3 or not np.all(np.isfinite(xyz)):
                    raise ValueError(f"line {n}: vertex {' '.join(parts[1:4])!r} is not 3 finite numbers")
                verts.append(xyz)
            elif parts[0] == "f":
                try:
                    idx = [int(p.split("/")[0]) for p in parts[1:]]
                except ValueError:
                    raise ValueError(f"line {n}: face {' '.join(parts[1:])!r} is not vertex numbers") from None
                if len(idx) < 3 or 0 in idx:
                    raise ValueError(f"line {n}: face {' '.join(parts[1:])!r} needs >= 3 vertex numbers, none 0")
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    if not verts or not faces:
        raise ValueError("no vertices or faces")
    v, f = np.array(verts, np.float64), np.array(faces, np.int32)
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError("a face refers to a vertex that does not exist")
    return v, f


CORNELL_RED = (0.63, 0.065, 0.05)
CORNELL_GREEN = (0.14, 0.45, 0.091)


def cornell_box(center=(0.0, 0.0, 0.0), size=(2.0, 2.0, 2.0), diffuse=(0.7, 0.7, 0.7)):
    """Floor, ceiling, back wall, red left wall, green right wall; open toward +z.

    Returns (vertices, faces, per-face diffuse (F, 3)).
    """
    c = np.asarray(center, np.float64)
    sx, sy, sz = (0.5 * np.asarray(size, np.float64)).tolist()
    lo = c - [sx, sy, sz]
    walls = [
        (lo, [2 * sx, 0, 0], [0, 0, 2 * sz], diffuse),  # floor
        (lo + [0, 2 * sy, 0], [0, 0, 2 * sz], [2 * sx, 0, 0], diffuse),  # ceiling
        (lo, [0, 2 * sy, 0], [2 * sx, 0, 0], diffuse),  # back
        (lo, [0, 0, 2 * sz], [0, 2 * sy, 0], CORNELL_RED),  # left
        (lo + [2 * sx, 0, 0], [0, 2 * sy, 0], [0, 0, 2 * sz], CORNELL_GREEN),  # right
    ]
    vs, fs, cs = [], [], []
    for corner, eu, ev, colour in walls:
        v, f = quad(np.asarray(corner, np.float64), np.asarray(eu, np.float64), np.asarray(ev, np.float64))
        fs.append(f + sum(len(x) for x in vs))
        vs.append(v)
        cs.append(np.tile(np.asarray(colour, np.float64), (len(f), 1)))
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(cs)


def cylinder(base, radius: float, height: float, segments: int = 32, stacks: int = 1):
    """An open vertical cylinder (no caps) standing on ``base``: segments x stacks x 2 triangles."""
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    y = np.linspace(0.0, height, stacks + 1)
    ring = np.column_stack([radius * np.cos(phi), np.zeros(segments), radius * np.sin(phi)])
    v = np.concatenate([ring + [0.0, h, 0.0] for h in y]) + np.asarray(base, np.float64)
    i, k = np.meshgrid(np.arange(segments), np.arange(stacks), indexing="ij")
    a = (k * segments + i).ravel()
    b = (k * segments + (i + 1) % segments).ravel()
    f = np.concatenate([np.column_stack([a, a + segments, b]), np.column_stack([b, a + segments, b + segments])])
    return v, f.astype(np.int32)


def colonnade(center=(0.0, 0.0, 0.0), columns: int = 8, segments: int = 64, stacks: int = 64,
              diffuse=(0.7, 0.7, 0.7)):
    """A temple front that throws light shafts (Tóth & Umenhoffer 2009's kind of scene): a floor, a row of
    ``columns`` fluted columns (cylinders of segments x stacks quads) under a lintel, and a back
    wall with a window grating of bars. With the defaults: 65 660 triangles.

    Spans x in [-4, 4], y in [0, 4], z in [-3, 1] around ``center``. Returns (vertices, faces,
    per-face diffuse (F, 3)).
    """
    c = np.asarray(center, np.float64)
    parts = [plane(c + [0, 0, -1], [0, 1, 0], (12.0, 10.0)),  # floor
             box(c + [0, 3.6, 0], [8.4, 0.4, 1.0]),  # lintel over the columns
             quad(c + [-6, 0, -3], np.array([12.0, 0, 0]), np.array([0, 5.0, 0]))]  # back wall
    for x in np.linspace(-3.5, 3.5, columns):
        parts.append(cylinder(c + [x, 0, 0], 0.22, 3.4, segments, stacks))
    for k in range(9):  # window grating: vertical bars in front of the back wall's window
        parts.append(box(c + [-1.2 + 0.3 * k, 2.6, -2.6], [0.06, 1.6, 0.06]))
    vs, fs, base = [], [], 0
    for v, f in parts:
        vs.append(v)
        fs.append(f + base)
        base += len(v)
    f = np.concatenate(fs)
    return np.concatenate(vs), f, np.tile(np.asarray(diffuse, np.float64), (len(f), 1))
