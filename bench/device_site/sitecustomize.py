"""Run warpvol from a checkout that is not installed (bench/gpu-run.sh puts this folder on
PYTHONPATH): the folders bench/ and viz/ import as warpvol.bench and warpvol.viz, as an install
maps them (pyproject.toml's package-dir)."""

import importlib.util
import sys
from pathlib import Path

_REPO = Path(__file__).resolve().parents[2]
_MAP = {"warpvol.bench": _REPO / "bench", "warpvol.viz": _REPO / "viz"}


class _CheckoutFinder:
    @staticmethod
    def find_spec(name, path=None, target=None):
        for package, folder in _MAP.items():
            if name == package or name.startswith(package + "."):
                rel = name[len(package):].lstrip(".").split(".") if name != package else []
                base = folder.joinpath(*rel)
                if (base / "__init__.py").exists():
                    return importlib.util.spec_from_file_location(name, base / "__init__.py",
                                                                  submodule_search_locations=[str(base)])
                if base.with_suffix(".py").exists():
                    return importlib.util.spec_from_file_location(name, base.with_suffix(".py"))
        return None


sys.meta_path.append(_CheckoutFinder())
sys.path.insert(0, str(_REPO))
