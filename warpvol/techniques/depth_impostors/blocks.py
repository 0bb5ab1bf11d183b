"""The depth impostors' blocks, built on the host: a cloud's particles as instances of template
blocks (``build_blocks``: ``Templates`` collected medium by medium, then a ``BlockLayout`` on the
device), the Morton-order grouping of a cloud not built of blocks (``morton_groups``), and the
impostors' texels a side, for the layout (``layout_res``) and for a view (``view_res``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from ...media.particles import Blocks
from ...scene.procedural import split_blocks

RES_MIN, RES_MAX = 2, 128  # impostor texels a side where impostor_res = 0


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


class Templates:
    """The template blocks and their instances as ``collect`` finds them. Per template: its
    particles' offsets from its centre (float64), its medium's radius, sigma_t and albedo, and
    its index among the textured templates (``texel0``; -1: one particle, no texture). Per
    instance (lists of arrays, one a medium or group): its centre, its template, and for a
    one-particle instance its particle in the cloud (-1: none)."""

    def __init__(self):
        self.offsets, self.first, self.count, self.radius, self.sigma_t, self.albedo, self.texel0 = (
            [] for _ in range(7))
        self.n_textured_templates = 0
        self.centres, self.tpl_of, self.particle_of = [], [], []

    def add(self, offsets: np.ndarray, medium, textured: bool) -> int:
        """A template of these offsets (n x 3) in ``medium``; returns its index."""
        self.first.append(sum(len(o) for o in self.offsets))
        self.offsets.append(np.asarray(offsets, np.float64).reshape(-1, 3))
        self.count.append(len(self.offsets[-1]))
        self.radius.append(medium.radius)
        self.sigma_t.append(medium.sigma_t)
        self.albedo.append(medium.albedo)
        self.texel0.append(self.n_textured_templates if textured else -1)  # times T^2 once T is known
        self.n_textured_templates += 1 if textured else 0
        return len(self.first) - 1

    def instances(self, centres: np.ndarray, tpl_of: np.ndarray, particle_of: np.ndarray) -> None:
        self.centres.append(centres)
        self.tpl_of.append(tpl_of)
        self.particle_of.append(particle_of)

    def reach(self) -> np.ndarray:
        """Per template: its bounding radius about its centre (the farthest sphere's reach), float32."""
        offsets = np.concatenate(self.offsets).astype(np.float64)
        return np.array([np.sqrt((offsets[f:f + c] ** 2).sum(1)).max() + r
                         for f, c, r in zip(self.first, self.count, self.radius)], np.float32)


def collect(media, cluster: int) -> Templates:
    """The particle media's templates and instances: a medium built of blocks (``block_size``
    b > 1) is K instances of one template; any other is grouped into blocks of ``cluster``
    particles along a Morton curve, each group its own template and one instance; with
    ``cluster`` = 1 every particle is an instance of a one-particle template."""
    tpl = Templates()
    base = 0
    for medium in media:
        p = np.asarray(medium.positions, np.float32).reshape(-1, 3)
        split = split_blocks(p, int(getattr(medium, "block_size", 0)))
        if split is not None:  # K copies of one block
            offs, inst = split
            t = tpl.add(offs, medium, True)
            tpl.instances(inst, np.full(len(inst), t, np.int32), np.full(len(inst), -1, np.int32))
        elif cluster > 1 and len(p) > 1:  # grouped: each group a template of its own
            for group in morton_groups(p, cluster):
                g = p[group].astype(np.float64)
                c = g.mean(axis=0)
                t = tpl.add(g - c, medium, len(g) > 1)
                tpl.instances(c[None], np.array([t], np.int32),
                              np.array([base + group[0] if len(g) == 1 else -1], np.int32))
        else:  # every particle an instance of a one-particle template
            t = tpl.add(np.zeros((1, 3)), medium, False)
            tpl.instances(p.astype(np.float64), np.full(len(p), t, np.int32),
                          np.arange(base, base + len(p), dtype=np.int32))
        base += len(p)
    return tpl


@dataclass
class BlockLayout:
    """The blocks on the device (``blocks``, impostor texels laid out ``blocks.res`` a side) and
    what the stages read of them: per template its bounding radius (``reach_t``), the textured
    templates (``textured_t``) and a texel's work (their mean particle count); per instance on
    the host its centre, bounding radius and whether it has a texture (float64, float64, bool);
    the textured instances (``textured``) and each one's first radiance texel (``first``); each
    one-particle instance's particle in the cloud (``particle_of``)."""

    blocks: Blocks
    reach_t: wp.array
    textured_t: wp.array
    texel_work: float
    texels: int  # impostor texels of every textured template
    centres: np.ndarray
    reach: np.ndarray
    has_texture: np.ndarray
    textured: wp.array
    first: wp.array
    particle_of: wp.array

    @property
    def n_instances(self) -> int:
        return len(self.centres)

    @property
    def n_textured(self) -> int:
        return self.textured.shape[0]


def blocks_struct(tpl: Templates, centres: np.ndarray, tpl_of: np.ndarray, reach_t: np.ndarray, texel0: list[int],
                  res: int, device) -> Blocks:
    """The ``Blocks`` struct of the templates and their instances, impostors ``res`` texels a side."""
    f3 = lambda a: wp.array(np.asarray(a, np.float32).reshape(-1, 3), dtype=wp.vec3, device=device)  # noqa: E731
    B = Blocks()
    B.centre = f3(centres)
    B.tpl = wp.array(tpl_of, dtype=int, device=device)
    B.reach = wp.array(reach_t[tpl_of] if len(tpl_of) else np.zeros(0, np.float32), dtype=float, device=device)
    B.first = wp.array(np.asarray(tpl.first, np.int32), dtype=int, device=device)
    B.count = wp.array(np.asarray(tpl.count, np.int32), dtype=int, device=device)
    B.offsets = f3(np.concatenate(tpl.offsets).astype(np.float64))
    B.radius = wp.array(np.asarray(tpl.radius, np.float32), dtype=float, device=device)
    B.sigma_t = f3(tpl.sigma_t)
    B.albedo = f3(tpl.albedo)
    B.texel0 = wp.array(np.asarray(texel0, np.int32), dtype=int, device=device)
    B.res = res  # the layout's texels a side; Impostors.res: this view's, at most this
    return B


def build_blocks(media, cluster: int, impostor_res: int, impostor_detail: float, device) -> BlockLayout:
    """The media's blocks (``collect``) on the device, their impostors laid out ``layout_res``
    texels a side."""
    tpl = collect(media, cluster)
    centres = np.concatenate(tpl.centres)
    tpl_of = np.concatenate(tpl.tpl_of)
    particle_of = np.concatenate(tpl.particle_of)
    reach_t = tpl.reach()
    textured_t = np.nonzero(np.asarray(tpl.texel0) >= 0)[0].astype(np.int32)
    T = layout_res(reach_t[textured_t], np.asarray(tpl.radius, np.float64)[textured_t], impostor_res, impostor_detail)
    texel0 = [j * T * T if j >= 0 else -1 for j in tpl.texel0]
    has_texture = np.asarray(texel0, np.int64)[tpl_of] >= 0 if len(tpl_of) else np.zeros(0, bool)
    textured = np.nonzero(has_texture)[0].astype(np.int32)
    first_rad = np.full(max(len(tpl_of), 1), 0, np.int32)
    first_rad[textured] = np.arange(len(textured), dtype=np.int32) * T * T
    return BlockLayout(
        blocks=blocks_struct(tpl, centres, tpl_of, reach_t, texel0, T, device),
        reach_t=wp.array(reach_t, dtype=float, device=device),
        textured_t=wp.array(textured_t, dtype=int, device=device),
        texel_work=float(np.mean(np.asarray(tpl.count)[textured_t])) if len(textured_t) else 1.0,
        texels=tpl.n_textured_templates * T * T,
        centres=centres.astype(np.float64), reach=reach_t[tpl_of].astype(np.float64), has_texture=has_texture,
        textured=wp.array(textured, dtype=int, device=device),
        first=wp.array(first_rad, dtype=int, device=device),
        particle_of=wp.array(np.maximum(particle_of, 0) if len(particle_of) else np.zeros(1, np.int32), dtype=int,
                             device=device))


def layout_res(reach: np.ndarray, radius: np.ndarray, impostor_res: int, impostor_detail: float) -> int:
    """Texels a side the impostors are laid out for: ``impostor_res``, or where that is 0,
    ``impostor_detail`` x 3 R / r for the textured template of the most particle radii r
    across its radius R (a texel two thirds of a radius wide: finer adds nothing the
    spheres' own edges do not blur), within [RES_MIN, RES_MAX]."""
    if impostor_res > 0 or not len(reach):
        return max(impostor_res, 1)
    across = float(np.max(reach / np.maximum(radius, 1e-12)))
    return int(np.clip(np.ceil(impostor_detail * 3.0 * across), RES_MIN, RES_MAX))


def view_res(layout: BlockLayout, camera, impostor_res: int, impostor_detail: float) -> int:
    """Texels a side for this view: the layout's, or where ``impostor_res`` is 0, no more
    than ``impostor_detail`` x D / 2 for D the largest projected diameter in pixels of a
    textured instance (2 R / (distance - R) x the focal length in pixels): a texel need not
    be finer than two pixels. An instance around the camera keeps the layout's."""
    T = layout.blocks.res
    textured = layout.has_texture
    if impostor_res > 0 or not textured.any():
        return T
    focal = 0.5 * camera.height / np.tan(np.radians(camera.fov_y) / 2.0)
    dist = np.linalg.norm(layout.centres[textured] - np.asarray(camera.origin, np.float64), axis=1)
    R = layout.reach[textured]
    if np.any(dist <= R):
        return T
    D = float(np.max(2.0 * R / (dist - R))) * focal
    return int(np.clip(np.ceil(impostor_detail * 0.5 * D), RES_MIN, T))
