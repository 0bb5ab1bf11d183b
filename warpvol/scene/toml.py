"""A scene's dict (the TOML layout) written back as TOML: ``python -m warpvol scenes NAME --toml``."""

from __future__ import annotations

import json
import math

import numpy as np

from .load import SceneError

#: Arrays longer than this (a density grid) cannot be written inline.
MAX_INLINE = 4096


def _value(v, where: str) -> str:
    if isinstance(v, np.ndarray):
        if v.size > MAX_INLINE:
            raise SceneError(f"{where}: a {'x'.join(map(str, v.shape))} array, too large for a TOML file (allowed: "
                             f"arrays up to {MAX_INLINE} values; save a grid with warpvol.save_volume and name its "
                             "file in the scene)")
        v = v.tolist()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        if not math.isfinite(x):
            raise SceneError(f"{where}: {x} has no TOML spelling (allowed: finite numbers)")
        return repr(x)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        if sum(1 for _ in np.ravel(np.asarray(v, dtype=object))) > MAX_INLINE:
            return _value(np.asarray(v), where)
        return "[" + ", ".join(_value(x, where) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_value(x, f'{where}.{k}')}" for k, x in v.items()) + " }"
    raise SceneError(f"{where}: {type(v).__name__} has no TOML spelling (allowed: numbers, strings, arrays, tables)")


def scene_toml(name: str, data: dict) -> str:
    """``data`` (a built-in scene's dict) as a TOML scene file: top-level keys, then [camera],
    then the [[lights]], [[media]] and [[surfaces]] arrays of tables."""
    lines = [f"# the built-in scene {name!r}; python -m warpvol render FILE.toml --technique T"]
    tables = ("camera",)
    arrays = ("lights", "media", "surfaces")
    for k, v in data.items():
        if k not in tables and k not in arrays:
            lines.append(f"{k} = {_value(v, k)}")
    for k in tables:
        if k in data:
            lines += ["", f"[{k}]"] + [f"{kk} = {_value(vv, f'{k}.{kk}')}" for kk, vv in data[k].items()]
    for k in arrays:
        for i, item in enumerate(data.get(k, [])):
            lines += ["", f"[[{k}]]"] + [f"{kk} = {_value(vv, f'{k}[{i}].{kk}')}" for kk, vv in item.items()]
    return "\n".join(lines) + "\n"
