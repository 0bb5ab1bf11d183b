"""The stage graph a frame runs (``Pipeline``): what runs, what is cached and what is skipped, and
the audit of the settings each stage reads."""

from __future__ import annotations

import time
from collections import defaultdict

import warp as wp

from .technique import PARTS, Stage, StageRun, Technique


def dynamic_parts(scene) -> set[str]:
    """Scene parts marked ``static = false``: treated as changed every frame."""
    out = set()
    if any(not m.static for m in scene.media):
        out.add("medium")
    if any(not light.static for light in scene.lights):
        out.add("lights")
    if any(not s.static for s in scene.surfaces):
        out.add("surfaces")
    if not scene.camera.static:
        out.add("camera")
    return out


class _ReadLog(dict):
    """The technique's settings while a stage runs under audit: every one of them read is noted
    (asking for a key the technique has no setting of reads nothing that could change)."""

    def __init__(self, settings: dict):
        super().__init__(settings)
        self.read: set[str] = set()

    def _note(self, key) -> None:
        if super().__contains__(key):
            self.read.add(key)

    def __getitem__(self, key):
        self._note(key)
        return super().__getitem__(key)

    def get(self, key, default=None):
        self._note(key)
        return super().get(key, default)


class Pipeline:
    """Runs a technique's stages frame after frame, re-running only what a change invalidates.

    With ``audit`` on, each stage runs with the technique's settings wrapped so that every key
    it reads is noted; ``undeclared`` then maps a stage to the settings it read but does not
    declare (its cache key would miss a change to them: a stale image). The attributes of the
    technique each stage assigns are noted too (``written``): ``shared_writes`` lists those more
    than one stage assigns, an output one stage could overwrite behind another's cache."""

    def __init__(self, technique: Technique, audit: bool = False):
        self.audit = audit
        self.undeclared: dict[str, set[str]] = {}
        self.written: dict[str, set[str]] = defaultdict(set)  # technique attribute -> stages that assigned it
        self.technique = technique
        self.versions = dict.fromkeys(PARTS, 0)
        self._keys: dict[str, tuple] = {}  # stage -> cache key it last ran with
        self._runs: dict[str, int] = defaultdict(int)  # stage -> times it ran (its output's version)
        self._dynamic = dynamic_parts(technique.scene)
        self._frames = 0
        self._checked: set[str] = set()

    def changed(self, *parts: str) -> None:
        """Mark scene parts as changed (the technique's scene already holds the new values)."""
        for part in parts:
            if part not in self.versions:
                raise ValueError(f"unknown scene part {part!r} (allowed: {', '.join(PARTS)})")
            self.versions[part] += 1
        self._dynamic = dynamic_parts(self.technique.scene)

    def _check(self, stage: Stage, seen: set[str]) -> None:
        bad = [p for p in stage.reads if p not in self.versions]
        bad += [s for s in stage.settings if s not in self.technique.settings]
        bad += [a for a in stage.after if a not in seen]
        if bad:
            raise ValueError(f"{self.technique.NAME}: stage {stage.name!r} declares unknown inputs {bad} "
                             f"(allowed: parts {PARTS}, settings, earlier stages)")
        self._checked.add(stage.name)

    def run(self) -> dict[str, StageRun]:
        if self._frames:
            for part in self._dynamic:
                self.versions[part] += 1
        self._frames += 1
        settings, versions, runs, keys = self.technique.settings, self.versions, self._runs, self._keys
        device = self.technique.device
        out: dict[str, StageRun] = {}
        seen: set[str] = set()
        for stage in self.technique.stages():
            if stage.name not in self._checked:
                self._check(stage, seen)
            seen.add(stage.name)
            if not stage.needed:
                keys.pop(stage.name, None)
                out[stage.name] = StageRun("skipped", 0.0)
                continue
            key = (tuple(map(versions.__getitem__, stage.reads)), tuple(map(settings.__getitem__, stage.settings)),
                   tuple(map(runs.__getitem__, stage.after)))
            if keys.get(stage.name) == key and stage.settled:
                out[stage.name] = StageRun("cached", 0.0)
                continue
            t0 = time.perf_counter()
            if self.audit:
                before = {k: id(v) for k, v in vars(self.technique).items()}
                log = self.technique.settings = _ReadLog(settings)
                try:
                    changed = stage.run()
                finally:
                    self.technique.settings = settings
                extra = log.read - set(stage.settings)
                if extra:
                    self.undeclared.setdefault(stage.name, set()).update(extra)
                for k, v in vars(self.technique).items():
                    if k != "settings" and before.get(k) != id(v):
                        self.written[k].add(stage.name)
            else:
                changed = stage.run()
            wp.synchronize_device(device)
            out[stage.name] = StageRun("ran", (time.perf_counter() - t0) * 1000.0)
            keys[stage.name] = key
            if changed is not False:  # False: it ran and found its outputs as they were
                runs[stage.name] += 1
        return out

    @property
    def shared_writes(self) -> dict[str, set[str]]:
        """The technique's attributes that more than one stage assigned under audit."""
        return {k: v for k, v in self.written.items() if len(v) > 1}

    def run_stage(self, name: str) -> float:
        """Run one stage now, on the outputs the last frame left, and return its
        device-synchronised time in ms. What the frame cached is left as it is."""
        stages = {s.name: s for s in self.technique.stages()}
        if name not in stages:
            raise ValueError(f"{self.technique.NAME}: no stage {name!r} (allowed: {', '.join(stages)})")
        t0 = time.perf_counter()
        stages[name].run()
        wp.synchronize_device(self.technique.device)
        return (time.perf_counter() - t0) * 1000.0
