"""Stages, their inputs, and what a change invalidates; Frames and validated settings.

A technique is a small graph of named stages (upload the medium, bake a shadow volume,
march, ...). Each ``Stage`` declares what it reads: scene parts (``PARTS``), settings by
name, and the stages whose outputs it uses. ``Pipeline`` runs a frame:

* a stage the scene does not call for (``needed=False``: no surfaces, no shadow pass;
  single scattering, no iteration) is **skipped**;
* a stage whose inputs are unchanged since it last ran is **cached**: its outputs, kept
  by the technique, are used again;
* every other stage **ran**, timed with the device synchronised after it.

A change is a version bump of a scene part: ``Pipeline.update`` bumps what it replaces,
and a part marked ``static = false`` in the scene is treated as changed every frame
(animated). A stage's cache key is the versions of the parts it reads, the values of the
settings it reads and the run counts of the stages it follows, so a re-run propagates
downstream and nothing else. This is the rule of Giroud & Biri 2011, Table 1.
"""

from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
import warp as wp

from .image import png_bytes, tonemap
from .names import did_you_mean

PARTS = ("medium", "lights", "camera", "surfaces", "background")


class SettingsError(ValueError):
    """A technique setting with an unknown name or a value out of range."""


@dataclass
class Setting:
    """A technique's setting: its default, its range [lo, hi] and what it does. ``names``: for a
    choice, the name of each value lo, lo + 1, .. hi in turn; a name is accepted wherever the
    number is (``light_pass="fourier"``, ``--set light_pass=fourier``) and stored as the number."""

    default: object
    lo: float
    hi: float
    doc: str
    names: tuple[str, ...] = ()

    def __post_init__(self):
        if self.names and len(self.names) != int(self.hi - self.lo) + 1:
            raise ValueError(f"Setting names {self.names}: one for each value {self.lo:g}..{self.hi:g}")

    def choices(self) -> dict[str, int]:
        """A choice's names and the values they stand for (empty for a plain number)."""
        return {n: int(self.lo) + i for i, n in enumerate(self.names)}

    def allowed(self) -> str:
        """The values it takes, for messages: the range, or each value with its name."""
        if self.names:
            return ", ".join(f"{v} or {n!r}" for n, v in self.choices().items())
        return f"{self.lo:.10g}..{self.hi:.10g}"


def resolve_settings(technique: str, spec: dict[str, Setting], given: dict, base: dict | None = None) -> dict:
    """Defaults (or ``base``) updated with ``given``; an unknown key or a bad value raises."""
    out = dict(base) if base is not None else {k: s.default for k, s in spec.items()}
    for key, value in given.items():
        if key not in spec:
            raise SettingsError(f"{technique}: unknown setting {key!r}{did_you_mean(key, spec)} "
                                f"(allowed: {', '.join(sorted(spec))})")
        s = spec[key]
        kind = type(s.default)
        allowed = f"allowed: {s.allowed()}; {s.doc}"
        if isinstance(value, str) and s.names:
            if value not in s.names:
                raise SettingsError(f"{technique}: setting {key}={value!r} is not one of its names{did_you_mean(value, s.names)} "
                                    f"({allowed})")
            value = s.choices()[value]
        if isinstance(value, float) and not np.isfinite(value):
            raise SettingsError(f"{technique}: setting {key}={value!r} is not finite ({allowed})")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (kind is int and int(value) != value):
            raise SettingsError(f"{technique}: setting {key}={value!r} must be {'an integer' if kind is int else 'a number'} "
                                f"({allowed})")
        if not (s.lo <= value <= s.hi):
            raise SettingsError(f"{technique}: setting {key}={value!r} is out of range ({allowed})")
        out[key] = kind(value)
    return out


@dataclass(frozen=True)
class Bias:
    """A discretisation setting that ``target_error`` does not raise with the ladder but whose
    bias it measures at the level the ladder found: against ``exact`` (the value at which the
    setting leaves no bias, e.g. light_shafts' block = 1), or, where the limit is infinite,
    against ``factor`` times the value, the difference scaled to the whole bias as an error
    of order ``order`` (|x(v) - x(f v)| / (1 - f^-order)). ``when``: the scene part that must
    be present for the setting to matter (``"sky"``: a non-black background; ``"multiple"``:
    the multiple-scattering term on; ``"rbf"``: an RBF medium; ``"heterogeneous"``: a medium not
    homogeneous), or None. ``top``: the most
    ``target_error`` takes the setting to (None: its range's top), where its cost rises
    steeply (the lattice's n^4 D)."""

    setting: str
    exact: object = None
    factor: int = 4
    order: float = 1.0
    when: str | None = None
    top: object = None


@dataclass(frozen=True, kw_only=True)
class Quality:
    """What ``render(target_error=...)`` does with a technique's discretisation settings.

    ``knob`` doubles from ``start`` up to ``top`` (the ladder), its error falling as
    knob^-``order``; each setting in ``tied`` rises with it, at ``factor x knob``; ``biases``
    are the other settings that leave a bias, measured at the level found (``Bias``). Together
    they are every setting whose limit is the technique's converged answer."""

    knob: str
    start: int
    top: int
    order: float
    tied: dict = None  # setting: factor
    biases: tuple = ()

    def level_settings(self, level: int) -> dict:
        """The knob and its tied settings at ``level``."""
        return {self.knob: level, **{k: max(1, int(round(f * level))) for k, f in (self.tied or {}).items()}}


def has_sky(scene) -> bool:
    """Whether the scene's background lights its media: a non-black sky and some medium."""
    return any(c > 0.0 for c in scene.background) and bool(scene.media)


class Stage(NamedTuple):
    """One pass of a technique.

    ``run`` computes the stage's outputs and keeps them on the technique. ``reads`` names
    scene parts (``PARTS``), ``settings`` the settings it reads, ``after`` the earlier
    stages whose outputs it uses. ``needed=False`` when the scene does not call for it.
    ``settled=False`` makes it run even with unchanged inputs: an iterative solver whose
    state has not converged yet. ``run`` may return False: it ran and found its outputs as
    they were (say, a block template that an animation moved but did not change), so the
    stages after it stay cached.
    """

    name: str
    run: Callable[[], None]
    reads: tuple[str, ...] = ()
    settings: tuple[str, ...] = ()
    after: tuple[str, ...] = ()
    needed: bool = True
    settled: bool = True


class StageRun(NamedTuple):
    status: str  # "ran" | "cached" | "skipped"
    ms: float  # device-synchronised wall time; 0 unless it ran


class Technique:
    """Base of every technique: the scene, device and settings, and the stages of a frame.

    Subclasses set ``NAME`` and ``SETTINGS``, keep their buffers as attributes, and define
    ``stages()`` (the graph, in order, re-read every frame so ``needed`` follows the
    scene) and ``output()`` (the last frame's image: H*W vec3 on the device, or numpy).
    """

    NAME = ""
    SETTINGS: dict[str, Setting] = {}

    def __init__(self, scene, device: str, settings: dict, progress: bool = False):
        self.scene = scene
        self.device = device
        self.settings = settings
        self.progress = progress
        self.check_settings(settings)

    def check_settings(self, settings: dict) -> None:
        """Raise ``SettingsError`` for combinations the ranges alone do not exclude."""

    def stages(self) -> list[Stage]:
        raise NotImplementedError

    def output(self):
        raise NotImplementedError

    #: What the technique's model leaves out of the physical answer (all orders of scattering
    #: of every light, the sky included), e.g. "multiple scattering".
    LEAVES_OUT: tuple[str, ...] = ()

    def leaves_out(self) -> list[str]:
        """``LEAVES_OUT``, and the sky's light where the scene has a sky the technique does not
        gather (``sky_samples`` = 0, or no such setting) and no multiple-scattering lattice
        approximates (``multiple_scattering`` = 0)."""
        out = list(self.LEAVES_OUT)
        # with the lattice on, it carries the sky over the media and lights the surfaces beyond them
        if has_sky(self.scene) and not self.gathers_sky and not self.settings.get("multiple_scattering", 0):
            out.append("the sky's light (the background) scattered in the media or reflected by surfaces")
        return out

    def pixel_work(self, light_samples: float, steps: float = 0.0) -> float:
        """A pixel's work in units of a simple pixel (``device.launch`` splits a CPU launch by it):
        ``light_samples`` for each of the scene's lights (one where it has none), and ``steps``
        density samples of its own."""
        return light_samples * max(1, len(self.scene.lights)) + steps

    #: True: the technique gathers the sky's light whatever its settings (e.g. by following paths).
    GATHERS_SKY: bool = False

    @property
    def gathers_sky(self) -> bool:
        """Whether the technique gathers the sky's light itself: always (``GATHERS_SKY``) or with
        ``sky_samples`` > 0 (else the multiple-scattering lattice carries it, where it is on)."""
        return self.GATHERS_SKY is True or self.settings.get("sky_samples", 0) > 0

    #: What ``render(target_error=...)`` raises and measures (``Quality``); None: target_error is
    #: not supported.
    QUALITY: Quality | None = None

    #: A seed setting whose values give independent answers of the same quality (Monte Carlo
    #: samples, turned direction sets): ``target_error`` then estimates the error from the spread
    #: of two seeds at one level instead of from successive levels. None: levels.
    QUALITY_SEED: str | None = None

    #: Settings ``target_error`` holds at these values (unless given) while it raises the knob.
    QUALITY_HOLD: dict = {}

    #: ``Renderer(one_shot=True)`` (as ``warpvol.render`` makes it): the frame is the only one, so
    #: an iterative technique runs to convergence instead of its per-frame iterations (by
    #: default a ``Renderer`` keeps the paper's loop).
    one_shot: bool = False

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """Intermediate arrays of the last frame, as numpy, for looking inside (``viz``).

        ``for_view`` adds what a picture needs beyond the frame's own arrays, however costly
        (rbf_propagation's marched optical depth); ``resolution`` is the side of arrays sampled
        only to be looked at (light_shafts' lit slice). Every technique takes both."""
        return {}

    def diagnostics(self) -> dict:
        """Named figures of the last frame a benchmark reports beside the image (e.g. the
        window illumination_network used), as plain numbers or numpy arrays; each technique
        documents its own. The public way for bench/ and viz/ to read a technique's state."""
        return {}


class Frame:
    """A rendered image (H x W x 3 float32, linear RGB, row 0 at the top) and what it cost.

    ``stages`` maps each stage to its ``StageRun`` (status and ms); ``timings`` is the
    {stage: seconds} view of the same data. The image is copied off the device the first
    time ``image`` is read, so timing a frame does not time the read-back.
    """

    #: How an entry of ``leaves_out`` starts when the model approximates that physics rather than omits it.
    APPROXIMATED = "approximated, not left out: "

    def __init__(self, output, shape: tuple[int, int], technique: str, device: str, settings: dict,
                 stages: dict[str, StageRun], leaves_out: list[str] | None = None):
        self.leaves_out = list(leaves_out or [])  # what the technique's model leaves out of the physics
        self.error_estimate: float | None = None  # render(target_error=...): the image's estimated error
        self.bias_estimates: dict[str, float] = {}  # render(target_error=...): each Bias setting's measured part
        self.moved_to_limit: dict = {}  # render(target_error=...): the Bias settings it took to their limits
        self.choice: str | None = None  # render(technique="auto"): what was chosen and why
        self._output = output
        self._image = None
        self.shape = shape
        self.technique = technique
        self.device = device
        self.settings = settings
        self.stages = stages

    @property
    def approximates(self) -> list[str]:
        """The entries of ``leaves_out`` the model approximates (after the ``APPROXIMATED`` mark)."""
        return [x[len(self.APPROXIMATED):] for x in self.leaves_out if x.startswith(self.APPROXIMATED)]

    @property
    def omits(self) -> list[str]:
        """The entries of ``leaves_out`` the model has no part of."""
        return [x for x in self.leaves_out if not x.startswith(self.APPROXIMATED)]

    def _repr_png_(self) -> bytes:
        """The image as a PNG (sRGB, exposure 0): what a notebook (Jupyter, IPython) shows for a Frame."""
        return png_bytes(tonemap(self.image))

    @property
    def image(self) -> np.ndarray:
        if self._image is None:
            data = self._output.numpy() if isinstance(self._output, wp.array) else np.asarray(self._output)
            self._image = data.astype(np.float32, copy=False).reshape(*self.shape, 3)
            self._output = None
        return self._image

    @property
    def timings(self) -> dict[str, float]:
        return {name: run.ms / 1000.0 for name, run in self.stages.items()}

    def __repr__(self) -> str:
        runs = ", ".join(f"{n}={r.status}" for n, r in self.stages.items())
        return f"Frame({self.technique} on {self.device}, {self.shape[1]}x{self.shape[0]}; {runs})"


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
    declare (its cache key would miss a change to them: a stale image)."""

    def __init__(self, technique: Technique, audit: bool = False):
        self.audit = audit
        self.undeclared: dict[str, set[str]] = {}
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
                log = self.technique.settings = _ReadLog(settings)
                try:
                    changed = stage.run()
                finally:
                    self.technique.settings = settings
                extra = log.read - set(stage.settings)
                if extra:
                    self.undeclared.setdefault(stage.name, set()).update(extra)
            else:
                changed = stage.run()
            wp.synchronize_device(device)
            out[stage.name] = StageRun("ran", (time.perf_counter() - t0) * 1000.0)
            keys[stage.name] = key
            if changed is not False:  # False: it ran and found its outputs as they were
                runs[stage.name] += 1
        return out

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
