"""The shared light pass (warpvol/media/lightpass.py) on its own, against exact chord sums
through the union of spheres computed here in numpy (float64): clouds with overlapping
spheres, a light inside the cloud, a light at a particle's centre, a flat cloud."""

import numpy as np
import pytest
import warp as wp

from warpvol.media.lightpass import LightPass
from warpvol.media.particles import ParticleBuffers
from warpvol.physics.lights import Emitter

RADIUS, SIGMA = 0.15, 3.0
RNG = np.random.default_rng(3)
CLOUD = RNG.uniform(-0.6, 0.6, (300, 3))  # 300 spheres of radius 0.15 in a 1.2 box: overlaps of 5 and more
FLAT = CLOUD * [1.0, 1.0, 0.0]  # every centre on the plane z = 0


def make_light(kind, position=(0.0, 0.0, 0.0), direction=(0.0, 0.0, -1.0)):
    s = Emitter()
    s.kind = {"point": 0, "directional": 2}[kind]
    s.position = wp.vec3(*position)
    s.direction = wp.vec3(*(np.asarray(direction, float) / np.linalg.norm(direction)))
    s.strength = wp.vec3(1.0)
    s.cos_inner = s.cos_outer = -1.0
    return s


CASES = {  # name: (centres, light kind, position or direction)
    "sun": (CLOUD, "directional", (0.3, -1.0, 0.2)),
    "point outside": (CLOUD, "point", (2.0, 1.0, 0.5)),
    "point inside the cloud": (CLOUD, "point", (0.05, 0.02, 0.0)),
    "point at a particle's centre": (CLOUD, "point", tuple(CLOUD[7])),
    "flat cloud, sun along the plane": (FLAT, "directional", (1.0, 0.2, 0.0)),
    "flat cloud, sun across it": (FLAT, "directional", (0.1, 0.2, -1.0)),
}


def setup(case, device):
    centres, kind, where = CASES[case]
    n = len(centres)
    cloud = ParticleBuffers(centres, np.full(n, RADIUS), np.full((n, 3), SIGMA), np.full((n, 3), 0.8), device)
    light = make_light(kind, position=where) if kind == "point" else make_light(kind, direction=where)
    return centres, cloud, wp.array([light], dtype=Emitter, device=device), kind, np.asarray(where, float)


def chord_sum(centres, x, w, t1):
    """Optical depth along x + t w (unit w), 0 <= t <= t1, through the union of the spheres."""
    oc = centres - x
    b = oc @ w
    h2 = RADIUS**2 - (np.sum(oc * oc, axis=1) - b * b)
    h = np.sqrt(np.maximum(h2, 0.0))
    chord = np.clip(np.minimum(b + h, t1) - np.maximum(b - h, 0.0), 0.0, None)
    return SIGMA * np.sum(np.where(h2 > 0, chord, 0.0))


def exact_depths(centres, kind, where, points):
    out = []
    for x in points:
        if kind == "directional":
            out.append(chord_sum(centres, x, -where / np.linalg.norm(where), np.inf))
        else:
            d = np.linalg.norm(where - x)
            out.append(chord_sum(centres, x, (where - x) / d, d) if d > 0 else 0.0)
    return np.asarray(out)


@pytest.mark.parametrize("case", list(CASES))
def test_exact_is_the_chord_sum(case, device):
    """representation "exact" (a BVH ray query per point) equals the chord sums, to float32."""
    centres, cloud, lights, kind, where = setup(case, device)
    lp = LightPass(device, "exact")
    lp.build(cloud, lights)
    pts = RNG.uniform(-0.7, 0.7, (64, 3))
    pts[0] = centres[7]  # a particle's centre (the light's own position in one case)
    got = lp.optical_depth(cloud, lights, 0, pts)
    want = exact_depths(centres, kind, where, pts)
    np.testing.assert_allclose(got[:, 0], want, rtol=1e-4, atol=1e-4)
    assert np.all(got[:, 0] == got[:, 2])


@pytest.mark.parametrize("case", ["sun", "point outside", "point inside the cloud"])
def test_slices_are_exact_at_the_slice_depths(case, device):
    """At a texel's centre ray and a slice's depth the map holds the exact optical depth
    (each sphere adds its chord's exact share to each slice interval; the prefix sum is the
    depth): a read there has bilinear weight 1 on that texel and no interpolation in depth."""
    centres, cloud, lights, kind, where = setup(case, device)
    S, M = 8, 32  # a sphere spans > 2 texels, so it is splatted by chords (not as a sub-texel mass)
    lp = LightPass(device, "slices", slices=S, texels=M)
    lp.build(cloud, lights)
    faces = lp.map.faces.numpy()
    pts = []
    for f in faces:
        for i, j in [(6, 10), (16, 16), (24, 4), (14, 18)]:
            u, v = (i + 0.5) * 2 / M - 1, (j + 0.5) * 2 / M - 1
            for k in (2, 5, 8):
                t = f["near"] + k * (f["far"] - f["near"]) / S
                if f["ortho"]:
                    x = f["origin"] + f["half"] * (u * f["right"] + v * f["up"]) + t * f["forward"]
                else:
                    d = f["forward"] + f["half"] * (u * f["right"] + v * f["up"])
                    x = f["origin"] + t * d / np.linalg.norm(d)
                pts.append(x)  # inside the face's frustum (|u|, |v| < 1): read from this face
    pts = np.asarray(pts)
    got = lp.optical_depth(cloud, lights, 0, pts)[:, 0]
    want = exact_depths(centres, kind, where, pts)
    assert len(pts) >= 12 and np.max(want) > 5.0  # the rays cross the thick of the cloud
    # float32 texel-centre arithmetic moves a read by ~1e-6 of a texel: well under 1e-3 of tau
    np.testing.assert_allclose(got, want, rtol=2e-3, atol=2e-3)


def test_fourier_total_depth_is_exact_and_midway_converges(device):
    """A Fourier opacity map holds the total optical depth exactly (tau(1) = a_0 / 2), and
    between, its error along a ray falls as K grows (the series of a step's integral
    converges as 1 / K^2 away from the step)."""
    centres, cloud, lights, kind, where = setup("sun", device)
    M = 16
    errs = []
    for K in (4, 16, 64):
        lp = LightPass(device, "fourier", terms=K, texels=M)
        lp.build(cloud, lights)
        f = lp.map.faces.numpy()[0]
        u = v = (8 + 0.5) * 2 / M - 1
        base = f["origin"] + f["half"] * (u * f["right"] + v * f["up"])
        ts = np.linspace(0.0, 1.0, 41) * (f["far"] - f["near"])
        pts = base + ts[:, None] * f["forward"]
        got = lp.optical_depth(cloud, lights, 0, pts)[:, 0]
        want = exact_depths(centres, kind, where, pts)
        assert got[-1] == pytest.approx(want[-1], rel=1e-4)
        errs.append(np.sqrt(np.mean((got - want) ** 2)) / want[-1])
    assert errs[1] < 0.5 * errs[0] and errs[2] < 0.5 * errs[1], errs


@pytest.mark.parametrize("case", list(CASES))
def test_map_error_falls_with_slices_and_texels(case, device):
    """The sphere-averaged transmittance from the map against the exact chord sums at the same
    16 points of every sphere (``LightPass.check``): the error is discretisation (slice
    width, texel size), so refining both halves it at least once in two steps, and at
    S = M = 128 (a texel r / 20 across at most) it is under 3%."""
    centres, cloud, lights, kind, where = setup(case, device)
    errs = []
    for S, M in [(16, 32), (64, 64), (128, 128)]:
        lp = LightPass(device, "slices", slices=S, texels=M, check_particles=len(centres))
        lp.build(cloud, lights)
        errs.append(lp.check(cloud, lights, 16))
    assert errs[2] < 0.5 * errs[0] and errs[2] <= errs[1] * 1.05, errs
    assert errs[2] < 0.03, errs


def test_falls_back_to_exact_above_the_tolerance(device):
    """A tolerance below the map's measured error switches the map off: the direct light is
    then the exact one, bit for bit."""
    centres, cloud, lights, kind, where = setup("sun", device)
    n = len(centres)
    out = {}
    for name, lp in [("exact", LightPass(device, "exact")),
                     ("fallback", LightPass(device, "slices", slices=4, texels=8, tolerance=1e-6))]:
        lp.build(cloud, lights, samples=4)
        direct = wp.zeros(n, dtype=wp.vec3, device=device)
        travel = wp.zeros(n, dtype=wp.vec3, device=device)
        lp.direct(cloud, lights, 4, direct, travel)
        out[name] = direct.numpy()
        if name == "fallback":
            assert lp.fell_back and lp.error > 1e-6
    np.testing.assert_array_equal(out["exact"], out["fallback"])


def test_light_at_a_particle_centre_stays_finite(device):
    """A point light at a particle's centre: that particle's light arrives from every side
    (travel 0, no shadowing term), everyone else's is finite and at most the unshadowed."""
    centres, cloud, lights, kind, where = setup("point at a particle's centre", device)
    n = len(centres)
    for rep in ("exact", "slices", "fourier"):
        for samples in (1, 16):
            lp = LightPass(device, rep)
            lp.build(cloud, lights, samples)
            direct = wp.zeros(n, dtype=wp.vec3, device=device)
            travel = wp.zeros(n, dtype=wp.vec3, device=device)
            lp.direct(cloud, lights, samples, direct, travel)
            d, w = direct.numpy(), travel.numpy()
            assert np.all(np.isfinite(d)) and np.all(d >= 0)
            assert np.all(w[7] == 0) and d[7, 0] == pytest.approx(3.0 / RADIUS**2, rel=1e-5)  # ball mean of 1/d^2


def test_a_map_above_its_tolerance_is_refined_before_it_falls_back(device):
    """A coarse map (4 slices, 8 texels) whose error is above a tolerance the finer maps meet
    is refined (texels and slices doubled) until the check passes, not replaced by exact; its
    error falls with each refinement (the map converges to the chord sums: slices exact at
    their depths, texels at their centres). A tolerance no map within REFINE_ROUNDS meets
    still ends at exact."""
    from warpvol.media.lightpass import REFINE_ROUNDS

    centres, cloud, lights, kind, where = setup("sun", device)
    coarse = LightPass(device, "slices", slices=4, texels=8, check_particles=len(centres))
    coarse.build(cloud, lights, samples=4)
    e0 = coarse.check(cloud, lights, 4)
    lp = LightPass(device, "slices", slices=4, texels=8, tolerance=0.6 * e0, check_particles=len(centres))
    lp.build(cloud, lights, samples=4)
    assert lp.refined and not lp.fell_back and lp.error <= 0.6 * e0 and lp.M > 8 and lp.map.C > 5
    errors = [e for _, _, e in lp.refined] + [lp.error]
    assert all(b < a for a, b in zip(errors, errors[1:])), errors
    strict = LightPass(device, "slices", slices=4, texels=8, tolerance=1e-9, check_particles=len(centres))
    strict.build(cloud, lights, samples=4)
    assert strict.fell_back and len(strict.refined) == REFINE_ROUNDS
