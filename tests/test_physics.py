"""Physics @wp.func building blocks, tested on scalars on every device."""

import math

import numpy as np
import pytest
import warp as wp

from warpvol import device as dev
from warpvol.geometry.intersect import ray_box, ray_sphere, sphere_chord
from warpvol.physics import airlight, phase, sampling, sphere, transmittance
from warpvol.physics.lights import (KINDS, Emitter, angle_point, angle_samples, angle_share, ball_mean_inverse_square,
                                    ball_window, light_incident, segment_mean_outside_window, step_angle,
                                    step_mean_irradiance)

dev.kernel_module(__name__)  # this file's kernels: warpvol's Warp options


@wp.kernel
def eval_phase(ph: phase.PhaseParams, table: wp.array(dtype=float), cos: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = phase.phase_eval(ph, table, cos[i])


@wp.kernel
def sample_phase(ph: phase.PhaseParams, table: wp.array(dtype=float), seed: int,
                 cos_out: wp.array(dtype=float), phi_out: wp.array(dtype=float),
                 weight: wp.array(dtype=float), pdf_ratio: wp.array(dtype=float)):
    i = wp.tid()
    rng = wp.rand_init(seed, i)
    d = wp.normalize(wp.vec3(0.3, -0.5, 0.8))
    wi, w, pdf = phase.phase_sample(ph, table, d, wp.randf(rng), wp.randf(rng))
    c = wp.dot(d, wi)
    cos_out[i] = c
    t, s = sampling.orthonormal_basis(d)
    phi_out[i] = wp.atan2(wp.dot(wi, s), wp.dot(wi, t))
    weight[i] = w
    pdf_ratio[i] = pdf / phase.phase_eval(ph, table, c)


@wp.kernel
def eval_transmittance(tau: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = transmittance.transmittance(tau[i])


@wp.kernel
def eval_power_heuristic(a: wp.array(dtype=float), b: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = sampling.power_heuristic(a[i], b[i])


@wp.kernel
def eval_step_integral(sigma: wp.array(dtype=float), dt: float, out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = transmittance.step_integral(sigma[i], dt)


@wp.kernel
def eval_light(light: Emitter, x: wp.array(dtype=wp.vec3), wi_out: wp.array(dtype=wp.vec3),
               dist_out: wp.array(dtype=float), e_out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    wi, dist, e = light_incident(light, x[i])
    wi_out[i] = wi
    dist_out[i] = dist
    e_out[i] = e


@wp.kernel
def eval_airlight(table: wp.array2d(dtype=float), d: wp.array(dtype=wp.vec3), length: float, light_pos: wp.vec3,
                  sigma_t: float, out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = airlight.airlight(table, wp.vec3(0.0), d[i], length, light_pos, wp.vec3(1.0), sigma_t, wp.vec3(1.0))


def make_phase(kind, g=0.0, table=None, g_d=0.0, alpha=0.0, w_d=0.0):
    """The kernel struct; a table is laid out as ``phase_struct`` does: n values, then their CDF."""
    ph = phase.PhaseParams()
    ph.kind, ph.g, ph.offset, ph.n = phase.KINDS[kind], g, 0, 0 if table is None else len(table) // 2
    ph.g_d, ph.alpha, ph.w_d = g_d, alpha, w_d
    return ph


def phase_values(device, ph, table, mu):
    tab = wp.array(table if table is not None else np.zeros(1, np.float32), dtype=float, device=device)
    out = wp.zeros(len(mu), dtype=float, device=device)
    wp.launch(eval_phase, dim=len(mu), inputs=[ph, tab, wp.array(mu.astype(np.float32), dtype=float, device=device), out], device=device)
    return out.numpy().astype(np.float64)


def hg_table():
    mu = np.linspace(-1, 1, 257)
    values = phase.tabulate((1 - 0.25) / (1 + 0.25 - mu) ** 1.5 + 0.3)
    return np.concatenate([values, phase.tabulated_cdf(values)])


CASES = [("isotropic", 0.0), ("rayleigh", 0.0)] + [
    (k, g) for k in ("hg", "cornette_shanks") for g in (-0.99, -0.9, -0.3, 0.0, 0.5, 0.9, 0.99)
] + [("tabulated", 0.0)]


def quadrature_nodes():
    """Cosines that resolve a lobe of width (1 - |g|)^2 at both poles: log-spaced in 1 -/+ mu,
    rounded to float32 so the nodes are the very values the kernel sees."""
    s = np.logspace(-8, np.log10(2.0), 20000)
    mu = np.unique(np.concatenate([1.0 - s, -1.0 + s, [-1.0, 1.0]]).astype(np.float32)).astype(np.float64)
    return mu


@pytest.mark.parametrize("kind,g", CASES)
def test_phase_integrates_to_one(device, kind, g):
    table = hg_table() if kind == "tabulated" else None
    mu = quadrature_nodes()
    p = phase_values(device, make_phase(kind, g, table), table, mu)
    integral = 2 * np.pi * np.trapezoid(p, mu)
    # trapezoid error on these nodes is below 1e-4 for |g| <= 0.99 (checked against float64 HG)
    assert integral == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("g", [-0.9, -0.3, 0.0, 0.5, 0.9, 0.99])
def test_hg_mean_cosine_is_g(device, g):
    mu = quadrature_nodes()
    p = phase_values(device, make_phase("hg", g), None, mu)
    assert 2 * np.pi * np.trapezoid(p * mu, mu) == pytest.approx(g, abs=2e-3)


def wilson_hilferty_pvalue(chi2, dof):
    """Upper tail of the chi^2 distribution (Wilson & Hilferty 1931), accurate for dof >= 10."""
    z = ((chi2 / dof) ** (1 / 3) - (1 - 2 / (9 * dof))) / math.sqrt(2 / (9 * dof))
    return 0.5 * math.erfc(z / math.sqrt(2))


@pytest.mark.parametrize("kind,g", [("isotropic", 0.0), ("hg", 0.0), ("hg", 0.7), ("hg", -0.5), ("hg", 0.95),
                                    ("cornette_shanks", 0.6), ("rayleigh", 0.0), ("tabulated", 0.0)])
def test_sampling_matches_pdf(device, kind, g):
    """Chi^2 test (as Mitsuba's): sampled directions binned in (cos, phi) against the pdf the
    sampler claims, integrated per bin. For exact samplers the weight must be 1 and the
    returned pdf equal the evaluated phase function."""
    n = 200_000
    table = hg_table() if kind == "tabulated" else None
    ph = make_phase(kind, g, table)
    tab = wp.array(table if table is not None else np.zeros(1, np.float32), dtype=float, device=device)
    outs = [wp.zeros(n, dtype=float, device=device) for _ in range(4)]
    wp.launch(sample_phase, dim=n, inputs=[ph, tab, 7, *outs], device=device)
    cos_s, phi_s, weight, pdf_ratio = (o.numpy().astype(np.float64) for o in outs)
    assert np.all(np.isfinite(weight)) and np.all(weight > 0)
    # the sampler's pdf: the phase function itself, HG for Cornette-Shanks, uniform for Rayleigh
    sampler = {"cornette_shanks": make_phase("hg", g), "rayleigh": make_phase("isotropic")}.get(kind, ph)
    if sampler is ph:
        np.testing.assert_allclose(weight, 1.0, rtol=1e-3)
        np.testing.assert_allclose(pdf_ratio, 1.0, rtol=1e-3)
    # bins equal in sampler probability, so every bin expects n / bins samples
    edges_mu = quadrature_nodes()  # resolves the HG lobe, so the bin CDF is accurate to < 1e-4
    p = phase_values(device, sampler, table, edges_mu)
    cdf = np.concatenate([[0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(edges_mu))]) * 2 * np.pi
    k_mu, k_phi = 20, 5
    mu_edges = np.interp(np.linspace(0, cdf[-1], k_mu + 1), cdf, edges_mu)
    counts, _, _ = np.histogram2d(cos_s, phi_s, bins=[mu_edges, np.linspace(-np.pi, np.pi, k_phi + 1)])
    expected = n / (k_mu * k_phi) * np.ones_like(counts)
    chi2 = np.sum((counts - expected) ** 2 / expected)
    assert wilson_hilferty_pvalue(chi2, k_mu * k_phi - 1) > 1e-3, f"chi2 = {chi2:.1f}"
    if kind in ("hg", "cornette_shanks"):
        # sample mean of cos under HG sampling equals g within 5 standard errors
        assert abs(cos_s.mean() - g) < 5 * cos_s.std() / math.sqrt(n)


@pytest.mark.parametrize("g", [0.999, 0.9999, -0.9999])
def test_hg_near_one_stays_finite_and_forward(device, g):
    """Past float32's resolution of cosines the lobe is sampled, not integrated: samples are
    finite and their mean cosine is g within 5 standard errors."""
    n = 100_000
    ph = make_phase("hg", g)
    tab = wp.zeros(1, dtype=float, device=device)
    outs = [wp.zeros(n, dtype=float, device=device) for _ in range(4)]
    wp.launch(sample_phase, dim=n, inputs=[ph, tab, 3, *outs], device=device)
    cos_s, _, weight, _ = (o.numpy() for o in outs)
    assert np.all(np.isfinite(cos_s)) and np.all(np.isfinite(weight))
    assert abs(cos_s.astype(np.float64).mean() - g) < 5 * cos_s.std() / math.sqrt(n) + 1e-6


def test_power_heuristic_is_finite_and_sums_to_one(device):
    """pdf_a^2 / (pdf_a^2 + pdf_b^2) against float64, and the two strategies' weights sum to 1,
    also where the squares leave float32's range (1e-30, 1e30) and where one pdf is 0; both 0
    (a sample neither strategy could draw) weighs 0, not NaN."""
    vals = np.array([0.0, 1e-30, 1e-3, 1.0, 2.0, 1e3, 1e25, 1e30, 3e38], np.float32)
    a, b = (x.ravel() for x in np.meshgrid(vals, vals))
    arrays = [wp.array(x, dtype=float, device=device) for x in (a, b, b, a)]
    w_ab, w_ba = wp.zeros(len(a), dtype=float, device=device), wp.zeros(len(a), dtype=float, device=device)
    wp.launch(eval_power_heuristic, dim=len(a), inputs=[arrays[0], arrays[1], w_ab], device=device)
    wp.launch(eval_power_heuristic, dim=len(a), inputs=[arrays[2], arrays[3], w_ba], device=device)
    w_ab, w_ba = w_ab.numpy(), w_ba.numpy()
    assert np.isfinite(w_ab).all() and ((w_ab >= 0) & (w_ab <= 1)).all()
    both_zero = (a == 0) & (b == 0)
    assert (w_ab[both_zero] == 0).all()
    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    want = 1.0 / (1.0 + (b64[~both_zero & (a > 0)] / a64[~both_zero & (a > 0)]) ** 2)
    np.testing.assert_allclose(w_ab[~both_zero & (a > 0)], want, rtol=2e-6, atol=1e-30)  # float32 rounding
    np.testing.assert_allclose((w_ab + w_ba)[~both_zero], 1.0, rtol=2e-6)


def test_transmittance_is_finite_for_any_optical_depth(device):
    tau = np.concatenate([[0.0], np.logspace(-8, 6, 400), [np.inf]]).astype(np.float32)
    out = wp.zeros(len(tau), dtype=float, device=device)
    wp.launch(eval_transmittance, dim=len(tau), inputs=[wp.array(tau, dtype=float, device=device), out], device=device)
    t = out.numpy()
    assert np.all(np.isfinite(t)) and np.all((t >= 0) & (t <= 1))
    assert np.all(np.diff(t) <= 0), "transmittance must not increase with optical depth"
    np.testing.assert_allclose(t[:-1], np.exp(-tau[:-1].astype(np.float64)), rtol=1e-5, atol=1e-37)
    assert t[-1] == 0.0


def test_step_integral_matches_its_closed_form(device):
    """(1 - exp(-sigma dt)) / sigma, in float64 with expm1; the series branch below tau = 1e-4
    is accurate to tau^2 / 6 relative, far below float32's 6e-8 at that size."""
    sigma = np.array([0.0, 1e-9, 1e-5, 0.1, 1.0, 10.0, 1e4, 1e8], np.float32)
    out = wp.zeros(len(sigma), dtype=float, device=device)
    wp.launch(eval_step_integral, dim=len(sigma), inputs=[wp.array(sigma, dtype=float, device=device), 0.5, out],
              device=device)
    s64 = sigma.astype(np.float64)
    exact = np.where(s64 > 0, -np.expm1(-s64 * 0.5) / np.where(s64 > 0, s64, 1.0), 0.5)
    np.testing.assert_allclose(out.numpy(), exact, rtol=2e-6)


def make_light(kind, position=(0, 0, 0), direction=(0, -1, 0), strength=(2, 3, 4), inner=20.0, outer=30.0):
    s = Emitter()
    s.kind = KINDS[kind]
    s.position, s.direction, s.strength = wp.vec3(*position), wp.vec3(*direction), wp.vec3(*strength)
    s.cos_inner, s.cos_outer = math.cos(math.radians(inner)), math.cos(math.radians(outer))
    return s


def run_light(device, light, x):
    n = len(x)
    wi, dist, e = wp.zeros(n, dtype=wp.vec3, device=device), wp.zeros(n, dtype=float, device=device), wp.zeros(n, dtype=wp.vec3, device=device)
    wp.launch(eval_light, dim=n, inputs=[light, wp.array(x.astype(np.float32), dtype=wp.vec3, device=device), wi, dist, e], device=device)
    return wi.numpy(), dist.numpy(), e.numpy()


def test_point_light_inverse_square(device):
    x = np.random.default_rng(0).normal(size=(100, 3)) * 3
    wi, dist, e = run_light(device, make_light("point", position=(0.5, 1, 0)), x)
    d = np.linalg.norm(np.array([0.5, 1, 0]) - x, axis=1)
    np.testing.assert_allclose(dist, d, rtol=1e-5)
    np.testing.assert_allclose(e, np.outer(1 / d**2, [2, 3, 4]), rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, rtol=1e-5)


@wp.kernel
def step_in_scatter(light: Emitter, o: wp.vec3, d: wp.vec3, t0: wp.array(dtype=float), dt: float, g: float,
                    sigma: float, split: int, out: wp.array(dtype=float)):
    """A march step's mean of I / r^2 p(d . wi) exp(-sigma r) (r the distance to the light):
    the equiangular points (split = 1) or the step's midpoint with the mean 1/r^2 (split = 0)."""
    i = wp.tid()
    a = t0[i]
    tc, h, phi = step_angle(light, o, d, a, a + dt)
    n = wp.where(split == 1, angle_samples(phi), 1)
    acc = float(0.0)
    for j in range(n):
        t = wp.where(n > 1, angle_point(a, tc, h, phi, j, n), a + 0.5 * dt)
        wi, dist, e = light_incident(light, o + t * d)
        if n > 1:
            e = angle_share(light, e, dist, h, phi, n, dt)
        else:
            e = step_mean_irradiance(light, e, dist, o, d, a, a + dt)
        acc += e[0] * phase.henyey_greenstein(g, wp.dot(d, wi)) * wp.exp(-sigma * dist)
    out[i] = acc


def test_a_step_beside_a_point_light_splits_at_equal_angles(device):
    """A march step passing 0.01 from a point light (so the light subtends up to pi across it),
    HG g = 0.7 and attenuation to the light: split into equal angles at the light, the step's
    mean of I p / r^2 e^(-sigma r) matches a 200 000-point quadrature in the angle to 1% (the
    midpoint rule's error at 0.1 rad a sample is about (0.1 / w)^2 / 24 = 0.5%, w = 1 - g the
    width of the phase function's forward lobe in radians). One point with the mean 1/r^2 (the step's midpoint) misses by
    more than 10% wherever the light lies off the step's middle."""
    o, d, h, dt, g, sigma = np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.01, 0.25, 0.7, 0.8
    light = make_light("point", position=(h, 0.0, 1.0))
    t0 = 1.0 - dt * np.array([0.05, 0.2, 0.5, 0.8, 0.95])  # where the closest approach falls in the step
    got = {}
    for split in (0, 1):
        out = wp.zeros(len(t0), dtype=float, device=device)
        wp.launch(step_in_scatter, dim=len(t0), inputs=[light, wp.vec3(*o), wp.vec3(*d),
                  wp.array(t0.astype(np.float32), dtype=float, device=device), dt, g, sigma, split, out],
                  device=device)
        got[split] = out.numpy()
    expected = []
    for a in t0:  # t = tc + h tan(phi): dt / r^2 = dphi / h
        lo, hi = np.arctan((a - 1.0) / h), np.arctan((a + dt - 1.0) / h)
        phi = lo + (np.arange(200_000) + 0.5) * (hi - lo) / 200_000
        t = 1.0 + h * np.tan(phi)
        r = h / np.cos(phi)
        cos = (1.0 - t) / r  # d . wi, wi toward the light
        p = (1 - g * g) / (4 * np.pi * (1 + g * g - 2 * g * cos) ** 1.5)
        expected.append(2.0 * np.mean(p * np.exp(-sigma * r)) * (hi - lo) / (h * dt))  # make_light: I = 2
    expected = np.array(expected)
    np.testing.assert_allclose(got[1], expected, rtol=0.01)
    assert np.max(np.abs(got[0] / expected - 1.0)) > 0.1


@wp.kernel
def outside_window(o: wp.vec3, d: wp.vec3, t0: wp.array(dtype=float), t1: wp.array(dtype=float), p: wp.vec3,
                   radius: float, out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = segment_mean_outside_window(o, d, t0[i], t1[i], p, radius)


@wp.kernel
def window_at(r: wp.array(dtype=float), radius: float, out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = ball_window(r[i], radius)


@pytest.mark.parametrize("h", [0.0, 1e-4, 0.3, 0.9, 1.5])
def test_a_lights_ball_and_what_it_leaves_sum_to_its_inverse_square(device, h):
    """A light's ball of radius 1 (``ball_window``) and the closed-form mean of what it leaves,
    (1 - w) / r^2 (``segment_mean_outside_window``), over steps before, across and after the
    ball, for rays passing at h from the light (0: through it): the remainder matches a
    400 000-point midpoint quadrature to 1e-4 (float32 atan and cubes; the quadrature's own error
    is below 1e-7 on this smooth, bounded integrand) and is at most 2 / R^2 inside the ball; at h
    beyond the ball it is the plain mean of 1/r^2. The window is 1 at the light, 0 at the ball's
    edge and beyond."""
    o, d, p, radius = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([h, 0.0, 2.0]), 1.0
    t0 = np.array([0.2, 0.5, 1.0, 1.9, 2.0, 2.6, 0.0], np.float32)
    t1 = np.array([0.9, 1.5, 3.0, 2.1, 2.05, 3.7, 4.0], np.float32)
    out = wp.zeros(len(t0), dtype=float, device=device)
    wp.launch(outside_window, dim=len(t0), inputs=[wp.vec3(*o), wp.vec3(*d), wp.array(t0, dtype=float, device=device),
              wp.array(t1, dtype=float, device=device), wp.vec3(*p), radius, out], device=device)
    expected = []
    for a, b in zip(t0.astype(float), t1.astype(float)):
        t = a + (np.arange(400_000) + 0.5) * (b - a) / 400_000
        r2 = h * h + (t - 2.0) ** 2
        w = np.clip(1.0 - r2 / radius**2, 0.0, None) ** 2
        expected.append(np.mean((1.0 - w) / r2))  # what the window leaves of 1/r^2
    np.testing.assert_allclose(out.numpy(), expected, rtol=1e-4)
    assert np.all(out.numpy() <= np.maximum(2.0 / radius**2, 1.0 / max(h, 1e-9) ** 2) * (1 + 1e-6))
    r = np.array([0.0, 0.5, 1.0, 2.0], np.float32)
    w = wp.zeros(4, dtype=float, device=device)
    wp.launch(window_at, dim=4, inputs=[wp.array(r, dtype=float, device=device), radius, w], device=device)
    np.testing.assert_allclose(w.numpy(), [1.0, 0.5625, 0.0, 0.0], atol=1e-7)


def test_spot_light_cone(device):
    angles = np.radians([0, 10, 19.9, 25, 30.1, 60, 120])
    x = np.stack([np.sin(angles), -np.cos(angles), np.zeros_like(angles)], 1) * 2.0  # distance 2 from the apex
    _, _, e = run_light(device, make_light("spot"), x)
    f = e[:, 0] / (2.0 / 4.0)
    np.testing.assert_allclose(f[:3], 1.0, rtol=1e-5)
    assert 0.0 < f[3] < 1.0
    np.testing.assert_allclose(f[4:], 0.0, atol=1e-7)


def test_directional_light(device):
    wi, dist, e = run_light(device, make_light("directional", direction=(0, -1, 0)), np.zeros((3, 3)))
    np.testing.assert_allclose(wi, [[0, 1, 0]] * 3)
    assert np.all(dist >= 1e29)
    np.testing.assert_allclose(e, [[2, 3, 4]] * 3)


@wp.kernel
def eval_ball_mean(r: float, d: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = ball_mean_inverse_square(r, d[i])


@wp.kernel
def eval_chord(o: wp.vec3, dirs: wp.array(dtype=wp.vec3), t1: float, c: wp.vec3, r: float, out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = sphere_chord(o, dirs[i], 0.0, t1, c, r)


def test_ball_mean_inverse_square_matches_quadrature(device):
    """Mean of 1/|x - s|^2 over a ball: in polar coordinates about s the 1/rho^2 cancels the
    Jacobian, so the mean is (2 pi / V) times the integral over mu of the chord length from s
    along a direction at cos mu to the centre (midpoint rule, 2e5 nodes over the directions
    that meet the ball: error ~ h^1.5 at the tangent kink, 1e-7). Covers the centre (3/r^2), the surface (3/(2r^2)), both series and their seams."""
    r = 0.3
    d = np.array([0.0, 1e-5, 2e-4, 0.05, 0.1499, 0.1501, 0.2999, 0.3, 0.3001, 0.45, 0.5999, 0.6001, 2.4, 30.0])
    out = wp.zeros(len(d), dtype=float, device=device)
    wp.launch(eval_ball_mean, dim=len(d), inputs=[r, wp.array(d.astype(np.float32), dtype=float, device=device), out],
              device=device)
    want = []
    for dd in d:
        lo = np.sqrt(1 - (r / dd) ** 2) if dd > r else -1.0  # directions that meet the ball
        mu = lo + (np.arange(200000) + 0.5) / 200000 * (1 - lo)
        b = dd * mu
        h2 = r * r - (dd * dd - b * b)
        h = np.sqrt(np.maximum(h2, 0))
        chord = np.where(h2 > 0, np.maximum(b + h, 0) - np.maximum(b - h, 0), 0)
        want.append(2 * np.pi * chord.mean() * (1 - lo) / (4 / 3 * np.pi * r**3))
    np.testing.assert_allclose(out.numpy(), want, rtol=2e-5)
    assert out.numpy()[0] == pytest.approx(3 / r**2, rel=1e-6)
    assert out.numpy()[7] == pytest.approx(1.5 / r**2, rel=1e-5)
    assert out.numpy()[-1] == pytest.approx(1 / 30.0**2, rel=1e-4)


def test_sphere_chord(device):
    """Chord of a segment through a sphere: 2 sqrt(r^2 - b^2) through it, clipped at the
    segment's ends, zero when it misses or the sphere lies behind."""
    dirs = np.array([[0, 0, 1], [0, 0, 1], [0, 0, -1], [0, 1, 0]], np.float32)
    out = wp.zeros(4, dtype=float, device=device)
    wp.launch(eval_chord, dim=4, inputs=[wp.vec3(0.3, 0, 0), wp.array(dirs, dtype=wp.vec3, device=device), 1e30,
                                         wp.vec3(0, 0, 2), 0.5, out], device=device)
    np.testing.assert_allclose(out.numpy(), [2 * np.sqrt(0.25 - 0.09), 2 * np.sqrt(0.25 - 0.09), 0, 0], rtol=1e-5)
    wp.launch(eval_chord, dim=1, inputs=[wp.vec3(0, 0, 2), wp.array(dirs[:1], dtype=wp.vec3, device=device), 0.2,
                                         wp.vec3(0, 0, 2), 0.5, out], device=device)
    assert out.numpy()[0] == pytest.approx(0.2, rel=1e-6)


@wp.kernel
def eval_intersect(o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), c: wp.vec3, r: float, lo: wp.vec3,
                   hi: wp.vec3, out: wp.array(dtype=wp.vec4)):
    i = wp.tid()
    a, b = ray_sphere(o[i], d[i], c, r)
    ta, tb = ray_box(o[i], d[i], lo, hi)
    out[i] = wp.vec4(a, b, ta, tb)


def test_ray_sphere_and_box_agree_with_their_chords(device):
    """Random unit rays: the sphere's (t_near, t_far) span is its chord (``sphere_chord`` over
    the whole line ahead, when the origin is outside), both ends lie on the sphere, and the
    box's span starts and ends on its surface with the midpoint inside; misses give t_near > t_far. Axis-parallel rays take the slab test's zero-direction branch."""
    rng = np.random.default_rng(3)
    o = rng.uniform(-3, 3, (400, 3)).astype(np.float32)
    d = rng.normal(size=(400, 3))
    d[:20] = np.eye(3)[rng.integers(0, 3, 20)] * rng.choice([-1, 1], (20, 1))
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    c, r, lo, hi = np.array([0.2, -0.1, 0.3]), 1.1, np.array([-1.0, -0.5, -0.7]), np.array([0.8, 1.2, 0.9])
    out = wp.zeros(len(o), dtype=wp.vec4, device=device)
    wp.launch(eval_intersect, dim=len(o), inputs=[wp.array(o, dtype=wp.vec3, device=device),
                                                  wp.array(d, dtype=wp.vec3, device=device), wp.vec3(*c), r,
                                                  wp.vec3(*lo), wp.vec3(*hi), out], device=device)
    a, b, ta, tb = out.numpy().astype(np.float64).T
    hit = a <= b
    assert 20 < hit.sum() < len(o) - 20
    for t in (a[hit], b[hit]):
        np.testing.assert_allclose(np.linalg.norm(o[hit] + t[:, None] * d[hit] - c, axis=1), r, atol=1e-4)
    outside = np.linalg.norm(o - c, axis=1) > r
    chords = wp.zeros(1, dtype=float, device=device)
    for k in np.flatnonzero(outside):
        wp.launch(eval_chord, dim=1, inputs=[wp.vec3(*o[k]), wp.array(d[k:k + 1], dtype=wp.vec3, device=device), 1e30,
                                             wp.vec3(*c), r, chords], device=device)
        want = max(b[k], 0.0) - max(a[k], 0.0) if hit[k] else 0.0
        assert chords.numpy()[0] == pytest.approx(want, abs=1e-4)
    box = ta <= tb
    assert 20 < box.sum() < len(o) - 20
    for t in (ta[box], tb[box]):
        p = o[box] + t[:, None] * d[box]
        gap = np.maximum(np.maximum(lo - p, p - hi), 0).max(axis=1)  # distance outside the box
        on_face = np.min(np.minimum(np.abs(p - lo), np.abs(p - hi)), axis=1)
        assert gap.max() < 1e-4 and on_face.max() < 1e-4
    mid = o[box] + 0.5 * (ta[box] + tb[box])[:, None] * d[box]
    assert np.all((mid >= lo - 1e-5) & (mid <= hi + 1e-5))


@wp.kernel
def eval_escape(tau: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = transmittance.sphere_escape(tau[i])


def test_sphere_escape_matches_quadrature(device):
    """Mean over a unit ball of exp(-tau l), l the distance to the surface along +z: midpoint
    quadrature in (rho^3, mu) with 400 x 400 nodes (smooth integrand: error ~1e-6 up to
    tau = 10), on both sides of the series switch at tau = 0.1."""
    taus = np.array([0.0, 1e-3, 0.0999, 0.1001, 0.5, 2.0, 10.0, 100.0], np.float32)
    out = wp.zeros(len(taus), dtype=float, device=device)
    wp.launch(eval_escape, dim=len(taus), inputs=[wp.array(taus, dtype=float, device=device), out], device=device)
    u = (np.arange(400) + 0.5) / 400
    rho = u ** (1 / 3)  # equal-volume shells
    mu = u * 2 - 1
    R, M = np.meshgrid(rho, mu, indexing="ij")
    ell = -R * M + np.sqrt(1 - R**2 * (1 - M**2))
    want = [np.exp(-t * ell).mean() for t in taus[:-1].astype(np.float64)]
    np.testing.assert_allclose(out.numpy()[:-1], want, rtol=2e-4, atol=1e-6)
    # at tau = 100 the integrand lives in a skin the grid cannot resolve: 3/(4 tau) - 3/(8 tau^3)
    assert out.numpy()[-1] == pytest.approx(0.75 / 100.0 - 0.375 / 100.0**3, rel=1e-5)


def test_fibonacci_directions_are_well_spread():
    """Equal-area cells: nearest-neighbour spacing stays within a factor of the ideal
    sqrt(4 pi / D) for every point, and the mean is near zero."""
    for count in (64, 256, 1024):
        dirs = sphere.fibonacci_directions(count).astype(np.float64)
        c = dirs @ dirs.T
        np.fill_diagonal(c, -1)
        spacing = np.arccos(np.clip(c.max(1), -1, 1))
        ideal = math.sqrt(4 * math.pi / count)
        assert spacing.min() > 0.5 * ideal and spacing.max() < 1.5 * ideal
        assert np.linalg.norm(dirs.mean(0)) < 2.0 / count


def test_airlight_table_matches_quadrature():
    table = airlight.f_table()
    us = np.expm1(np.linspace(0, np.log1p(float(airlight.U_MAX)), airlight.TABLE_NU))
    vs = np.linspace(0, np.pi / 2, airlight.TABLE_NV)
    rng = np.random.default_rng(1)
    i, j = rng.integers(0, len(us), 50), rng.integers(0, len(vs) - 1, 50)
    np.testing.assert_allclose(table[i, j], airlight.f_exact(us[i], vs[j]), rtol=1e-5, atol=1e-6)


def test_airlight_closed_form_matches_ray_quadrature(device):
    """Sun et al.'s closed form through the bilinear F table against float64 quadrature along
    each ray. Bilinear interpolation of F leaves an absolute error in F (O(h^2) per cell), which
    the difference F(v_far) - F(v_near) keeps: 0.2 % of a ray's value, plus 0.1 % of the
    brightest ray for dim rays facing away from the light, where the difference cancels."""
    rng = np.random.default_rng(4)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    light, length, sigma = np.array([0.5, 0.3, -2.0]), 30.0, 0.4
    out = wp.zeros(len(d), dtype=wp.vec3, device=device)
    table = wp.array(airlight.f_table(), dtype=float, device=device)
    wp.launch(eval_airlight, dim=len(d), inputs=[table, wp.array(d.astype(np.float32), dtype=wp.vec3, device=device),
                                                   length, wp.vec3(*light), sigma, out], device=device)
    exact = airlight.airlight_exact(np.zeros(3), d, length, light, np.ones(3), sigma, n=8192)
    np.testing.assert_allclose(out.numpy()[:, 0], exact[:, 0], rtol=2e-3, atol=1e-3 * exact[:, 0].max())


@pytest.mark.parametrize("kind", ["hg", "cornette_shanks"])
@pytest.mark.parametrize("g", [0.9, 0.999, 0.9999, -0.999, -0.9999])
def test_peaked_phase_is_finite_past_the_cosine_range(device, kind, g):
    """A float32 dot of two unit vectors can land an ulp or two outside [-1, 1]; with
    |g| -> 1 that once made 1 + g^2 - 2 g cos negative and p NaN. The cosine is clamped in
    hg_denominator, so just outside the range p is finite, positive, and equal to p at the
    end point (exactly: the clamp makes the arguments identical)."""
    ends = np.array([1.0, -1.0], np.float32)
    out = np.array([np.nextafter(np.float32(1), np.float32(2)), np.float32(1.0000005), np.float32(1.01),
                    np.nextafter(np.float32(-1), np.float32(-2)), np.float32(-1.0000005), np.float32(-1.01)],
                   np.float32)
    ph = make_phase(kind, g)
    p_end = phase_values(device, ph, None, ends)
    p_out = phase_values(device, ph, None, out)
    assert np.all(np.isfinite(p_out)) and np.all(p_out > 0), p_out
    np.testing.assert_array_equal(p_out[:3], p_end[0])
    np.testing.assert_array_equal(p_out[3:], p_end[1])
    # the peak is the closed form at cos = +-1, (1 - g^2) / (4 pi (1 - |g|)^3) for HG; tolerance:
    # float32 g = 0.9999 makes 1 - g 2e-4 off relatively, 6e-4 once cubed
    peak = p_end[0] if g > 0 else p_end[1]
    want = (1 - g * g) / (4 * np.pi * (1 - abs(g)) ** 3)
    if kind == "cornette_shanks":
        want *= 3 * 2 / (2 * (2 + g * g))  # 3 (1 + cos^2) / (2 (2 + g^2)) times HG at cos = +-1
    assert peak == pytest.approx(want, rel=2e-3)
