"""The generated parts of docs/: the scene format (``warpvol.scene.doc``), and in each
technique's page and in README the tables that come from the code (its settings, and what
``target_error`` does with each of them). ``python -m warpvol docs`` writes them;
``python -m warpvol docs --check`` (and tests/test_docs.py) fails where a checked-in page
differs from what it would write.

A generated block in a hand-written page sits between ``<!-- generated: NAME -->`` and
``<!-- end generated -->``; the text around it is kept.
"""

from __future__ import annotations

import re
from pathlib import Path

from .api import technique_class, technique_names
from .scene import doc as scene_doc

BEGIN, END = "<!-- generated: {} -->", "<!-- end generated -->"


def _number(v) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, int) and v >= 1 << 16 and (v & (v - 1)) == 0:
        return f"2^{v.bit_length() - 1}"
    return str(v)


def settings_table(name: str) -> str:
    """A technique's settings: name, default, range, meaning (units in the meaning)."""
    cls = technique_class(name)
    lines = ["| setting | default | range | meaning |", "|---|---|---|---|"]
    for key, s in cls.SETTINGS.items():
        span = ", ".join(f"{v} `{n}`" for n, v in s.choices().items()) if s.names else \
            f"{_number(s.lo)} .. {_number(s.hi)}"
        lines.append(f"| `{key}` | {_number(s.default)} | {span} | "
                     f"{s.doc.replace('|', '&#124;')} |")
    return "\n".join(lines)


def quality_row(name: str) -> tuple[str, str, str]:
    """(ladder, measured biases, held) of a technique's ``Quality``, as text."""
    cls = technique_class(name)
    q = cls.QUALITY
    ladder = f"`{q.knob}` {q.start} -> {q.top} (doubling, error ~ {q.knob}^-{q.order:g})"
    if q.tied:
        ladder += "; with it " + ", ".join(f"`{k}` = {f:g} x {q.knob}" for k, f in q.tied.items())
    biases = []
    for b in q.biases:
        limit = f"= {b.exact}" if b.exact is not None else f"x {b.factor} (order {b.order:g})"
        when = {"sky": " with a sky", "multiple": " with the term on", "rbf": " with an RBF medium",
                "heterogeneous": " with a medium not homogeneous"}
        biases.append(f"`{b.setting}` {limit}" + when.get(b.when, ""))
    held = ", ".join(f"`{k}` = {v}" for k, v in getattr(cls, "QUALITY_HOLD", {}).items())
    seed = getattr(cls, "QUALITY_SEED", None)
    if seed:
        held = ", ".join(x for x in (held, f"each level the mean of two `{seed}`s") if x)
    return ladder, ", ".join(biases) or "none", held or "–"


def target_error_table() -> str:
    """Per technique: what target_error raises, which biases it measures and at what limit."""
    lines = ["| technique | ladder (raised together) | biases measured at the level found (limit) | held |",
             "|---|---|---|---|"]
    for name in technique_names():
        if getattr(technique_class(name), "QUALITY", None) is not None:
            lines.append(f"| {name} | " + " | ".join(quality_row(name)) + " |")
    return "\n".join(lines)


def technique_block(name: str) -> str:
    """A technique page's generated part: its module's docstring (what is implemented and
    where it departs from its paper), its settings and what target_error does with them."""
    import inspect
    import sys

    ladder, biases, held = quality_row(name)
    module = sys.modules[technique_class(name).__module__]
    return "\n".join(["## Implementation", "", "From the module's docstring (`" + module.__name__ + "`):", "",
                      "```text", inspect.cleandoc(module.__doc__ or ""), "```", "",
                      "## Settings", "", settings_table(name), "", "## target_error", "",
                      f"- ladder: {ladder}", f"- biases measured at the level found, then taken to their limit "
                      f"where they are the larger part: {biases}", f"- held: {held}",
                      f"- leaves out (against the physical answer): {leaves_out_text(name)}"])


def leaves_out_text(name: str) -> str:
    """What a technique's model leaves out, as its page says it."""
    cls = technique_class(name)
    out = list(cls.LEAVES_OUT)
    if "multiple_scattering" in cls.SETTINGS:
        out.append("multiple scattering where `multiple_scattering` = 0 (the paper's model); with the lattice "
                   "(the default) it and the surfaces' indirect light are approximated, not left out "
                   "([multiple-scattering.md](../multiple-scattering.md))")
    return ", ".join(out) or "nothing"


def _fill(text: str, name: str, body: str) -> str:
    begin = BEGIN.format(name)
    pattern = re.compile(re.escape(begin) + r"\n.*?" + re.escape(END), re.S)
    if not pattern.search(text):
        raise ValueError(f"no block {begin} ... {END}")
    return pattern.sub(lambda _: f"{begin}\n{body}\n{END}", text)


def pages(root: Path) -> dict[Path, str]:
    """Every generated page or page with generated blocks under ``root`` (the repo), with the
    text it should have."""
    out = {root / "docs" / "scene-format.md": scene_doc.page()}
    for name in technique_names():
        path = root / "docs" / "techniques" / f"{name}.md"
        if not path.exists():
            raise ValueError(f"{path.relative_to(root)}: missing: every technique has its page (its model, what it "
                             f"leaves out, and a block {BEGIN.format('settings')} ... {END} for its settings)")
        out[path] = _fill(path.read_text(), "settings", technique_block(name))
    readme = root / "README.md"
    out[readme] = _fill(readme.read_text(), "target-error", target_error_table())
    return out


def write(root: Path, check: bool = False) -> list[Path]:
    """Write the pages (or, with ``check``, only compare); returns those that differed."""
    stale = []
    for path, text in pages(root).items():
        if not path.exists() or path.read_text() != text:
            stale.append(path)
            if not check:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(text)
    return stale
