"""Depth impostors (Umenhoffer & Szirmay-Kalos 2005): the impostor of a block against ray-sphere chords, blocks
found in a block-built cloud, objects in clouds (depth impostors against billboards), the
pipeline's caching, and the hard cases (one particle, all particles at one point, alpha -> 1,
a light inside the cloud and at a particle's centre, a surface through block centres,
S = 1, a camera inside the cloud)."""

import numpy as np
import pytest

import warpvol as wv
from warpvol.scene.procedural import split_blocks

SUN = {"type": "directional", "direction": [0.5, -0.8, -0.3], "irradiance": 2.0}


def block_scene(blocks=6, per_block=12, width=32, lights=(SUN,), surfaces=(), sigma_t=8.0, radius=0.08,
                origin=(0.0, 0.0, 4.0), positions=None, background=0.1):
    medium = {"type": "particles", "radius": radius, "sigma_t": sigma_t, "albedo": 0.9, "phase": {"type": "hg", "g": 0.3}}
    if positions is None:
        medium["generator"] = {"kind": "blocks", "blocks": blocks, "per_block": per_block, "seed": 3, "extent": 1.0,
                               "block_extent": 0.3}
    else:
        medium["positions"] = np.asarray(positions, float).tolist()
    return {"name": "di-test", "background": [background] * 3,
            "camera": {"origin": list(origin), "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40.0, "width": width,
                       "height": width},
            "lights": list(lights), "media": [medium], "surfaces": list(surfaces)}


def test_a_block_built_cloud_splits_into_its_template_and_instances():
    scene = wv.load_scene(block_scene(blocks=5, per_block=7))
    m = scene.media[0]
    assert m.block_size == 7 and len(m.positions) == 35
    template, centres = split_blocks(np.asarray(m.positions), 7)
    assert template.shape == (7, 3) and centres.shape == (5, 3)
    np.testing.assert_allclose(template.mean(0), 0.0, atol=1e-6)
    moved = np.asarray(m.positions).copy()
    moved[3] += 0.01  # one particle off its template: not a block-built cloud any more
    assert split_blocks(moved, 7) is None


def test_impostor_is_the_chord_sum_of_its_block(device):
    """Per texel: opacity 1 - exp(-sigma sum of chords), front = min entry, back = max exit
    (depths from the block's centre along the view), against numpy ray-sphere chords."""
    r = wv.Renderer(block_scene(blocks=1, per_block=9), "depth_impostors", device=device, impostor_res=12)
    r.render()
    a = r.arrays()
    t = r.technique
    pos = np.asarray(t.scene.media[0].positions, np.float64)
    offsets = pos - pos.mean(0)
    radius, sigma, T = 0.08, 8.0, 12
    R = np.sqrt((offsets**2).sum(1)).max() + radius
    cam = t.scene.camera
    fwd = np.asarray(cam.target, float) - cam.origin
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, cam.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    for j in range(T):
        for i in range(T):
            u, v = ((i + 0.5) / T * 2 - 1) * R, ((j + 0.5) / T * 2 - 1) * R
            o = u * right + v * up - R * fwd
            oc = offsets - o
            b = oc @ fwd
            h2 = radius**2 - ((oc * oc).sum(1) - b * b)
            hit = h2 > 0
            h = np.sqrt(np.where(hit, h2, 0))
            chords = np.where(hit, 2 * h, 0).sum()
            assert a["impostor_alpha"][j, i, 0] == pytest.approx(1 - np.exp(-sigma * chords), abs=2e-5)
            if hit.any():
                assert a["impostor_front"][j, i] == pytest.approx((b - h)[hit].min() - R, abs=1e-4)
                assert a["impostor_back"][j, i] == pytest.approx((b + h)[hit].max() - R, abs=1e-4)


def test_a_surface_inside_a_block_cuts_its_opacity(device):
    """A black plane just in front of the blocks' centres, facing the camera: what the cloud
    scatters toward the camera in front of it. Depth impostors keep the part of each block
    in front of the plane (between none and all of it); billboards (object_depth = 0) put
    each block wholly behind the plane, so nothing of the cloud shows."""
    def image(z, **settings):
        plane = {"type": "plane", "center": [0.0, 0.0, z], "normal": [0.0, 0.0, 1.0], "size": [20.0, 20.0], "diffuse": 0.0}
        scene = block_scene(blocks=1, per_block=20, background=0.0, surfaces=[plane])
        return wv.render(scene, "depth_impostors", device=device, light_pass=0, **settings).image.mean()

    full, none = image(-5.0), image(2.0)  # behind the cloud; between it and the camera (z = 4)
    z_cut = 0.0 + 0.01  # the single block's centre is at the origin (one instance)
    cut, billboard = image(z_cut), image(z_cut, object_depth=0)
    assert none == 0.0 and full > 0.0
    assert 0.1 * full < cut < 0.9 * full, (cut, full)
    assert billboard == 0.0


def test_pipeline_caches_what_does_not_change(device):
    """A moved camera re-makes impostors, shading and the gather, not the light pass; a moved
    light re-runs the light pass and shading, not the impostors; nothing moved: all cached."""
    r = wv.Renderer(block_scene(), "depth_impostors", device=device)
    r.render()
    status = lambda f: {k: v.status for k, v in f.stages.items()}  # noqa: E731
    s = status(r.render())
    assert all(s[k] == "cached" for k in ("blocks", "light", "impostors", "shade", "gather"))
    r.update(camera={"origin": [0.5, 0.2, 4.0], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40.0, "width": 32,
                     "height": 32})
    s = status(r.render())
    assert s["light"] == "cached" and s["blocks"] == "cached"
    assert s["impostors"] == s["shade"] == s["gather"] == "ran"
    r.update(lights=[{"type": "directional", "direction": [-0.3, -1.0, 0.2], "irradiance": 2.0}])
    s = status(r.render())
    assert s["impostors"] == "cached" and s["light"] == s["shade"] == s["gather"] == "ran"


HARD = {
    "one particle": dict(positions=[[0.0, 0.0, 0.0]]),
    "all particles at one point": dict(positions=[[0.1, 0.2, 0.0]] * 50),
    "alpha -> 1 (sigma_t r = 1e4)": dict(sigma_t=1.25e5),
    "a light inside the cloud": dict(lights=[{"type": "point", "position": [0.05, 0.0, 0.0], "intensity": 3.0}]),
    "a light at a particle's centre": dict(positions=[[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.15, 0.05]],
                                          lights=[{"type": "point", "position": [0.0, 0.0, 0.0], "intensity": 3.0}]),
    "a surface through the block centres": dict(blocks=3, surfaces=[{"type": "plane", "center": [0, 0, 0],
                                                                      "normal": [0, 0, 1], "size": [4.0, 4.0]}]),
    "a camera inside the cloud": dict(origin=(0.0, 0.0, 0.05)),
}


@pytest.mark.parametrize("case", list(HARD))
@pytest.mark.parametrize("slices", [1, 4])
def test_hard_cases_stay_finite(case, slices, device):
    image = wv.render(block_scene(**HARD[case]), "depth_impostors", device=device, slices=slices).image
    assert np.all(np.isfinite(image)) and np.all(image >= 0)
    assert image.max() > 0.0


def test_blocks_of_one_particle_render_as_particles(device):
    """per_block = 1 is the paper's "no blocks" row: the same image as the positions given
    as a plain cloud (each particle its own instance, its opacity the sphere's chord)."""
    scene = block_scene(blocks=40, per_block=1)
    plain = block_scene(positions=wv.load_scene(scene).media[0].positions)
    a = wv.render(scene, "depth_impostors", device=device).image
    b = wv.render(plain, "depth_impostors", device=device).image
    np.testing.assert_array_equal(a, b)


def test_morton_groups_partition_the_cloud_into_compact_blocks():
    from warpvol.techniques.depth_impostors.blocks import morton_groups

    pos = wv.load_scene("particle-cloud").media[0].positions
    groups = morton_groups(pos, 32)
    assert sorted(np.concatenate(groups).tolist()) == list(range(len(pos)))
    assert all(len(g) == 32 for g in groups[:-1])
    spread = np.mean([np.sqrt(((pos[g] - pos[g].mean(0)) ** 2).sum(1)).mean() for g in groups])
    whole = np.sqrt(((pos - pos.mean(0)) ** 2).sum(1)).mean()
    # a random group spreads like the whole cloud; a ball holding 1/32 of it, (1/32)^(1/3) = 0.31 of it
    assert spread < 0.6 * whole


def test_a_cloud_grouped_into_blocks_keeps_its_transmittance(device):
    """No lights, a white sky: the image is the cloud's transmittance. Each particle on its
    own, it is exact (chords along the pixel ray); grouped into blocks of 32 (cluster) it is
    the impostors' bilinear reconstruction, whose error shrinks with the texel size (the
    sky's light pass particle by particle in both, so only the impostors differ)."""
    pc = wv.load_scene("particle-cloud").media[0]
    scene = block_scene(positions=pc.positions, radius=pc.radius, sigma_t=4.0, lights=(), background=1.0, width=96,
                        origin=(0.0, 0.0, 6.0))
    exact = wv.render(scene, "depth_impostors", device=device).image.mean()
    err = [abs(wv.render(scene, "depth_impostors", device=device, cluster=32, impostor_res=t,
                         light_blocks=0).image.mean() - exact)
           for t in (8, 32)]
    assert err[1] < 0.7 * err[0] and err[1] < 0.012 * exact, (err, exact)


def test_moving_instances_keep_the_impostors(device):
    """An animated block-built cloud whose instances move but whose block does not: the
    impostors stay cached (the templates stage finds them unchanged), the rest re-runs,
    and the image equals a fresh render of the moved cloud."""
    import dataclasses

    scene = wv.load_scene(block_scene(blocks=6, per_block=12))
    m = scene.media[0]
    r = wv.Renderer(scene, "depth_impostors", device=device)
    r.render()
    shift = np.repeat(np.random.default_rng(1).normal(0.0, 0.1, (6, 3)), 12, axis=0).astype(np.float32)
    moved = dataclasses.replace(m, positions=np.asarray(m.positions) + shift)
    r.update(medium=moved)
    frame = r.render()
    status = {k: v.status for k, v in frame.stages.items()}
    assert status["blocks"] == status["templates"] == status["light"] == status["gather"] == "ran"
    assert status["impostors"] == "cached"
    fresh = wv.render(dataclasses.replace(scene, media=[moved]), "depth_impostors", device=device).image
    # the fresh render re-rounds the block's offsets in float32 (1e-7 of its size): nothing else differs
    np.testing.assert_allclose(frame.image, fresh, rtol=1e-4, atol=1e-6)
    r.update(medium=dataclasses.replace(m, radius=m.radius * 1.1))  # the block itself changed
    assert r.render().stages["impostors"].status == "ran"


def test_block_size_key_checks_the_positions():
    """Positions given with block_size must be copies of one block; otherwise the scene is
    refused with the key named."""
    pos = wv.load_scene(block_scene(blocks=3, per_block=4)).media[0].positions
    ok = block_scene(positions=pos)
    ok["media"][0]["block_size"] = 4
    assert wv.load_scene(ok).media[0].block_size == 4
    bad = block_scene(positions=np.asarray(pos) + np.random.default_rng(0).normal(0, 0.01, np.shape(pos)))
    bad["media"][0]["block_size"] = 4
    with pytest.raises(wv.SceneError, match="block_size"):
        wv.load_scene(bad)


def test_sky_light_of_a_thin_cloud_is_albedo_times_sky(device):
    """No lights, a grey sky L: an optically thin cloud (sigma_t r = 8e-4, so the sky's light
    reaches every point through optical depth < 0.01) scatters albedo L T toward the eye with
    T in [e^-0.01, 1], for a block's texels and for one-particle instances alike. The sky's
    7 directions (an odd count, so not symmetric) weight the phase function unevenly; only
    the division by sum p_k makes the result L (a plain 4 pi / K quadrature of HG g = 0.3
    is off by several per cent)."""
    L, albedo = 0.2, 0.9
    for settings in ({"cluster": 1}, {"cluster": 9}):
        scene = block_scene(blocks=1, per_block=9, lights=(), sigma_t=0.01, background=L,
                            positions=np.random.default_rng(1).uniform(-0.3, 0.3, (9, 3)))
        r = wv.Renderer(scene, "depth_impostors", multiple_scattering=0, device=device, sky_samples=7, **settings)
        r.render()
        t = r.technique
        if settings["cluster"] == 1:
            rad = t.particle_radiance.numpy()[: t.layout.n_instances, 0]
        else:
            alpha = t.impostors.alpha.numpy()[:, 0]
            rad = t.texel_radiance.numpy()[: len(alpha), 0][alpha > 0]
        assert len(rad) and np.all(rad <= albedo * L * (1 + 1e-5)) and np.all(rad >= albedo * L * np.exp(-0.01))


def test_sky_lights_an_open_diffuse_floor_to_albedo_times_sky(device):
    """A diffuse floor (albedo 0.5) under a grey sky L, the cloud a thin particle far to the
    side: every pixel sees the floor at pi (0.5 / pi) L = 0.5 L, whatever the sky's
    directions (sum cos_k T_k / sum cos_k with T = 1); and the floor, off the light pass's
    face, reads no shadow from it."""
    L = 0.2
    floor = {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": [40, 40], "diffuse": 0.5}
    scene = block_scene(lights=(), surfaces=(floor,), sigma_t=0.01, background=L, origin=(0.0, 3.0, 0.01),
                        positions=[[6.0, -0.5, 0.0]])
    for k in (5, 16):
        image = wv.Renderer(scene, "depth_impostors", device=device, sky_samples=k).render().image
        np.testing.assert_allclose(image, 0.5 * L, rtol=1e-4)


def test_widening_averages_the_light_with_an_unshadowed_ring(device):
    """Forward-scattering widening, isotropic phase: with a ring wider than the cloud every
    ring point sees the light unshadowed, so a texel's light becomes (T_0 + 6) / 7 of the
    unwidened T_0: radiance_w = (radiance_0 + 6 a E / (4 pi)) / 7, texel by texel."""
    scene = block_scene(blocks=1, per_block=9, sigma_t=20.0, background=0.0)
    scene["media"][0]["phase"] = {"type": "isotropic"}
    out = {}
    for widen in (0.0, 16.0):
        r = wv.Renderer(scene, "depth_impostors", multiple_scattering=0, device=device, widen=widen)
        r.render()
        alpha = r.technique.impostors.alpha.numpy()[:, 0]
        out[widen] = r.technique.texel_radiance.numpy()[: len(alpha)][alpha > 0]
    unshadowed = 0.9 * 2.0 / (4 * np.pi)
    assert out[0.0].min() < 0.5 * unshadowed  # the block shadows itself: the test sees the ring
    np.testing.assert_allclose(out[16.0], (out[0.0] + 6 * unshadowed) / 7, rtol=1e-4, atol=1e-7)


def test_the_block_light_pass_keeps_the_optical_volume_and_the_light(device):
    """The light pass made block by block (one light impostor per template, splatted per
    instance) against the same map made particle by particle. Closed form: the optical depth
    at the far slice, summed over an orthographic face's texels times a texel's area, is the
    cloud's optical volume sum sigma (4/3) pi r^3; both maps sample it at texel centres (a
    midpoint rule at a texel of about half a radius), so each is within 5% of it. And the
    light that reaches the particles (sphere-averaged transmittance at 4 points, every 7th
    particle): the block map's error against exact chord sums at most 1.5x the particle
    map's (both are discretised at the same texels; the block map adds a shift of at most
    half a texel, the order of its bilinear reading)."""
    import warp as wp

    scene = block_scene(blocks=30, per_block=40, width=32, sigma_t=6.0, radius=0.06, background=0.0)
    n = len(wv.load_scene(scene).media[0].positions)
    volume = n * 6.0 * (4.0 / 3.0) * np.pi * 0.06**3
    which = wp.array(np.arange(0, n, 7, dtype=np.int32), dtype=int, device=device)
    light = {}
    for key, settings in (("particles", {"light_blocks": 0}), ("blocks", {"light_blocks": 1}), ("exact", {"light_pass": 0})):
        r = wv.Renderer(scene, "depth_impostors", device=device, slices=8, **settings)
        r.render()
        t = r.technique
        assert (r.diagnostics()["light_template_texels"] > 0) == (key == "blocks")
        light[key] = t.light_pass.transmittance(t._cloud, t.uploads.lights, 4, which)
        if key != "exact":
            layers = t.light_pass.layers()
            area = (2.0 * float(layers["faces"][0]["half"]) / t.light_pass.M) ** 2
            held = float(layers["slices"][0, :, :, -1, 0].sum()) * area
            assert abs(held / volume - 1.0) < 0.05, (key, held, volume)
    err = {k: float(np.sqrt(np.sum((light[k] - light["exact"]) ** 2) / np.sum(light["exact"] ** 2)))
           for k in ("particles", "blocks")}
    assert err["blocks"] <= 1.5 * err["particles"], err


def test_impostor_resolution_follows_the_block_size(device):
    """impostor_res = 0: T = 3 R / r (a texel two thirds of a particle radius), and no finer
    than two pixels of the largest projected block, D / 2. Invariances: the scene scaled by 2
    (positions, radii and the camera, sigma_t halved so every optical depth stays) keeps T and
    the image (float rounding); the camera 4x as far makes the pixel bound decide, T following
    D / 2 of the numpy projection; a fixed impostor_res is kept whatever the view."""
    import dataclasses

    def scene_at(scale, distance):
        base = wv.load_scene(block_scene(blocks=4, per_block=20, width=160, radius=0.06, sigma_t=8.0))
        m = base.media[0]
        m = dataclasses.replace(m, positions=np.asarray(m.positions) * scale, radius=m.radius * scale,
                                sigma_t=tuple(np.asarray(m.sigma_t) / scale))
        cam = dataclasses.replace(base.camera, origin=(0.0, 0.0, 4.0 * scale * distance))
        return dataclasses.replace(base, media=[m], camera=cam, lights=list(base.lights))

    frames = {}
    for key, scale, distance in (("near", 1.0, 1.0), ("scaled", 2.0, 1.0), ("far", 1.0, 4.0)):
        r = wv.Renderer(scene_at(scale, distance), "depth_impostors", device=device)
        frames[key] = (r.render().image, r.diagnostics(), r.technique)
    d = frames["near"][1]
    m = frames["near"][2].scene.media[0]
    pos = np.asarray(m.positions, np.float64).reshape(4, 20, 3)
    reach = max(np.sqrt(((b - b.mean(0)) ** 2).sum(1)).max() for b in pos) + m.radius
    assert d["impostor_res"] == int(np.ceil(3.0 * reach / m.radius)), (d["impostor_res"], reach / m.radius)
    assert frames["scaled"][1]["impostor_res"] == d["impostor_res"]
    near, scaled = frames["near"][0], frames["scaled"][0]
    assert np.max(np.abs(scaled - near)) < 1e-4 * np.max(near)
    far = frames["far"][2]
    cam = far.scene.camera
    dist = np.linalg.norm(pos.mean(1) - np.asarray(cam.origin), axis=1)
    focal = 0.5 * cam.height / np.tan(np.radians(cam.fov_y) / 2)
    D = np.max(2.0 * reach / (dist - reach)) * focal
    assert frames["far"][1]["impostor_res"] == max(2, int(np.ceil(0.5 * D))) < d["impostor_res"], D
    r = wv.Renderer(scene_at(1.0, 4.0), "depth_impostors", device=device, impostor_res=12)
    r.render()
    assert r.diagnostics()["impostor_res"] == 12


def test_media_order_does_not_change_the_image(device):
    """A cloud of single particles and a block-built cloud in one scene, listed either way
    round: every instance's texels land where its gather reads them (the texel radiance is
    laid out per textured instance, whichever media come first), so the two images agree to
    float rounding."""
    blocks = wv.load_scene(block_scene(blocks=3, per_block=10, width=32)).media[0]
    loose = dict(block_scene(positions=np.random.default_rng(4).uniform(-0.6, 0.6, (12, 3)), width=32)["media"][0])
    scene = block_scene(blocks=3, per_block=10, width=32)
    block_medium = dict(scene["media"][0], positions=np.asarray(blocks.positions).tolist())
    block_medium.pop("generator")
    block_medium["block_size"] = 10
    images = []
    for media in ([loose, block_medium], [block_medium, loose]):
        r = wv.Renderer({**scene, "media": media}, "depth_impostors", device=device)
        images.append(r.render().image)
        assert r.diagnostics()["instances"] == 3 + 12
    assert np.max(np.abs(images[0] - images[1])) < 1e-5 * np.max(images[0])


def test_a_surface_in_the_cloud_is_named_as_not_shadowing_it(device):
    """The light pass holds the particles alone: with a surface and a light the frame says the
    surface's shadow on the cloud is left out, and without a surface it does not."""
    plane = {"type": "plane", "center": [0, 0, 0], "normal": [0, 0, 1], "size": [3, 3], "diffuse": 0.5}
    with_plane = wv.Renderer(block_scene(surfaces=[plane]), technique="depth_impostors", device=device)
    without = wv.Renderer(block_scene(), technique="depth_impostors", device=device)
    says = "the surfaces' shadows on the cloud"
    assert any(says in x for x in with_plane.technique.leaves_out())
    assert not any(says in x for x in without.technique.leaves_out())


def test_chord_shading_follows_a_thick_particles_light(device):
    """One thick particle (sigma_t r = 2) lit from the side, against the single-scattering
    reference: one radiance for the sphere (``particle_shading = "sphere"``, its irradiance
    averaged over its volume) cannot hold its lit side and its self-shadowed side, shading each
    pixel's chord (``"chord"``) at the depth its light comes from does. Measured 1.25 and 0.48,
    the reference's noise 0.05 (two seeds of 256 spp); chord is asked to be under half of sphere,
    a margin of 0.15 over the measured ratio, far above the noise."""
    t = {"name": "one-thick", "background": [0, 0, 0],
         "camera": {"origin": [0, 0, 3], "target": [0, 0, 0], "fov_y": 30, "width": 24, "height": 24},
         "lights": [{"type": "directional", "direction": [-1, 0, 0], "irradiance": 2.0}],
         "media": [{"type": "particles", "positions": [[0, 0, 0]], "radius": 0.5, "sigma_t": 4.0, "albedo": 0.9,
                    "phase": {"type": "isotropic"}}]}
    ref = [wv.render(t, technique="reference", device=device, spp=256, max_bounces=1, seed=s).image for s in (1, 2)]
    truth = 0.5 * (ref[0] + ref[1])
    assert wv.relative_rmse(ref[0], ref[1]) / 2 < 0.1
    err = {sh: wv.relative_rmse(wv.render(t, technique="depth_impostors", device=device, multiple_scattering=0,
                                          particle_shading=sh, light_pass="exact").image, truth)
           for sh in ("sphere", "chord")}
    assert err["chord"] < 0.5 * err["sphere"], err
