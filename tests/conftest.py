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


def pixel_rays(cam):
    """Unit directions through pixel centres, as the kernels compute them (float64)."""
    o = np.asarray(cam["origin"], float)
    f = np.asarray(cam["target"], float) - o
    f /= np.linalg.norm(f)
    r = np.cross(f, [0, 1, 0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    th = np.tan(np.radians(cam["fov_y"]) / 2)
    px, py = np.meshgrid(np.arange(cam["width"]) + 0.5, np.arange(cam["height"]) + 0.5)
    sx, sy = 2 * px / cam["width"] - 1, 1 - 2 * py / cam["height"]
    d = f + sx[..., None] * r * th * cam["width"] / cam["height"] + sy[..., None] * u * th
    return o, d / np.linalg.norm(d, axis=-1, keepdims=True)
