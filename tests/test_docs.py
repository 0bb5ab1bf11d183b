"""The repo's documentation is current and stands on its own: the generated pages equal what
``python -m warpvol docs`` writes, every key the scene loader reads is documented, and nothing
in the repo points outside it."""

import subprocess
from pathlib import Path

from warpvol.docs import write
from warpvol.scene import doc

ROOT = Path(__file__).resolve().parent.parent


def test_generated_docs_are_current():
    stale = write(ROOT, check=True)
    assert not stale, f"out of date (run python -m warpvol docs): {[str(p.relative_to(ROOT)) for p in stale]}"


def test_every_scene_key_has_a_meaning():
    keys = doc.recorded_keys()
    assert len(keys) > 60
    missing = [(t, v, k) for t, v, k, *_ in keys if not doc.meaning(t, v, k)]
    assert not missing, missing
    stale = [k for k in doc.MEANING if (k[0], k[1]) not in {(t, key) for t, _, key, *_ in keys}]
    assert not stale, f"MEANING names keys the loader no longer reads: {stale}"


def test_nothing_points_outside_the_repo():
    tracked = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    this = Path(__file__).relative_to(ROOT).as_posix()
    hits = []
    for name in tracked:
        path = ROOT / name
        if name == this or path.suffix not in {".py", ".md", ".toml", ".txt", ".sh", ""} or not path.is_file():
            continue
        text = path.read_text(errors="ignore")
        hits += [f"{name}: {needle}" for needle in ("../shared", "DESIGN.md", "STYLE.md", "papers/00") if needle in text]
    assert not hits, hits
