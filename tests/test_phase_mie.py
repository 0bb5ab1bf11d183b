"""Droplet phase functions: the Mie table (log-normal sizes, miepython) and the Jendersie &
d'Eon 2023 HG + Draine blend. Properties as for the other kinds (tests/test_physics.py, whose
kernels these tests launch: no new Warp module): normalised, sampled as evaluated, mean cosine;
then against their sources (miepython, the paper's test vector) and against each other."""

import importlib.util
import math

import numpy as np
import pytest
import warp as wp

from tests.test_physics import make_phase, phase_values, quadrature_nodes, sample_phase, wilson_hilferty_pvalue
from warpvol.physics import phase
from warpvol.scene import SceneError, mie, scene_from_dict
from warpvol.scene.model import Phase

NEEDS_MIEPYTHON = pytest.mark.skipif(importlib.util.find_spec("miepython") is None,
                                     reason="miepython is the [mie] extra")
FIT_20 = mie.jendersie_deon(20.0)


def blend(f: mie.HGDraine):
    return make_phase("hg_draine", f.g_hg, g_d=f.g_d, alpha=f.alpha, w_d=f.w_d)


def mie_struct(median_um, sigma):
    """The kernel struct and device-layout table of the loader's Mie phase."""
    return phase.phase_struct(Phase("tabulated", values=mie.mie_table(median_um, sigma).mean.astype(np.float32)))


BLENDS = {
    "fit d=5": mie.jendersie_deon(5.0),
    "fit d=20": FIT_20,
    "fit d=50": mie.jendersie_deon(50.0),
    "draine only": mie.HGDraine(0.0, FIT_20.g_d, FIT_20.alpha, 1.0),
    "draine g=0.05 alpha=100": mie.HGDraine(0.0, 0.05, 100.0, 1.0),
    "explicit": mie.HGDraine(-0.3, 0.9, 2.0, 0.3),
}


def test_jendersie_deon_fit_matches_the_papers_test_vector():
    """Their values at d = 20 um, printed to 5-6 significant digits: agreement to 1e-4
    (alpha: 1e-4 relative) is what those digits allow."""
    assert FIT_20.g_hg == pytest.approx(0.99461, abs=1e-4)
    assert FIT_20.g_d == pytest.approx(0.59379, abs=1e-4)
    assert FIT_20.alpha == pytest.approx(27.1137, rel=1e-4)
    assert FIT_20.w_d == pytest.approx(0.49816, abs=1e-4)
    for d in (4.99, 50.01):
        with pytest.raises(ValueError, match="5-50 um"):
            mie.jendersie_deon(d)


@pytest.mark.parametrize("name", list(BLENDS))
def test_hg_draine_integrates_to_one(device, name):
    """Trapezoid on ``quadrature_nodes``. Its own error is measured with the float64 host
    function (which integrates to 1 exactly): 2.5e-5 at g_HG = 0.998 (d = 50 um). The kernel adds float32
    rounding, ~1e-6 relative per value and at most a few 1e-5 where a g_HG = 0.998 lobe meets
    float32's cosine spacing near 1: tolerance 1e-4 plus the quadrature's error."""
    f = BLENDS[name]
    mu = quadrature_nodes()
    quadrature_error = abs(2 * np.pi * np.trapezoid(mie.hg_draine(mu, f), mu) - 1.0)
    assert quadrature_error < 1e-4
    p = phase_values(device, blend(f), None, mu)
    np.testing.assert_allclose(p, mie.hg_draine(mu, f), rtol=2e-5 if f.g_hg < 0.995 else 2e-4)
    assert 2 * np.pi * np.trapezoid(p, mu) == pytest.approx(1.0, abs=1e-4 + quadrature_error)


def test_draine_mean_cosine_closed_form():
    """The closed-form mean cosine against quadrature (float64 trapezoid, error < 1e-4 as above)."""
    mu = quadrature_nodes()
    for f in BLENDS.values():
        g = 2 * np.pi * np.trapezoid(mie.hg_draine(mu, f) * mu, mu)
        assert mie.hg_draine_mean_cosine(f) == pytest.approx(g, abs=1e-4)


def assert_pdf_is_p(pdf_ratio, cos_s, p_host):
    """pdf / p = 1 up to float32: ``sample_phase`` evaluates p at the cosine of the returned
    direction, whose rounding (a few ulps of 1, 1e-6) moves ln p by up to its change over 1e-6
    (1e-2 on a g_HG = 0.995 lobe), the tolerance per sample."""
    d = 1e-6
    tol = 1e-5 + np.abs(np.log(p_host(np.minimum(cos_s + d, 1))) - np.log(p_host(np.maximum(cos_s - d, -1))))
    assert np.all(np.abs(pdf_ratio - 1.0) <= tol), np.max(np.abs(pdf_ratio - 1.0) / tol)


def sampling_chi2(device, ph, table, nodes, n=200_000, seed=11):
    """Sample n directions with ``phase_sample``; chi^2 p-value of their (cos, phi) histogram
    against the evaluated pdf, in 20 x 5 bins of equal probability (bin edges from the CDF of
    the pdf by trapezoid on ``nodes``). Returns (p-value, cosines, weights, pdf / p)."""
    tab = wp.array(table if table is not None else np.zeros(1, np.float32), dtype=float, device=device)
    outs = [wp.zeros(n, dtype=float, device=device) for _ in range(4)]
    wp.launch(sample_phase, dim=n, inputs=[ph, tab, seed, *outs], device=device)
    cos_s, phi_s, weight, pdf_ratio = (o.numpy().astype(np.float64) for o in outs)
    p = phase_values(device, ph, table, nodes)
    cdf = np.concatenate([[0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(nodes))]) * 2 * np.pi
    k_mu, k_phi = 20, 5
    mu_edges = np.interp(np.linspace(0, cdf[-1], k_mu + 1), cdf, nodes)
    counts, _, _ = np.histogram2d(cos_s, phi_s, bins=[mu_edges, np.linspace(-np.pi, np.pi, k_phi + 1)])
    expected = n / (k_mu * k_phi)
    chi2 = np.sum((counts - expected) ** 2 / expected)
    return wilson_hilferty_pvalue(chi2, k_mu * k_phi - 1), cos_s, weight, pdf_ratio


@pytest.mark.parametrize("name", ["fit d=5", "draine only", "draine g=0.05 alpha=100", "explicit"])
def test_hg_draine_sampling_matches_pdf(device, name):
    """Exact sampler: weight 1 and pdf = p (``assert_pdf_is_p``); chi^2 p-value > 1e-3 (bin CDF from quadrature_nodes,
    accurate to < 1e-4 per bin of probability 0.05); sample mean cosine = the closed form within
    5 standard errors."""
    f = BLENDS[name]
    pvalue, cos_s, weight, pdf_ratio = sampling_chi2(device, blend(f), None, quadrature_nodes())
    np.testing.assert_allclose(weight, 1.0, rtol=1e-6)
    assert_pdf_is_p(pdf_ratio, cos_s, lambda c: mie.hg_draine(c, f))
    assert pvalue > 1e-3, f"chi2 p-value {pvalue:.2g}"
    assert abs(cos_s.mean() - mie.hg_draine_mean_cosine(f)) < 5 * cos_s.std() / math.sqrt(len(cos_s))


@pytest.mark.parametrize("name", ["fit d=20", "fit d=50"])
def test_hg_draine_peaked_fits_sample_their_mean_cosine(device, name):
    """The fits' HG lobes (g_HG = 0.9946 at 20 um, 0.998 at 50 um) are a few float32 ulps of
    cos wide: plain HG fails the chi^2 test there too (p < 1e-3 for g = 0.9946, seeds 11 and 13),
    as the cosine of a float32 direction is rounded by ~1e-7. As for HG near 1
    (test_physics.py), they are checked by sampling: weight 1, mean cosine = the closed form
    within 5 standard errors. Their Draine lobe passes chi^2 above ("draine only")."""
    f = BLENDS[name]
    _, cos_s, weight, _ = sampling_chi2(device, blend(f), None, quadrature_nodes())
    np.testing.assert_allclose(weight, 1.0, rtol=1e-6)
    assert abs(cos_s.mean() - mie.hg_draine_mean_cosine(f)) < 5 * cos_s.std() / math.sqrt(len(cos_s))


@NEEDS_MIEPYTHON
@pytest.mark.parametrize("sigma", [0.0, 0.3])
def test_mie_table_is_normalised_and_resolves_the_peak(device, sigma):
    """Before ``tabulate`` rescales it, the trapezoid integral of the table is 1 up to what the
    piecewise-linear table loses at the forward peak: ``table_entries`` puts ~16 nodes across
    1 - cos(lambda / d), a trapezoid error of order (1/16)^2 / 12 = 3e-4 of the peak's share
    (~1/2) times its curvature (a few): below 2e-3. The kernel's table integrates to 1 exactly
    on its own nodes (trapezoid is exact for a piecewise-linear function); the tolerance is
    float32 rounding of the values (6e-8 each), 1e-5."""
    t = mie.mie_table(10.0, sigma)
    assert max(abs(e) for e in t.norm_error) < 2e-3, t.norm_error
    ph, table = mie_struct(10.0, sigma)
    assert ph.n == len(t.mu) and len(table) == 2 * ph.n
    mu = t.mu.astype(np.float32).astype(np.float64)
    np.testing.assert_array_equal(mu, t.mu)  # nodes -1 + i / 2^k are float32 numbers: the kernel sees these
    p = phase_values(device, ph, table, mu)
    assert 2 * np.pi * np.trapezoid(p, mu) == pytest.approx(1.0, abs=1e-5)
    # the table's mean cosine against the exact one (miepython's g per size, averaged like p);
    # the same trapezoid error bound applies to the first moment
    g_table = 2 * np.pi * np.trapezoid(p * mu, mu)
    assert g_table == pytest.approx(t.g_mean, abs=2e-3)


@NEEDS_MIEPYTHON
@pytest.mark.parametrize("diameter_um", [2.0, 10.0])
def test_monodisperse_mie_table_equals_miepython(diameter_um):
    """sigma = 0 is one droplet size: at every node where the table evaluated Mie (both ends,
    the forward peak, one node per angular step beyond), its values are miepython's own
    unpolarised phase function (norm="one") to rounding; the stored float32 table is that
    divided by 1 + norm_error (``tabulate``), to float32 rounding."""
    miepython = mie.load_miepython()  # not imported at the top: that would skip its numba kernels
    t = mie.mie_table(diameter_um, 0.0)
    idx = np.flatnonzero(t.evaluated)
    assert idx[0] == 0 and idx[-1] == len(t.mu) - 1 and len(idx) > 500
    pick = idx[np.linspace(0, len(idx) - 1, 12).astype(int)]
    for k, lam in enumerate(t.wavelengths_um):
        want = miepython.i_unpolarized(mie.WATER_INDEX, math.pi * diameter_um / lam, t.mu[pick], norm="one")
        np.testing.assert_allclose(t.values[k, pick], want, rtol=1e-10)
    _, table = mie_struct(diameter_um, 0.0)
    np.testing.assert_allclose(table[pick], t.mean[pick] / (1 + t.norm_error[-1]), rtol=1e-6)


@NEEDS_MIEPYTHON
def test_mie_table_sampling_matches_pdf(device):
    """The binary-search sampler on a 262145-entry table: weight 1 and pdf = p, chi^2 p-value
    > 1e-3 with bin edges from the table's own nodes (exact CDF of the piecewise-linear pdf)."""
    t = mie.mie_table(20.0, 0.3)
    ph, table = mie_struct(20.0, 0.3)
    pvalue, cos_s, weight, pdf_ratio = sampling_chi2(device, ph, table, t.mu)
    np.testing.assert_allclose(weight, 1.0, rtol=1e-6)
    assert_pdf_is_p(pdf_ratio, cos_s, lambda c: np.interp(c, t.mu, table[:ph.n]))
    assert pvalue > 1e-3, f"chi2 p-value {pvalue:.2g}"
    assert abs(cos_s.mean() - t.g_mean) < 5 * cos_s.std() / math.sqrt(len(cos_s)) + 2e-3  # + table error, as above


@NEEDS_MIEPYTHON
def test_mie_and_hg_draine_agree_on_g_at_20um():
    """Mie (median 20 um, sigma = 0.1, mean of 650/550/450 nm) against the fit at d = 20 um.
    Tolerance 0.02, an estimate, not a measurement: the fit matches the shape of a spectrally
    averaged Mie phase function, not g; if its error in the cosine-weighted integral is ~2 %
    of g (our assumption: the paper gives no g error), g differs by up to 0.018; plus the
    size-quadrature noise of the Mie g (~1e-3, bench/mie_phase.py). Measured: 0.012."""
    t = mie.mie_table(20.0, 0.1)
    g_fit = mie.hg_draine_mean_cosine(FIT_20)
    assert abs(t.g_mean - g_fit) < 0.02, (t.g_mean, g_fit)
    # the per-wavelength spread the scalar table averages away is smaller than that
    assert max(t.g) - min(t.g) < 0.01, t.g


def scene_with(ph):
    return {"camera": {"origin": [0, 0, 5], "target": [0, 0, 0]},
            "media": [{"type": "homogeneous", "size": [1, 1, 1], "sigma_t": 1.0, "albedo": 0.9, "phase": ph}]}


@NEEDS_MIEPYTHON
def test_scene_mie_and_hg_draine():
    s = scene_from_dict(scene_with({"type": "mie", "median_diameter_um": 10, "sigma": 0.3}))
    ph = s.media[0].phase
    assert ph.type == "tabulated" and len(ph.values) == len(mie.mie_table(10.0, 0.3).mu)
    s = scene_from_dict(scene_with({"type": "hg_draine", "diameter_um": 20}))
    ph = s.media[0].phase
    assert (ph.g, ph.g_d, ph.alpha, ph.w_d) == (FIT_20.g_hg, FIT_20.g_d, FIT_20.alpha, FIT_20.w_d)
    s = scene_from_dict(scene_with({"type": "hg_draine", "g_hg": 0.9, "g_d": 0.5, "alpha": 10, "w_d": 0.4}))
    assert (s.media[0].phase.g, s.media[0].phase.w_d) == (0.9, 0.4)


@pytest.mark.parametrize("ph,key,allowed", [
    ({"type": "hg_draine", "diameter_um": 4}, "media[0].phase.diameter_um", "[5, 50]"),
    ({"type": "hg_draine", "diameter_um": 20, "alpha": 3}, "media[0].phase.alpha", "either diameter_um"),
    ({"type": "hg_draine", "g_hg": 0.9, "g_d": 0.5, "alpha": 10}, "media[0].phase.w_d", "missing"),
    ({"type": "hg_draine", "g_hg": 0.9, "g_d": 0.0, "alpha": 10, "w_d": 0.5}, "media[0].phase.g_d", "[0.001, 0.99]"),
    ({"type": "mie", "sigma": 0.3}, "media[0].phase.median_diameter_um", "missing"),
    ({"type": "mie", "median_diameter_um": 80, "sigma": 0.3}, "media[0].phase.median_diameter_um", "[0.1, 60]"),
    ({"type": "mie", "median_diameter_um": 10, "sigma": 0.9}, "media[0].phase.sigma", "[0, 0.5]"),
    ({"type": "mie", "median_diameter_um": 50, "sigma": 0.5}, "media[0].phase.sigma", "exp(2 sigma^2) <= 60"),
    ({"type": "mie", "median_diameter_um": 10, "sigma": 0.3, "g": 0.5}, "media[0].phase.g", "unknown key"),
])
def test_scene_rejects_bad_droplet_phases(ph, key, allowed):
    with pytest.raises(SceneError) as err:
        scene_from_dict(scene_with(ph))
    assert key in str(err.value) and allowed in str(err.value), str(err.value)


def test_a_mie_phase_without_miepython_names_the_extra(monkeypatch):
    """miepython is the [mie] extra: without it a Mie phase fails at load, before any kernel,
    with one line naming the key and the extra (its absence simulated: find_spec says none)."""
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "miepython" else real(name, *a))
    with pytest.raises(SceneError, match=r"media\[0\]\.phase\.type: \"mie\" needs miepython.*warpvol\[mie\]"):
        scene_from_dict(scene_with({"type": "mie", "median_diameter_um": 10, "sigma": 0.3}))
