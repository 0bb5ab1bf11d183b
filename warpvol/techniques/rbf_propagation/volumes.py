"""The extinction and opacity volumes' grid: the box it covers (``volume_bounds``), the
``Volume`` struct the kernels index it by, and what the march reads (``Volumes``: the EV, the
OPV and the first medium's albedo and phase function), filled on the host."""

from __future__ import annotations

import numpy as np
import warp as wp

from ...physics.phase import PhaseParams, phase_struct
from ...scene.model import RBFMedium
from ...upload import medium_bounds, scene_bounds

ROOM = 2.0  # the surfaces' box is a room around the media when no wider than ROOM x theirs, per axis
THINNEST = 0.01  # no axis of the volume thinner than this fraction of its widest


def volume_bounds(scene) -> tuple[np.ndarray, np.ndarray]:
    """The box (lo, hi) the EV and OPV cover.

    * The media's bounds (RBFs to their cut-off), so every medium is inside and its cells go
      to the media alone: surfaces reach the OPV through ``surface_optical_depth``, exactly
      wherever they lie, so spanning them buys nothing and a floor plane 8 wide under a
      medium 2 wide would leave the medium a quarter of the cells per axis (and a plane
      alone gave the volume zero thickness: NaN images).
    * Except when the surfaces' box is a room around the media (the paper's Cornell box):
      it holds every RBF centre and every other medium whole, and is no more than ``ROOM``
      times the media's bounds on any axis. Then the room is the volume, as in the paper:
      cells cover the room, which the camera sees, and what falls outside are RBF tails past
      the walls (below 2.3 sigma from a centre in rbf-single), hidden behind the walls but
      at an open side. This keeps rbf-single, rbf-cornell and rbf-thick-fog as they were.
    * Without media, the surfaces' box ([-1, 1]^3 without either).

    Then every axis thinner than ``THINNEST`` of the widest is padded about its centre to
    that thickness: a zero-thickness axis divides by zero, and a thickness near float32's
    rounding (1e-7 of the coordinates) makes cell indices and trilinear weights noise. 1%
    keeps the thinnest cells (n <= 512) 200 times above that rounding, and a medium
    thinner than that is crossed in about one march step at the default 64 steps per
    diagonal anyway, so the padding costs no resolution the march could use.
    """
    boxes = [b for b in map(medium_bounds, scene.media) if b is not None]
    if not boxes:
        lo, hi = scene_bounds(scene, media=False)
    else:
        lo, hi = np.min([b[0] for b in boxes], 0), np.max([b[1] for b in boxes], 0)
        if scene.surfaces:
            cores = [(m.centers.min(0), m.centers.max(0)) if isinstance(m, RBFMedium) else b
                     for m, b in zip([m for m in scene.media if medium_bounds(m) is not None], boxes)]
            clo, chi = np.min([c[0] for c in cores], 0), np.max([c[1] for c in cores], 0)
            slo, shi = scene_bounds(scene, media=False)
            if (slo <= clo).all() and (chi <= shi).all() and (shi - slo <= ROOM * (hi - lo)).all():
                lo, hi = slo, shi
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    ext = hi - lo
    widest = ext.max() if ext.max() > 0 else 1.0
    half = 0.5 * np.maximum(ext, THINNEST * widest)
    mid = 0.5 * (lo + hi)
    return np.where(ext < THINNEST * widest, mid - half, lo), np.where(ext < THINNEST * widest, mid + half, hi)


@wp.struct
class Volume:
    """An n[0] x n[1] x n[2] grid of cells over [lo, hi]; values at cell centres, x fastest."""

    lo: wp.vec3
    hi: wp.vec3
    n: wp.vec3i
    h: wp.vec3  # cell size


@wp.struct
class Volumes:
    """What the march reads: the extinction volume (EV) and the per-light optical depth
    volumes (OPV, a cell's lights side by side: light l of cell c at c L + l for L lights) over
    one ``Volume``, and the medium's albedo and phase function (the first medium's)."""

    ev: wp.array(dtype=wp.vec3)
    opv: wp.array(dtype=wp.vec3)
    v: Volume
    albedo: wp.vec3
    phase: PhaseParams
    phase_table: wp.array(dtype=float)


def grid_volume(scene, n: int) -> Volume:
    """n^3 cells over ``volume_bounds(scene)``."""
    lo, hi = volume_bounds(scene)
    v = Volume()
    v.lo, v.hi, v.n = wp.vec3(*lo), wp.vec3(*hi), wp.vec3i(n, n, n)
    v.h = wp.vec3(*((hi - lo) / n))
    return v


def march_inputs(ev, opv, v: Volume, medium, device) -> Volumes:
    """The EV ``ev`` and OPV ``opv`` over ``v``, with the albedo and phase function of ``medium``
    (the scene's first; None: no medium)."""
    albedo = wp.vec3(*medium.albedo) if medium is not None else wp.vec3(0.0)
    phase, table = PhaseParams(), np.zeros(1, np.float32)
    if medium is not None:  # the first medium's
        phase, table = phase_struct(medium.phase)
    phase_table = wp.array(table if len(table) else np.zeros(1, np.float32), dtype=float, device=device)
    vols = Volumes()
    vols.ev, vols.opv, vols.v = ev, opv, v
    vols.albedo, vols.phase, vols.phase_table = albedo, phase, phase_table
    return vols
