"""Reading one table of a scene (TOML or dict): each key checked for its type and range as it is
read, a key nobody read reported as unknown, and every problem raised as ``SceneError`` with one
line, ``FILE: KEY: what is wrong (allowed: RANGE)``. With ``RECORD`` on, every key read is
recorded with its type, default and range (how ``warpvol.scene.doc`` documents the format)."""

from __future__ import annotations

import math
import os
from typing import Any

from ..names import closest, did_you_mean


class SceneError(ValueError):
    """A scene file or dict that cannot be rendered; the message names file, key and range."""


NO_DEFAULT = object()  # the default of a required key
REQUIRED = "required"  # what RECORD holds for a key without a default

#: While not None, every key a ``Table`` reads is appended here as (table, variant, key, kind,
#: default, allowed): how ``warpvol.scene.doc`` writes docs/scene-format.md from the loader itself.
RECORD: list | None = None


class Table:
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

    def raw(self, name: str, default=NO_DEFAULT, allowed: str = "", kind: str = "value"):
        self.used.add(name)
        if RECORD is not None:
            variant = self.data.get("type", self.data.get("kind", "")) if name not in ("type", "kind") else ""
            RECORD.append((self.where, variant if isinstance(variant, str) else "", name, kind,
                           REQUIRED if default is NO_DEFAULT else default, allowed))
        if name not in self.data:
            if default is NO_DEFAULT:
                typo = closest(name, [k for k in self.data if k not in self.used])
                problem = f"missing (there is a key {typo!r}: a misspelling of {name}?)" if typo else "missing"
                self.fail(self.key(name), problem, allowed or "a value: this key is required")
            return default
        return self.data[name]

    def number(self, name, default=NO_DEFAULT, lo=-math.inf, hi=math.inf, lo_open=False, hi_open=False, integer=False):
        allowed = _range_text(lo, hi, lo_open, hi_open, integer)
        v = self.raw(name, default, allowed, "integer" if integer else "number")
        if v is default and default is not NO_DEFAULT:
            return v
        ok_type = isinstance(v, int) if integer else isinstance(v, (int, float))
        if isinstance(v, bool) or not ok_type:
            self.fail(self.key(name), f"expected {'an integer' if integer else 'a number'}, got {v!r}", allowed)
        if not math.isfinite(v):
            self.fail(self.key(name), f"{v} is not finite", allowed)
        if v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi):
            self.fail(self.key(name), f"{v} is out of range", allowed)
        return int(v) if integer else float(v)

    def vec3(self, name, default=NO_DEFAULT, lo=-math.inf, hi=math.inf, scalar_ok=False, lo_open=False):
        each = _range_text(lo, hi, lo_open, False, False)
        allowed = (("a number or " if scalar_ok else "") + "[x, y, z], each "
                   + ("" if each.startswith("any") else "a ") + each)
        v = self.raw(name, default, allowed, "number or [x, y, z]" if scalar_ok else "[x, y, z]")
        if v is default and default is not NO_DEFAULT:
            return tuple(float(x) for x in v) if isinstance(v, (list, tuple)) else v
        if scalar_ok and isinstance(v, (int, float)) and not isinstance(v, bool):
            if not math.isfinite(v):
                self.fail(self.key(name), f"{v} is not finite", allowed)
            if v < lo or v > hi or (lo_open and v == lo):
                self.fail(self.key(name), f"{v} is out of range", allowed)
            v = [v, v, v]
        if not isinstance(v, (list, tuple)) or len(v) != 3 or any(
                isinstance(x, bool) or not isinstance(x, (int, float)) for x in v):
            self.fail(self.key(name), f"expected 3 numbers, got {v!r}", allowed)
        for x in v:
            if not math.isfinite(x):
                self.fail(self.key(name), f"{v!r} contains a non-finite value", allowed)
            if x < lo or x > hi or (lo_open and x == lo):
                self.fail(self.key(name), f"{v!r} is out of range", allowed)
        return tuple(float(x) for x in v)

    def string(self, name, default=NO_DEFAULT, choices=None):
        allowed = " | ".join(choices) if choices else "a string"
        v = self.raw(name, default, allowed, "string")
        if not isinstance(v, str):
            self.fail(self.key(name), f"expected a string, got {v!r}", allowed)
        if choices and v not in choices:
            self.fail(self.key(name), f"unknown value {v!r}", allowed)
        return v

    def boolean(self, name, default=NO_DEFAULT):
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
            self.fail(self.key(extra[0]), "unknown key" + did_you_mean(extra[0], self.used),
                      ", ".join(sorted(self.used)))


def _range_text(lo, hi, lo_open, hi_open, integer):
    kind = "integer" if integer else "number"
    if lo == -math.inf and hi == math.inf:
        return f"any finite {kind}"
    if hi == math.inf:
        return f"{kind} {'>' if lo_open else '>='} {lo:g}"
    left = "(" if lo_open else "["
    right = ")" if hi_open or hi == math.inf else "]"
    return f"{kind} in {left}{lo:g}, {hi:g}{right}"
