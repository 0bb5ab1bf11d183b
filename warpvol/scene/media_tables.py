"""The ``[[media]]`` tables of a scene: each medium kind's keys (homogeneous, grid from an array,
a .npy or a NanoVDB file, RBF, particles), their phase function's (``phase`` tables, Mie
through ``warpvol.scene.mie``), and the arrays of points and numbers they hold, read with
``Table`` so their types and ranges are checked."""

from __future__ import annotations

import importlib.util
import math

import numpy as np

from . import mie, nanovdb
from .model import GridMedium, HomogeneousMedium, Medium, ParticleMedium, Phase, RBFMedium
from .tables import NO_DEFAULT, SceneError, Table


def _array(t: Table, name: str, value, shape_tail: tuple, what: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        t.fail(t.key(name), "cannot be read as numbers", what)
    if a.ndim != 1 + len(shape_tail) or tuple(a.shape[1:]) != shape_tail:
        if not (a.size == 0 and shape_tail):
            t.fail(t.key(name), f"has shape {a.shape}", what)
        a = a.reshape((0,) + shape_tail)
    if not np.all(np.isfinite(a)):
        t.fail(t.key(name), "contains NaN or Inf", what)
    return a.astype(np.float32)


def _load_npy(t: Table, name: str, path: str, allowed: str) -> np.ndarray:
    """The numeric array in the .npy file ``path``; anything else fails naming the file and key."""
    try:
        with open(path, "rb") as fh:
            is_npy = fh.read(6) == b"\x93NUMPY"
        if not is_npy:
            raise ValueError("not a .npy file")
        a = np.load(path, allow_pickle=False)
    except ValueError as exc:
        t.fail(t.key(name), f"cannot read {path!r}: {'it holds Python objects' if 'allow_pickle' in str(exc) else exc}",
               allowed)
    except Exception as exc:  # noqa: BLE001 - a truncated or unreadable file fails the same way
        t.fail(t.key(name), f"cannot read {path!r}: {type(exc).__name__}: {exc}", allowed)
    if a.dtype.kind not in "biuf":
        t.fail(t.key(name), f"cannot read {path!r}: it holds {a.dtype} values, not numbers", allowed)
    return a


def _points(t: Table, name: str, base_dir: str, what: str, alternatives: str = "a file",
            file_columns: tuple = (3,), file_shape: str = "(N, 3)") -> np.ndarray:
    """RBF centres or particle positions, (N, 3) with N >= 1, from ``file`` or the list ``name``;
    a file may hold rows of any of ``file_columns`` values (the first three the point), as
    ``file_shape`` says."""
    if "file" in t.data:
        key, allowed = "file", f"a .npy file of shape {file_shape} with at least one {what}"
        path = t.path("file", base_dir)
        value = _load_npy(t, "file", path, allowed)
        if value.size and (value.ndim != 2 or value.shape[1] not in file_columns):
            t.fail(t.key(key), f"{path!r} holds an array of shape {value.shape}", allowed)
        tail = (value.shape[1],) if value.ndim == 2 else (3,)
    else:
        key, allowed = name, f"[[x, y, z], ...] with at least one {what}, or {alternatives}"
        value = t.raw(name, allowed=allowed, kind="[[x, y, z], ...]")
        tail = (3,)
    a = _array(t, key, value, tail, allowed)
    if len(a) == 0:
        t.fail(t.key(key), f"has no {what}s" if key == name else f"{path!r} holds no {what}s", allowed)
    return a


_GRID_FILE = "a .npy file of shape (D, H, W), x fastest, or a .nvdb file (" + nanovdb.ALLOWED + ")"


def _grid_medium(t: Table, common: dict, base_dir: str) -> GridMedium:
    """A grid medium from ``density`` (an array, in a dict), a .npy ``file`` or a NanoVDB ``file``."""
    scale = t.vec3("sigma_t_scale", (1.0, 1.0, 1.0), lo=0.0, scalar_ok=True)
    if "density" in t.data:
        key = t.key("density")
        try:
            dens = np.asarray(t.raw("density", allowed="a 3-D array (D, H, W), x fastest", kind="array"))
        except ValueError:
            dens = np.zeros(0, object)
        if dens.dtype.kind not in "biuf":
            t.fail(key, "cannot be read as numbers", "a non-empty 3-D array (D, H, W) of numbers, x fastest")
    else:
        key, path = t.key("file"), t.path("file", base_dir)
        if path.lower().endswith(".nvdb") or nanovdb.is_nanovdb(path):
            return _nanovdb_medium(t, common, path, scale)
        dens = _load_npy(t, "file", path, _GRID_FILE)
    if dens.ndim != 3 or dens.size == 0:
        t.fail(key, f"density has shape {dens.shape}", "a non-empty 3-D array (D, H, W), x fastest")
    lo, hi = float(dens.min()), float(dens.max())  # NaN propagates; no temporaries the size of the grid
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo < 0 or hi > float(np.finfo(np.float32).max):
        t.fail(key, "density has NaN, Inf or negative values", "finite values >= 0 (float32)")
    bmin, bmax = _grid_bounds(t)
    return GridMedium(**common, density=dens.astype(np.float32, copy=False), bounds_min=bmin, bounds_max=bmax,
                      sigma_t_scale=scale)


def _grid_bounds(t: Table, default_min=NO_DEFAULT, default_max=NO_DEFAULT):
    bmin, bmax = t.vec3("bounds_min", default_min), t.vec3("bounds_max", default_max)
    if any(a >= b for a, b in zip(bmin, bmax)):
        t.fail(t.key("bounds_max"), f"{list(bmax)} is not above bounds_min {list(bmin)} on every axis",
               "bounds_max > bounds_min component-wise")
    return bmin, bmax


def _nanovdb_medium(t: Table, common: dict, path: str, scale) -> GridMedium:
    """A grid medium over a NanoVDB file: header and values checked here with numpy (no Warp),
    the bounds (by default the faces around the active voxels) on the grid's voxel faces."""
    try:
        grid = nanovdb.read_grid(path)
    except nanovdb.NanoVDBError as exc:
        t.fail(t.key("file"), f"{path!r} {exc.problem}", exc.allowed)
    except OSError as exc:
        t.fail(t.key("file"), f"cannot read {path!r}: {exc}", nanovdb.ALLOWED)
    bmin, bmax = _grid_bounds(t, *nanovdb.active_faces(grid))
    try:
        first, dims = nanovdb.sample_frame(grid, bmin, bmax)
    except nanovdb.NanoVDBError as exc:
        which, problem = exc.problem.split(": ", 1)
        t.fail(t.key(which), problem, exc.allowed)
    return GridMedium(**common, density=None, bounds_min=bmin, bounds_max=bmax, sigma_t_scale=scale, volume=grid,
                      volume_index_min=first, volume_dims=dims)


def _phase(data, where, source) -> Phase:
    if data is None:
        return Phase()
    t = Table(data, where, source)
    kind = t.string("type", choices=["isotropic", "hg", "cornette_shanks", "rayleigh", "tabulated", "mie", "hg_draine"])
    ph = Phase(kind)
    if kind in ("hg", "cornette_shanks"):
        ph.g = t.number("g", 0.0, -1.0, 1.0, lo_open=True, hi_open=True)
    if kind == "tabulated":
        allowed = "list of >= 2 non-negative numbers"
        v = _array(t, "values", t.raw("values", allowed=allowed, kind="list"), (), allowed)
        if v.size < 2 or np.any(v < 0) or v.sum() <= 0:
            t.fail(t.key("values"), "needs >= 2 non-negative values, not all zero", allowed)
        ph.values = v
    if kind == "mie":
        ph = _mie_phase(t)
    if kind == "hg_draine":
        _hg_draine_phase(t, ph)
    t.finish()
    return ph


_MIE_LARGEST_UM = 60.0  # the cross-section weighted median whose forward peak mie.MAX_ENTRIES still resolves


def _mie_phase(t: Table) -> Phase:
    """Log-normal water droplets through Mie theory, as a tabulated phase (``mie.mie_table``)."""
    d = t.number("median_diameter_um", lo=0.1, hi=_MIE_LARGEST_UM)
    sigma = t.number("sigma", lo=0.0, hi=0.5)
    index = t.number("refractive_index", mie.WATER_INDEX, 1.0, 2.0, lo_open=True)
    if d * math.exp(2.0 * sigma * sigma) > _MIE_LARGEST_UM:
        t.fail(t.key("sigma"), f"median_diameter_um x exp(2 sigma^2) = {d * math.exp(2 * sigma * sigma):.4g} um, the "
               "cross-section weighted median, has a forward peak narrower than the largest table",
               f"median_diameter_um x exp(2 sigma^2) <= {_MIE_LARGEST_UM:g} um")
    if importlib.util.find_spec("miepython") is None:
        raise SceneError(f"{t.source}: {t.key('type')}: \"mie\" needs miepython, which is not installed "
                         "(allowed: pip install 'warpvol[mie]', or type = \"hg_draine\", its fit)")
    return Phase("tabulated", values=mie.mie_table(d, sigma, index).mean.astype(np.float32))


def _hg_draine_phase(t: Table, ph: Phase) -> None:
    """Jendersie & d'Eon 2023: the fit at ``diameter_um``, or the four parameters given."""
    explicit = [k for k in ("g_hg", "g_d", "alpha", "w_d") if k in t.data]
    if explicit and "diameter_um" in t.data:
        t.fail(t.key(explicit[0]), "given with diameter_um", "either diameter_um or all of g_hg, g_d, alpha, w_d")
    if explicit:
        fit = mie.HGDraine(g_hg=t.number("g_hg", lo=-1.0, hi=1.0, lo_open=True, hi_open=True),
                           g_d=t.number("g_d", lo=0.001, hi=0.99), alpha=t.number("alpha", lo=0.001, hi=100.0),
                           w_d=t.number("w_d", lo=0.0, hi=1.0))
    else:
        fit = mie.jendersie_deon(t.number("diameter_um", lo=mie.FIT_RANGE_UM[0], hi=mie.FIT_RANGE_UM[1]))
    ph.g, ph.g_d, ph.alpha, ph.w_d = fit.g_hg, fit.g_d, fit.alpha, fit.w_d


def _rbf_medium(t: Table, common: dict, base_dir: str) -> RBFMedium:
    """Gaussians from ``centers`` (or a .npy ``file`` of rows x, y, z or x, y, z, radius,
    amplitude), each of ``radius`` (a number, or one a centre) and ``amplitude`` (one a centre,
    default 1)."""
    rows = _points(t, "centers", base_dir, "centre", file_columns=(3, 5),
                   file_shape="(N, 3) (centres) or (N, 5) (x, y, z, radius, amplitude)")
    centers, n = rows[:, :3], len(rows)
    if rows.shape[1] == 5:
        for key in ("radius", "amplitude"):
            if key in t.data:
                t.fail(t.key(key), "given with a 5-column file", "the file's columns, or a 3-column file with this key")
        radii, amps, scalar = rows[:, 3], rows[:, 4], None
        if np.any(radii <= 0) or np.any(amps < 0):
            t.fail(t.key("file"), "has a radius <= 0 or an amplitude < 0", "radii > 0 and amplitudes >= 0")
    else:
        radii, scalar = _per_centre(t, "radius", n, lo_open=True, default=None)
        amps, _ = _per_centre(t, "amplitude", n, lo_open=False, default=1.0)
    return RBFMedium(**common, centers=centers, radius=scalar if scalar is not None else float(np.max(radii)),
                     radii=radii, amplitudes=amps, peak=t.vec3("peak", lo=0.0, scalar_ok=True))


def _per_centre(t: Table, name: str, n: int, lo_open: bool, default) -> tuple[np.ndarray, float | None]:
    """A number for every centre, or a list of n numbers (> 0 with ``lo_open``, else >= 0):
    (n values as float32, the number where one was given, else None)."""
    bound = "> 0" if lo_open else ">= 0"
    allowed = f"a number {bound}, or a list of them, one a centre"
    v = t.raw(name, NO_DEFAULT if default is None else default, allowed, "number or list")
    scalar = None
    if isinstance(v, (list, tuple, np.ndarray)):
        a = _array(t, name, v, (), allowed)
        if a.shape != (n,):
            t.fail(t.key(name), f"has {a.size} values for {n} centres", allowed)
    elif isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
        scalar = float(v)
        a = np.full(n, scalar, np.float32)
    else:
        t.fail(t.key(name), f"expected a number or a list, got {v!r}", allowed)
    if np.any(a <= 0) if lo_open else np.any(a < 0):
        t.fail(t.key(name), "has a value out of range", allowed)
    return a, scalar


def parse_medium(data, where, source, base_dir) -> Medium:
    t = Table(data, where, source)
    kind = t.string("type", choices=["homogeneous", "grid", "rbf", "particles"])
    common = dict(
        albedo=t.vec3("albedo", lo=0.0, hi=1.0, scalar_ok=True),
        phase=_phase(t.raw("phase", None, "a phase table", "table"), t.key("phase"), source),
        static=t.boolean("static", True),
    )
    if kind == "homogeneous":
        shape = t.string("shape", "box", choices=["box", "sphere"])
        m = HomogeneousMedium(**common, shape=shape, center=t.vec3("center", (0.0, 0.0, 0.0)),
                              sigma_t=t.vec3("sigma_t", lo=0.0, scalar_ok=True))
        if shape == "box":
            m.size = t.vec3("size", lo=0.0, lo_open=True)
        else:
            m.radius = t.number("radius", lo=0.0, lo_open=True)
    elif kind == "grid":
        m = _grid_medium(t, common, base_dir)
    elif kind == "rbf":
        m = _rbf_medium(t, common, base_dir)
    else:
        radius = t.number("radius", lo=0.0, lo_open=True)
        block_size = 0
        if "generator" in t.data:
            g = Table(t.raw("generator", allowed="a generator table", kind="table"), t.key("generator"), source)
            gen = g.string("kind", choices=["cloud", "blocks"])
            from .procedural import block_particles, cloud_particles

            seed = g.number("seed", 1, 0, 2**31 - 1, integer=True)
            center = g.vec3("center", (0.0, 0.0, 0.0))
            extent = g.number("extent", 1.0, 0.0, lo_open=True)
            if gen == "cloud":
                positions = cloud_particles(count=g.number("count", 1024, 1, 10_000_000, integer=True), seed=seed,
                                            center=center, extent=extent)
            else:  # Umenhoffer & Szirmay-Kalos 2005: blocks copies of one block of per_block particles
                blocks = g.number("blocks", 40, 1, 10_000_000, integer=True)
                block_size = g.number("per_block", 200, 1, 10_000_000, integer=True)
                if blocks * block_size > 10_000_000:
                    g.fail(g.key("per_block"), f"blocks x per_block = {blocks * block_size} particles",
                           "at most 10000000 particles")
                positions = block_particles(blocks, block_size, seed=seed, center=center, extent=extent,
                                            block_extent=g.number("block_extent", 0.25, 0.0, lo_open=True))
            g.finish()
        else:
            positions = _points(t, "positions", base_dir, "particle", "a file or a generator")
            block_size = t.number("block_size", 0, 0, 10_000_000, integer=True)
            if block_size > 1:
                from .procedural import split_blocks

                if split_blocks(np.asarray(positions, np.float32).reshape(-1, 3), block_size) is None:
                    t.fail(t.key("block_size"), f"the {len(positions)} positions are not copies of one block of "
                           f"{block_size} particles", "block-major copies of one block (see generator kind "
                           "\"blocks\"), or 0")
        m = ParticleMedium(**common, positions=_array(t, "positions", positions, (3,), "[[x, y, z], ...]"),
                           radius=radius, sigma_t=t.vec3("sigma_t", lo=0.0, scalar_ok=True), block_size=block_size)
    t.finish()
    return m
