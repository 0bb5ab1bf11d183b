"""The wavefront's plan on the host (NumPy): per light, the cell it starts from and the axis a
shell thread solves for, and how many shells reach every cell (``propagate_shell`` runs one
launch a shell)."""

from __future__ import annotations

import numpy as np

from ...scene.model import LightKind


def shell_plan(lights, v, n: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The wavefront's plan for the ``lights`` over the n^3 grid ``v`` (a ``Volume``): per light
    its cell (clamped to [-1, n] per axis in floating point before any integer, so a light at
    1e30 cannot overflow; unused for directional lights), the Manhattan distance of its nearest
    grid cell (launch k updates the cells at that distance + k) and the launches that reach
    every cell: the largest (farthest - nearest) + 1 over the lights, at most 3(n - 1) + 1."""
    lo, h = np.asarray(v.lo, np.float32), np.asarray(v.h, np.float32)
    cells, base, spread = [], [], [0]
    for light in lights:
        if light.type == LightKind.DIRECTIONAL:  # offsets from the upwind corner: 0 .. n - 1 on each axis used
            cells.append((0, 0, 0))
            base.append(0)
            spread.append(int(np.sum(np.asarray(light.direction) != 0)) * (n - 1))
            continue
        with np.errstate(over="ignore", invalid="ignore"):  # float32 as the kernels: the same cell on a boundary
            g = np.floor((np.asarray(light.position, np.float32) - lo) / h)
        g = np.clip(np.nan_to_num(g, nan=-1.0), -1, n).astype(int)
        near = np.maximum(np.maximum(-g, g - (n - 1)), 0)  # distance to the range 0 .. n - 1 per axis
        far = np.maximum(np.abs(g), np.abs(n - 1 - g))
        cells.append(tuple(g))
        base.append(int(near.sum()))
        spread.append(int(far.sum() - near.sum()))
    return (np.asarray(cells, np.int32).reshape(-1, 3), np.asarray(base, np.int32).reshape(-1),
            max(spread) + 1)


def solve_axes(lights) -> list[int]:
    """Per light, the axis a shell thread solves for: one the light travels along (z for a point
    or spot light)."""
    return [2 if light.type != LightKind.DIRECTIONAL else int(np.argmax(np.abs(light.direction))) for light in lights]
