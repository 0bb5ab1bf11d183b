"""warpvol's benchmark harness: named sweeps (``sweeps``), the runner that measures and
resumes them (``harness``) and the reports generated from their JSON (``report``).

    python -m warpvol bench --list
    python -m warpvol bench raymarch-accuracy [--quick] [--device cpu] [--out results]
    python -m warpvol bench report [SWEEP ...]

pytest-benchmark suites for the hot kernels sit beside them: ``pytest bench/ --benchmark-only``.
Uses only warpvol's public API.
"""
