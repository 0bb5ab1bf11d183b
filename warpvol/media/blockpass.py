"""The light pass's block pass (Umenhoffer & Szirmay-Kalos 2005): a cloud made of instances of a
few templates (``particles.BlockCloud``) reaches a directional light's orthographic face by
rendering each template once from the light into a small light impostor (``template_light``,
b work for b spheres in the templates) and splatting that impostor once per instance
(``splat_blocks``, N / b), instead of every particle (``lightpass.splat_spheres``)."""

from __future__ import annotations

import numpy as np
import warp as wp

from .. import device as dev
from ..physics.constants import PI
from .lightmap import LightMap, deposit, item_and_face
from .particles import BlockCloud, Blocks

dev.kernel_module(__name__)

MAX_TEMPLATE_TEXELS = 128  # texels a side of a template's light impostor, at most


@wp.kernel
def template_light(offset: int, B: Blocks, owner: wp.array(dtype=int), reach: wp.array(dtype=float), m: LightMap,
                   T: int, out: wp.array(dtype=wp.vec3)):
    """Thread j F + f: sphere j of its template (``owner[j]``) into the template's light
    impostor for orthographic face f, a T x T grid over the template's bounding disc (radius
    ``reach``) across the light, the paper's block rendered once from the light (b work).
    A cell sums, over the chords of its centre ray, the chord length L, L z and
    L (z^2 + L^2 / 12) (z: the chord's mid-depth from the template's centre): the chords'
    total and the mean and second moment of their depth, all sums, so cores may add
    private copies. A sphere under a cell deposits its volume in the cell of its centre."""
    j, fi, f = item_and_face(m, wp.tid() + offset)
    if f.ortho == 0:
        return
    t = owner[j]
    R = reach[t]
    r = B.radius[t]
    c = B.offsets[j]
    h = 2.0 * R / float(T)  # a cell's side
    cu = wp.dot(c, f.right)
    cv = wp.dot(c, f.up)
    z = wp.dot(c, f.forward)
    base = (t * m.faces.shape[0] + fi) * T * T
    if r < h:
        i = wp.clamp(int(wp.floor((cu + R) / h)), 0, T - 1)
        k = wp.clamp(int(wp.floor((cv + R) / h)), 0, T - 1)
        L = (4.0 / 3.0) * PI * r * r * r / (h * h)
        out[base + k * T + i] += wp.vec3(L, L * z, L * (z * z + r * r / 5.0))
        return
    ia = wp.max(int(wp.ceil((cu - r + R) / h - 0.5)), 0)
    ib = wp.min(int(wp.floor((cu + r + R) / h - 0.5)), T - 1)
    ja = wp.max(int(wp.ceil((cv - r + R) / h - 0.5)), 0)
    jb = wp.min(int(wp.floor((cv + r + R) / h - 0.5)), T - 1)
    for k in range(ja, jb + 1):
        for i in range(ia, ib + 1):
            du = (float(i) + 0.5) * h - R - cu
            dv = (float(k) + 0.5) * h - R - cv
            q = r * r - du * du - dv * dv
            if q > 0.0:
                L = 2.0 * wp.sqrt(q)
                out[base + k * T + i] += wp.vec3(L, L * z, L * (z * z + L * L / 12.0))


@wp.kernel
def splat_blocks(offset: int, B: Blocks, m: LightMap, T: int, cells: wp.array(dtype=wp.vec3),
                 out: wp.array(dtype=wp.vec3)):
    """Thread i F + f: instance i into orthographic face f from its template's light impostor
    (N / b work): every texel whose centre ray crosses the instance's bounding disc takes the
    impostor cell under it, its optical depth spread evenly over the depth interval with the
    chords' mean and variance (mean +- sqrt(3) sd: the block's chords through that texel
    merged into one segment)."""
    i, fi, f = item_and_face(m, wp.tid() + offset)
    if f.ortho == 0:
        return
    t = B.tpl[i]
    R = B.reach[i]
    rel = B.centre[i] - f.origin
    cu = wp.dot(rel, f.right) / f.half
    cv = wp.dot(rel, f.up) / f.half
    tc = wp.dot(rel, f.forward)
    ru = R / f.half
    M = m.M
    texel = 2.0 / float(M)
    ia = wp.max(int(wp.ceil((cu - ru + 1.0) / texel - 0.5)), 0)
    ib = wp.min(int(wp.floor((cu + ru + 1.0) / texel - 0.5)), M - 1)
    ja = wp.max(int(wp.ceil((cv - ru + 1.0) / texel - 0.5)), 0)
    jb = wp.min(int(wp.floor((cv + ru + 1.0) / texel - 0.5)), M - 1)
    base = (t * m.faces.shape[0] + fi) * T * T
    sig = B.sigma_t[t]
    for j in range(ja, jb + 1):
        tj = int(wp.floor((((float(j) + 0.5) * texel - 1.0 - cv) / ru + 1.0) * 0.5 * float(T)))
        if tj < 0 or tj >= T:
            continue
        for ii in range(ia, ib + 1):
            ti = int(wp.floor((((float(ii) + 0.5) * texel - 1.0 - cu) / ru + 1.0) * 0.5 * float(T)))
            if ti < 0 or ti >= T:
                continue
            s = cells[base + tj * T + ti]
            if s[0] > 0.0:
                mean = s[1] / s[0]
                half = wp.max(wp.sqrt(3.0 * wp.max(s[2] / s[0] - mean * mean, 0.0)), 1.0e-6)
                deposit(m, f.first + j * M + ii, tc + mean - half, tc + mean + half, sig * (s[0] / (2.0 * half)),
                        f.near, f.far, out)


def splat_block_faces(blocks: BlockCloud, cloud_R: float, median_radius: float, m: LightMap, faces: int, data,
                      merge, device) -> int:
    """The orthographic faces of map ``m`` (``faces`` faces, M texels a side, C values a texel)
    splatted into ``data`` from ``blocks``: one light impostor per template and face
    (``template_light``), then one splat per instance (``splat_blocks``); ``merge`` folds the
    cores' private copies (``device.launch_private``). Returns T, the impostor's texels a side."""
    M, C = m.M, m.C
    R = max(float(cloud_R), 1e-9)
    # a template texel as wide as a map texel (2 R / M across an orthographic face)
    T = int(np.clip(np.ceil(blocks.reach_max * M / R), 2, MAX_TEMPLATE_TEXELS))
    cells = wp.zeros(blocks.n_templates * faces * T * T, dtype=wp.vec3, device=device)
    r_cell = float(median_radius) * T / (2.0 * blocks.reach_max)  # a sphere's radius in cells
    dev.launch_private(template_light, blocks.n_offsets * faces, [blocks.struct, blocks.owner, blocks.reach, m, T],
                       cells, merge, device, work=max(1.0, 4.0 * r_cell * r_cell))
    dev.launch_private(splat_blocks, blocks.n_instances * faces, [blocks.struct, m, T, cells], data, merge, device,
                       work=C * max(1.0, (M * blocks.reach_max / R) ** 2))
    return T
