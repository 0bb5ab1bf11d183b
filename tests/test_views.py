"""pyvista views: off-screen pictures of every built-in scene show something, and the
array-to-mesh functions keep the arrays' values and layout."""

from pathlib import Path

import numpy as np
import pytest

pv = pytest.importorskip("pyvista", reason="pyvista is the [viz] extra")

from warpvol import viz
import warpvol as wv
from warpvol.scene.procedural import BUILTIN


def not_blank(img: np.ndarray) -> float:
    """Fraction of pixels that differ from the most common colour (the background)."""
    flat = img.reshape(-1, img.shape[-1])[:, :3]
    colours, counts = np.unique(flat, axis=0, return_counts=True)
    return 1.0 - counts.max() / len(flat)


@pytest.mark.parametrize("name", list(BUILTIN))
def test_view_screenshot_of_each_builtin_scene(device, name, tmp_path):
    out = tmp_path / f"{name}.png"
    from warpvol.cli import main

    assert main(["view", name, "--screenshot", str(out)]) == 0
    png = pv.read(str(out))
    w, h, _ = png.dimensions
    img = np.asarray(png.point_data.active_scalars).reshape(h, w, -1)
    assert w > 100 and h > 100
    # the frustum, the media and the surfaces cover far more than 2% of the picture
    assert not_blank(img) > 0.02
    # the scene's name in the top-left corner (VTK's rows run bottom-up), in ink that shows on the
    # background: white on a dark one, black on a bright one
    corner = img[-32:, :160, :3].astype(int)
    bright = sum(wv.load_scene(name).background) > 1.5
    ink = np.all(corner <= 5, axis=-1) if bright else np.all(corner >= 250, axis=-1)
    assert ink.sum() >= 10


def test_volume_grid_keeps_the_extinction_layout(device):
    scene = wv.load_scene("smoke-grid")
    grid_medium = scene.media[0]
    d, h, w = grid_medium.density.shape
    # sampled at the grid's own cell centres, the extinction volume is the density times the scale
    sigma, lo, hi = wv.extinction_volume(scene, resolution=w, device=device)
    assert sigma.shape == (d, h, w, 3)
    np.testing.assert_allclose(sigma[..., 0], grid_medium.density * grid_medium.sigma_t_scale[0], rtol=1e-5, atol=1e-6)
    mesh = viz.volume_grid(sigma, lo, hi)
    assert mesh.n_cells == d * h * w
    # cell (x=3, y=5, z=7) holds sample [7, 5, 3]
    cell = mesh.find_closest_cell(np.asarray(lo) + (np.array([3, 5, 7]) + 0.5) * (np.subtract(hi, lo) / (w, h, d)))
    assert mesh.cell_data["sigma_t"][cell] == pytest.approx(sigma[7, 5, 3].mean(), rel=1e-6)


def test_per_light_volumes_and_lattices_are_separate_fields():
    tau = np.random.default_rng(1).random((3, 4, 5, 6)).astype(np.float32)  # 3 lights
    grid = viz.volume_grid(tau, (0, 0, 0), (1, 1, 1), name="tau")
    assert [f"tau[{i}]" in grid.cell_data for i in range(3)] == [True] * 3
    np.testing.assert_array_equal(grid.cell_data["tau[2]"], tau[2].ravel())
    lattice = viz.lattice_grid(tau[0], (0, 0, 0), (1, 1, 1))
    assert lattice.n_points == tau[0].size and lattice.bounds[1] == pytest.approx(1.0)


def test_network_and_particles_and_slices():
    rng = np.random.default_rng(2)
    pos = rng.random((10, 3))
    visible = np.full((10, 4), -1)
    visible[:6, 1] = np.arange(1, 7)  # six particles see a neighbour in direction 1
    alpha = rng.random((10, 4))
    net = viz.network_mesh(pos, visible, 1, alpha)
    assert net.n_lines == 6
    np.testing.assert_allclose(net.cell_data["alpha"], alpha[:6, 1].astype(np.float32))
    assert viz.network_mesh(pos, visible, 0).n_lines == 0
    spheres = viz.particles_mesh(pos, 0.05, scalars=rng.random((10, 3)))
    assert spheres.n_points > 10 * 20


def test_a_volume_plot_is_not_blank(device):
    sigma, lo, hi = wv.extinction_volume("rbf-cornell", resolution=24, device=device)
    p = pv.Plotter(off_screen=True, window_size=(200, 150))
    p.add_volume(viz.volume_grid(sigma, lo, hi), cmap="bone")
    img = p.screenshot(return_img=True)
    p.close()
    assert not_blank(img) > 0.02


def test_light_shafts_arrays_and_their_view(device):
    from .test_light_shafts import pillar_scene

    r = wv.Renderer(pillar_scene(width=32, height=24), technique="light_shafts", device=device, shadow_map_res=32)
    r.render()
    arrays = r.arrays(resolution=24)
    (pts,) = arrays["shadow_points"]  # one point light: a cube map
    assert pts.shape == (6 * 32 * 32, 3)
    hit = np.all(np.abs(pts) < 1e29, axis=1)
    # every texel ray of the cube ends on the floor (y = 0), the pillar or escapes through the open sides
    light = np.array([0.3, 1.4, -1.5])
    np.testing.assert_allclose(np.linalg.norm(pts[hit] - light, axis=1), arrays["shadow_distance"][0][hit], rtol=1e-4)
    assert hit.mean() > 0.3 and np.min(pts[hit, 1]) > -1e-3
    lit = arrays["lit_slice"]
    assert lit.shape == (24, 24, 3) and np.isfinite(lit).all() and lit.max() > 0
    p = pv.Plotter(off_screen=True, window_size=(200, 150))
    viz.technique_actors(p, "light_shafts", arrays)
    img = p.screenshot(return_img=True)
    p.close()
    assert not_blank(img) > 0.02


def test_illumination_network_view(device):
    """Particles coloured by radiance and the edges of the direction nearest the sun: one
    edge per particle that sees another upstream, drawn from its own arrays."""
    r = wv.Renderer("particle-cloud", technique="illumination_network", device=device, directions=32,
                    iterations=20)
    r.render()
    arrays = r.arrays(for_view=True)
    d = arrays["view_direction"]
    sun = np.array([-0.4, -1.0, -0.5]) / np.linalg.norm([-0.4, -1.0, -0.5])
    assert arrays["directions"][d] @ sun == pytest.approx((arrays["directions"] @ sun).max())
    edges = viz.network_mesh(arrays["positions"], arrays["visibility"], d, arrays["alpha"][..., 0])
    assert edges.n_cells == int((arrays["visibility"][:, d] >= 0).sum()) > 0
    p = pv.Plotter(off_screen=True, window_size=(200, 150))
    viz.technique_actors(p, "illumination_network", arrays)
    img = p.screenshot(return_img=True)
    p.close()
    assert not_blank(img) > 0.02


def test_depth_impostors_view(device, tmp_path):
    """Instances, one block's impostor layers (its opacity plane holds the impostor's opacity)
    and the light slices (one plane per slice, the last the most opaque), drawn from the
    technique's own arrays."""
    scene = Path(__file__).resolve().parent.parent / "scenes" / "impostor-cloud.toml"
    r = wv.Renderer(str(scene), technique="depth_impostors", device=device, impostor_res=8,
                    slices=3)
    r.render()
    arrays = r.arrays(for_view=True)
    i = arrays["impostor_instance"]
    layers = viz.impostor_layers(arrays["instances"][i], arrays["impostor_frame"], float(arrays["instance_reach"][i]),
                                 arrays["impostor_alpha"], arrays["impostor_front"], arrays["impostor_back"])
    np.testing.assert_allclose(np.sort(layers[0].point_data["opacity"]), np.sort(arrays["impostor_alpha"].mean(-1).ravel()),
                               rtol=1e-6)
    planes = viz.light_slice_planes(arrays["light_faces"][0], arrays["light_slices"][0])
    assert len(planes) == 3
    assert planes[-1].point_data["opacity"].mean() >= planes[0].point_data["opacity"].mean() > 0
    p = pv.Plotter(off_screen=True, window_size=(200, 150))
    viz.technique_actors(p, "depth_impostors", arrays)
    img = p.screenshot(return_img=True)
    p.close()
    assert not_blank(img) > 0.02


def test_view_with_a_technique_from_outside_the_checkout(device, tmp_path):
    """``view --technique`` as an installed package runs it: from a folder that is not the
    repo, so no top-level ``viz`` or ``warpvol`` folder is on the path but the installed ones."""
    import subprocess
    import sys

    out = tmp_path / "view.png"
    run = subprocess.run([sys.executable, "-m", "warpvol", "view", "fog-box", "--technique", "raymarch", "--device", device,
                          "--set", "shadow_grid=8", "--screenshot", str(out)], cwd=tmp_path, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    png = pv.read(str(out))
    w, h, _ = png.dimensions
    assert not_blank(np.asarray(png.point_data.active_scalars).reshape(h, w, -1)) > 0.02
