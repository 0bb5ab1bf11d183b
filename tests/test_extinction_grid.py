"""What a march pays per Gaussian: RBF optical depth toward the lights in closed form, and the
extinction baked into a grid (warpvol.upload.extinction_cells)."""

import numpy as np
import pytest

import warpvol as wv
from warpvol.scene import scene_from_dict
from warpvol.upload import BAKE_CELL, BAKE_OVERLAP, extinction_cells, gaussians_in_reach


def fog(count, radius, width=16, height=12, seed=3):
    """``count`` Gaussians of one radius in a Cornell box, one point light among them."""
    centers = np.random.default_rng(seed).uniform(-0.7, 0.7, (count, 3)).tolist()
    return {"name": "rbf-fog", "camera": {"origin": [0, 0, 3.9], "target": [0, 0, 0], "width": width, "height": height},
            "lights": [{"type": "point", "position": [0.1, 0.5, 0.2], "intensity": 2.0}],
            "media": [{"type": "rbf", "centers": centers, "radius": radius, "peak": 1.5, "albedo": 0.9}],
            "surfaces": [{"type": "procedural", "name": "cornell_box", "diffuse": 0.7}]}


def march(scene, device, **settings):
    return wv.Renderer(scene, technique="raymarch", device=device, multiple_scattering=0, sky_samples=0, **settings)


def test_shadow_rays_take_the_closed_form(device):
    """Toward a light an RBF medium's optical depth is the erf chord sum, whatever shadow_steps:
    one shadow step gives the image 256 give (to float rounding), where a midpoint march of a
    Gaussian 0.15 wide would be off by tens of percent at one step."""
    scene = fog(12, 0.15)
    one = march(scene, device, extinction_grid=0, shadow_steps=1).render().image
    many = march(scene, device, extinction_grid=0, shadow_steps=256).render().image
    np.testing.assert_allclose(one, many, rtol=1e-4, atol=1e-6 * many.max())


def test_the_choice_follows_the_grid_it_needs(device):
    """A medium whose grid of cells a quarter of its smallest radius is small (at most 64 a side)
    is baked at that grid, a few Gaussians as many (even one costs a march more than the grid's
    8 samples); a larger one only where many Gaussians overlap (a lookup sums them all), a cell
    half the radius; small Gaussians spread thin are summed where they are (their grid would be
    hundreds of cells a side). The choice is in diagnostics() and a setting overrides it."""
    few, many, sparse = (scene_from_dict(fog(n, r)) for n, r in ((4, 0.15), (400, 0.1), (4, 0.02)))

    def extent(scene, radius):  # the centres' spread and the cut-off on both sides
        return np.ptp(np.asarray(scene.media[0].centers), axis=0).max() + 2 * 5 * radius

    assert extinction_cells(few.media[0], -1) == pytest.approx(extent(few, 0.15) / (BAKE_CELL * 0.15), abs=2)
    assert extinction_cells(few.media[0], -1) <= 64
    assert extent(many, 0.1) / (BAKE_CELL * 0.1) > 64 and gaussians_in_reach(many.media[0]) > BAKE_OVERLAP
    assert extinction_cells(many.media[0], -1) == pytest.approx(extent(many, 0.1) / 0.05, abs=2)
    assert gaussians_in_reach(sparse.media[0]) <= BAKE_OVERLAP and extinction_cells(sparse.media[0], -1) == 0
    cells = extinction_cells(many.media[0], -1)
    r = march(fog(400, 0.1, 8, 6), device)
    r.render()
    assert r.diagnostics()["extinction_grid"] == [cells]
    r = march(fog(400, 0.1, 8, 6), device, extinction_grid=0)
    r.render()
    assert r.diagnostics()["extinction_grid"] == [0]


def test_the_baked_grid_converges_to_the_gaussians_at_second_order(device):
    """Trilinear interpolation of a smooth density errs as (cell / radius)^2: against the exact
    sum (extinction_grid = 0, same march), doubling the cells cuts the error at least 2.5x
    (4x in the limit; measured 3.7x and 4.2x). At 48 cells (a cell 0.4 radii) it was 2.6%;
    the bound, 3.5%, is that figure with a third to spare for the march's own rounding."""
    scene = fog(60, 0.15)
    exact = march(scene, device, extinction_grid=0, steps=64).render().image
    err = {n: wv.relative_rmse(march(scene, device, extinction_grid=n, steps=64).render().image, exact)
           for n in (12, 24, 48)}
    assert err[24] <= err[12] / 2.5 and err[48] <= err[24] / 2.5, err
    assert err[48] < 0.035, err


def test_target_error_measures_the_grid_as_a_bias(device):
    """target_error counts the baked grid's bias (its limit: the exact sum) beside the ladder's."""
    scene = fog(400, 0.1, 8, 6)
    frame = wv.render(scene, technique="raymarch", device=device, multiple_scattering=0, sky_samples=0,
                      target_error=0.2)
    assert "extinction_grid" in frame.bias_estimates
