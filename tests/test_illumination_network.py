"""Illumination networks (papers/000): the visibility network, the iteration's fixed points in
closed form, the splat of one particle, and the hard cases (albedo 1, a light at a particle's
centre, particles on a plane, D = 1, float16)."""

import numpy as np
import pytest

import warpvol as wv
from warpvol.physics.sphere import fibonacci_directions
from warpvol.techniques.illumination_network import window_rule

SKY = [0.3, 0.4, 0.6]


def cloud(n=200, seed=4, radius=0.15, sigma_t=3.0, albedo=0.8, phase=None, lights=(), width=32, height=24,
          positions=None):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-0.6, 0.6, size=(n, 3)) if positions is None else np.asarray(positions, float)
    return {
        "name": "test-cloud", "background": SKY,
        "camera": {"origin": [0.0, 0.0, 3.0], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40.0,
                   "width": width, "height": height},
        "lights": list(lights),
        "media": [{"type": "particles", "positions": pos.tolist(), "radius": radius, "sigma_t": sigma_t,
                   "albedo": albedo, "phase": phase or {"type": "isotropic"}}],
    }


SUN = {"type": "directional", "direction": [-0.3, -1.0, -0.2], "irradiance": 3.0}


def converged(scene, device, **settings):
    s = {"iterations": 5000, "tolerance": 1e-6, **settings}
    r = wv.Renderer(scene, "illumination_network", device=device, **s)
    frame = r.render()
    return r, frame


def basis(n):
    """Duff et al. 2017, as warpvol.physics.phase.orthonormal_basis."""
    sign = 1.0 if n[2] >= 0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    return (np.array([1 + sign * n[0] ** 2 * a, sign * b, -sign * n[0]]), np.array([b, sign + n[1] ** 2 * a, -n[1]]))


def test_visibility_network_chains_each_pixel_front_to_back(device):
    """V equals a numpy depth peeling: per direction and pixel, each particle sees the one just
    upstream; alpha is 1 - exp(-tau_vp distance along w_i) with tau from the sphere overlaps."""
    D, M = 16, 8
    scene = cloud()
    r = wv.Renderer(scene, "illumination_network", device=device, directions=D, window=M, iterations=0)
    r.render()
    a = r.arrays()
    pos = np.asarray(scene["media"][0]["positions"])
    n = len(pos)
    centre = 0.5 * (pos.min(0) + pos.max(0))
    R = np.sqrt(((pos - centre) ** 2).sum(1)).max() + 0.15
    assert a["bounds"][1] == pytest.approx(R, rel=1e-6)
    overlap = (((pos[:, None] - pos[None]) ** 2).sum(-1) <= 0.15**2).sum(1)
    tau = 3.0 * overlap
    dirs = fibonacci_directions(D).astype(np.float64)
    want_v = np.full((n, D), -1)
    want_alpha = np.zeros((n, D))
    for i, w in enumerate(dirs):
        e1, e2 = basis(w)
        x = pos - centre
        u = np.clip(np.floor((x @ e1 + R) * M / (2 * R)), 0, M - 1)
        v = np.clip(np.floor((x @ e2 + R) * M / (2 * R)), 0, M - 1)
        depth = x @ w
        for cell in np.unique(v * M + u):
            members = np.flatnonzero(v * M + u == cell)
            members = members[np.argsort(depth[members])]
            for up, p in zip(members[:-1], members[1:]):
                want_v[p, i] = up
                want_alpha[up, i] = 1 - np.exp(-tau[up] * (depth[p] - depth[up]))
    np.testing.assert_array_equal(a["visibility"], want_v)
    np.testing.assert_allclose(a["alpha"][..., 1], want_alpha, atol=2e-5)


def test_window_follows_the_paper_rule():
    # D (R tau)^2 / pi >= M^2: R tau = 10, D = 128 -> M = floor(sqrt(128 * 100 / pi)) = 63
    assert window_rule(128, 1.0, 10.0) == 63
    assert window_rule(1, 0.01, 0.01) == 1


@pytest.mark.parametrize("phase,norm", [({"type": "isotropic"}, 0), ({"type": "hg", "g": 0.7}, 1),
                                        ({"type": "cornette_shanks", "g": 0.5}, 1)])
def test_white_furnace(device, phase, norm):
    """Albedo 1 under a uniform sky and no lights: radiance is the sky everywhere, so the
    network converges to it and the cloud vanishes into the background. Exact when the phase
    weights of each direction sum to 1 (isotropic with 4 pi / D, or ``phase_norm``): the only
    error left is the iteration's float32 rounding."""
    r, frame = converged(cloud(albedo=1.0, phase=phase), device, phase_norm=norm)
    I = r.arrays()["radiance"]
    assert r.technique.converged
    np.testing.assert_allclose(I, np.broadcast_to(SKY, I.shape), rtol=2e-4)
    np.testing.assert_allclose(frame.image, np.broadcast_to(SKY, frame.image.shape), rtol=2e-4)


def test_absorbing_cloud_attenuates_the_sky_along_each_chain(device):
    """Albedo 0: I[p, i] = sky x prod (1 - alpha) over the particles upstream in the chain,
    exact once the iterations outnumber the longest chain (200 particles)."""
    r, _ = converged(cloud(albedo=0.0), device, directions=32, window=6, iterations=200, tolerance=0.0)
    a = r.arrays()
    V, alpha, I = a["visibility"], a["alpha"], a["radiance"]
    want = np.zeros_like(I)
    for p in range(V.shape[0]):
        for i in range(V.shape[1]):
            t, q = np.ones(3), V[p, i]
            while q >= 0:
                t *= 1 - alpha[q, i]
                q = V[q, i]
            want[p, i] = t * SKY
    np.testing.assert_allclose(I, want, rtol=1e-4, atol=1e-6)


def test_one_particle_in_closed_form(device):
    """One sphere under a sun and a sky: it sees only sky, so its radiance toward the eye is
    a (p E P(sigma r) + sky), P the sphere's escape probability (the sun's mean transmittance
    over the sphere, with light_samples = 1), the sky's isotropic in-scatter summing to sky;
    the pixel through its centre is (1 - e^(-2 sigma r)) L + e^(-2 sigma r) sky."""
    sig, rad, alb = 2.0, 0.3, 0.7
    scene = cloud(positions=[[0.0, 0.0, 0.0]], radius=rad, sigma_t=sig, albedo=alb, lights=[SUN], width=33,
                  height=33)
    r, frame = converged(scene, device, directions=64, light_samples=1)
    tau = sig * rad
    escape = 3 / (8 * tau**3) * (2 * tau**2 - 1 + (1 + 2 * tau) * np.exp(-2 * tau))
    L = alb * (3.0 / (4 * np.pi) * escape + np.asarray(SKY))
    np.testing.assert_allclose(r.arrays()["outgoing"][0], L, rtol=1e-5)
    t = np.exp(-2 * sig * rad)
    np.testing.assert_allclose(frame.image[16, 16], (1 - t) * L + t * np.asarray(SKY), rtol=1e-5)
    np.testing.assert_allclose(frame.image[0, 0], SKY, rtol=1e-6)  # outside the sphere's disc
    # the escape probability is the mean over the sphere of the sun's transmittance: sampled
    r4, _ = converged(scene, device, directions=64, light_samples=512)
    np.testing.assert_allclose(r4.technique.direct.numpy()[0], 3.0 * escape, rtol=0.01)


@pytest.mark.parametrize("albedo", [0.99, 1.0])
def test_high_albedo_converges_without_blow_up(device, albedo):
    """Sun and sky at albedo 0.99 and 1: the iteration settles, the change per iteration
    falls monotonically once the light has crossed the cloud, and every radiance is finite
    and non-negative."""
    r, frame = converged(cloud(n=300, albedo=albedo, phase={"type": "hg", "g": 0.5}, lights=[SUN]), device,
                         tolerance=1e-6, phase_norm=1)
    t = r.technique
    assert t.converged
    h = np.asarray(t.history)
    assert np.all(np.isfinite(h)) and h[-1] < 1e-6
    tail = h[len(h) // 2:]
    assert np.all(np.diff(tail) <= 1e-12 + 1e-3 * tail[:-1])
    I = r.arrays()["radiance"]
    assert np.all(np.isfinite(I)) and I.min() >= 0.0
    assert np.all(np.isfinite(frame.image))


def test_light_at_a_particle_centre_is_bounded(device):
    """A point light exactly at a particle's centre: the irradiance averaged over the sphere is
    3 I / r^2 (not I / 0), every value is finite, and the solution stays linear in the light:
    L(10) - L(1) = 9 (L(1) - L(0)) to the iteration's tolerance."""
    pos = np.random.default_rng(2).uniform(-0.5, 0.5, size=(60, 3))
    out = []
    for k in (0.0, 1.0, 10.0):
        lights = [{"type": "point", "position": pos[7].tolist(), "intensity": k}] if k else []
        r, frame = converged(cloud(positions=pos, lights=lights), device, directions=32)
        assert np.all(np.isfinite(frame.image)) and np.all(np.isfinite(r.arrays()["radiance"]))
        out.append(r.arrays()["outgoing"].astype(np.float64))
    np.testing.assert_allclose(r.technique.direct.numpy()[7], 10.0 * 3.0 / 0.15**2, rtol=1e-5)
    np.testing.assert_allclose(out[2] - out[1], 9.0 * (out[1] - out[0]), rtol=1e-3, atol=1e-4 * out[2].max())


def test_particles_on_a_plane(device):
    """All particles at z = 0: a degenerate (flat) cloud still gives finite radiance, and the
    white furnace still holds."""
    rng = np.random.default_rng(5)
    pos = np.c_[rng.uniform(-0.6, 0.6, (150, 2)), np.zeros(150)]
    r, frame = converged(cloud(positions=pos, albedo=1.0), device)
    np.testing.assert_allclose(r.arrays()["radiance"], np.broadcast_to(SKY, r.arrays()["radiance"].shape), rtol=2e-4)
    r, frame = converged(cloud(positions=pos, lights=[SUN]), device)
    assert np.all(np.isfinite(frame.image))


def test_one_direction(device):
    """D = 1: a single direction, each particle's phase weight 4 pi p(1) (paper) or 1
    (normalised); the furnace holds with the normalised weight."""
    r, frame = converged(cloud(albedo=1.0, phase={"type": "hg", "g": 0.4}, lights=[]), device, directions=1,
                         phase_norm=1)
    np.testing.assert_allclose(r.arrays()["radiance"], np.broadcast_to(SKY, (200, 1, 3)), rtol=2e-4)
    r, frame = converged(cloud(lights=[SUN]), device, directions=1)
    assert np.all(np.isfinite(frame.image))


def test_float16_storage_matches_float32_without_overflow(device):
    """A light of intensity 1e6 at a particle's centre (sources far above float16's 65504):
    the power-of-two scale keeps the stored values small, so the float16 solution equals the
    float32 one to float16's precision (2^-11 relative per rounding, a few hundred roundings
    along the longest chains: 2%)."""
    pos = np.random.default_rng(3).uniform(-0.5, 0.5, size=(120, 3))
    lights = [{"type": "point", "position": pos[3].tolist(), "intensity": 1.0e6}]
    scene = cloud(positions=pos, lights=lights, albedo=0.9)
    r32, _ = converged(scene, device, half=0, directions=32, tolerance=1e-5)
    r16, f16 = converged(scene, device, half=1, directions=32, tolerance=1e-3)
    assert r16.technique.I.dtype.__name__ == "float16"
    assert np.all(np.isfinite(f16.image)) and np.all(np.isfinite(r16.arrays()["radiance"]))
    stored = r16.technique.I.numpy().astype(np.float32)
    assert np.abs(stored).max() < 100.0
    a, b = r16.arrays()["outgoing"], r32.arrays()["outgoing"]
    assert np.abs(a - b).max() <= 0.02 * np.abs(b).max()


def test_stages_follow_what_changed(device):
    """Network once for a static cloud; a moved light re-runs direct, emission and iterate
    (warm-started: it settles in fewer iterations than from zero); a moved camera only splats."""
    scene = cloud(n=150, lights=[SUN])
    r = wv.Renderer(scene, "illumination_network", device=device, iterations=1000, tolerance=1e-5)
    first = r.render().stages
    assert first["network"].status == "ran" and r.technique.converged
    cold = len(r.technique.history)
    again = r.render().stages
    assert all(again[s].status == "cached" for s in ("network", "direct", "emission", "iterate", "splat"))
    moved = dict(SUN, direction=[-0.25, -1.0, -0.2])
    r.update(lights=[moved])
    st = r.render().stages
    assert st["network"].status == "cached"
    assert all(st[s].status == "ran" for s in ("direct", "emission", "iterate", "splat"))
    warm = len(r.technique.history) - cold
    assert warm < cold
    cam = dict(scene["camera"], origin=[0.2, 0.1, 3.0])
    r.update(camera=cam)
    st = r.render().stages
    assert st["splat"].status == "ran" and st["iterate"].status == "cached" and st["direct"].status == "cached"


def test_one_iteration_per_frame_runs_until_settled(device):
    """iterations = 1 (the paper): the iterate stage runs every frame until the change falls
    below the tolerance, then stays cached."""
    r = wv.Renderer(cloud(n=80, lights=[SUN]), "illumination_network", device=device, iterations=1,
                    tolerance=1e-3)
    runs = [r.render().stages["iterate"].status for _ in range(60)]
    assert runs[:5] == ["ran"] * 5
    assert runs[-1] == "cached" and r.technique.converged


def test_rejects_scenes_it_cannot_render():
    with pytest.raises(wv.SettingsError, match="particle media only"):
        wv.Renderer("fog-box", "illumination_network", device="cpu")


def test_refreshing_k_directions_a_frame_catches_up_with_a_full_rebuild(device):
    """refresh = k re-peels k directions per medium change, round robin: after the cloud moves
    once and stays, D / k more changes leave V and alpha equal to a full rebuild's."""
    import dataclasses

    D, k = 16, 4
    scene = wv.load_scene(cloud(n=120))
    jitter = np.random.default_rng(9).uniform(-0.05, 0.05, scene.media[0].positions.shape).astype(np.float32)
    moved = dataclasses.replace(scene.media[0], positions=scene.media[0].positions + jitter)
    lag = wv.Renderer(scene, "illumination_network", device=device, directions=D, window=8, refresh=k,
                      iterations=0)
    lag.render()
    lag.update(medium=moved)
    lag.render()
    full = wv.Renderer(wv.load_scene(cloud(n=120)), "illumination_network", device=device, directions=D, window=8,
                       iterations=0)
    full.update(medium=moved)
    full.render()
    a, b = lag.arrays(), full.arrays()
    stale = np.any(a["visibility"] != b["visibility"], axis=0)
    assert stale.sum() == D - k  # only the first k directions are current
    for _ in range(D // k - 1):
        lag.update(medium=moved)
        lag.render()
    a = lag.arrays()
    np.testing.assert_array_equal(a["visibility"], b["visibility"])
    np.testing.assert_allclose(a["alpha"], b["alpha"], rtol=1e-6)
