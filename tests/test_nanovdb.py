"""NanoVDB grids (.nvdb) for grid media: a dense grid written with ``save_volume`` reads back
as the same samples, renders the same image with every technique that reads grids, has the
same majorant grid, and bad files stop with one line naming the file before any kernel runs."""

import os
import shutil

import numpy as np
import pytest
import warp as wp

import warpvol as wv
from warpvol import device as dev
from warpvol.media.grid import grid_trilinear, majorant_grid, volume_trilinear
from warpvol.scene import SceneError, load_scene
from warpvol.scene.procedural import NANOVDB_CLOUD, sparse_cloud_density
from warpvol.upload import MediaBuffers

dev.kernel_module(__name__)  # this file's kernels: warpvol's Warp options

BMIN, BMAX = [-1.0, -0.8, -0.9], [1.0, 0.9, 1.1]


def density() -> np.ndarray:
    """(12, 10, 14) [z, y, x]: a lumpy block of non-zero samples, one touching the x = min face,
    zeros elsewhere; sizes not multiples of 8 and cells of three sizes."""
    a = np.zeros((12, 10, 14), np.float32)
    a[2:9, 1:8, 3:12] = np.random.default_rng(0).uniform(0.2, 1.5, (7, 7, 9))
    a[5, 5, 0] = 2.0
    return a


@pytest.fixture(scope="module")
def nvdb(tmp_path_factory):
    """The dense grid as cloud.nvdb (and as cloud.npy beside it)."""
    folder = tmp_path_factory.mktemp("nvdb")
    np.save(folder / "cloud.npy", density())
    return wv.save_volume(str(folder / "cloud.nvdb"), density(), BMIN, BMAX)


def scene(medium: dict) -> dict:
    return {"camera": {"origin": [0.3, 0.4, 3.5], "target": [0, 0, 0], "width": 16, "height": 12},
            "lights": [{"type": "point", "position": [0.5, 1.5, 0.8], "intensity": 4.0}],
            "media": [{"type": "grid", "sigma_t_scale": 3.0, "albedo": 0.8, "phase": {"type": "hg", "g": 0.3},
                       **medium}]}


def cut(path: str, cells: int) -> tuple[dict, dict]:
    """The dense grid without its first ``cells`` x planes and the .nvdb over the same bounds:
    the file's voxel (cells, 0, 0) is then sample (0, 0, 0)."""
    lo = list(BMIN)
    lo[0] += cells * (BMAX[0] - BMIN[0]) / density().shape[2]
    return ({"density": density()[:, :, cells:], "bounds_min": lo, "bounds_max": BMAX},
            {"file": path, "bounds_min": lo, "bounds_max": BMAX})


@wp.kernel
def lookups(volume: wp.uint64, origin: wp.vec3i, dims: wp.vec3i, data: wp.array(dtype=float), lo: wp.vec3,
            hi: wp.vec3, points: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    """Per point: (dense grid_trilinear, volume_trilinear, Warp's own trilinear volume_sample_f
    at the index-space point of the volume's transform)."""
    tid = wp.tid()
    x = points[tid]
    warp_linear = wp.volume_sample_f(volume, wp.volume_world_to_index(volume, x), wp.Volume.LINEAR)
    out[tid] = wp.vec3(grid_trilinear(data, 0, dims, lo, hi, x), volume_trilinear(volume, origin, dims, lo, hi, x),
                       warp_linear)


@pytest.mark.parametrize("cells", [0, 2], ids=["whole", "cut"])
def test_round_trip_samples_equal_the_dense_lookup(nvdb, device, cells):
    """numpy -> .nvdb -> samples in a kernel: bit-identical to the dense grid's trilinear lookup
    everywhere (inside, in the clamped half-cell border, outside: 0). Warp's own LINEAR sampling
    at the point its transform maps x to agrees to float rounding away from the border (where
    the dense lookup clamps and Warp blends in the zero voxels outside): voxel centres sit at
    integer index coordinates, as the cell-centred dense samples do."""
    dense, sparse = cut(nvdb, cells)
    dm, sm = load_scene(scene(dense)).media[0], load_scene(scene(sparse)).media[0]
    assert sm.volume_index_min == (cells, 0, 0) and sm.dims == dm.dims
    with open(nvdb, "rb") as fh:
        vol = wp.Volume.load_from_nvdb(fh, device=device)
    rng = np.random.default_rng(1)
    lo, hi = np.asarray(dense["bounds_min"]), np.asarray(BMAX)
    cell = (hi - lo) / dm.dims
    pts = np.concatenate([rng.uniform(lo - 0.2, hi + 0.2, (4000, 3)),  # inside, the border, outside
                          lo + (np.stack(np.meshgrid(*[np.arange(n) for n in dm.dims], indexing="ij"), -1)
                                .reshape(-1, 3) + 0.5) * cell])  # every sample's centre
    out = wp.empty(len(pts), dtype=wp.vec3, device=device)
    wp.launch(lookups, len(pts), [vol.id, wp.vec3i(*sm.volume_index_min), wp.vec3i(*dm.dims),
                                  wp.array(dm.density.ravel(), dtype=float, device=device), wp.vec3(*lo), wp.vec3(*hi),
                                  wp.array(pts.astype(np.float32), dtype=wp.vec3, device=device), out], device=device)
    v = out.numpy()
    np.testing.assert_array_equal(v[:, 1], v[:, 0])
    assert np.count_nonzero(v[:, 0]) > 1000
    interior = np.all((pts > lo + 0.5 * cell + 1e-4) & (pts < hi - 0.5 * cell - 1e-4), axis=1)
    # Warp's index point (its float32 inverse map) differs from (x - lo) / cell - 1/2 by a few ulps
    # of an index below 16 (ulp 2^-20), times the steepest step between samples (2.0); the sums
    # of eight weights x values against nested lerps add a few roundings of the largest sample (2.0)
    np.testing.assert_allclose(v[interior, 2], v[interior, 0], rtol=0, atol=8 * 2.0**-20 * 2.0 + 16 * 2.0**-24 * 2.0)


def test_save_volume_stores_only_the_leaves_that_hold_samples(tmp_path):
    """A 64^3 box holding one 3^3 lump: one 8^3 leaf (sparse), background 0, the box's voxel
    size and the cell-centred placement (voxel (0, 0, 0) centred half a cell inside the box)."""
    a = np.zeros((64, 64, 64), np.float32)
    a[20:23, 41:44, 9:12] = 1.5
    path = wv.save_volume(tmp_path / "lump.nvdb", a, (0, 0, 0), (6.4, 3.2, 1.6), codec="zip")
    m = load_scene(scene({"file": path, "bounds_min": [0, 0, 0], "bounds_max": [6.4, 3.2, 1.6]})).media[0]
    assert (m.volume.leaves, m.volume.voxels, m.volume.outside_leaves, m.volume.value_max) == (1, 512, 0.0, 1.5)
    np.testing.assert_allclose(m.volume.voxel_size, (0.1, 0.05, 0.025), rtol=1e-7)
    np.testing.assert_allclose(m.volume.origin, (0.05, 0.025, 0.0125), rtol=1e-7)
    assert m.dims == (64, 64, 64) and m.volume_index_min == (0, 0, 0)
    default = load_scene(scene({"file": path})).media[0]  # bounds default to the active leaf's faces
    np.testing.assert_allclose(default.bounds_min, (0.8, 2.0, 0.4), rtol=1e-6)
    np.testing.assert_allclose(default.bounds_max, (1.6, 2.4, 0.6), rtol=1e-6)


@pytest.mark.parametrize("cells", [0, 2], ids=["whole", "cut"])
def test_majorant_grid_from_the_leaves_equals_the_dense_one(nvdb, device, cells):
    dense, sparse = cut(nvdb, cells)
    d = MediaBuffers(load_scene(scene(dense)), device)
    s = MediaBuffers(load_scene(scene(sparse)), device)
    (dg,), (sg,) = d.grids, s.grids
    np.testing.assert_array_equal(sg.struct.majorant.numpy(), dg.struct.majorant.numpy())
    assert tuple(sg.struct.majorant_dims) == tuple(dg.struct.majorant_dims)
    assert np.asarray(s.struct.majorant).tolist() == np.asarray(d.struct.majorant).tolist()
    np.testing.assert_array_equal(dg.struct.majorant.numpy(), majorant_grid(dense["density"]).ravel())


RENDERS = {"reference": {"spp": 4, "seed": 7}, "raymarch": {"steps": 32, "shadow_steps": 16},
           "light_shafts": {"steps": 32, "shadow_steps": 16}}


@pytest.mark.parametrize("technique", sorted(RENDERS))
def test_dense_and_nanovdb_render_the_same_image(nvdb, device, technique):
    """The densities are bit-identical (same corners, same blend: media/grid.py) and so is the
    majorant grid, so every technique, the seeded path tracer included, takes the same steps and
    paths: the images agree to float rounding (1e-6 leaves room for a compiler that fuses the
    blend's multiply-adds differently in the two code paths; on the CPU they are equal)."""
    dense, sparse = cut(nvdb, 2)
    a = wv.render(scene(dense), technique=technique, device=device, **RENDERS[technique]).image
    b = wv.render(scene(sparse), technique=technique, device=device, **RENDERS[technique]).image
    assert a.mean() > 1e-4
    np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-7)


def _grid_of(path, bg_value):
    """A one-leaf Warp volume of the value type of ``bg_value`` (None: an index grid), saved."""
    tiles = wp.array(np.zeros((1, 3), np.int32), dtype=wp.vec3i, device="cpu")
    wp.Volume.allocate_by_tiles(tiles, voxel_size=0.1, bg_value=bg_value, device="cpu").save_to_nvdb(str(path))


def _truncated(path, good):
    with open(good, "rb") as fh:
        path.write_bytes(fh.read()[: os.path.getsize(good) // 2])


BAD = {
    "truncated": (_truncated, "file", "is truncated"),
    "not-nanovdb": (lambda p, good: p.write_bytes(b"P6 16 12 255\n" + bytes(600)), "file", "is not a NanoVDB file"),
    "npy-renamed": (lambda p, good: shutil.copy(good.replace(".nvdb", ".npy"), p), "file", "is not a NanoVDB file"),
    "vec3-values": (lambda p, good: _grid_of(p, wp.vec3(0.0)), "file", "holds a grid of Vec3f values, not float"),
    "double-values": (lambda p, good: _grid_of(p, wp.float64(0.0)), "file", "holds a grid of double values, not float"),
    "index-grid": (lambda p, good: _grid_of(p, None), "file", "holds an index grid"),
    "negative": (lambda p, good: _grid_of(p, -1.0), "file", "NaN, Inf or negative values"),
}


@pytest.mark.parametrize("kind", sorted(BAD))
def test_bad_file_is_one_line_naming_the_file_before_any_kernel(device, nvdb, tmp_path, monkeypatch, kind):
    make, key, problem = BAD[kind]
    path = tmp_path / f"{kind}.nvdb"
    make(path, nvdb)

    def no_kernel(*args, **kwargs):
        raise AssertionError("a kernel ran (or a volume loaded) before the bad file was refused")

    monkeypatch.setattr(wp, "launch", no_kernel)
    monkeypatch.setattr(wp.Volume, "load_from_nvdb", no_kernel)
    with pytest.raises(SceneError) as err:
        wv.render(scene({"file": str(path), "bounds_min": BMIN, "bounds_max": BMAX}), technique="raymarch",
                  device=device)
    msg = str(err.value)
    assert "\n" not in msg and f"media[0].{key}: " in msg and str(path) in msg and problem in msg, msg
    assert "(allowed: " in msg, msg


def test_bounds_off_the_voxel_faces_name_the_key_and_the_faces(nvdb):
    with pytest.raises(SceneError) as err:
        load_scene(scene({"file": nvdb, "bounds_min": [-1.0, -0.8, -0.85], "bounds_max": BMAX}))
    msg = str(err.value)
    assert "media[0].bounds_min: " in msg and "does not lie on voxel faces" in msg and nvdb in msg, msg
    assert "e.g. [-1.0, -0.8, -0.9]" in msg and "\n" not in msg, msg


def test_builtin_cloud_is_sparse_and_holds_its_generator(device):
    """The shipped nanovdb-cloud.nvdb is ``save_volume`` of ``sparse_cloud_density()``: its samples
    (the extinction at the cell centres) are the generator's, and it stores a leaf only where the
    cloud is (about 5% of the box is cloud)."""
    s = load_scene("nanovdb-cloud")
    m = s.media[0]
    assert m.volume.path == NANOVDB_CLOUD and m.dims == (128, 128, 128)
    expected = sparse_cloud_density()
    assert 0.04 < np.count_nonzero(expected) / expected.size < 0.06
    blocks = np.count_nonzero(expected.reshape(16, 8, 16, 8, 16, 8).any(axis=(1, 3, 5)))
    assert m.volume.leaves == blocks < 0.1 * 16**3
    sigma, _, _ = wv.extinction_volume(s, resolution=128, device=device)
    np.testing.assert_allclose(sigma[..., 0], expected * m.sigma_t_scale[0], rtol=1e-5, atol=1e-5)
    assert os.path.getsize(NANOVDB_CLOUD) < 100_000


@pytest.mark.cpu_only
def test_majorant_grid_from_many_leaves_split_over_the_cores_equals_the_dense_one(tmp_path):
    """A 64^3 grid of 512 full leaves: the leaf pass is split over the CPU's cores, 32^3 voxels
    folding into each coarse cell's maximum. Each core fills its own copy (Warp's CPU atomics
    are not atomic across threads; a shared grid lost maxima now and then, and the majorant
    fell below the samples it bounds). Five builds, each equal to the dense bound."""
    import warp as wp

    from warpvol.media.grid import volume_majorant_grid

    a = np.random.default_rng(5).uniform(0.1, 2.0, (64, 64, 64)).astype(np.float32)
    path = wv.save_volume(str(tmp_path / "full.nvdb"), a, (0, 0, 0), (1, 1, 1))
    with open(path, "rb") as fh:
        vol = wp.Volume.load_from_nvdb(fh, device="cpu")
    want = majorant_grid(a)
    for _ in range(5):  # sample (i, j, k) is voxel (i, j, k): save_volume's layout
        np.testing.assert_array_equal(volume_majorant_grid(vol, (0, 0, 0), (64, 64, 64)), want)
