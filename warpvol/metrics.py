"""Error measures between an image and a reference (both H x W x 3, linear radiance).

Every accuracy figure in warpvol (``render(target_error=...)``, ``frame.error_estimate``,
``technique="auto"``, ``model_error.json`` and the accuracy sweeps in ``results/``) is
``relative_rmse``: the RMSE over the reference's mean. It is free of exposure: scaling the
image and the reference by any k > 0 leaves it unchanged, so a dim fog box and a bright one
with the same structure of error score the same.
"""

import numpy as np


def error_scale(reference: np.ndarray) -> float:
    """The reference's mean value over pixels and channels: what ``relative_rmse`` divides by."""
    return float(np.mean(np.abs(np.asarray(reference, np.float64))))


def relative_rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """sqrt(mean((x - r)^2)) / mean(r): the RMSE in units of the reference's mean radiance.

    Scale-free: relative_rmse(k x, k r) = relative_rmse(x, r) for every k > 0. It is the
    normalised RMSE (NRMSE, the coefficient of variation of the error). The per-pixel relMSE
    of Rousselle, Knaus and Zwicker ("Adaptive sampling and reconstruction using greedy
    error minimization", SIGGRAPH Asia 2011), mean((x - r)^2 / (r^2 + eps)), is free of
    exposure only if eps is taken relative to the image's scale, and even then it weighs a
    dim pixel's error up to 1/eps times a bright one's, so a few dark pixels decide the
    score. Dividing by the mean weighs every pixel's error in the same radiance units, as a
    viewer at one exposure sees it, and an image's standard error is the same quantity for
    the mean of its noise. A black reference: 0 for a black image, else inf."""
    x, r = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    err = rmse(x, r)
    scale = error_scale(r)
    if scale > 0.0:
        return err / scale
    return 0.0 if err == 0.0 else float("inf")


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """sqrt(mean((x - r)^2)), in the images' units; ``reference`` may be a scalar (0: the RMS)."""
    return float(np.sqrt(np.mean((np.asarray(image, np.float64) - np.asarray(reference, np.float64)) ** 2)))
