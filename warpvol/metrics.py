"""Error measures between an image and a reference (both H x W x 3, linear)."""

import numpy as np


def relative_rmse(image: np.ndarray, reference: np.ndarray, eps: float = 1e-2) -> float:
    """sqrt(mean((x - r)^2 / (r^2 + eps))): relative error that does not explode in the dark."""
    x, r = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    return float(np.sqrt(np.mean((x - r) ** 2 / (r * r + eps))))


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """sqrt(mean((x - r)^2)), in the images' units; ``reference`` may be a scalar (0: the RMS)."""
    return float(np.sqrt(np.mean((np.asarray(image, np.float64) - np.asarray(reference, np.float64)) ** 2)))
