"""Direction sets on the unit sphere.

The Fibonacci (golden-spiral) set places D directions with equal area per direction
(each owns 4 pi / D sr) and near-uniform spacing; González, Math. Geosci. 2010.
"""

import numpy as np


def fibonacci_directions(count: int, seed: int = 0) -> np.ndarray:
    """``count`` unit vectors, shape (count, 3) float32, spread evenly over the sphere; with
    ``seed`` > 0 the whole set turned by a rotation drawn uniformly from SO(3) (the QR of a
    Gaussian matrix, seeded): independent sets of the same quality, whose spread is the
    quadrature's error."""
    if count < 1:
        raise ValueError(f"direction count must be >= 1, got {count}")
    i = np.arange(count, dtype=np.float64) + 0.5
    z = 1.0 - 2.0 * i / count
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    dirs = np.stack([r * np.cos(phi), z, r * np.sin(phi)], axis=1)
    if seed:
        q, t = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
        q = q * np.sign(np.diag(t))  # Haar-distributed (Mezzadri 2007)
        dirs = dirs @ (q * np.sign(np.linalg.det(q))).T  # a rotation, not a reflection
    return dirs.astype(np.float32)
