"""The visibility network's window resolution M (the M x M pixels each direction's particles are
projected onto): the paper's rule (``window_rule``), the largest window whose columns hold a
given number of particles (``column_counts``, ``column_window``), and the technique's choice
between them (``network_window``). NumPy on the host."""

from __future__ import annotations

import numpy as np


def window_rule(directions: int, radius: float, tau: float) -> int:
    """The paper's largest window: M^2 <= D (R tau)^2 / pi, at least 1."""
    return max(1, int(np.floor(np.sqrt(directions * (radius * tau) ** 2 / np.pi))))


def column_counts(pos: np.ndarray, centre, R: float, M: int, dirs: np.ndarray) -> float:
    """Particles per occupied pixel column of an M x M window over the ball (centre, R),
    averaged over the directions ``dirs``: N over the columns the particles fall in."""
    x = np.asarray(pos, np.float64) - np.asarray(centre, np.float64)
    means = []
    for w in np.asarray(dirs, np.float64):
        # the window's axes as project_particles takes them (physics.sampling.orthonormal_basis)
        sign = 1.0 if w[2] >= 0.0 else -1.0
        a = -1.0 / (sign + w[2])
        b = w[0] * w[1] * a
        e1 = np.array([1.0 + sign * w[0] * w[0] * a, sign * b, -sign * w[0]])
        e2 = np.array([b, sign + w[1] * w[1] * a, -w[1]])
        u = np.clip(np.floor((x @ e1 + R) * M / (2.0 * R)), 0, M - 1).astype(np.int64)
        v = np.clip(np.floor((x @ e2 + R) * M / (2.0 * R)), 0, M - 1).astype(np.int64)
        means.append(len(x) / len(np.unique(v * M + u)))
    return float(np.mean(means))


def column_window(pos: np.ndarray, centre, R: float, per_column: float, dirs: np.ndarray, largest: int) -> int:
    """The largest window M (1 .. ``largest``) whose occupied columns hold at least
    ``per_column`` particles on average along ``dirs`` (``column_counts``): links then join
    chains of about that many particles instead of mostly seeing past the cloud. The count
    falls as M grows (finer columns), so M is found by bisection."""
    if len(pos) < per_column:  # one column holds them all: M = 1 is as coarse as a window gets
        return 1
    lo, hi = 1, max(int(largest), 1)  # column_counts(lo) >= per_column holds throughout
    if column_counts(pos, centre, R, hi, dirs) >= per_column:
        return hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if column_counts(pos, centre, R, mid, dirs) >= per_column:
            lo = mid
        else:
            hi = mid
    return lo



def network_window(window: int, column: float, window_at: int, pos: np.ndarray, centre, R: float, tau: float,
                   dirs: np.ndarray) -> int:
    """M for the settings ``window``, ``column`` and ``window_at``: ``window`` where it is set,
    else the paper's rule at ``window_at`` (0: at D) directions for the cloud's mean extinction
    ``tau``, and with ``column`` = K > 0 no finer than that and chains of K particles
    (``column_window``, counted along three of the D directions ``dirs``)."""
    D = len(dirs)
    M = window or window_rule(window_at or D, R, tau)
    if not window and column > 0:  # no finer than the paper's rule, and chains of `column`
        M = column_window(pos, centre, R, column, dirs[:: max(D // 3, 1)][:3], M)
    return M
