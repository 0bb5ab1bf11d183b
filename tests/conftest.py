"""Shared fixtures: every test that renders takes ``device``.

``device`` runs a test on each device of ``WARPVOL_TEST_DEVICES`` (comma-separated: ``cpu``,
``cuda`` for every CUDA device present, or ``cuda:N``), else on the CPU and every CUDA device
present. With the switch set, tests that take no ``device`` render on its first device
(``WARPVOL_DEVICE``), and tests marked ``cpu_only`` (they test the CPU's own launch split or
run Dask workers on the CPU) skip when it leaves the CPU out. Tests of an optional package
(OpenEXR, pyvista, Dask, Mitsuba, miepython, hypothesis) skip when it is not installed."""

import os

import numpy as np
import pytest
import warp as wp

import warpvol  # noqa: F401  (sets Warp quiet before initialisation)
from warpvol import device as dev


def _devices() -> list[str]:
    dev.init()
    present = ["cpu"] + [str(d) for d in wp.get_cuda_devices()]
    asked = os.environ.get("WARPVOL_TEST_DEVICES", "").strip()
    if not asked:
        return present
    chosen = []
    for name in (s.strip() for s in asked.split(",") if s.strip()):
        match = [d for d in present if d == name or (name == "cuda" and d.startswith("cuda:"))]
        if not match:
            raise pytest.UsageError(f"WARPVOL_TEST_DEVICES={asked}: no device {name!r} here "
                                    f"(allowed: cpu, cuda, cuda:N; present: {', '.join(present)})")
        chosen += [d for d in match if d not in chosen]
    os.environ["WARPVOL_DEVICE"] = chosen[0]
    return chosen


DEVICES: list[str] = []


def pytest_configure(config):
    config.addinivalue_line("markers", "cpu_only: a test of the CPU itself; skipped when WARPVOL_TEST_DEVICES leaves the CPU out")
    DEVICES[:] = _devices()


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        metafunc.parametrize("device", DEVICES)


def pytest_collection_modifyitems(config, items):
    if "cpu" in DEVICES:
        return
    skip = pytest.mark.skip(reason=f"a test of the CPU; WARPVOL_TEST_DEVICES={','.join(DEVICES)}")
    for item in items:
        if "cpu_only" in item.keywords:
            item.add_marker(skip)


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


def sky_over_ball(cam, L, sigma):
    """Single scattering of a uniform sky L in a homogeneous ball (radius 1 at the origin,
    extinction sigma, albedo 1, isotropic), per pixel centre (H x W x 3):
    L [exp(-sigma chord) + int sigma e^(-sigma t) <exp(-sigma l(x, w))>_w dt], l the
    distance from x to the ball's edge along w; 48 Gauss points along the ray and 4096
    Fibonacci directions (error below 1e-4)."""
    o, d = pixel_rays(cam)
    d = d.reshape(-1, 3)
    k = np.arange(4096) + 0.5
    z = 1 - 2 * k / 4096
    phi = np.pi * (3 - np.sqrt(5)) * k
    w = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], 1)
    xg, wg = np.polynomial.legendre.leggauss(48)
    expected = []
    for dr in d:
        b = o @ dr
        disc = b * b - (o @ o - 1.0)
        if disc <= 0:
            expected.append(L)
            continue
        t0, t1 = -b - np.sqrt(disc), -b + np.sqrt(disc)
        t = t0 + (t1 - t0) * 0.5 * (xg + 1)
        x = o + t[:, None] * dr
        bx = x @ w.T  # (t, dirs): exit distance along w from inside the unit ball
        ell = -bx + np.sqrt(bx * bx - ((x * x).sum(1) - 1.0)[:, None])
        inner = np.exp(-sigma * ell).mean(1)
        ss = np.sum(0.5 * (t1 - t0) * wg * sigma * np.exp(-sigma * (t - t0)) * inner)
        expected.append(L * (np.exp(-sigma * (t1 - t0)) + ss))
    expected = np.repeat(np.asarray(expected).reshape(cam["height"], cam["width"], 1), 3, axis=2)
    return expected
