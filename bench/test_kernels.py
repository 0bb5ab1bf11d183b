"""pytest-benchmark suites for the hot kernels (not part of the CI test run):

    pytest bench/ --benchmark-only

Each benchmark times one frame after a warm-up frame (JIT compile excluded)."""

import pytest

import warpvol as wv


@pytest.mark.parametrize("scene", ["fog-box", "smoke-grid", "rbf-cornell", "particle-cloud", "cumulus-400"])
def test_reference_frame(benchmark, scene):
    """8 spp of every order of scattering; cumulus-400 is issue 14's 400-sphere cloud (80x60)."""
    from warpvol.bench.sweeps import cumulus_scene

    s = cumulus_scene() if scene == "cumulus-400" else wv.load_scene(scene)
    wv.render(s, technique="reference", spp=1)
    benchmark.pedantic(lambda: wv.render(s, technique="reference", spp=8), rounds=3, iterations=1)


@pytest.mark.parametrize("steps", [16, 64, 256])
def test_raymarch_frame(benchmark, steps):
    s = wv.load_scene("fog-box")
    wv.render(s, technique="raymarch", multiple_scattering=0, steps=steps)
    benchmark.pedantic(lambda: wv.render(s, technique="raymarch", multiple_scattering=0, steps=steps), rounds=5, iterations=1)


@pytest.mark.parametrize("particles,directions", [(512, 128), (1024, 128), (1024, 256)])
def test_illumination_network_iteration(benchmark, particles, directions):
    """One iteration of Szirmay-Kalos et al. 2005's update (S = I P, then the gather), the paper's cloud."""
    import warp as wp

    from warpvol.bench.sweeps import network_scene

    r = wv.Renderer(network_scene(False, particles, 64), technique="illumination_network", directions=directions,
                    iterations=0)
    r.render()
    t = r.technique

    def step():
        t.step(measure=False)
        wp.synchronize_device(t.device)

    benchmark.pedantic(step, rounds=20, iterations=1, warmup_rounds=2)


def test_illumination_network_build(benchmark):
    """The visibility network for 1024 particles, 128 directions, a 128 x 128 window."""
    from warpvol.bench.sweeps import network_scene

    r = wv.Renderer(network_scene(False, 1024, 64), technique="illumination_network", window=128, iterations=0)
    r.render()

    def build():
        r.touch("medium")
        r.render()

    benchmark.pedantic(build, rounds=5, iterations=1)


@pytest.mark.parametrize("stage,raster", [("shadow_maps", 1), ("shadow_maps", 0), ("visible", 1), ("visible", 0)])
def test_light_shafts_passes(benchmark, stage, raster):
    """Tóth & Umenhoffer 2009's shadow-map pass and visible-surface pass on colonnade-shafts (65 660 triangles,
    800x600, 256^2 cube map): rasterised (raster = 1) against BVH ray casts (raster = 0)."""
    from warpvol.bench.sweeps import shafts_scene

    r = wv.Renderer(shafts_scene(False), technique="light_shafts", multiple_scattering=0, raster=raster)
    r.render()

    def once():
        r.run_stage(stage)

    benchmark.pedantic(once, rounds=5, iterations=1, warmup_rounds=1)


@pytest.mark.parametrize("block", [1, 4])
def test_light_shafts_march(benchmark, block):
    """The march at N = 64 with and without M x M interleaving (the issue's 0.7 M^2 target)."""
    from warpvol.bench.sweeps import shafts_scene

    r = wv.Renderer(shafts_scene(False), technique="light_shafts", multiple_scattering=0, steps=64, block=block)
    r.render()

    def once():
        r.run_stage("march")

    benchmark.pedantic(once, rounds=3 if block == 1 else 10, iterations=1, warmup_rounds=1)
