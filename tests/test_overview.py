"""The results overview is written from its pages' data: results/README.md is what
`python -m warpvol bench report --overview` writes, and the writer refuses a figure that is not
read from a page, a row it cannot find, and a paragraph that does not link the page it reads."""

import json
from pathlib import Path

import pytest

from warpvol.bench.overview import OverviewError, render

RESULTS = Path(__file__).resolve().parent.parent / "results"


def test_results_readme_is_what_the_command_writes():
    assert (RESULTS / "README.md").read_text() == render(RESULTS), (
        "results/README.md differs from its template and the pages' data: "
        "run `python -m warpvol bench report --overview`")


@pytest.fixture
def pages(tmp_path):
    rows = [{"params": {"steps": 8, "family": "fog box"}, "median_ms": 12.5, "rel_rmse": 0.25,
             "device": "test machine", "commit": "abc1234", "measured": "2026-12-05 10:00:00"},
            {"params": {"steps": 32, "family": "fog box"}, "median_ms": 50.0, "rel_rmse": 0.125, "window": 70},
            {"params": {"steps": 32, "family": "fog box", "window": 16}, "median_ms": 60.0, "rel_rmse": 0.5,
             "table": {"gain": "+21.8%"}}]
    (tmp_path / "ladder").mkdir()
    (tmp_path / "ladder" / "cpu.json").write_text(json.dumps({"sweep": "ladder", "rows": rows}))
    (tmp_path / "ladder" / "README.md").write_text("# ladder\n")
    (tmp_path / "single").mkdir()
    (tmp_path / "single" / "data.json").write_text(json.dumps({"commit": "def5678", "overhead_ms": 3.5}))
    return tmp_path


def test_placeholders_read_rows_fields_and_ratios(pages):
    text = render(pages, "[`ladder/`](ladder/README.md): "
                         "{{ladder; steps=8 family=\"fog box\"; rel_rmse; .3f}} in "
                         "{{ladder; steps=32 window=70; median_ms; .0f}} ms, "
                         "{{ladder; steps=32 window=16; median_ms; .2f; / steps=8; median_ms}}x, "
                         "{{ladder; window=16; table.gain; s}}; "
                         "[`single/`](single/README.md) {{single; ; overhead_ms; .1f}} ms, "
                         "{{ladder; .; sweep; s}}\n")
    assert "0.250 in 50 ms, 4.80x, +21.8%" in text
    assert "3.5 ms, ladder" in text  # "." selects the file's own fields beside its rows
    assert "| [ladder](ladder/README.md) | test machine | abc1234 | 2026-12-05 |" in text


@pytest.mark.parametrize("template, message", [
    ("[`ladder/`](ladder/README.md) is 0.25 off\n", "written by hand"),
    ("[`ladder/`](ladder/README.md) {{ladder; steps=64; rel_rmse; .3f}}\n", "matches 0 rows"),
    ("[`ladder/`](ladder/README.md) {{ladder; steps=32; rel_rmse; .3f}}\n", "matches 2 rows"),
    ("[`ladder/`](ladder/README.md) {{ladder; steps=8; spread; .3f}}\n", "no field"),
    ("the ladder: {{ladder; steps=8; rel_rmse; .3f}}\n", "does not link it"),
    ("[`ladder/`](ladder/README.md) {{ladder; steps=8; rel_rmse}}\n", "need page; row; field; format"),
])
def test_the_writer_refuses_what_would_drift(pages, template, message):
    with pytest.raises(OverviewError, match=message):
        render(pages, template)


def test_settings_and_code_may_hold_decimals(pages):
    text = render(pages, "A setting `g = 0.6`, and code:\n\n```toml\nsigma_t = 12.0\n```\n")
    assert "`g = 0.6`" in text and "sigma_t = 12.0" in text
