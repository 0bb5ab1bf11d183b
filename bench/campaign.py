"""The device campaign: the test suite, a kernel census, then the sweeps, on one device, within
one time budget.

    python -m warpvol.bench.campaign --device cuda --budget 540 --out results/campaign-h200

Steps, in order, each in its own process with its own time limit (a step past its limit is
stopped and marked "did not fit"; the rows a sweep measured before that are kept):

1. ``suite``: pytest on the device (``WARPVOL_TEST_DEVICES=DEVICE``), counted from its JUnit XML;
2. ``census``: one frame of each technique on a built-in scene, every kernel launch recorded:
   launches, threads, the bytes of the arrays it is handed (each moved once: a lower bound on
   its memory traffic), its arithmetic from a per-thread model where one is written (``WORK``),
   and its time (the device synchronised around each launch);
3. ``paper``: the sweeps that reproduce a paper's table (``Sweep.paper`` set), all their rows;
4. ``quick``: every other sweep's quick rows;
5. ``reference``: the reference path tracer's speed rows.

The budget is shared out by phase (``PHASES``: the weights of what is left); within a phase a
step may take up to twice an even share of what the phase has left, so time a step leaves unused
passes to the ones after it and a slow one is stopped before it takes the rest.
Writes, under ``--out``: ``campaign.log`` (every line of every step, flushed as it comes),
``summary.json`` and ``summary.md`` (what ran, passed, failed and did not fit), ``suite.xml``,
``census.json`` and ``results/<sweep>/<device>[-quick].json`` (``python -m warpvol bench report``
writes their pages). ``--tiny``: the whole suite collected (an import that fails is found) but a
few test files run, quick rows everywhere and small frames, for a dry run on the CPU.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import threading
import time
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

#: Phases and their weights: a phase gets weight / (weights of it and the phases after it) of
#: the time left when it starts.
PHASES = {"suite": 0.40, "census": 0.05, "paper": 0.30, "quick": 0.17, "reference": 0.08}
#: A step with less than this left is not started.
MIN_STEP_S = 8.0
#: The test files of a tiny campaign (a dry run).
TINY_TESTS = ["tests/test_physics.py", "tests/test_lightpass.py", "tests/test_pipeline.py"]


def census() -> dict:
    """The census: each technique's own frame (``Technique.CENSUS``: a scene and settings, a frame
    of tens of milliseconds on a GPU). Read when run: warpvol is imported only then."""
    import warpvol as wv

    return {name: wv.technique_class(name).CENSUS for name in wv.technique_names()}


@dataclass
class Step:
    name: str
    phase: str
    argv: list[str]
    env: dict = field(default_factory=dict)
    limit_s: float = 0.0
    wall_s: float = 0.0
    status: str = "not run"  # passed | failed | did not fit | not run
    rc: int | None = None
    detail: dict = field(default_factory=dict)


class Log:
    """The campaign's log: each line stamped with the seconds since the start, written and
    flushed at once (a campaign stopped from outside keeps every line it printed)."""

    def __init__(self, path: Path):
        self.t0 = time.perf_counter()
        self.fh = open(path, "a", buffering=1, encoding="utf-8")
        self.lock = threading.Lock()

    def __call__(self, step: str, line: str) -> None:
        text = f"[{time.perf_counter() - self.t0:7.1f} s] {step}: {line.rstrip()}"
        with self.lock:
            self.fh.write(text + "\n")
            self.fh.flush()
            print(text, flush=True)


def plan(device: str, out: Path, tiny: bool, tests: list[str] | None) -> list[Step]:
    """The campaign's steps, in order."""
    from warpvol.bench.sweeps import SWEEPS

    py = [sys.executable, "-m", "warpvol.bench.campaign", "--device", device, "--out", str(out)]
    tiny_flag = ["--tiny"] if tiny else []
    suite = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={out / 'suite.xml'}",
             *(tests or (TINY_TESTS if tiny else ["tests"]))]
    steps = [Step("collect", "suite", [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--collect-only",
                                       "tests"], {"WARPVOL_TEST_DEVICES": device})] if tiny else []
    steps += [Step("suite", "suite", suite, {"WARPVOL_TEST_DEVICES": device}),
             Step("census", "census", py + ["--census"] + tiny_flag)]
    paper = [n for n, s in SWEEPS.items() if s.paper]
    others = [n for n, s in SWEEPS.items() if not s.paper and n != "reference-speed"]
    steps += [Step(n, "paper", py + ["--sweep", n] + (["--quick"] if tiny else [])) for n in paper]
    steps += [Step(n, "quick", py + ["--sweep", n, "--quick"]) for n in others]
    steps.append(Step("reference-speed", "reference", py + ["--sweep", "reference-speed"] + (["--quick"] if tiny else [])))
    return steps


def run_step(step: Step, log: Log) -> None:
    """Run ``step`` in its own process group, its output into the log line by line; stop the
    group at ``step.limit_s``."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "TQDM_DISABLE": "1", **step.env}
    t0 = time.perf_counter()
    proc = subprocess.Popen(step.argv, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, errors="replace", start_new_session=True)
    reader = threading.Thread(target=lambda: [log(step.name, line) for line in proc.stdout], daemon=True)
    reader.start()
    try:
        step.rc = proc.wait(timeout=step.limit_s)
        step.status = "passed" if step.rc == 0 else "failed"
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        step.rc, step.status = proc.returncode, "did not fit"
    reader.join(timeout=5)
    step.wall_s = round(time.perf_counter() - t0, 1)


def suite_counts(path: Path) -> dict:
    """Tests, failures, errors and skips from pytest's JUnit XML, and the failed tests' names."""
    if not path.exists():
        return {}
    root = ET.parse(path).getroot()
    suites = [root] if root.tag == "testsuite" else list(root)
    counts = {k: sum(int(s.get(k, 0)) for s in suites) for k in ("tests", "failures", "errors", "skipped")}
    failed = [f"{c.get('classname')}::{c.get('name')}" for s in suites for c in s
              if c.find("failure") is not None or c.find("error") is not None]
    counts["passed"] = counts["tests"] - counts["failures"] - counts["errors"] - counts["skipped"]
    return {**counts, "failed": failed[:50]}


def sweep_rows(out: Path, name: str) -> int:
    return sum(len(json.loads(p.read_text()).get("rows", [])) if p.suffix == ".json" else 0
               for p in (out / "results" / name).glob("*.json")) if (out / "results" / name).is_dir() else 0


def campaign(device: str, budget_s: float, out: Path, tiny: bool = False, tests: list[str] | None = None) -> list[Step]:
    out.mkdir(parents=True, exist_ok=True)
    log = Log(out / "campaign.log")
    start = time.perf_counter()
    steps = plan(device, out, tiny, tests)
    log("campaign", f"{len(steps)} steps on {device}, budget {budget_s:.0f} s, out {out}")
    phases = list(PHASES)
    for i, phase in enumerate(phases):
        todo = [s for s in steps if s.phase == phase]
        left = budget_s - (time.perf_counter() - start)
        phase_end = time.perf_counter() + left * PHASES[phase] / sum(PHASES[p] for p in phases[i:])
        for k, step in enumerate(todo):
            phase_left = phase_end - time.perf_counter()
            # at most twice an even share of what the phase has left: a slow step cannot take the rest
            step.limit_s = round(min(phase_left, max(MIN_STEP_S, 2.0 * phase_left / (len(todo) - k)),
                                     budget_s - (time.perf_counter() - start)), 1)
            if step.limit_s < MIN_STEP_S:
                step.status = "did not fit"
                log(step.name, f"not started: {max(step.limit_s, 0):.0f} s left for it")
                continue
            log(step.name, f"start (limit {step.limit_s:.0f} s): {' '.join(step.argv[1:])}")
            run_step(step, log)
            if step.name == "suite":
                step.detail = suite_counts(out / "suite.xml")
            elif step.phase in ("paper", "quick", "reference"):
                step.detail = {"rows": sweep_rows(out, step.name)}
            log(step.name, f"{step.status} in {step.wall_s:.1f} s {json.dumps(step.detail) if step.detail else ''}")
    write_summary(out, device, budget_s, time.perf_counter() - start, steps, tiny)
    log("campaign", f"done in {time.perf_counter() - start:.0f} s: " + ", ".join(
        f"{sum(s.status == k for s in steps)} {k}" for k in ("passed", "failed", "did not fit")))
    return steps


def write_summary(out: Path, device: str, budget_s: float, wall_s: float, steps: list[Step], tiny: bool) -> None:
    from warpvol.bench.harness import device_name, git_commit

    import warp as wp

    import warpvol  # noqa: F401  (Warp quiet)

    shown = out.relative_to(REPO) if out.is_relative_to(REPO) else out.name
    command = f"python -m warpvol.bench.campaign --device {device} --budget {budget_s:.0f} --out {shown}" + (" --tiny" if tiny else "")
    via = os.environ.get("WARPVOL_CAMPAIGN_VIA", "")  # the wrapper that ran it (bench/gpu-run.sh)
    summary = {"device": device, "device_name": device_name(device), "warp": wp.config.version, "commit": git_commit(),
               "command": command, "via": via, "budget_s": budget_s, "wall_s": round(wall_s, 1), "steps": [asdict(s) for s in steps]}
    for s in summary["steps"]:
        s.pop("env")
        s["argv"] = " ".join(s["argv"][1:])
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    lines = [f"# Campaign on {summary['device_name']}", "",
             f"`{command}`{f' (run by `{via}`)' if via else ''} at commit {summary['commit']}, Warp {summary['warp']}: "
             f"{wall_s:.0f} s of {budget_s:.0f}.", "",
             "| step | phase | status | s | limit s | what |", "|---|---|---|---|---|---|"]
    for s in steps:
        what = s.detail
        if s.name == "suite" and what:
            what = f"{what['passed']} passed, {what['failures'] + what['errors']} failed, {what['skipped']} skipped"
        elif "rows" in what:
            what = f"{what['rows']} rows"
        elif s.name == "census" and (out / "census.json").exists():
            what = f"{len(json.loads((out / 'census.json').read_text())['kernels'])} kernels"
        lines.append(f"| {s.name} | {s.phase} | {s.status} | {s.wall_s:.1f} | {s.limit_s:.0f} | {what or ''} |")
    failed = next((s.detail.get("failed") for s in steps if s.name == "suite" and s.detail.get("failed")), None)
    if failed:
        lines += ["", "Failed tests:", ""] + [f"- `{f}`" for f in failed]
    if (out / "census.json").exists():
        lines += ["", census_table(json.loads((out / "census.json").read_text()))]
    (out / "summary.md").write_text("\n".join(lines) + "\n")


# --- the kernel census ---------------------------------------------------------------------

def census(device: str, out: Path, tiny: bool) -> dict:
    """One frame of each technique with every launch recorded (``wp.launch`` wrapped: the device
    synchronised before and after, the arrays handed to it summed); per kernel the totals."""
    import numpy as np
    import warp as wp

    import warpvol as wv
    from warpvol import device as dev
    from warpvol.bench.harness import device_name

    device = dev.pick(device)
    records: dict[str, dict] = {}
    recording = [None]
    launch = wp.launch

    def nbytes(x) -> int:
        if isinstance(x, wp.array):
            return int(x.capacity)
        if isinstance(x, (list, tuple)):
            return sum(nbytes(y) for y in x)
        if isinstance(x, wp.Volume):
            return int(x.array().capacity)
        fields = getattr(getattr(x, "_cls", None), "vars", None)  # a wp.struct: the arrays it holds
        if fields:
            return sum(nbytes(getattr(x, name)) for name in fields)
        return 0

    def recorded(kernel, dim=0, inputs=(), outputs=(), *args, **kw):
        if recording[0] is None:
            return launch(kernel, dim, inputs, outputs, *args, **kw)
        where = kw.get("device") or device
        wp.synchronize_device(where)
        t = time.perf_counter()
        result = launch(kernel, dim, inputs, outputs, *args, **kw)
        wp.synchronize_device(where)
        seconds = time.perf_counter() - t
        threads = int(np.prod(dim)) if not isinstance(dim, int) else dim
        r = records.setdefault(f"{recording[0]}/{kernel.key}", {"technique": recording[0], "kernel": kernel.key,
                                                                "launches": 0, "threads": 0, "bytes": 0, "ms": 0.0})
        r["launches"] += 1
        r["threads"] += threads
        r["bytes"] += nbytes(list(inputs) + list(outputs or ()))
        r["ms"] += seconds * 1000.0
        return result

    wp.launch = recorded
    frames = {}
    try:
        for technique, (scene_name, settings) in census().items():
            size = ["camera.width=64", "camera.height=48"] if tiny else ["camera.width=640", "camera.height=480"]
            scene = wv.load_scene(scene_name, size)
            r = wv.Renderer(scene, technique=technique, device=device, **settings)
            r.render()  # compiles and warms up
            r.touch()
            recording[0] = technique
            t = time.perf_counter()
            r.render()
            wp.synchronize_device(device)
            frames[technique] = {"scene": scene_name, "size": size, "frame_ms": round((time.perf_counter() - t) * 1e3, 3)}
            recording[0] = None
    finally:
        wp.launch = launch
    kernels = sorted(records.values(), key=lambda r: -r["ms"])
    for r in kernels:
        r["ms"] = round(r["ms"], 3)
        r["gb_per_s"] = round(r["bytes"] / max(r["ms"], 1e-6) / 1e6, 2)
    result = {"device": device_name(device), "frames": frames, "kernels": kernels,
              "bytes_is": "the arrays, volumes and structs' arrays handed to a launch, each counted once per launch "
                          "(a lower bound on its traffic where it reads them whole)"}
    (out / "census.json").write_text(json.dumps(result, indent=1) + "\n")
    return result


def census_table(c: dict, top: int = 20) -> str:
    lines = [f"Kernel census ({c['device']}; bytes: {c['bytes_is']}), the {top} slowest:", "",
             "| technique | kernel | launches | threads | MB | ms | GB/s |", "|---|---|---|---|---|---|---|"]
    for r in c["kernels"][:top]:
        lines.append(f"| {r['technique']} | `{r['kernel']}` | {r['launches']} | {r['threads']} | "
                     f"{r['bytes'] / 1e6:.2f} | {r['ms']:.2f} | {r['gb_per_s']:.1f} |")
    return "\n".join(lines)


def one_sweep(name: str, device: str, out: Path, quick: bool) -> None:
    from warpvol.bench.harness import run_sweep
    from warpvol.bench.sweeps import SWEEPS

    command = f"python -m warpvol bench {name}{' --quick' if quick else ''} --device {device}"
    path = run_sweep(SWEEPS[name], device, out / "results", quick=quick, progress=False, command=command)
    print(f"{name}: rows in {path}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m warpvol.bench.campaign", description=__doc__.split("\n\n")[0])
    p.add_argument("--device", default="cuda", help="cpu, cuda or cuda:N (default cuda)")
    p.add_argument("--budget", type=float, default=540.0, help="seconds for the whole campaign (default 540)")
    p.add_argument("--out", type=Path, default=Path("results/campaign"), help="the folder it writes")
    p.add_argument("--tiny", action="store_true", help="a dry run: a few test files, quick rows, small frames")
    p.add_argument("--tests", nargs="+", help="the suite's test files or node ids (default: tests)")
    p.add_argument("--census", action="store_true", help=argparse.SUPPRESS)  # one step, run by the campaign
    p.add_argument("--sweep", help=argparse.SUPPRESS)
    p.add_argument("--quick", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.budget <= 0:
        p.error(f"--budget must be > 0 seconds (got {args.budget})")
    out = args.out.resolve()
    if args.census:
        census(args.device, out, args.tiny)
        return 0
    if args.sweep:
        one_sweep(args.sweep, args.device, out, args.quick)
        return 0
    steps = campaign(args.device, args.budget, out, args.tiny, args.tests)
    return 0 if all(s.status == "passed" for s in steps) else 1


if __name__ == "__main__":
    sys.exit(main())
