"""The results overview (``results/README.md``), written from a template whose every figure is
read from the data of the page it cites.

    python -m warpvol bench report --overview

The template (``bench/overview.md``) is prose with placeholders::

    {{light-shafts-accuracy; steps=16 block=1 shadow_map_res=256; rel_rmse_corrected; .3f}}

that is: the page (a folder of ``results/``, optionally ``/file.json``; default its one JSON file
other than ``*-quick.json``), the row (``key=value`` pairs matched against the row's fields and
its ``params``, quoted where a value has spaces, ``key=null`` for a field the row lacks; empty
for a file that has no rows; ``.`` for the file's own fields beside its rows), the field
(dotted: ``stages.multiple.median_ms``, ``spread_ms.0``; a number, or a figure the page holds as
text such as ``+21.8%``, format ``s``) and a Python format spec. A placeholder
may divide two figures of the same page: ``{{page; row; field; .2f; / row; field}}``.

Checked as it is written, so the overview cannot drift from its pages:

* a row selector must match exactly one row;
* a paragraph that holds a page's figure links that page (``](page/``);
* outside code (backticks, fences) the template holds no decimal figure of its own: a number
  with a decimal point is a placeholder, or it is a setting and written as code.

The overview ends with a table of every page: the machine, commit and date it was measured on,
and whether its probes still render as they did then (``results/stale.json``, written by
``bench report --stale``: ``bench/fingerprint.py``).
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

TEMPLATE = Path(__file__).resolve().parent / "overview.md"
PLACEHOLDER = re.compile(r"\{\{(.+?)\}\}", re.S)
#: A decimal figure written by hand: digits, a point, digits (not inside code or a link's target).
DECIMAL = re.compile(r"(?<![\w.])\d+\.\d+")
STALE_FILE = "stale.json"  # bench report --stale's verdicts (bench/fingerprint.py), read for the table
HEADER = ("<!-- Written by `python -m warpvol bench report --overview` from bench/overview.md and the pages' data; "
          "edit the template, not this file. -->")


class OverviewError(ValueError):
    """A placeholder that cannot be read, or a template that breaks the overview's rules."""


def _value(text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def _page_file(results: Path, page: str) -> Path:
    path = results / page
    if path.suffix == ".json":
        if not path.exists():
            raise OverviewError(f"{page}: no such file under {results}")
        return path
    files = sorted(p for p in path.glob("*.json") if not p.name.endswith("-quick.json"))
    if len(files) != 1:
        found = ", ".join(p.name for p in files) or "none"
        raise OverviewError(f"{page}: name the JSON file (page/file.json); found {found}")
    return files[0]


def _matches(row: dict, want: dict) -> bool:
    view = {**row, **(row.get("params") or {})}
    for key, value in want.items():
        have = view.get(key, _MISSING)
        if value is None:  # key=null: the row has no such field (or it is null)
            if have is not _MISSING and have is not None:
                return False
        elif isinstance(value, float) and isinstance(have, (int, float)):
            if abs(have - value) > 1e-9 * max(1.0, abs(value)):
                return False
        elif have != value:
            return False
    return True


_MISSING = object()


def _select(doc, page: str, selector: str):
    if selector.strip() == ".":  # the file's own fields, beside its rows
        return doc
    want = {}
    for token in shlex.split(selector):
        key, eq, value = token.partition("=")
        if not eq:
            raise OverviewError(f"{page}: row selector {token!r} is not key=value")
        want[key] = _value(value)
    if not isinstance(doc, dict) or "rows" not in doc:
        if want:
            raise OverviewError(f"{page}: has no rows to select {selector!r} from")
        return doc
    rows = [r for r in doc["rows"] if _matches(r, want)]
    if len(rows) != 1:
        raise OverviewError(f"{page}: row {selector!r} matches {len(rows)} rows (need exactly one)")
    return rows[0]


def _field(node, page: str, path: str):
    for part in path.split("."):
        try:
            node = node[int(part)] if isinstance(node, list) else node[part]
        except (KeyError, IndexError, ValueError, TypeError):
            raise OverviewError(f"{page}: no field {path!r}") from None
    if not isinstance(node, (int, float, str)) or isinstance(node, bool):
        raise OverviewError(f"{page}: field {path!r} is {node!r}, not a number or a page's text")
    return node


def figure(results: Path, spec: str, cache: dict) -> tuple[str, str]:
    """The text of one placeholder and the page it reads."""
    parts = [p.strip() for p in spec.split(";")]
    if len(parts) not in (4, 6):
        raise OverviewError(f"placeholder {{{{{spec}}}}}: need page; row; field; format[; / row; field]")
    page = parts[0]
    path = _page_file(results, page)
    if path not in cache:
        cache[path] = json.loads(path.read_text())
    value = _field(_select(cache[path], page, parts[1]), page, parts[2])
    if len(parts) == 6:
        if not parts[4].startswith("/"):
            raise OverviewError(f"placeholder {{{{{spec}}}}}: the fifth part starts with '/'")
        below = _field(_select(cache[path], page, parts[4][1:].strip()), page, parts[5])
        if isinstance(value, str) or isinstance(below, str):
            raise OverviewError(f"{page}: divides text ({parts[2]} / {parts[5]})")
        if below == 0:
            raise OverviewError(f"{page}: divides by {parts[5]} = 0")
        value = value / below
    try:
        text = format(value, parts[3])
    except ValueError:
        raise OverviewError(f"{page}: format {parts[3]!r} does not fit {value!r}") from None
    return text, page.split("/")[0]


def _paragraphs(text: str) -> list[str]:
    return re.split(r"\n\s*\n", text)


def _prose(paragraph: str) -> str:
    """A line without its code spans and link targets."""
    text = re.sub(r"`[^`]*`", " ", paragraph)
    return re.sub(r"\]\([^)]*\)", "]", text)


def check_template(text: str) -> None:
    """The template's own rules: no hand-written decimal figure outside code."""
    text = PLACEHOLDER.sub(lambda m: " " + "\n" * m.group(0).count("\n"), text)
    fenced = False
    for number, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced or line.lstrip().startswith("<!--"):
            continue
        found = DECIMAL.findall(_prose(line))
        if found:
            raise OverviewError(f"{TEMPLATE.name}:{number}: the figure {found[0]} is written by hand "
                                f"(read it from a page with a placeholder, or write a setting as code)")


def _machine(meta: dict) -> str:
    m = meta.get("device") or meta.get("machine") or "–"
    if isinstance(m, dict):  # a tool's own record of the machine
        m = ", ".join(str(m[k]) + (" cores" if k == "cores" else "") for k in ("cpu", "cores") if k in m) or "–"
    return str(m)


def _day(measured) -> str:
    text = str(measured or "–")
    return text if len(text) <= 10 or "…" in text else text[:10]


def _still_true(status: dict | None) -> str:
    if status is None:
        return "not checked"
    return {"current": "yes", "changed": "**no**: the images have changed since", "unprobed": "unknown",
            "record": "a record"}[status["status"]] + (f" ({status['why']})" if status["status"] != "current" else "")


def page_files(results: Path) -> list[tuple[str, Path]]:
    """Every page's data: (key, path) per JSON file of a folder of ``results`` that has a README
    (``*-quick.json`` left out), the key the folder's name, or folder/file for a second JSON."""
    out = []
    for folder in sorted(p for p in Path(results).iterdir() if p.is_dir() and (p / "README.md").exists()):
        for path in sorted(p for p in folder.glob("*.json") if not p.name.endswith("-quick.json")):
            out.append((folder.name if path.name == "cpu.json" else f"{folder.name}/{path.name}", path))
    return out


def pages_table(results: Path) -> list[str]:
    """Every page: where and when its data was measured."""
    status = json.loads((results / STALE_FILE).read_text()) if (results / STALE_FILE).exists() else {}
    lines = ["| page | measured on | commit | date | still true (`bench report --stale`) |", "|---|---|---|---|---|"]
    for key, path in page_files(results):
        doc = json.loads(path.read_text())
        rows = (doc.get("rows") or [{}]) if isinstance(doc, dict) else [{}]
        meta = {**rows[0], **{k: v for k, v in doc.items() if k != "rows"}} if isinstance(doc, dict) else {}
        if not any(k in meta for k in ("device", "commit")):
            continue
        dated = sorted((str(r.get("measured", "")), str(r.get("commit", ""))) for r in rows if r.get("commit"))
        if len({c for _, c in dated}) > 1:  # rows measured at several commits: the first and the last
            meta["commit"] = f"{dated[0][1]} … {dated[-1][1]}"
            days = dict.fromkeys((dated[0][0][:10], dated[-1][0][:10]))
            meta["measured"] = " … ".join(days)
        folder = path.parent.name
        link = f"[{folder}]({folder}/README.md)" + (f" ({path.name})" if path.name != "cpu.json" else "")
        lines.append(f"| {link} | {_machine(meta)} | {meta.get('commit', '–')} | "
                     f"{_day(meta.get('measured'))} | {_still_true(status.get(key))} |")
    return lines


def render(results: Path, template: str | None = None) -> str:
    """The overview's text, from ``template`` (default ``bench/overview.md``) and ``results``."""
    results = Path(results)
    text = TEMPLATE.read_text() if template is None else template
    check_template(text)
    cache: dict = {}
    out = []
    for paragraph in _paragraphs(text):
        pages: set[str] = set()

        def fill(match, pages=pages):
            value, page = figure(results, match.group(1), cache)
            pages.add(page)
            return value

        filled = PLACEHOLDER.sub(fill, paragraph)
        for page in sorted(pages):
            if f"]({page}/" not in paragraph:
                first = paragraph.strip().splitlines()[0][:60]
                raise OverviewError(f"a paragraph reads {page} but does not link it ([{page}/]({page}/README.md)): "
                                    f"{first!r}")
        out.append(filled)
    body = "\n\n".join(out).rstrip("\n")
    return "\n".join([HEADER, "", body, "", "## Where each page was measured", "", *pages_table(results), ""])


def write(results: Path) -> Path:
    path = Path(results) / "README.md"
    path.write_text(render(results))
    return path
