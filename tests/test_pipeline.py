"""The pipeline runs only what the scene calls for and what a change invalidated.

The rule is Giroud & Biri 2011 Table 1, asserted through ``frame.stages`` on the raymarch technique
with a baked light volume: ``medium`` is its density stage (the grid is injected into
device memory), ``light_volume`` its propagation stage (transmittance from each light,
reads the medium and the lights), ``march`` the per-frame image.
"""

import numpy as np
import pytest

import warpvol as wv
from warpvol.pipeline import Pipeline, Stage, Technique
from warpvol.scene.procedural import smoke_grid
from warpvol.techniques import TECHNIQUES

SMALL = dict(shadow_grid=8, shadow_steps=8, steps=16)


def smoke(static_medium=True, static_lights=True, surfaces=True, lights=True):
    d = smoke_grid()
    d["camera"].update(width=24, height=18)
    d["media"][0]["static"] = static_medium
    for light in d["lights"]:
        light["static"] = static_lights
    if not surfaces:
        d["surfaces"] = []
    if not lights:
        d["lights"] = []
    return d


def statuses(frame, names=("medium", "light_volume", "march")):
    return tuple(frame.stages[n].status for n in names)


@pytest.mark.parametrize("static_medium, static_lights, expected", [
    # Table 1: nothing static -> injection and propagation every frame
    (False, False, ("ran", "ran", "ran")),
    # static medium -> injection precomputed, propagation per frame
    (True, False, ("cached", "ran", "ran")),
    # static medium and lighting -> both precomputed (and with a still camera the march too)
    (True, True, ("cached", "cached", "cached")),
])
def test_table1_rule(device, static_medium, static_lights, expected):
    r = wv.Renderer(smoke(static_medium, static_lights), technique="raymarch", device=device, **SMALL)
    first = r.render()
    assert statuses(first) == ("ran", "ran", "ran")  # frame 1 computes everything
    for _ in range(2):  # from frame 2 on
        assert statuses(r.render()) == expected


def test_moving_a_light_reruns_what_depends_on_lights_only(device):
    r = wv.Renderer(smoke(), technique="raymarch", device=device, **SMALL)
    r.render()
    moved = dict(smoke()["lights"][0], direction=[0.5, -1.0, -0.3])
    r.update(lights=[moved])
    frame = r.render()
    assert {n: s.status for n, s in frame.stages.items()} == {
        "medium": "cached", "surfaces": "cached", "lights": "ran", "light_volume": "ran", "multiple": "ran",
        "multiple_view": "ran", "march": "ran"}
    # the cached stages hold what a fresh render of the changed scene computes
    fresh = wv.render(smoke() | {"lights": [moved]}, technique="raymarch", device=device, **SMALL)
    np.testing.assert_array_equal(frame.image, fresh.image)
    assert not np.array_equal(frame.image, wv.render(smoke(), technique="raymarch", device=device, **SMALL).image)


def test_camera_and_settings_rerun_only_their_readers(device):
    r = wv.Renderer(smoke(), technique="raymarch", device=device, **SMALL)
    before = r.render().image
    r.update(camera=dict(smoke()["camera"], origin=[0.5, 0.2, 4.2]))
    assert statuses(r.render()) == ("cached", "cached", "ran")
    r.update(settings={"steps": 8})  # read by the march only
    assert statuses(r.render()) == ("cached", "cached", "ran")
    r.update(settings={"shadow_grid": 6})  # read by the light volume
    assert statuses(r.render()) == ("cached", "ran", "ran")
    r.update(camera=smoke()["camera"], settings=SMALL)
    np.testing.assert_array_equal(r.render().image, before)


@pytest.mark.parametrize("scene, settings, skipped", [
    (smoke(surfaces=False), SMALL, {"surfaces"}),  # no occluders: no BVH
    (smoke(lights=False), dict(SMALL, sky_samples=0), {"light_volume"}),  # nothing to propagate (no lights, no sky)
    (smoke(), dict(SMALL, shadow_grid=0), {"light_volume"}),  # marched shadow rays asked for
    ("point-in-fog", SMALL, {"light_volume", "surfaces"}),  # homogeneous: transmittance is exact; no walls
])
def test_stages_the_scene_does_not_call_for_are_skipped(device, scene, settings, skipped):
    frame = wv.render(scene, technique="raymarch", device=device, **settings)
    assert {n for n, s in frame.stages.items() if s.status == "skipped"} == skipped
    assert all(s.status == "ran" for n, s in frame.stages.items() if n not in skipped)


def test_timings_are_the_seconds_view_of_stages(device):
    frame = wv.render(smoke(), technique="raymarch", device=device, **SMALL)
    assert frame.timings == {n: s.ms / 1000.0 for n, s in frame.stages.items()}
    assert all(s.ms > 0.0 for s in frame.stages.values())


def test_update_validates_like_the_loader(device):
    r = wv.Renderer(smoke(), technique="raymarch", device=device, **SMALL)
    with pytest.raises(wv.SceneError, match=r"lights\[0\]\.intensity.*allowed"):
        r.update(lights=[{"type": "point", "position": [0, 0, 0], "intensity": -1.0}])
    with pytest.raises(wv.SettingsError, match=r"shadow_grid=1 .*allowed: 0 or 2\.\.512"):
        r.update(settings={"shadow_grid": 1})


class _Counting(Technique):
    """Pure-Python stages that count their runs: the scheduling rule without kernels."""

    NAME = "counting"
    SETTINGS = {}

    def __init__(self, scene, stages):
        super().__init__(scene, "cpu", {"k": 1})
        self._stages = stages
        self.count = {}

    def stages(self):
        return [Stage(name, lambda n=name: self.count.__setitem__(n, self.count.get(n, 0) + 1), **kw)
                for name, kw in self._stages]

    def output(self):
        return np.zeros((1, 3), np.float32)


def test_a_rerun_propagates_downstream_and_nowhere_else():
    graph = [("a", dict(reads=("medium",))), ("b", dict(reads=("lights",))),
             ("c", dict(after=("a",))), ("d", dict(after=("b", "c"), settings=("k",)))]
    t = _Counting(wv.load_scene("fog-box"), graph)
    p = Pipeline(t)
    p.run()
    p.changed("medium")
    runs = p.run()
    assert {n: r.status for n, r in runs.items()} == {"a": "ran", "b": "cached", "c": "ran", "d": "ran"}
    p.changed("lights")
    runs = p.run()
    assert {n: r.status for n, r in runs.items()} == {"a": "cached", "b": "ran", "c": "cached", "d": "ran"}
    t.settings = {"k": 2}
    assert {n: r.status for n, r in p.run().items()} == {"a": "cached", "b": "cached", "c": "cached", "d": "ran"}
    assert t.count == {"a": 2, "b": 2, "c": 2, "d": 4}


def test_a_stage_declaring_unknown_inputs_is_an_error():
    t = _Counting(wv.load_scene("fog-box"), [("a", dict(after=("later",))), ("later", {})])
    with pytest.raises(ValueError, match=r"stage 'a' declares unknown inputs \['later'\]"):
        Pipeline(t).run()
    t = _Counting(wv.load_scene("fog-box"), [("a", dict(reads=("weather",)))])
    with pytest.raises(ValueError, match=r"unknown inputs \['weather'\]"):
        Pipeline(t).run()


def test_a_frame_says_what_its_technique_leaves_out(device):
    """The sky (a non-black background) is a light: raymarch gathers it unless sky_samples = 0,
    light_shafts does not; without the multiple-scattering lattice (which then carries it) they
    leave it out and say so; single-scattering models name multiple scattering,
    and with the multiple-scattering lattice (the default) say it is approximated; the reference names the orders beyond max_bounces, and nothing at -1."""
    scene = {"name": "sky", "background": [0.2, 0.3, 0.5],
             "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "fov_y": 40.0, "width": 4, "height": 3},
             "lights": [{"type": "directional", "direction": [0, -1, 0], "irradiance": 1.0}],
             "media": [{"type": "homogeneous", "shape": "sphere", "radius": 1.0, "sigma_t": 0.5, "albedo": 0.9}]}
    sky = "the sky's light (the background) scattered in the media or reflected by surfaces"
    assert wv.render(scene, "raymarch", device=device, multiple_scattering=0).leaves_out == ["multiple scattering"]
    approximated = wv.render(scene, "raymarch", device=device).leaves_out  # the lattice's term, by default
    assert len(approximated) == 1 and approximated[0].startswith("approximated, not left out: multiple scattering")
    assert sky in wv.render(scene, "raymarch", device=device, sky_samples=0, multiple_scattering=0).leaves_out
    assert sky in wv.render(scene, "light_shafts", device=device, multiple_scattering=0).leaves_out
    for technique, settings in (("raymarch", {"sky_samples": 0}), ("light_shafts", {})):  # the lattice carries it
        assert sky not in wv.render(scene, technique, device=device, **settings).leaves_out
    assert wv.render(scene, "reference", device=device, spp=1).leaves_out == []
    assert wv.render(scene, "reference", device=device, spp=1, max_bounces=1).leaves_out == [
        "light scattered more than 1 time (max_bounces = 1)"]
    scene["background"] = [0.0, 0.0, 0.0]
    assert wv.render(scene, "light_shafts", device=device, multiple_scattering=0).leaves_out == ["multiple scattering"]


def test_a_camera_table_changes_only_its_keys(device):
    """``update(camera=dict(origin=...))`` moves the camera and keeps its size and field of view;
    the image equals a fresh render of the moved camera."""
    scene = smoke()
    scene["camera"].update(fov_y=30.0)
    r = wv.Renderer(scene, technique="raymarch", device=device, **SMALL)
    r.render()
    r.update(camera=dict(origin=[1.0, 0.2, 4.0]))
    frame = r.render()
    assert frame.image.shape == (18, 24, 3)
    assert r.scene.camera.fov_y == 30.0 and r.scene.camera.origin == (1.0, 0.2, 4.0)
    moved = {**scene, "camera": {**scene["camera"], "origin": [1.0, 0.2, 4.0]}}
    np.testing.assert_array_equal(frame.image, wv.render(moved, technique="raymarch", device=device, **SMALL).image)


#: Each technique's own examples (``Technique.EXAMPLES``).
AUDITED = {name: cls.EXAMPLES for name, cls in TECHNIQUES.items()}


def _audited(technique: str, name: str):
    """A Renderer of ``technique`` on built-in ``name`` (16x12) after two frames under audit, the
    second with every scene part changed, so that every stage the scene calls for ran twice."""
    scene = wv.load_scene(name, ["camera.width=16", "camera.height=12"])
    r = wv.Renderer(scene, technique=technique, device="cpu", **({"spp": 2} if technique == "reference" else {}))
    r._pipeline.audit = True
    r.render()
    r.update(camera=dict(origin=[0.1, 0.3, 4.0]))
    r.touch()
    r.render()
    return r


@pytest.mark.parametrize("technique", list(AUDITED))
def test_every_stage_declares_the_settings_it_reads(technique):
    """Run each technique's stages with its settings wrapped (``Pipeline.audit``): a setting a
    stage reads but does not declare is one its cache key misses, so changing it would serve a
    stale image. Small built-in scenes that between them call every stage."""
    for name in AUDITED[technique]:
        r = _audited(technique, name)
        assert r._pipeline.undeclared == {}, f"{technique} on {name}"


#: Attributes two stages may both assign, and why: the network's ping-pong radiance buffers are
#: allocated (sized) by ``network`` and swapped each iteration by ``iterate``, whose state they are.
SHARED_STATE = {"illumination_network": {"I", "I_next"}}


@pytest.mark.parametrize("technique", list(AUDITED))
def test_each_stage_writes_only_its_own_outputs(technique):
    """Under audit the pipeline notes which technique attributes each stage assigns: an output two
    stages assign is one that a stage re-running could overwrite behind the other's cache."""
    for name in AUDITED[technique]:
        r = _audited(technique, name)
        assert set(r._pipeline.written), f"{technique} on {name}: the audit saw no stage assign anything"
        shared = {k: v for k, v in r._pipeline.shared_writes.items() if k not in SHARED_STATE.get(technique, ())}
        assert shared == {}, f"{technique} on {name}: attributes assigned by more than one stage"


@pytest.mark.parametrize("technique", ["raymarch", "particle_glow", "light_shafts", "rbf_propagation"])
def test_a_march_fills_the_cores_when_its_pixels_are_few(monkeypatch, technique):
    """A march's launch is split over the CPU cores by its work, pixels times steps, not by its
    pixels alone: 24 x 18 pixels of 128 steps are more work than device.MIN_SPLIT simple threads,
    so the march stage runs in chunks on both cores (at 160x120 it once ran on one). light_shafts
    without interleaving (block 1): with M x M blocks a pixel takes 1 / M^2 of the samples."""
    from warpvol import device as dev

    monkeypatch.setenv("WARPVOL_THREADS", "2")
    split = []
    real = dev._run_chunks
    monkeypatch.setattr(dev, "_run_chunks", lambda kernel, *a: (split.append(kernel.key), real(kernel, *a))[1])
    scene = wv.load_scene("dusty-lamp", ["camera.width=24", "camera.height=18"])
    assert 24 * 18 < dev.MIN_SPLIT <= 24 * 18 * 128
    extra = {"block": 1} if technique == "light_shafts" else {}
    r = wv.Renderer(scene, technique=technique, device="cpu", steps=128, multiple_scattering=0, **extra)
    r.render()
    split.clear()
    r.run_stage("march")
    assert split, f"{technique}: the march ran on one core"


def test_a_large_private_copy_is_not_kept():
    """A core's private copy of a launch's output is kept between launches up to SCRATCH_KEEP bytes
    (a small map re-used), and made afresh above it (a big map is not held for the process's life)."""
    import warp as wp

    from warpvol import device as dev

    small = wp.full(1000, 2.0, dtype=float, device="cpu")
    big = wp.full(dev.SCRATCH_KEEP // 4 + 1, 3.0, dtype=float, device="cpu")
    a = dev._scratch(small, 1)
    b = dev._scratch(big, 1)
    assert np.all(a.numpy() == 2.0) and np.all(b.numpy() == 3.0)
    assert (str(small.device), small.dtype, 1) in dev._scratch_pool  # the small one kept
    assert all(v.capacity <= dev.SCRATCH_KEEP for v in dev._scratch_pool.values())  # the big one not


def test_the_scratch_pool_goes_with_the_last_renderer(monkeypatch):
    """The per-core copies a CPU launch combines into (``device.launch_private``) are kept between
    launches while a Renderer lives, and freed when the last one is collected."""
    import gc

    from warpvol import device as dev

    monkeypatch.setattr(dev, "threads", lambda: 2)  # two cores, so that the light pass makes copies
    gc.collect()
    scene = wv.load_scene("particle-cloud", ["camera.width=16", "camera.height=12"])
    a = wv.Renderer(scene, technique="depth_impostors", device="cpu")
    b = wv.Renderer(scene, technique="depth_impostors", device="cpu")
    a.render()
    assert dev.scratch_bytes() > 0
    del a
    gc.collect()
    assert dev.scratch_bytes() > 0  # b may still use it
    del b
    gc.collect()
    assert dev.scratch_bytes() == 0
