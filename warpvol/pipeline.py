"""Frames, per-stage timing, and settings that name the bad key and its range."""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import warp as wp


class SettingsError(ValueError):
    """A technique setting with an unknown name or a value out of range."""


@dataclass
class Setting:
    default: object
    lo: float
    hi: float
    doc: str


def resolve_settings(technique: str, spec: dict[str, Setting], given: dict) -> dict:
    out = {k: s.default for k, s in spec.items()}
    for key, value in given.items():
        if key not in spec:
            raise SettingsError(f"{technique}: unknown setting {key!r} (allowed: {', '.join(sorted(spec))})")
        s = spec[key]
        kind = type(s.default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (kind is int and int(value) != value):
            raise SettingsError(f"{technique}: setting {key}={value!r} must be {'an integer' if kind is int else 'a number'} "
                                f"(allowed: {s.lo:g}..{s.hi:g}; {s.doc})")
        if not (s.lo <= value <= s.hi):
            raise SettingsError(f"{technique}: setting {key}={value!r} is out of range (allowed: {s.lo:g}..{s.hi:g}; {s.doc})")
        out[key] = kind(value)
    return out


@dataclass
class Frame:
    """A rendered image (H x W x 3 float32, linear RGB, row 0 at the top) and what it cost."""

    image: np.ndarray
    technique: str
    device: str
    settings: dict
    timings: dict[str, float] = field(default_factory=dict)  # stage -> seconds, device-synchronised


@contextmanager
def timed(timings: dict, stage: str, device: str):
    """Add the device-synchronised wall time of the block to ``timings[stage]``."""
    t0 = time.perf_counter()
    yield
    wp.synchronize_device(device)
    timings[stage] = timings.get(stage, 0.0) + time.perf_counter() - t0
