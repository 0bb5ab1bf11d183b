"""TOML (or dict) -> Scene, validated before any kernel runs.

Every problem raises ``SceneError`` with one line: ``FILE: KEY: what is wrong (allowed: RANGE)``.
"""

from __future__ import annotations

import copy
import importlib.util
import json
import math
import os
import sys
from typing import Any

import numpy as np

from . import mie, nanovdb, shapes
from .model import (Camera, GridMedium, HomogeneousMedium, Light, Medium, ParticleMedium, Phase, RBFMedium, Scene,
                    Surface)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


class SceneError(ValueError):
    """A scene file or dict that cannot be rendered; the message names file, key and range."""


from ..names import closest, did_you_mean

_REQUIRED = object()
REQUIRED = "required"  # what RECORD holds for a key without a default

#: While not None, every key a ``_Table`` reads is appended here as (table, variant, key, kind,
#: default, allowed): how ``warpvol.scene.doc`` writes docs/scene-format.md from the loader itself.
RECORD: list | None = None


class _Table:
    """Reads one TOML table, checking types and ranges, and reports keys nobody read."""

    def __init__(self, data: Any, where: str, source: str):
        self.source = source
        self.where = where
        if not isinstance(data, dict):
            self.fail(where, f"must be a table, got {type(data).__name__}", "a table of keys")
        self.data = data
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.where}.{name}" if self.where else name

    def fail(self, key: str, problem: str, allowed: str):
        raise SceneError(f"{self.source}: {key}: {problem} (allowed: {allowed})")

    def raw(self, name: str, default=_REQUIRED, allowed: str = "", kind: str = "value"):
        self.used.add(name)
        if RECORD is not None:
            variant = self.data.get("type", self.data.get("kind", "")) if name not in ("type", "kind") else ""
            RECORD.append((self.where, variant if isinstance(variant, str) else "", name, kind,
                           REQUIRED if default is _REQUIRED else default, allowed))
        if name not in self.data:
            if default is _REQUIRED:
                typo = closest(name, [k for k in self.data if k not in self.used])
                problem = f"missing (there is a key {typo!r}: a misspelling of {name}?)" if typo else "missing"
                self.fail(self.key(name), problem, allowed or "a value: this key is required")
            return default
        return self.data[name]

    def number(self, name, default=_REQUIRED, lo=-math.inf, hi=math.inf, lo_open=False, hi_open=False, integer=False):
        allowed = _range_text(lo, hi, lo_open, hi_open, integer)
        v = self.raw(name, default, allowed, "integer" if integer else "number")
        if v is default and default is not _REQUIRED:
            return v
        ok_type = isinstance(v, int) if integer else isinstance(v, (int, float))
        if isinstance(v, bool) or not ok_type:
            self.fail(self.key(name), f"expected {'an integer' if integer else 'a number'}, got {v!r}", allowed)
        if not math.isfinite(v):
            self.fail(self.key(name), f"{v} is not finite", allowed)
        if v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi):
            self.fail(self.key(name), f"{v} is out of range", allowed)
        return int(v) if integer else float(v)

    def vec3(self, name, default=_REQUIRED, lo=-math.inf, hi=math.inf, scalar_ok=False, lo_open=False):
        each = _range_text(lo, hi, lo_open, False, False)
        allowed = ("a number or " if scalar_ok else "") + "[x, y, z], each " + ("" if each.startswith("any") else "a ") + each
        v = self.raw(name, default, allowed, "number or [x, y, z]" if scalar_ok else "[x, y, z]")
        if v is default and default is not _REQUIRED:
            return tuple(float(x) for x in v) if isinstance(v, (list, tuple)) else v
        if scalar_ok and isinstance(v, (int, float)) and not isinstance(v, bool):
            if not math.isfinite(v):
                self.fail(self.key(name), f"{v} is not finite", allowed)
            if v < lo or v > hi or (lo_open and v == lo):
                self.fail(self.key(name), f"{v} is out of range", allowed)
            v = [v, v, v]
        if not isinstance(v, (list, tuple)) or len(v) != 3 or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in v):
            self.fail(self.key(name), f"expected 3 numbers, got {v!r}", allowed)
        for x in v:
            if not math.isfinite(x):
                self.fail(self.key(name), f"{v!r} contains a non-finite value", allowed)
            if x < lo or x > hi or (lo_open and x == lo):
                self.fail(self.key(name), f"{v!r} is out of range", allowed)
        return tuple(float(x) for x in v)

    def string(self, name, default=_REQUIRED, choices=None):
        allowed = " | ".join(choices) if choices else "a string"
        v = self.raw(name, default, allowed, "string")
        if not isinstance(v, str):
            self.fail(self.key(name), f"expected a string, got {v!r}", allowed)
        if choices and v not in choices:
            self.fail(self.key(name), f"unknown value {v!r}", allowed)
        return v

    def boolean(self, name, default=_REQUIRED):
        v = self.raw(name, default, "true | false", "boolean")
        if not isinstance(v, bool):
            self.fail(self.key(name), f"expected true or false, got {v!r}", "true | false")
        return v

    def path(self, name, base_dir):
        p = self.raw(name, allowed="a file path, relative to the scene file", kind="file")
        if not isinstance(p, str):
            self.fail(self.key(name), f"expected a file path, got {p!r}", "a file path, relative to the scene file")
        full = p if os.path.isabs(p) else os.path.join(base_dir, p)
        if not os.path.isfile(full):
            self.fail(self.key(name), f"file {full!r} not found", "an existing file, relative to the scene file")
        return full

    def finish(self):
        extra = sorted(set(self.data) - self.used)
        if extra:
            self.fail(self.key(extra[0]), "unknown key" + did_you_mean(extra[0], self.used), ", ".join(sorted(self.used)))


def _range_text(lo, hi, lo_open, hi_open, integer):
    kind = "integer" if integer else "number"
    if lo == -math.inf and hi == math.inf:
        return f"any finite {kind}"
    if hi == math.inf:
        return f"{kind} {'>' if lo_open else '>='} {lo:g}"
    left = "(" if lo_open else "["
    right = ")" if hi_open or hi == math.inf else "]"
    return f"{kind} in {left}{lo:g}, {hi:g}{right}"


def _array(t: _Table, name: str, value, shape_tail: tuple, what: str) -> np.ndarray:
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


def _load_npy(t: _Table, name: str, path: str, allowed: str) -> np.ndarray:
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


def _points(t: _Table, name: str, base_dir: str, what: str, alternatives: str = "a file",
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


def _grid_medium(t: _Table, common: dict, base_dir: str) -> GridMedium:
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


def _grid_bounds(t: _Table, default_min=_REQUIRED, default_max=_REQUIRED):
    bmin, bmax = t.vec3("bounds_min", default_min), t.vec3("bounds_max", default_max)
    if any(a >= b for a, b in zip(bmin, bmax)):
        t.fail(t.key("bounds_max"), f"{list(bmax)} is not above bounds_min {list(bmin)} on every axis",
               "bounds_max > bounds_min component-wise")
    return bmin, bmax


def _nanovdb_medium(t: _Table, common: dict, path: str, scale) -> GridMedium:
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


def _camera(data, source) -> Camera:
    t = _Table(data, "camera", source)
    cam = Camera(
        origin=t.vec3("origin"),
        target=t.vec3("target"),
        up=t.vec3("up", (0.0, 1.0, 0.0)),
        fov_y=t.number("fov_y", 40.0, 0.0, 180.0, lo_open=True, hi_open=True),
        width=t.number("width", 128, 1, 16384, integer=True),
        height=t.number("height", 96, 1, 16384, integer=True),
        static=t.boolean("static", True),
    )
    t.finish()
    fwd = np.subtract(cam.target, cam.origin)
    if np.linalg.norm(fwd) == 0:
        t.fail("camera.target", "equals camera.origin", "a point other than the origin")
    if np.linalg.norm(np.cross(fwd, cam.up)) <= 1e-6 * np.linalg.norm(fwd) * np.linalg.norm(cam.up):
        t.fail("camera.up", "is parallel to the viewing direction (or zero)", "a vector not parallel to target - origin")
    return cam


def _light(data, where, source) -> Light:
    t = _Table(data, where, source)
    kind = t.string("type", choices=["point", "spot", "directional"])
    static = t.boolean("static", True)
    if kind == "directional":
        direction = t.vec3("direction")
        if np.linalg.norm(direction) == 0:
            t.fail(t.key("direction"), "is the zero vector", "a non-zero vector")
        light = Light(kind, strength=t.vec3("irradiance", lo=0.0, scalar_ok=True),
                      direction=tuple((np.asarray(direction) / np.linalg.norm(direction)).tolist()))
    else:
        light = Light(kind, strength=t.vec3("intensity", lo=0.0, scalar_ok=True), position=t.vec3("position"))
        if kind == "spot":
            direction = t.vec3("direction")
            if np.linalg.norm(direction) == 0:
                t.fail(t.key("direction"), "is the zero vector", "a non-zero vector")
            light.direction = tuple((np.asarray(direction) / np.linalg.norm(direction)).tolist())
            light.outer_angle = t.number("outer_angle", 30.0, 0.0, 180.0, lo_open=True)
            light.inner_angle = t.number("inner_angle", min(20.0, light.outer_angle), 0.0, light.outer_angle)
    light.static = static
    t.finish()
    return light


def _phase(data, where, source) -> Phase:
    if data is None:
        return Phase()
    t = _Table(data, where, source)
    kind = t.string("type", choices=["isotropic", "hg", "cornette_shanks", "rayleigh", "tabulated", "mie", "hg_draine"])
    ph = Phase(kind)
    if kind in ("hg", "cornette_shanks"):
        ph.g = t.number("g", 0.0, -1.0, 1.0, lo_open=True, hi_open=True)
    if kind == "tabulated":
        v = _array(t, "values", t.raw("values", allowed="list of >= 2 non-negative numbers", kind="list"), (), "list of >= 2 non-negative numbers")
        if v.size < 2 or np.any(v < 0) or v.sum() <= 0:
            t.fail(t.key("values"), "needs >= 2 non-negative values, not all zero", "list of >= 2 non-negative numbers")
        ph.values = v
    if kind == "mie":
        ph = _mie_phase(t)
    if kind == "hg_draine":
        _hg_draine_phase(t, ph)
    t.finish()
    return ph


_MIE_LARGEST_UM = 60.0  # the cross-section weighted median whose forward peak mie.MAX_ENTRIES still resolves


def _mie_phase(t: _Table) -> Phase:
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


def _hg_draine_phase(t: _Table, ph: Phase) -> None:
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


def _rbf_medium(t: _Table, common: dict, base_dir: str) -> RBFMedium:
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


def _per_centre(t: _Table, name: str, n: int, lo_open: bool, default) -> tuple[np.ndarray, float | None]:
    """A number for every centre, or a list of n numbers (> 0 with ``lo_open``, else >= 0):
    (n values as float32, the number where one was given, else None)."""
    bound = "> 0" if lo_open else ">= 0"
    allowed = f"a number {bound}, or a list of them, one a centre"
    v = t.raw(name, _REQUIRED if default is None else default, allowed, "number or list")
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


def _medium(data, where, source, base_dir) -> Medium:
    t = _Table(data, where, source)
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
            g = _Table(t.raw("generator", allowed="a generator table", kind="table"), t.key("generator"), source)
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


def _surface(data, where, source, base_dir) -> Surface:
    t = _Table(data, where, source)
    kind = t.string("type", choices=["mesh", "box", "plane", "sphere", "procedural"])
    name = t.string("name", "")
    diffuse = t.vec3("diffuse", (0.7, 0.7, 0.7), lo=0.0, hi=1.0, scalar_ok=True)
    specular = t.number("specular", 0.0, 0.0, 1.0)
    shininess = t.number("shininess", 20.0, 0.0)
    static = t.boolean("static", True)
    if max(diffuse) + specular > 1.0:
        t.fail(t.key("specular"), f"diffuse + specular = {max(diffuse) + specular:g} creates energy", "diffuse + specular <= 1")
    colours = None
    if kind == "mesh":
        path = t.path("file", base_dir)
        try:
            v, f = shapes.read_obj(path)
        except (OSError, ValueError) as exc:
            t.fail(t.key("file"), f"cannot read {path!r}: {exc}",
                   "a triangle or polygon .obj file, vertices 3 finite numbers")
    elif kind == "box":
        v, f = shapes.box(t.vec3("center", (0.0, 0.0, 0.0)), t.vec3("size", lo=0.0, lo_open=True))
    elif kind == "plane":
        normal = t.vec3("normal", (0.0, 1.0, 0.0))
        if np.linalg.norm(normal) == 0:
            t.fail(t.key("normal"), "is the zero vector", "a non-zero vector")
        size = t.raw("size", [100.0, 100.0], "[w, h] with w, h > 0", "[w, h]")
        if not isinstance(size, (list, tuple)) or len(size) != 2 or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0 for x in size
        ):
            t.fail(t.key("size"), f"expected [w, h], got {size!r}", "[w, h] with w, h > 0")
        v, f = shapes.plane(t.vec3("center", (0.0, 0.0, 0.0)), normal, size)
    elif kind == "sphere":
        v, f = shapes.sphere(t.vec3("center", (0.0, 0.0, 0.0)), t.number("radius", lo=0.0, lo_open=True))
    elif name == "colonnade":
        v, f, colours = shapes.colonnade(t.vec3("center", (0.0, 0.0, 0.0)),
                                         t.number("columns", 8, 1, 64, integer=True),
                                         t.number("segments", 64, 3, 1024, integer=True),
                                         t.number("stacks", 64, 1, 1024, integer=True), diffuse)
    else:
        if name != "cornell_box":
            t.fail(t.key("name"), f"unknown procedural surface {name!r}", "cornell_box | colonnade")
        v, f, colours = shapes.cornell_box(t.vec3("center", (0.0, 0.0, 0.0)),
                                           t.vec3("size", (2.0, 2.0, 2.0), lo=0.0, lo_open=True), diffuse)
    t.finish()
    if colours is None:
        colours = np.tile(np.asarray(diffuse, np.float64), (len(f), 1))
    return Surface(kind, v.astype(np.float32), f.astype(np.int32), colours.astype(np.float32),
                   specular, shininess, name, static)


def scene_from_dict(data: dict, source: str = "<dict>", base_dir: str = ".") -> Scene:
    """Validate a scene given as a dict (the TOML layout; arrays may be numpy)."""
    t = _Table(data, "", source)
    name = t.string("name", os.path.splitext(os.path.basename(source))[0] if source != "<dict>" else "scene")
    background = t.vec3("background", (0.0, 0.0, 0.0), lo=0.0, scalar_ok=True)
    camera = _camera(t.raw("camera", allowed="a [camera] table", kind="table"), source)

    def items(key):
        v = t.raw(key, [], f"[[{key}]] tables", "array of tables")
        if not isinstance(v, list):
            t.fail(key, f"must be an array of tables ([[{key}]]), got {type(v).__name__}", f"[[{key}]] tables")
        return v

    lights = [_light(d, f"lights[{i}]", source) for i, d in enumerate(items("lights"))]
    media = [_medium(d, f"media[{i}]", source, base_dir) for i, d in enumerate(items("media"))]
    surfaces = [_surface(d, f"surfaces[{i}]", source, base_dir) for i, d in enumerate(items("surfaces"))]
    t.finish()
    if not media and not surfaces and not any(background):
        t.fail("media", "the scene has no media, no surfaces and a black background: nothing to see",
               "at least one medium or surface, or a non-black background")
    return Scene(name, camera, lights, media, surfaces, background, source)


def apply_overrides(data: dict, assignments: list[str], source: str) -> dict:
    """Apply ``key=value`` overrides (dotted keys, list indices as numbers; value in TOML syntax)."""
    data = copy.deepcopy(data)
    for item in assignments:
        if "=" not in item:
            raise SceneError(f"{source}: --set {item!r}: expected key=value (allowed: e.g. camera.width=64)")
        key, value = item.split("=", 1)
        try:
            parsed = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            parsed = value
        node = data
        parts = key.strip().split(".")
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise SceneError(f"{source}: --set {key}: index {part!r} out of range (allowed: 0..{len(node) - 1})")
                if last:
                    node[int(part)] = parsed
                else:
                    node = node[int(part)]
            elif isinstance(node, dict):
                if last:
                    node[part] = parsed
                else:
                    node = node.setdefault(part, {})
            else:
                raise SceneError(f"{source}: --set {key}: {part!r} is not inside a table (allowed: a dotted path to a key)")
    return data


def override_items(overrides) -> list[str]:
    """Overrides as the CLI's ``KEY=VALUE`` strings, from those or from a {dotted key: value}
    dict (``{"camera.width": 320, "media.0.sigma_t": [1, 2, 3]}``; values as in TOML)."""
    if overrides is None:
        return []
    if isinstance(overrides, dict):
        return [f"{k}={json.dumps(v.tolist() if hasattr(v, 'tolist') else v)}" for k, v in overrides.items()]
    return list(overrides)


def load_scene(scene, overrides: list[str] | dict | None = None) -> Scene:
    """A Scene from a .toml path, a built-in scene name, a dict, or a Scene (returned as is);
    ``overrides`` (``override_items``) change keys by their dotted path, as ``--set`` does."""
    overrides = override_items(overrides)
    if isinstance(scene, Scene):
        if overrides:
            raise SceneError(f"overrides {', '.join(overrides)}: apply to a scene file, built-in name or dict "
                             "(allowed: for a loaded Scene, dataclasses.replace, or Renderer.update)")
        return scene
    if isinstance(scene, dict):
        return scene_from_dict(apply_overrides(scene, overrides or [], "<dict>"), "<dict>", ".")
    path = os.fspath(scene)
    from .procedural import BUILTIN

    if path in BUILTIN and not os.path.exists(path):
        data = BUILTIN[path]()
        return scene_from_dict(apply_overrides(data, overrides or [], f"<builtin {path}>"), f"<builtin {path}>", ".")
    if not os.path.isfile(path):
        raise SceneError(f"{path}: file not found (allowed: a .toml scene file or a built-in name: {', '.join(sorted(BUILTIN))})")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc} (allowed: a TOML scene file: a [camera] table and [[lights]], [[media]], [[surfaces]] arrays of tables)") from None
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not a text file: byte {exc.start} is not UTF-8 "
                         "(allowed: a UTF-8 TOML scene file)") from None
    return scene_from_dict(apply_overrides(data, overrides or [], path), path, os.path.dirname(os.path.abspath(path)))


def parse_part(part: str, value, source: str = "<update>"):
    """A scene part for ``Renderer.update``: model objects pass through, dicts are validated.

    ``part`` is ``camera`` (a Camera or table), ``lights``, ``medium`` or ``surfaces`` (one
    item or a list of them).
    """
    if part == "camera":
        return value if isinstance(value, Camera) else _camera(value, source)
    parse, kind = {"lights": (lambda d, w: _light(d, w, source), Light),
                   "medium": (lambda d, w: _medium(d, w, source, "."), Medium),
                   "surfaces": (lambda d, w: _surface(d, w, source, "."), Surface)}[part]
    items = value if isinstance(value, (list, tuple)) else [value]
    return [v if isinstance(v, kind) else parse(v, f"{part}[{i}]") for i, v in enumerate(items)]
