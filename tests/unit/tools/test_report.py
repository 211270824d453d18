"""tools.evidence.report: the README's and the docs' generated tables agree with their committed data."""
from __future__ import annotations

import json
import shutil

import pytest

from tools.evidence import report


def test_committed_tables_match_their_data():
    """Every ``<!-- report:NAME -->`` block of the documents is what its docs/data/*.json
    renders today (run ``python -m tools.evidence.report write`` after importing a new run)."""
    blocks = []
    for doc in report.DOCUMENTS:
        path = report.ROOT / doc
        if path.exists():
            blocks += [m.group("name") for m in report._BLOCK.finditer(path.read_text())]
    assert {"hil_steps", "hil_steps_paper_gains", "mc_paper", "mc_paper_gains", "mc_cruise",
            "mc_cruise_b", "mc_surfaces", "beta0_dip", "hil_prefilter",
            "eq14_mirror_claim"} <= set(blocks), blocks
    assert report.check() == []


def test_a_table_that_disagrees_with_its_data_is_reported(tmp_path):
    """GIVEN a copy of the documents and data; WHEN one source figure changes (or a table is
    edited by hand); THEN check names that table, and write repairs it."""
    for doc in report.DOCUMENTS:
        src = report.ROOT / doc
        if src.exists():
            (tmp_path / doc).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, tmp_path / doc)
    shutil.copytree(report.ROOT / report.DATA_DIR, tmp_path / report.DATA_DIR)
    assert report.check(tmp_path) == []
    # each run's data renders its own table (the paper's fixed gains' run included)
    for name, variant, channel, metric, table in (
            ("hil_paper", "coordinated", "alpha", "overshoot_pct", "hil_steps"),
            ("hil_paper_gains", "uncoordinated", "mu", "settling_time_s",
             "hil_steps_paper_gains"),
            ("hil_prefilter", "coordinated", "beta", "overshoot_pct", "hil_prefilter"),
            ("hil_paper_gains_eq14_mirror", "coordinated", "mu", "overshoot_pct",
             "eq14_mirror_claim")):
        data = tmp_path / report.DATA_DIR / f"{name}.json"
        d = json.loads(data.read_text())
        d["summary"]["runs"][variant][channel][metric] += 1.0
        data.write_text(json.dumps(d))
        assert report.check(tmp_path) == [f"README.md: {table}"]
        report.write(tmp_path)
        assert report.check(tmp_path) == []
    # each campaign's data renders its own table: the default law's, the fixed gains' (and the
    # surfaces' table drawn from it) and the cruise point's two
    for name, tables in (("mc_paper", {"mc_paper"}),
                         ("mc_paper_gains", {"mc_paper_gains", "mc_surfaces"}),
                         ("mc_cruise", {"mc_cruise"}), ("mc_cruise_b", {"mc_cruise_b"})):
        data = tmp_path / report.DATA_DIR / f"{name}.json"
        d = json.loads(data.read_text())
        d["summary"]["variants"]["uncoordinated"]["meets_spec"] += 1
        d["summary"]["variants"]["uncoordinated"]["surfaces"]["peak_rudder_deg"]["p50"] += 1.0
        data.write_text(json.dumps(d))
        assert {c.split(": ")[1] for c in report.check(tmp_path)} == tables, name
        report.write(tmp_path)
        assert report.check(tmp_path) == []
    readme = tmp_path / "README.md"
    readme.write_text(readme.read_text().replace("| diverged | 0 |", "| diverged | 1 |", 1))
    assert report.check(tmp_path) == ["README.md: mc_paper"]


def test_unknown_block_is_an_error():
    with pytest.raises(KeyError):
        report.render("<!-- report:nope -->\nx\n<!-- /report:nope -->\n")
