"""The phase weights the network's iteration applies: the phase function tabulated between the D
directions (the ``phase_matrix`` kernel) and weighted the paper's way, 4 pi / D, or scaled doubly
stochastic (``doubly_stochastic``, symmetric Sinkhorn-Knopp in float64), blocked 16 columns to a
vector for ``scatter_matmul`` (``tabulate_weights``)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ... import device as dev
from ...physics.phase import PhaseParams
from .kernels import phase_matrix, vec16


def tabulate_weights(dirs: wp.array, ph: PhaseParams, table: wp.array, Dp: int, normalise: int,
                     device) -> tuple[wp.array, float]:
    """W[d, i] = weight p(w_d . w_i) for the D directions ``dirs`` (Dp x Dp, padding zero, as Dp
    x Dp / 16 vectors of 16): the paper's weight 4 pi / D, or with ``normalise`` the doubly
    stochastic scaling; and the largest p(w_d . w_i) before weighting."""
    D = dirs.shape[0]
    flat = wp.empty(Dp * Dp, dtype=float, device=device)
    dev.launch(phase_matrix, Dp * Dp, [dirs, ph, table, Dp, flat], device)
    weights = flat.numpy().reshape(Dp, Dp).astype(np.float64)
    p_max = float(weights.max())
    if normalise:
        weights[:D, :D] = doubly_stochastic(weights[:D, :D])
    else:
        weights *= 4.0 * np.pi / D
    return wp.array(weights.astype(np.float32).reshape(Dp, Dp // 16, 16), dtype=vec16, device=device), p_max


def doubly_stochastic(P: np.ndarray, tol: float = 1e-9, max_iter: int = 10000) -> np.ndarray:
    """diag(x) P diag(x) for a symmetric non-negative P (float64): every row and column sums
    to 1. Symmetric Sinkhorn-Knopp, x <- x / sqrt(row sums), from x = 1 / sqrt(P 1), to a
    largest row-sum error of ``tol`` (or ``max_iter`` steps: a matrix without total support
    may not converge). The result is then divided by its largest row or column sum, so the
    sums are <= 1 whatever happened (the iteration's gain bound), and symmetrised."""
    P = np.asarray(P, np.float64)
    sums = P.sum(1)
    x = 1.0 / np.sqrt(np.where(sums > 0, sums, 1.0))
    for _ in range(max_iter):
        r = x * (P @ x)
        if np.abs(r[sums > 0] - 1.0).max(initial=0.0) < tol:
            break
        x = x / np.sqrt(np.where(r > 0, r, 1.0))
    B = x[:, None] * P * x[None, :]
    B = 0.5 * (B + B.T)
    top = max(B.sum(0).max(initial=0.0), B.sum(1).max(initial=0.0))
    return B / top if top > 0 else B

