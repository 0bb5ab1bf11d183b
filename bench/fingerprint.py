"""Whether a results page is still true: each row carries a probe, a tiny render of its scene with
its technique and settings made when the row was measured, and ``bench report --stale`` renders
the probes again and lists the pages whose images have changed since.

A probe is the row's scene (a built-in, or a file under ``scenes/``, named by the row's
``scene``; or the scene table a sweep built it from, ``scene_table``, kept in the probe) at PROBE_SIZE, rendered on the CPU with the row's technique and the settings its
parameters name (the reference at PROBE_SPP samples, seeded: deterministic), kept as the image's
means over PROBE_BLOCKS blocks. A refactor leaves them to float rounding; a change of what a row
measures moves them. The tolerance, PROBE_RTOL of the image's mean, is far above rounding (1e-6)
and far below what a change of model or default does (a percent and more).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import warpvol as wv
from warpvol.scene import BUILTIN

from .overview import STALE_FILE, page_files

PROBE_SIZE = (16, 12)
PROBE_BLOCKS = (3, 4)  # rows x columns of the block means kept
PROBE_SPP = 2
PROBE_RTOL = 1e-3
#: Rows re-rendered per technique and scene of a page by ``stale`` (the first ones): a change of
#: a technique's code shows in most rows of it, a change for one kind of medium in that scene's.
CHECK_PER_TECHNIQUE = 2
SCENES = Path(__file__).resolve().parent.parent / "scenes"


def _scene_source(row: dict):
    """What a probe loads: the row's scene table (a dict, as ``wv.load_scene`` takes it), or the
    built-in or ``scenes/`` file its ``scene`` names; None for neither."""
    if isinstance(row.get("scene_table"), dict):
        return row["scene_table"]
    name = str(row.get("scene", "")).split(" ")[0].rstrip(",")
    if name in BUILTIN:
        return name
    path = SCENES / f"{name}.toml"
    return str(path) if name and path.exists() else None


#: The largest scene table a probe keeps (JSON characters): a generated cloud's generator, not a grid's samples.
TABLE_LIMIT = 20000


def _keepable(table: dict) -> bool:
    """Whether a scene table can be kept with a row: plain JSON (no arrays) of at most TABLE_LIMIT characters."""
    try:
        return len(json.dumps(table)) <= TABLE_LIMIT
    except TypeError:
        return False


def probe_spec(row: dict) -> dict | None:
    """What a row's probe renders: scene, technique and settings; None where the row names no
    scene a probe can load, or no technique."""
    source = _scene_source(row)
    params = row.get("params") or {}
    technique = params.get("technique", row.get("technique"))
    if source is None or technique not in wv.technique_names():
        return None
    known = wv.technique_class(technique).SETTINGS
    settings = {k: v for k, v in params.items() if k in known and k != "spp"}
    if technique == "reference":
        settings["spp"] = PROBE_SPP
    return {"scene": source, "technique": technique, "settings": settings}


def probe_image(spec: dict) -> list[float]:
    """The probe's block means (PROBE_BLOCKS, RGB averaged), rounded to 6 significant digits."""
    w, h = PROBE_SIZE
    scene = wv.load_scene(spec["scene"], [f"camera.width={w}", f"camera.height={h}"])
    image = wv.render(scene, technique=spec["technique"], device="cpu", **spec["settings"]).image
    lum = np.asarray(image, np.float64).mean(axis=2)
    by, bx = PROBE_BLOCKS
    blocks = lum.reshape(by, h // by, bx, w // bx).mean(axis=(1, 3))
    return [float(f"{v:.6g}") for v in blocks.ravel()]


def probe(row: dict, scene_table: dict | None = None) -> dict | None:
    """The probe to store with a freshly measured row (None where it has none or it fails);
    ``scene_table``: the table the row's scene was built from, where it names no file."""
    if scene_table is not None and not _keepable(scene_table):
        return None
    spec = probe_spec({**row, "scene_table": scene_table} if scene_table is not None else row)
    if spec is None:
        return None
    try:
        return {**spec, "blocks": probe_image(spec)}
    except Exception:  # noqa: BLE001 -- a probe is optional: a setting the scene refuses, no CPU compiler
        return None


def changed(stored: dict) -> str | None:
    """Why a stored probe no longer holds (None: it does)."""
    try:
        now = probe_image(stored)
    except (ValueError, wv.SettingsError) as exc:
        return f"no longer renders: {exc}"
    was = np.asarray(stored["blocks"], np.float64)
    scale = max(float(np.abs(was).mean()), 1e-12)
    moved = float(np.abs(np.asarray(now) - was).max()) / scale
    return f"its probe moved by {moved:.2g} of its mean" if moved > PROBE_RTOL else None


def _scene_name(source) -> str:
    return source.get("name", "a scene table") if isinstance(source, dict) else Path(source).stem


def page_status(path: Path) -> dict:
    """``{"status": "current" | "changed" | "unprobed" | "record", "why": ...}`` for one page's JSON.
    A record (its ``record`` says of what) is kept as of its commit on purpose: one side of a
    comparison of two commits measured back to back (re-running it alone would break the
    comparison), or a baseline that later pages are read against; it is not probed."""
    doc = json.loads(Path(path).read_text())
    if isinstance(doc, dict) and doc.get("record"):
        return {"status": "record", "why": str(doc["record"])}
    rows = doc.get("rows") if isinstance(doc, dict) else None
    if not rows:
        return {"status": "unprobed", "why": "no rows"}
    before = sum("probe" not in r for r in rows)  # a row whose scene takes no probe holds None
    if before:
        return {"status": "unprobed", "why": f"{before} of {len(rows)} rows measured before rows carried probes"}
    probed = [r for r in rows if r["probe"]]
    if not probed:
        return {"status": "unprobed", "why": "no row names a scene a probe can render"}
    per: dict[tuple, int] = {}
    for r in probed:
        t = r["probe"]["technique"]
        key = (t, json.dumps(r["probe"]["scene"], sort_keys=True))
        if per.get(key, 0) >= CHECK_PER_TECHNIQUE:
            continue
        per[key] = per.get(key, 0) + 1
        why = changed(r["probe"])
        if why:
            return {"status": "changed", "why": f"{t} on {_scene_name(r['probe']['scene'])}: {why}",
                    "commit": r.get("commit")}
    unprobed = len(rows) - len(probed)
    note = f"; {unprobed} rows whose scene takes no probe" if unprobed else ""
    return {"status": "current", "why": f"{sum(per.values())} probes as measured{note}"}


def stale(results: Path, progress: bool = True) -> dict:
    """Every page's status (``page_status``), by page (folder, or folder/file for a second JSON),
    written to ``results/stale.json`` for the overview."""
    from tqdm import tqdm

    results = Path(results)
    out = {}
    for key, path in tqdm(page_files(results), desc="stale", unit="page", disable=not progress):
        out[key] = page_status(path)
    (results / STALE_FILE).write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    return out
