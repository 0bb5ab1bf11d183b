"""Illumination networks (Szirmay-Kalos et al. 2005): the visibility network, the iteration's fixed points in
closed form, the splat of one particle, and the hard cases (albedo 1, a light at a particle's
centre, particles on a plane, D = 1, float16)."""

import numpy as np
import pytest

import warpvol as wv
from warpvol.physics.sphere import fibonacci_directions
from warpvol.techniques.illumination_network.weights import doubly_stochastic
from warpvol.techniques.illumination_network.window import window_rule

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
                                        ({"type": "cornette_shanks", "g": 0.5}, 1),
                                        ({"type": "hg", "g": 0.9999}, 1), ({"type": "hg", "g": -0.999}, 1),
                                        ({"type": "cornette_shanks", "g": 0.9999}, 1)])
def test_white_furnace(device, phase, norm):
    """Albedo 1 under a uniform sky and no lights: radiance is the sky everywhere, so the
    network converges to it and the cloud vanishes into the background. Exact when the phase
    weights of each direction sum to 1 (isotropic with 4 pi / D, or ``phase_norm``, whose
    doubly stochastic matrix sums to 1 to 1e-9 in float64, 1e-7 once float32) for any lobe,
    |g| -> 1 included: the only error left is the iteration's float32 rounding. A backward
    lobe at albedo 1 bounces light between neighbours, the iteration's spectral radius near
    1 and its error about change / (1 - radius): it settles to 1e-8 there (measured: 1e-6
    leaves 0.9% in I, 1e-8 leaves 9e-5)."""
    tolerance = 1e-8 if phase.get("g", 0.0) < -0.99 else 1e-6
    r, frame = converged(cloud(albedo=1.0, phase=phase), device, phase_norm=norm, tolerance=tolerance)
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


def test_rejects_scenes_it_cannot_render(device):
    with pytest.raises(wv.SettingsError, match="particle media only"):
        wv.Renderer("fog-box", "illumination_network", device=device)


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


def phase_matrix(r):
    """The technique's D x D phase matrix (the weights the iteration applies), float64."""
    t = r.technique
    return t.phase_weights.numpy().reshape(t.Dp, t.Dp).astype(np.float64)[: t.D, : t.D]


def hg(g, c):
    c = np.clip(c, -1.0, 1.0)
    return (1 - g * g) / (4 * np.pi * (1 + g * g - 2 * g * c) ** 1.5)


def test_doubly_stochastic_scaling():
    """Rows and columns of diag(x) P diag(x) sum to 1, it stays symmetric, a constant matrix
    becomes 1 / D, and an HG lobe far narrower than the directions' spacing becomes the
    identity (light passes straight on)."""
    dirs = fibonacci_directions(64).astype(np.float64)
    c = dirs @ dirs.T
    for g in (0.0, 0.6, 0.9999, -0.9999):
        B = doubly_stochastic(hg(g, c))
        np.testing.assert_allclose(B.sum(0), 1.0, atol=1e-8)
        np.testing.assert_allclose(B.sum(1), 1.0, atol=1e-8)
        np.testing.assert_allclose(B, B.T, atol=1e-15)
    np.testing.assert_allclose(doubly_stochastic(np.full((5, 5), 0.3)), 0.2, rtol=1e-12)
    np.testing.assert_allclose(doubly_stochastic(hg(0.9999, c)), np.eye(64), atol=1e-6)


def chain_solve(V, a, z):
    """u = z + T u, (T u)[p, i] = (1 - a[p, i]) u[V[p, i], i]: transmission along the chains
    (acyclic, so at most N + 1 sweeps reach the fixed point)."""
    up = V >= 0
    cols = np.broadcast_to(np.arange(V.shape[1]), V.shape)
    u = z.copy()
    for _ in range(V.shape[0] + 1):
        nxt = z.copy()
        nxt[up] += (1 - a[up]) * u[V[up], cols[up]]
        if np.array_equal(nxt, u):
            break
        u = nxt
    return u


@pytest.mark.parametrize("g", [0.9, 0.95, 0.99, 0.999, 0.9999, -0.999])
def test_iteration_gain_is_at_most_the_albedo_for_peaked_lobes(device, g):
    """The default (``phase_norm = 1``) phase matrix of an HG lobe of any width has rows and
    columns summing to 1 (to float32 rounding, D terms of relative error 6e-8: 1e-5 is
    ample), so the scattering gain is at most the albedo. Checked two ways on a small cloud
    (sources zero):

    * the iteration's own map M (``step`` with no lights and a black sky), by power iteration
      from a random positive I: each step's max-norm gain is at most
      max over links of 1 - alpha (1 - a) <= 1 (transmission plus scattering; float32
      rounding of a few terms: 1e-5);
    * its gain per scattering event K = (1 - T)^-1 a alpha P (numpy, from V, alpha and P):
      each power step's max-norm gain is at most the albedo (the transmission chain sum of
      alpha (1 - alpha)... is <= 1), so its spectral radius is too (float64, the matrix's
      float32 sums: 1e-5).

    The paper's weights 4 pi / D p fail the bound for all these g (row sums up to
    (1 + g) / (D (1 - g)^2) on the diagonal alone)."""
    al, D = 0.8, 32
    scene = cloud(n=100, albedo=al, phase={"type": "hg", "g": g})
    scene["background"] = [0.0, 0.0, 0.0]
    r = wv.Renderer(scene, "illumination_network", device=device, directions=D, iterations=0)
    r.render()
    P = phase_matrix(r)
    assert P.sum(0).max() <= 1 + 1e-5 and P.sum(1).max() <= 1 + 1e-5
    assert P.sum(0).min() >= 1 - 1e-5 and P.sum(1).min() >= 1 - 1e-5  # conserving, not just bounded
    paper = wv.Renderer(scene, "illumination_network", device=device, directions=D, iterations=0, phase_norm=0)
    paper.render()
    assert phase_matrix(paper).sum(1).max() > 1.0

    a = r.arrays()
    V, alpha = a["visibility"], a["alpha"][..., 0]
    up = V >= 0
    cols = np.broadcast_to(np.arange(D), V.shape)
    link = np.zeros(V.shape)
    link[up] = alpha[V[up], cols[up]]  # opacity of the segment upstream of p along i
    # the iteration's own map, run by the kernels
    rng = np.random.default_rng(1)
    x = rng.uniform(0.5, 1.0, (100, D, 3)).astype(np.float32)
    r.technique.set_radiance_network(x)
    bound = (1 - link * (1 - al)).max()
    norms = [np.abs(x).max()]
    for _ in range(40):
        r.technique.step(measure=False)
        norms.append(np.abs(r.technique.radiance_network()).max())
    gains = np.asarray(norms[1:]) / np.asarray(norms[:-1])
    assert np.all(np.isfinite(gains)) and gains.max() <= bound + 1e-5, (gains.max(), bound)
    # the gain per scattering event, in numpy
    u = rng.uniform(0.5, 1.0, (100, D))
    for _ in range(30):
        s = u @ P
        z = np.zeros_like(u)
        z[up] = link[up] * al * s[V[up], cols[up]]
        nxt = chain_solve(V, link, z)
        gain = np.abs(nxt).max() / np.abs(u).max()
        assert gain <= al + 1e-5, gain
        u = nxt / np.abs(nxt).max()


def test_peaked_lobe_render_stays_within_a_physical_bound(device):
    """HG g = 0.98 under a sun and a sky, 300 iterations (settled to 1e-6 well before): every
    value is finite and within the bound of the maximum principle. If I <= B everywhere, an
    update gives (1 - alpha) B + E + alpha a B (the columns of P sum to <= 1), which is <= B
    when E <= alpha (1 - a) B; E <= alpha a c p E_sun with c p <= D / (4 pi) (one term of a
    sum normalised to D / (4 pi)), so B = sky + a / (1 - a) D / (4 pi) E_sun holds from I = 0
    on. A particle's radiance toward the eye is a (its normalised average of I + p(w_sun .
    w_eye) E_sun) and a pixel a mix of those and the sky, hence the image bound. Float32
    rounding of these sums: 1e-5 relative. The paper's weights break the same bound."""
    al, g, D, E_sun = 0.8, 0.98, 32, 3.0
    scene = cloud(albedo=al, phase={"type": "hg", "g": g}, lights=[SUN])
    r = wv.Renderer(scene, "illumination_network", device=device, directions=D, iterations=300, tolerance=1e-6)
    frame = r.render()
    assert r.technique.converged
    I, image = r.arrays()["radiance"], frame.image
    assert np.all(np.isfinite(I)) and np.all(np.isfinite(image)) and I.min() >= 0.0
    B = max(SKY) + al / (1 - al) * D / (4 * np.pi) * E_sun
    assert I.max() <= B * (1 + 1e-5)
    pos = np.asarray(scene["media"][0]["positions"])
    eye = np.asarray(scene["camera"]["origin"], float)
    w_eye = (eye - pos) / np.linalg.norm(eye - pos, axis=1, keepdims=True)
    sun = np.asarray(SUN["direction"], float) / np.linalg.norm(SUN["direction"])
    L_max = al * (I.max() + hg(g, w_eye @ sun).max() * E_sun)
    assert image.max() <= max(max(SKY), L_max) * (1 + 1e-5)
    paper = wv.Renderer(scene, "illumination_network", device=device, directions=D, iterations=300, tolerance=1e-6,
                        phase_norm=0)
    with np.errstate(invalid="ignore"):  # its change measure divides inf by inf
        paper.render()
    Ip = paper.arrays()["radiance"]
    assert not (np.all(np.isfinite(Ip)) and Ip.max() <= B * (1 + 1e-5))


def test_peaked_lobe_emission_carries_the_scattered_energy(device):
    """With ``phase_norm`` (default) light l's emission is E[vp, i] = alpha a c p(w_l . w_i)
    E_l T_l with c = D / (4 pi sum_i p(w_l . w_i)): the D directions carry exactly what the
    segment scatters, (4 pi / D) sum_i c p_i = 1, for a lobe narrower than the directions'
    spacing too (HG g = 0.999 at D = 32: the paper's weights give 4 pi / D sum_i p_i far
    from 1). Tolerance: float32 evaluation of the lobe (a few ulp of a denominator >= 0.05
    here) and of the sums: 1e-4."""
    D, g, al = 32, 0.999, 0.8
    scene = cloud(n=60, albedo=al, phase={"type": "hg", "g": g}, lights=[SUN])
    r = wv.Renderer(scene, "illumination_network", device=device, directions=D, iterations=0)
    r.render()
    t = r.technique
    dirs = t.dirs.numpy().astype(np.float64)
    sun = np.asarray(SUN["direction"], float) / np.linalg.norm(SUN["direction"])
    p = hg(g, dirs @ sun)
    c = D / (4 * np.pi * p.sum())
    assert abs(4 * np.pi / D * p.sum() - 1) > 0.5  # the unnormalised weights lose or make energy
    E = t.E.numpy()[: 3 * 60, :D].astype(np.float64).reshape(60, 3, D)
    alpha = r.arrays()["alpha"].astype(np.float64)  # (N, D, 3)
    direct = t.direct.numpy().astype(np.float64)  # (N, 3): one light
    want = np.einsum("ndc,nc,d->ncd", alpha, al * direct, c * p)
    np.testing.assert_allclose(E, want, rtol=1e-4, atol=1e-7 * want.max())
    np.testing.assert_allclose(t.light_weight.numpy(), c, rtol=1e-4)


def test_a_one_shot_render_is_finished(device, monkeypatch):
    """``warpvol.render`` iterates to the tolerance (1e-4): against a solution converged to
    1e-6, the image differs by at most the remaining change summed as a geometric series,
    tolerance x a / (1 - a) with the contraction a = albedo 0.8 (4e-4), doubled for the
    image's norm against I's; a Renderer's first frame (the paper's one iteration) is far
    off. A cap that stops it short warns."""
    scene = cloud(lights=[SUN])
    _, fine = converged(scene, device)
    one_shot = wv.render(scene, "illumination_network", device=device)
    assert wv.relative_rmse(one_shot.image, fine.image) < 2 * 1e-4 * 0.8 / 0.2
    first = wv.Renderer(scene, "illumination_network", device=device).render()
    assert wv.relative_rmse(first.image, fine.image) > 0.05
    import warpvol.techniques.illumination_network as net
    monkeypatch.setattr(net, "ONE_SHOT_CAP", 2)
    with pytest.warns(RuntimeWarning, match="not converged after 2 iterations"):
        wv.render(scene, "illumination_network", device=device)


@pytest.mark.parametrize("n,spread,per_column", [(120, 0.6, 3.0), (600, 0.6, 4.0), (2000, 0.3, 8.0), (2000, 1.2, 2.0)])
def test_window_from_particles_per_column(device, n, spread, per_column):
    """``column = K``: M is the largest window (up to the paper's rule) whose occupied columns
    hold K particles or more on average along the measured directions. Checked on the network
    the kernels build: along a direction each occupied column has one particle that sees the
    sky (V = -1), so N / that count is its mean column; at M the mean is at least K, at M + 1
    (where the paper's rule allows it) below K. Clouds of several densities; scaling a cloud
    (positions and radius) leaves M as it is."""
    D, WINDOW_AT, SIGMA = 24, 4096, 20.0  # the paper's rule taken at 4096 directions: a cap above the column rule's M
    rng = np.random.default_rng(n)
    pos = rng.uniform(-spread, spread, size=(n, 3))

    def window(scale, M=0):
        s = cloud(positions=pos * scale, radius=0.05 * scale, sigma_t=SIGMA / scale)
        r = wv.Renderer(s, "illumination_network", device=device, directions=D, column=per_column, window=M,
                        window_at=WINDOW_AT, iterations=0)
        r.render()
        heads = (r.arrays()["visibility"] < 0).sum(0)  # per direction: the occupied columns
        return r.diagnostics()["window"], float(np.mean(n / heads[:: D // 3][:3]))

    M, mean = window(1.0)
    assert mean >= per_column
    centre = 0.5 * (pos.min(0) + pos.max(0))
    R = np.sqrt(((pos - centre) ** 2).sum(1)).max() + 0.05
    tau = SIGMA * n * 0.05**3 / R**3
    cap = window_rule(WINDOW_AT, R, tau)
    assert M <= cap
    if M < cap:
        assert window(1.0, M + 1)[1] < per_column
    assert window(7.0)[0] == M
