"""Every technique carries its own facts, and every list that names techniques names them all:
a new technique forgotten in one fails here, not silently (issue 62)."""

from pathlib import Path

import pytest

import warpvol as wv
from warpvol.scene.procedural import BUILTIN

ROOT = Path(__file__).resolve().parent.parent
NAMES = wv.technique_names()


def check_settings(name: str, settings: dict) -> None:
    """The settings exist for the technique, each within its range."""
    known = wv.technique_class(name).SETTINGS
    for key, value in settings.items():
        assert key in known, f"{name}: {key} is no setting of it"
        assert known[key].lo <= value <= known[key].hi, f"{name}: {key} = {value} outside its range"


@pytest.mark.parametrize("name", NAMES)
def test_a_technique_carries_its_facts(name):
    """Its examples (audited in tests/test_pipeline.py), its tiny fuzz case (tests/test_fuzz.py)
    and its census frame (bench/campaign.py) are the technique's attributes: built-in scenes
    and settings it has."""
    cls = wv.technique_class(name)
    assert cls.EXAMPLES and all(scene in BUILTIN for scene in cls.EXAMPLES), (name, cls.EXAMPLES)
    assert cls.TINY, name
    check_settings(name, cls.TINY)
    scene, settings = cls.CENSUS
    assert scene in BUILTIN, (name, scene)
    check_settings(name, settings)


@pytest.mark.parametrize("name", NAMES)
def test_every_list_of_techniques_names_it(name):
    """Its target-error check (bench/target_error_check.py, where it takes target_error), its
    sweeps (bench/sweeps/), its page (docs/techniques/) and its row in docs/choosing.md."""
    from warpvol.bench.sweeps import SWEEPS
    from warpvol.bench.target_error_check import CASES

    if wv.technique_class(name).QUALITY is not None:
        assert name in CASES, f"bench/target_error_check.py: no case for {name}"
    assert any(s.technique == name for s in SWEEPS.values()), f"bench/sweeps: no sweep of {name}"
    assert (ROOT / "docs" / "techniques" / f"{name}.md").exists(), f"docs/techniques/{name}.md missing"
    assert f"`{name}`" in (ROOT / "docs" / "choosing.md").read_text(), f"docs/choosing.md does not name {name}"


def test_docs_fail_on_a_missing_page(tmp_path):
    """The docs generator stops with one line naming the page a technique lacks."""
    from warpvol.docs import pages

    for sub in ("docs/techniques",):
        (tmp_path / sub).mkdir(parents=True)
    (tmp_path / "README.md").write_text((ROOT / "README.md").read_text())
    with pytest.raises(ValueError, match="docs/techniques/.*md: missing"):
        pages(tmp_path)
