"""The visibility network's links, launched from the host: each direction's particles projected
onto its M x M window, one radix sort of all (direction, pixel, depth) keys (the paper's depth
peeling), and the links between consecutive particles of a pixel's list (``peel``); and the
padding of I's rows and columns (``pad``)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ... import device as dev
from ...media.particles import Particles
from .kernels import clear_directions, link_network, project_particles


def pad(n: int, k: int) -> int:
    """n rounded up to a multiple of k."""
    return -(-n // k) * k


def peel(P: Particles, tau: wp.array, dirs: wp.array, which: np.ndarray, centre, R: float, M: int, V: wp.array,
         alpha: wp.array, device, clear: bool) -> None:
    """The links V (upstream particle, -1: the sky) and segment opacities alpha of the particles
    ``P`` (extinction ``tau`` at their centres) along the directions ``which`` of ``dirs``, on an
    M x M window over the ball (``centre``, R); with ``clear`` their earlier links are forgotten
    first (the directions re-peeled while the others keep theirs)."""
    n, D, k = P.centres.shape[0], dirs.shape[0], len(which)
    which = wp.array(which.astype(np.int32), dtype=int, device=device)
    if clear:
        dev.launch(clear_directions, n * k, [which, D, V, alpha], device)
    keys = wp.empty(2 * n * k, dtype=wp.int64, device=device)
    values = wp.empty(2 * n * k, dtype=int, device=device)
    dev.launch(project_particles, n * k, [P.centres, dirs, which, wp.vec3(*centre), R, M, keys, values], device)
    wp.utils.radix_sort_pairs(keys, values, n * k)
    dev.launch(link_network, n * k, [keys, values, P.centres, dirs, tau, M, V, alpha], device)
