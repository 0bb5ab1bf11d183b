"""The wheel holds one top-level package, warpvol: every package folder is listed in
pyproject.toml, bench/ and viz/ under their installed names warpvol.bench and warpvol.viz."""

import os
import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = os.path.join(os.path.dirname(__file__), "..")
INSTALLED_AS = {"warpvol": "warpvol", "bench": "warpvol.bench", "viz": "warpvol.viz"}


def test_every_package_folder_is_installed_under_warpvol():
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as fh:
        setuptools = tomllib.load(fh)["tool"]["setuptools"]
    found = set()
    for top, name in INSTALLED_AS.items():
        for folder, dirs, files in os.walk(os.path.join(ROOT, top)):
            dirs[:] = [d for d in dirs if d != "__pycache__"]
            if "__init__.py" in files:
                rel = os.path.relpath(folder, os.path.join(ROOT, top))
                found.add(name if rel == "." else f"{name}.{rel.replace(os.sep, '.')}")
    assert set(setuptools["packages"]) == found
    assert {p.split(".")[0] for p in setuptools["packages"]} == {"warpvol"}
    assert setuptools["package-dir"] == {v: k for k, v in INSTALLED_AS.items()}


def test_bench_and_viz_import_as_warpvol_subpackages():
    import importlib.util

    import warpvol.bench.sweeps

    assert warpvol.bench.sweeps.SWEEPS
    assert importlib.util.find_spec("warpvol.viz") is not None
