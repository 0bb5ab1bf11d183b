"""The GPU campaign's own machinery, on the CPU and without rendering: steps in order, a step
past its limit stopped and reported while the next still runs, the log written line by line,
and the suite's counts read from pytest's JUnit XML."""

import json
import sys

from warpvol.bench import campaign


def test_the_plan_runs_the_suite_then_the_census_then_paper_quick_and_reference_rows(tmp_path):
    from warpvol.bench.sweeps import SWEEPS

    steps = campaign.plan("cpu", tmp_path, tiny=False, tests=None)
    phases = [s.phase for s in steps]
    assert phases == sorted(phases, key=list(campaign.PHASES).index)  # phase by phase, in PHASES' order
    assert [s.name for s in steps[:2]] == ["suite", "census"] and steps[-1].name == "reference-speed"
    assert {s.name for s in steps if s.phase in ("paper", "quick", "reference")} == set(SWEEPS)
    assert all(("--quick" in s.argv) == (s.phase == "quick") for s in steps if s.phase != "suite")
    assert steps[0].env == {"WARPVOL_TEST_DEVICES": "cpu"}


def test_a_step_past_its_limit_is_stopped_and_the_next_still_runs(tmp_path, monkeypatch):
    slow = campaign.Step("slow", "paper", [sys.executable, "-c", "import time; print('started', flush=True); time.sleep(60)"])
    quick = campaign.Step("quick", "quick", [sys.executable, "-c", "print('done')"])
    monkeypatch.setattr(campaign, "plan", lambda *a: [slow, quick])
    monkeypatch.setattr(campaign, "PHASES", {"paper": 0.5, "quick": 0.5})
    monkeypatch.setattr(campaign, "MIN_STEP_S", 1.0)
    steps = campaign.campaign("cpu", 6.0, tmp_path)
    assert [s.status for s in steps] == ["did not fit", "passed"]
    assert slow.wall_s < 10.0 and slow.limit_s <= 3.0 + 1e-9  # stopped at its phase's share, not at 60 s
    log = (tmp_path / "campaign.log").read_text()
    assert "slow: started" in log and "quick: done" in log
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert [s["status"] for s in summary["steps"]] == ["did not fit", "passed"]
    assert "| slow | paper | did not fit |" in (tmp_path / "summary.md").read_text()


def test_suite_counts_from_junit_xml(tmp_path):
    (tmp_path / "suite.xml").write_text(
        '<testsuites><testsuite tests="4" failures="1" errors="0" skipped="1">'
        '<testcase classname="tests.a" name="t1"/><testcase classname="tests.a" name="t2"><failure/></testcase>'
        '<testcase classname="tests.b" name="t3"><skipped/></testcase><testcase classname="tests.b" name="t4"/>'
        '</testsuite></testsuites>')
    c = campaign.suite_counts(tmp_path / "suite.xml")
    assert (c["passed"], c["failures"], c["skipped"], c["failed"]) == (2, 1, 1, ["tests.a::t2"])
