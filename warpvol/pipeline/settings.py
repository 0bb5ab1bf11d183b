"""A technique's settings: each one's default, range and meaning (``Setting``), their validation
(``resolve_settings``, ``SettingsError``), and what ``target_error`` raises and measures
(``Quality``, ``Bias``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..names import did_you_mean


class SettingsError(ValueError):
    """A technique setting with an unknown name or a value out of range."""


#: The names of an on/off setting's values 0 and 1 (``names=FLAG``): ``warm="off"``, ``--set warm=on``,
#: and from Python ``False`` / ``True`` too.
FLAG = ("off", "on")


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
        if isinstance(value, bool) and s.names == FLAG:
            value = int(value)
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
