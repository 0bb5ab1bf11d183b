"""A results page knows whether it is still true: a row's probe (bench/fingerprint.py) renders
again to its stored block means (to float rounding), and a page whose probe no longer does is
listed as changed; a page without probes is unknown, not current."""

import json

import numpy as np

from warpvol.bench.fingerprint import PROBE_RTOL, changed, page_status, probe

ROW = {"scene": "fog-box 64x48", "technique": "raymarch",
       "params": {"family": "fog box", "technique": "raymarch", "steps": 8, "multiple_scattering": 0}}


def test_a_fresh_probe_holds_and_a_moved_one_does_not():
    p = probe(ROW)
    assert p["scene"] == "fog-box" and p["settings"] == {"steps": 8, "multiple_scattering": 0}
    assert changed(p) is None  # rendered again: the same to float rounding
    moved = {**p, "blocks": list(np.asarray(p["blocks"]) * (1.0 + 10 * PROBE_RTOL))}
    assert "moved" in changed(moved)
    other = {**p, "settings": {"steps": 8, "multiple_scattering": 8}}  # what the lattice changes
    assert changed({**other, "blocks": p["blocks"]}) is not None


def test_page_status(tmp_path):
    p = probe(ROW)
    page = tmp_path / "cpu.json"
    page.write_text(json.dumps({"rows": [{**ROW, "probe": p}]}))
    assert page_status(page)["status"] == "current"
    page.write_text(json.dumps({"rows": [{**ROW, "probe": {**p, "blocks": [2.0 * b for b in p["blocks"]]}}]}))
    assert page_status(page)["status"] == "changed"
    page.write_text(json.dumps({"rows": [ROW, {**ROW, "probe": p}]}))  # one row measured before probes
    assert page_status(page)["status"] == "unprobed"
    assert probe({**ROW, "scene": "no-such-scene 4x4"}) is None
    page.write_text(json.dumps({"rows": [ROW], "record": "two commits measured back to back"}))  # kept as measured
    assert page_status(page) == {"status": "record", "why": "two commits measured back to back"}
