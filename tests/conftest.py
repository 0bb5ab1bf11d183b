"""Shared fixtures: every device test runs on the CPU and on each CUDA device present."""

import numpy as np
import pytest
import warp as wp

import warpvol  # noqa: F401  (sets Warp quiet before initialisation)
from warpvol import device as dev


def _devices():
    dev.init()
    return ["cpu"] + [str(d) for d in wp.get_cuda_devices()]


@pytest.fixture(params=_devices())
def device(request):
    return request.param


def two_seed_render(scene, device, **settings):
    """Render twice with independent seeds. Returns (mean image, per-pixel standard error of
    that mean): for two i.i.d. estimates a, b of the same pixel, Var(a) ~ (a - b)^2 / 2, so
    the mean (a + b) / 2 has variance (a - b)^2 / 4."""
    import warpvol as wv

    a = wv.render(scene, technique="reference", device=device, seed=1, **settings).image.astype(np.float64)
    b = wv.render(scene, technique="reference", device=device, seed=2, **settings).image.astype(np.float64)
    return 0.5 * (a + b), np.abs(a - b) / 2.0


def assert_mean_within_noise(image, stderr, expected, k=5.0):
    """The image mean equals the expected mean within k standard errors (Monte Carlo noise only).
    The pixels are independent, so the standard error of the mean is sqrt(sum se^2) / N."""
    n = image.size
    se_mean = np.sqrt(np.sum(stderr**2)) / n
    diff = abs(image.mean() - np.mean(expected))
    assert diff <= k * se_mean, f"mean {image.mean():.6g} vs expected {np.mean(expected):.6g}: {diff:.3g} > {k} x {se_mean:.3g}"
