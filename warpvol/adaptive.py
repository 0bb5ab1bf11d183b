"""Renders to an accuracy asked for: ``target_error`` (a technique's quality ladder, its error
extrapolated from three levels and measured against the next, its biases at their limits) and
``technique = "auto"`` (the fastest technique whose measured error on the scene's family meets
the target). ``warpvol.render`` documents both; results/target-error measures how well they hold."""

from __future__ import annotations

import sys
import time
import warnings

import numpy as np

from .metrics import error_scale, relative_rmse
from .pipeline import Frame, SettingsError, has_sky
from .renderer import Renderer, technique_class, technique_names
from .scene import load_scene
from .scene.model import MediumKind


#: The reference stops at this fraction of ``target_error`` (see ``render_to_target``).
SPP_MARGIN = 0.8

#: The slowest convergence ``remaining_error`` trusts, as a power of the knob's nominal rate
#: 2^-order per doubling: an observed ratio below 2^-1.5 order is taken as a lucky
#: cancellation between two levels, not as convergence that fast.
RATE_FLOOR = 1.5


def remaining_error(images: list, spreads: list, order: float) -> float:
    """The relative RMSE still in the finest of three levels a, b, c of a quality knob (each
    one doubling of it), estimated from the steps u = b - a and v = c - b.

    Model: a level's error is an aligned part that falls by r per doubling (x r^k g, the
    Richardson assumption) plus a part unrelated from level to level (m_k, mutually
    orthogonal, also falling by r): a step pattern that moves when the step count changes
    makes the second. Then |v| = r |u| and u.v = r A - r^2 B / (1 + r^2), where A + B = |u|^2
    splits |u|^2 into the aligned and the unrelated part, and the error of c is
    r^2 sqrt(A / (1 - r)^2 + B / (1 + r^2)): r |v| / (1 - r) when the levels' errors line up
    (Richardson), r |v| / sqrt(1 + r^2) when they are unrelated (where Richardson alone
    over-estimates up to 4x). ``spreads``: each level's own relative standard error (0 for a
    deterministic technique); that noise is taken out of |u|^2, |v|^2 and u.v. r is kept in
    [2^-(RATE_FLOOR order), 0.95]. Norms are relative_rmse's: over c's mean."""
    a, b, c = images[-3:]
    s0, s1, s2 = (x * x for x in spreads[-3:])
    scale = error_scale(c)
    if scale <= 0.0:
        return 0.0 if not (np.any(a) or np.any(b)) else float("inf")
    u, v = (b - a) / scale, (c - b) / scale
    uu = max(float(np.mean(u * u)) - s0 - s1, 0.0)
    vv = max(float(np.mean(v * v)) - s1 - s2, 0.0)
    uv = float(np.mean(u * v)) + s1
    if uu <= 0.0:
        return float(np.sqrt(vv))
    r = min(max(np.sqrt(vv / uu), 0.5 ** (RATE_FLOOR * order)), 0.95)
    B = min(max((uu - uv / r) / (1.0 + r / (1.0 + r * r)), 0.0), uu)
    return float(r * r * np.sqrt((uu - B) / (1.0 - r) ** 2 + B / (1.0 + r * r)))


def measured_error(coarse, fine, order: float, coarse_spread: float = 0.0, fine_spread: float = 0.0) -> float:
    """The relative RMSE of level ``coarse``, measured against the next level ``fine`` (one
    doubling finer) instead of extrapolated: ``remaining_error``'s error model one level on.
    The step w = fine - coarse is relative_rmse(coarse, fine).

    If the error falls by r per doubling, |w| is the coarse level's error times 1 - r where
    the levels' errors line up (Richardson), and times sqrt(1 + r^2) where they are unrelated.
    At the knob's nominal rate r = 2^-order the estimate is |w| times the geometric mean of the
    two corrections, 1 / sqrt((1 - r) sqrt(1 + r^2)): 1.34 for order 1, 1.14 for order 2. It is
    then 0.67x (aligned) to 1.49x (unrelated) the error at that rate, 2x apart at most. The
    observed ratio of successive steps is not used: its noise near r = 1 blows up 1 / (1 - r).
    The levels' own noise (``*_spread``, as in ``remaining_error``) is taken out of the step
    and the coarse level's put back: the coarse image's error includes its noise."""
    r = 0.5**order
    step = max(relative_rmse(coarse, fine) ** 2 - coarse_spread**2 - fine_spread**2, 0.0)
    return float(np.sqrt(step / ((1.0 - r) * np.sqrt(1.0 + r * r)) + coarse_spread**2))


def bias_error(image, limit_image, bias) -> float:
    """The relative RMSE a ``Bias`` setting leaves in ``image``, measured against a render with
    the setting at its limit (``limit_image``, else the same): the difference itself where the
    limit is exact, else the difference over 1 - factor^-order (the part a render at factor x
    the value still misses, as an error of that order). Where the technique is seeded both
    renders take the same seeds, so their noise is common and cancels in the difference
    (common random numbers): none is taken out (taking out both spreads hid a light-pass bias
    of 0.022 under a direction noise of 0.02 on random cloud 2)."""
    d = relative_rmse(image, limit_image)
    return float(d if bias.exact is not None else d / (1.0 - float(bias.factor) ** -bias.order))


#: The share of a budget's time left that a predicted step may take (a step's time varies by a
#: few percent from the last one's scaled; the budget may be overrun by at most 10%).
BUDGET_SHARE = 0.85


class Budget:
    """A search's time limit (``max_seconds``; None: none): ``affords(seconds)`` says whether
    work of that length still ends within it (each next level's time is predicted from the last
    level's, its work scaling with the knob), so a search stops at the budget instead of past it."""

    def __init__(self, max_seconds: float | None):
        self.max_seconds = max_seconds
        self.start = time.perf_counter()
        self.stopped = False  # a step was refused: the search stopped at the budget

    def left(self) -> float:
        if self.max_seconds is None:
            return float("inf")
        return self.max_seconds - (time.perf_counter() - self.start)

    def affords(self, seconds: float) -> bool:
        ok = seconds <= BUDGET_SHARE * self.left()
        self.stopped = self.stopped or not ok
        return ok


def positive_number(value, message: str) -> float:
    """``value`` as a finite number > 0 (the CLI's --set may give it as a string), else
    SettingsError(``message``)."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = float("nan")
    if not (np.isfinite(number) and number > 0.0):
        raise SettingsError(message)
    return number


def check_budget(value) -> float:
    """``max_seconds``, a number of seconds > 0."""
    return positive_number(value, f"setting max_seconds={value!r} is out of range (allowed: a number of seconds > 0, "
                                  "with target_error)")


def check_target(value) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and 0.0 < float(value) < 1.0
    if not ok:
        raise SettingsError(f"setting target_error={value!r} is out of range (allowed: 0 < target_error < 1; the "
                            "relative RMSE of the image against the technique's converged answer)")
    return float(value)


def _with_image(frame: Frame, image: np.ndarray, settings: dict) -> Frame:
    """``frame`` with its own copy of ``image`` (as float32) and ``settings``."""
    return Frame(image.astype(np.float32), frame.shape, frame.technique, frame.device, settings, frame.stages,
                 frame.leaves_out)


#: Rounds of ladder-then-biases ``render_to_target`` takes at most (each round moves one bias
#: setting to its limit or tightens the ladder's share of the target).
MAX_ROUNDS = 8


def render_to_target(scene, technique: str, device, progress: bool, target: float, settings: dict,
                     max_seconds: float | None = None) -> Frame:
    """Render to ``target`` against the technique's converged answer: the ladder of its
    ``Quality`` knob, then each ``Bias`` setting's bias measured at the level found (see
    ``render``); within ``max_seconds`` where given (the best image found by then, with its
    estimate, and a warning)."""
    cls = technique_class(technique)
    q, seed = _check_target_settings(cls, technique, settings)
    scene = load_scene(scene)
    base = {**getattr(cls, "QUALITY_HOLD", {}), **settings}
    renders = _Renders(scene, technique, device, progress)
    budget = Budget(max_seconds)
    if q.knob == "spp":  # unbiased Monte Carlo: its noise is the whole error
        return _render_spp(renders, technique, progress, target, base, q, seed, budget)

    held: dict = {}  # bias settings moved to their limit
    aim = target  # the ladder's share of the target
    first = q.start
    best = None  # (total, frame) of the rounds so far
    for _ in range(MAX_ROUNDS):
        current = {**base, **held}
        frame, estimate, level, took = _ladder(renders, technique, progress, aim, current, q, seed, first, budget)
        biases, limits = ({}, {}) if budget.stopped else _measure_biases(renders, cls, scene, frame, current, level)
        total = float(np.sqrt(estimate**2 + sum(e * e for e in biases.values())))
        frame.bias_estimates = dict(biases)
        frame.moved_to_limit = dict(held)
        if best is None or total < best[0]:
            best = (total, frame)
        if total <= target:
            frame.error_estimate = total
            return frame
        if budget.stopped or not budget.affords(took):  # another round would not end within the budget
            total, frame = best
            frame.error_estimate = total
            warnings.warn(f"{technique}: stopped at max_seconds={budget.max_seconds:g} with error estimate "
                          f"{total:.3g} (target_error {target:.3g}) at {frame.settings}", RuntimeWarning, stacklevel=3)
            return frame
        fixed = sum(e * e for k, e in biases.items() if k in settings or k not in limits)
        if fixed >= target**2:  # the biases nothing may move (given, or at their top) exceed it alone
            break
        movable = {k: e for k, e in biases.items() if k not in settings and k in limits}
        worst = max(movable, key=movable.get) if movable else None
        rest = target**2 - sum(e * e for e in biases.values())
        if worst is not None and (movable[worst] > 0.5 * target or rest < (0.25 * target) ** 2):
            held[worst] = limits[worst]  # this setting's bias is the larger part: take it to its limit
            first = max(q.start, level // 4)
            continue
        if rest <= 0.0 or 2 * level > q.top:
            break
        aim = min(aim, float(np.sqrt(rest)))  # the biases are small: the ladder aims lower
        first = max(q.start, level // 4)
    frame.error_estimate = total
    warnings.warn(f"{technique}: error estimate {total:.3g} above target_error {target:.3g} at {frame.settings} "
                  f"(biases measured: {', '.join(f'{k} {e:.3g}' for k, e in biases.items()) or 'none'})",
                  RuntimeWarning, stacklevel=3)
    return frame


def _check_target_settings(cls, technique: str, settings: dict):
    """The technique's ``Quality`` and seed setting, after refusing what target_error chooses
    itself (the knob, its tied settings, the seed) among the given ``settings``."""
    q = getattr(cls, "QUALITY", None)
    if q is None:
        raise SettingsError(f"{technique}: target_error is not supported yet (supported: "
                            f"{', '.join(n for n in technique_names() if getattr(technique_class(n), 'QUALITY', None))})")
    for key in (q.knob, *(q.tied or {})):
        if key in settings:
            raise SettingsError(f"{technique}: give target_error or {key}, not both (target_error chooses {key})")
    seed = getattr(cls, "QUALITY_SEED", None)
    if seed is not None and seed in settings:
        raise SettingsError(f"{technique}: give target_error or {seed}, not both (target_error draws two)")
    return q, seed


def _bias_applies(b, scene, current: dict, defaults: dict) -> bool:
    """Whether the scene has what bias setting ``b`` acts on (``Bias.when``)."""
    if b.when == "sky":
        return has_sky(scene)
    if b.when == "multiple":
        return bool(current.get("multiple_scattering", defaults.get("multiple_scattering")))
    if b.when == "rbf":
        return any(m.type == MediumKind.RBF for m in scene.media)
    if b.when == "heterogeneous":
        return not all(m.type == MediumKind.HOMOGENEOUS for m in scene.media)
    return True


def _measure_biases(renders: "_Renders", cls, scene, frame: Frame, current: dict, level: int):
    """Each ``Bias`` setting's bias in ``frame`` (the ladder's, at ``level``): against the setting
    at its limit, or, at the top target_error takes it to, against the level below. Returns
    ({setting: bias}, {setting: its limit, where it could be moved there})."""
    q, seed = cls.QUALITY, getattr(cls, "QUALITY_SEED", None)
    defaults = {k: s.default for k, s in cls.SETTINGS.items()}
    biases, limits = {}, {}
    for b in q.biases:
        value = current.get(b.setting, defaults[b.setting])
        if not _bias_applies(b, scene, current, defaults):
            continue
        hi = cls.SETTINGS[b.setting].hi if b.top is None else b.top
        limit = b.exact if b.exact is not None else min(value * b.factor, hi)
        if b.exact is None and value == 0:  # off (0: left out)
            continue
        if limit == value:
            if b.top is None or b.exact is not None:  # at its limit: no bias left
                continue
            # at the top target_error takes it to (the cost), short of the limit: its bias
            # measured against the level below (an over-estimate: that level's own), not moved
            lower = type(value)(max(value // b.factor, 1))
            if lower == value:
                continue
            img = _level_image(renders, {**current, b.setting: lower}, q, seed, level)
            biases[b.setting] = bias_error(frame.image, img, b)
            continue
        img = _level_image(renders, {**current, b.setting: type(value)(limit)}, q, seed, level)
        biases[b.setting] = bias_error(frame.image, img, b)
        limits[b.setting] = type(value)(limit)
    return biases, limits


def _say(progress: bool, line: str) -> None:
    """A search's progress, one line on stderr (where the progress bars go), when ``progress``."""
    if progress:
        print(line, file=sys.stderr, flush=True)


class _Renders:
    """The renders of one search, from one Renderer: each render moves the settings
    (``Renderer.update`` with every setting named, so none is left over from the render before)
    and the stages whose inputs the move leaves alone (the uploads and their BVHs; a lattice, a
    light pass or a bake at unchanged settings) are kept instead of rebuilt, as a fresh Renderer
    per render would. Each frame's image is copied off at once: the next render may reuse the
    technique's output buffer."""

    def __init__(self, scene, technique: str, device, progress: bool):
        self._args = (scene, technique, device, progress)
        self._defaults = {k: s.default for k, s in technique_class(technique).SETTINGS.items()}
        self._renderer: Renderer | None = None

    def frame(self, settings: dict) -> Frame:
        full = {**self._defaults, **settings}
        if self._renderer is None:
            scene, technique, device, progress = self._args
            self._renderer = Renderer(scene, technique, device, progress, one_shot=True, **full)
        else:
            self._renderer.update(settings=full)
        frame = self._renderer.render()
        return _with_image(frame, frame.image, frame.settings)


def _two_seeds(renders: _Renders, settings: dict, seed: str):
    """The mean of two independent answers (``seed`` 1 and 2) at ``settings`` and its relative
    standard error: (frame, mean image, spread)."""
    a = renders.frame({**settings, seed: 1})
    b = renders.frame({**settings, seed: 2})
    ia, ib = a.image.astype(np.float64), b.image.astype(np.float64)
    mean = 0.5 * (ia + ib)
    frame = _with_image(a, mean, {**a.settings, seed: "1 and 2, averaged"})
    return frame, mean, relative_rmse(mean + 0.5 * np.abs(ia - ib), mean)


def _level_image(renders: _Renders, settings: dict, q, seed, level: int) -> np.ndarray:
    """One level's image (the mean of two seeds where the technique is seeded)."""
    settings = {**settings, **q.level_settings(level)}
    if seed is None:
        return renders.frame(settings).image.astype(np.float64)
    return _two_seeds(renders, settings, seed)[1]


def _render_spp(renders: _Renders, technique: str, progress: bool, target: float, settings: dict, q,
                seed: str, budget: Budget) -> Frame:
    """The reference: two runs of independent samples, raised until the standard error of
    their mean is under SPP_MARGIN of the target, or to the most samples the budget affords
    (time taken in proportion to the samples)."""
    level, limit = max(1, q.start // 2), q.top // 2  # samples of each run
    # two runs give one difference a pixel, which runs low where a few paths carry much of
    # a pixel's variance (measured: the truth up to 1.16x the estimate on random scenes), so
    # the samples are raised until the estimate is under SPP_MARGIN of the target
    aim = SPP_MARGIN * target
    while True:
        t0 = time.perf_counter()
        frame, _, estimate = _two_seeds(renders, {**settings, q.knob: level}, seed)
        took = time.perf_counter() - t0
        if estimate <= aim or level >= limit:
            _say(progress, f"target_error: {technique} {q.knob} = {2 * level}: estimate {estimate:.3g} "
                           f"(target {target:g}), {took:.1f} s")
            break
        # the error falls as spp^-1/2: jump to the count the target needs, or the budget allows
        level_was = level
        level = min(limit, int(level * max(2.0, (estimate / aim) ** (1.0 / q.order))))
        if not budget.affords(took * level / level_was):
            level = int(level_was * BUDGET_SHARE * budget.left() / max(took, 1e-9))
            if level <= level_was:  # not even as many again: the budget is spent
                _say(progress, f"target_error: {technique} {q.knob} = {2 * level_was}: estimate {estimate:.3g} "
                               f"(target {target:g}), {took:.1f} s; stopped at max_seconds={budget.max_seconds:g}")
                level = level_was
                break
        _say(progress, f"target_error: {technique} {q.knob} = {2 * level_was}: estimate {estimate:.3g} "
                       f"(target {target:g}), {took:.1f} s; next {q.knob} = {2 * level}, about "
                       f"{took * level / level_was:.0f} s")
    frame.settings[q.knob] = 2 * level
    frame.error_estimate = estimate
    if estimate > target:
        why = f"stopped at max_seconds={budget.max_seconds:g}" if budget.stopped else "the most it may use"
        warnings.warn(f"{technique}: error estimate {estimate:.3g} above target_error {target:.3g} at {q.knob} = "
                      f"{2 * level} ({why})", RuntimeWarning, stacklevel=4)
    return frame


def _ladder(renders: _Renders, technique: str, progress: bool, target: float, settings: dict, q, seed, first: int,
            budget: Budget):
    """Double the knob from ``first`` until the error is at most ``target``: at the first level
    whose three-level extrapolation (``remaining_error``) meets it, one more level is rendered
    and the level's error measured against it (``measured_error``); or until the next level (twice
    the last one's time) would not end within the budget. Returns (frame, estimate, level, the
    whole ladder's seconds)."""
    level, images, spreads, candidate = first, [], [], None
    start = time.perf_counter()
    while True:
        t0 = time.perf_counter()
        if seed is None:
            frame = renders.frame({**settings, **q.level_settings(level)})
            images.append(frame.image.astype(np.float64))
            spreads.append(0.0)
        else:  # seeded (jitter, turned directions): each level is the mean of two seeds
            frame, mean, spread = _two_seeds(renders, {**settings, **q.level_settings(level)}, seed)
            images.append(mean)
            spreads.append(spread)
        if candidate is not None:  # the previous level met the target by extrapolation: measure it
            measured = measured_error(images[-2], images[-1], q.order, spreads[-2], spreads[-1])
            if measured <= target:
                return candidate, measured, level // 2, time.perf_counter() - start
            candidate = None
        estimate = float("inf")
        if len(images) >= 3:
            estimate = float(np.hypot(remaining_error(images, spreads, q.order), spreads[-1]))
        _say(progress, f"target_error: {technique} {q.knob} = {level}: "
                       + (f"estimate {estimate:.3g} (target {target:g})" if np.isfinite(estimate)
                          else f"{len(images)} of the 3 levels an estimate needs"))
        took = time.perf_counter() - t0
        if 2 * level > q.top or not budget.affords(2.0 * took):  # no finer level: the extrapolation stands
            if not np.isfinite(estimate) and len(images) >= 2:  # the coarser level's measured error, one doubling on
                estimate = 0.5**q.order * measured_error(images[-2], images[-1], q.order, spreads[-2], spreads[-1])
            if budget.stopped:
                _say(progress, f"target_error: {technique} {q.knob} = {level}: stopped at "
                               f"max_seconds={budget.max_seconds:g}")
            return frame, estimate, level, time.perf_counter() - start
        if estimate <= target:  # a frame of _Renders owns its image: the next level leaves it
            candidate = frame
        level *= 2


def render_auto(scene, device, progress: bool, settings: dict) -> Frame:
    """``technique="auto"``: the fastest technique whose measured error against the physical
    answer (all orders of scattering: ``model_error.json``, from results/accuracy-vs-time) on
    the families of the scene's kind of media (the worst of them) meets ``target_error``, at
    the settings that measured it; else the reference, to the target by its own noise."""
    if "frame_ms" in settings:
        if "target_error" in settings:
            raise SettingsError("auto: give target_error or frame_ms, not both (allowed: target_error, the fastest "
                                "that meets it; frame_ms, the most accurate within it)")
        return _auto_within(scene, device, progress, settings)
    if "target_error" not in settings:
        raise SettingsError("auto: give target_error (allowed: 0 < target_error < 1): the technique is chosen to meet "
                            "it; or frame_ms (> 0), the most accurate technique within that frame time")
    target = check_target(settings.pop("target_error"))
    budget = check_budget(settings.pop("max_seconds")) if "max_seconds" in settings else None
    if settings:
        raise SettingsError(f"auto: unknown setting {sorted(settings)[0]!r} (allowed: target_error; the chosen "
                            "technique's settings come with it)")
    scene = load_scene(scene)
    kinds = sorted({m.type for m in scene.media})
    table = _model_error()
    # every measured family of the scene's kind of media; per technique its worst error there
    families = [name for name, f in table["families"].items() if f["media"] == kinds]
    measured = {}
    for name in families:
        for t, m in table["families"][name]["techniques"].items():
            if all(t in table["families"][n]["techniques"] for n in families):
                old = measured.get(t)
                if old is None or m["error"] > old["error"]:
                    measured[t] = {**m, "ms": max(m["ms"], old["ms"]) if old else m["ms"], "family": name}
    family = (families[0] if len(families) == 1 else
              f"the {len(families)} families of {' and '.join(kinds)} media" if families else None)
    why = f"no technique's measured error on {family or 'this kind of media'} meets {target:g}"
    if measured:
        best = min(measured.items(), key=lambda kv: kv[1]["error"])
        why += f" (best: {best[0]} {best[1]['error']:.3g})"
    for name, m in sorted(measured.items(), key=lambda kv: kv[1]["ms"]):
        if m["error"] <= target:
            try:
                renderer = Renderer(scene, name, device, progress, one_shot=True, **m["settings"])
            except SettingsError:
                continue
            frame = renderer.render()
            worst = f" (the worst: {m['family']})" if len(families) > 1 else ""
            frame.choice = (f"{name}: measured error {m['error']:.3g} <= {target:g} on {family}{worst} in {m['ms']:.0f} ms "
                            f"({', '.join(f'{k}={v}' for k, v in m['settings'].items())}; {table['device']}, "
                            f"{table['image']})")
            return frame
    _say(progress, f"auto: {why}; the reference, to {target:g} by its own noise (its samples rise until "
                   "then: the lines below say what each level cost and what the next will)")
    frame = render_to_target(scene, "reference", device, progress, target, {}, budget)
    frame.choice = f"reference: {why}; to {target:g} by its own noise"
    return frame


def _model_error() -> dict:
    import json
    from importlib import resources

    return json.loads(resources.files("warpvol").joinpath("model_error.json").read_text())


def _auto_within(scene, device, progress: bool, settings: dict) -> Frame:
    """``technique="auto"`` with ``frame_ms``: among the points measured on every family of the
    scene's kind of media (``model_error.json``'s fronts: a technique at one set of settings), the
    one whose worst error there is lowest and whose frame time, the slowest family's scaled from
    the measured image to this one by its pixels, fits ``frame_ms``; the fastest point where none
    fits (with a warning). The times are the measuring machine's (``model_error.json``'s device)."""
    given = settings.pop("frame_ms")
    frame_ms = positive_number(given, f"auto: setting frame_ms={given!r} is out of range (allowed: a number of "
                                      "milliseconds > 0)")
    if settings:
        raise SettingsError(f"auto: unknown setting {sorted(settings)[0]!r} (allowed: frame_ms; the chosen "
                            "technique's settings come with it)")
    scene = load_scene(scene)
    table = _model_error()
    kinds = sorted({m.type for m in scene.media})
    families = [f for f in table["families"].values() if f["media"] == kinds]
    if not families:
        raise SettingsError(f"auto: no measured family of {' and '.join(kinds) or 'empty'} media to choose from "
                            f"(allowed: frame_ms with homogeneous, grid, rbf or particle media; or a technique)")
    w, h = (int(v) for v in table["image"].split("x"))
    scale = scene.camera.width * scene.camera.height / (w * h)
    points: dict = {}  # (technique, settings) -> (worst error, slowest ms) over the families
    for f in families:
        for p in f.get("front", []):
            key = (p["technique"], tuple(sorted(p["settings"].items())))
            err, ms, n = points.get(key, (0.0, 0.0, 0))
            points[key] = (max(err, p["error"]), max(ms, p["ms"] * scale), n + 1)
    whole = {k: v for k, v in points.items() if v[2] == len(families)}
    if not whole:
        raise SettingsError("auto: frame_ms needs model_error.json's fronts (python -m warpvol bench report "
                            "accuracy-vs-time writes them)")
    fits = {k: v for k, v in whole.items() if v[1] <= frame_ms}
    if fits:
        (name, key), (err, ms, _) = min(fits.items(), key=lambda kv: (kv[1][0], kv[1][1]))
    else:
        (name, key), (err, ms, _) = min(whole.items(), key=lambda kv: kv[1][1])
        warnings.warn(f"auto: no measured point fits frame_ms={frame_ms:g} at {scene.camera.width}x"
                      f"{scene.camera.height} (the fastest: {name}, about {ms:.0f} ms)", RuntimeWarning, stacklevel=3)
    chosen = dict(key)
    frame = Renderer(scene, name, device, progress, one_shot=True, **chosen).render()
    how = f"the lowest measured error within {frame_ms:g} ms" if fits else f"none fits {frame_ms:g} ms, the fastest"
    frame.choice = (f"{name}: {how}, {err:.3g} (the worst of "
                    f"{len(families)} families of {' and '.join(kinds)} media), about {ms:.0f} ms at this size "
                    f"({', '.join(f'{k}={v}' for k, v in chosen.items())}; measured on {table['device']} at "
                    f"{table['image']}, scaled by pixels)")
    return frame

