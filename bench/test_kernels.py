"""pytest-benchmark suites for the hot kernels (not part of the CI test run):

    pytest bench/ --benchmark-only

Each benchmark times one frame after a warm-up frame (JIT compile excluded)."""

import pytest

import warpvol as wv


@pytest.mark.parametrize("scene", ["fog-box", "smoke-grid", "particle-cloud"])
def test_reference_frame(benchmark, scene):
    s = wv.load_scene(scene)
    wv.render(s, technique="reference", spp=1)
    benchmark.pedantic(lambda: wv.render(s, technique="reference", spp=8), rounds=3, iterations=1)


@pytest.mark.parametrize("steps", [16, 64, 256])
def test_raymarch_frame(benchmark, steps):
    s = wv.load_scene("fog-box")
    wv.render(s, technique="raymarch", steps=steps)
    benchmark.pedantic(lambda: wv.render(s, technique="raymarch", steps=steps), rounds=5, iterations=1)
