"""pytest-benchmark: the pipeline's own cost per frame, and the raymarch frame with and without
a baked light volume (``pytest bench/ --benchmark-only``; not part of the CI test run)."""

import pytest

import warpvol as wv


def test_pipeline_bookkeeping_all_cached(benchmark):
    """Every stage cached: the frame is nothing but stage-list, cache-key and Frame work."""
    r = wv.Renderer(wv.load_scene("smoke-grid", ["camera.width=4", "camera.height=3"]), technique="raymarch", multiple_scattering=0,
                    device="cpu", steps=4, shadow_grid=2, shadow_steps=2)
    r.render()
    benchmark(r.render)


@pytest.mark.parametrize("shadow_grid", [0, 16, 64])
def test_raymarch_smoke_grid(benchmark, shadow_grid):
    r = wv.Renderer("smoke-grid", technique="raymarch", multiple_scattering=0, device="cpu", steps=64, shadow_grid=shadow_grid)
    r.render()

    def frame():
        r.touch()
        r.render()

    benchmark.pedantic(frame, rounds=3, iterations=1)
