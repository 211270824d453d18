"""Tier 1: the fc's one parameter table (fc/params.py): validation, persistence, docs."""
from __future__ import annotations

import math
import os
from pathlib import Path

import pytest
from pymavlink import mavparm

from fc.params import (PROCESS_PARAMS, ParamFileError, ParamTable, build_table,
                       render_markdown, set_aside)

REPO = str(Path(__file__).resolve().parents[3])


@pytest.fixture()
def table() -> ParamTable:
    return build_table()


def test_names_are_mavlink_ids_and_unique(table):
    assert len(set(table.names)) == len(table.names)
    for d in table.defs:
        assert len(d.name) <= 16 and d.name == d.name.upper(), d.name
        assert d.min <= d.default <= d.max, d.name
        assert d.unit and d.description, d.name


def test_table_is_law_params_then_process_params_then_guidance_then_mission(table):
    from fc.control.params import LAW_PARAMS
    from fc.guidance.params import GUIDANCE_PARAMS
    from fc.mission_mode import MISSION_PARAMS
    expected = ([p.name for p in LAW_PARAMS] + [p.name for p in PROCESS_PARAMS]
                + [p.name for p in GUIDANCE_PARAMS] + [p.name for p in MISSION_PARAMS])
    assert table.names == expected


def test_out_of_range_and_non_finite_are_refused_and_value_kept(table):
    old = table.get("CMD_ALPHA_DEG")
    assert "outside" in table.set("CMD_ALPHA_DEG", 90.0)
    assert "non-finite" in table.set("CMD_ALPHA_DEG", math.nan)
    assert "non-finite" in table.set("CMD_ALPHA_DEG", math.inf)
    assert table.get("CMD_ALPHA_DEG") == old
    assert table.set("CMD_ALPHA_DEG", 5.0) is None
    assert table.get("CMD_ALPHA_DEG") == 5.0


def test_integer_parameter_refuses_fractions(table):
    assert "whole number" in table.set("FS_RECOVER", 0.5)
    assert table.set("FS_RECOVER", 0.0) is None


def test_bound_given_as_float32_is_accepted(table):
    import numpy as np
    d = table.defn("FS_TIMEOUT_S")
    assert table.set("FS_TIMEOUT_S", float(np.float32(d.min))) is None
    assert table.get("FS_TIMEOUT_S") == d.min


def test_save_load_round_trip(table, tmp_path):
    path = str(tmp_path / "p.parm")
    table.set("FS_TIMEOUT_S", 1.25)
    table.set("SLW_K1", 2.5)
    table.save(path)
    fresh = build_table()
    applied, warnings = fresh.load(path)
    assert not warnings
    assert fresh.get("FS_TIMEOUT_S") == 1.25 and fresh.get("SLW_K1") == 2.5
    assert set(applied) == set(table.names) - {"CO_ENABLE"}


def test_mavproxy_param_file_round_trip(table, tmp_path):
    """Our file -> MAVProxy (pymavlink mavparm) load/save -> our load: same values."""
    ours = str(tmp_path / "ours.parm")
    theirs = str(tmp_path / "theirs.parm")
    table.set("FST_KAPPA", 7.125)
    table.set("TRIM_RUD_DEG", -1.5)
    table.save(ours)
    mp = mavparm.MAVParmDict()
    assert mp.load(ours, use_excludes=False)
    mp.save(theirs)
    fresh = build_table()
    _, warnings = fresh.load(theirs)
    assert not warnings
    for n in table.names:
        assert fresh.get(n) == pytest.approx(table.get(n), abs=1e-6), n


def test_unknown_and_out_of_range_lines_are_skipped_with_a_warning(table, tmp_path):
    path = tmp_path / "p.parm"
    path.write_text("NOPE_PARAM 3\nCMD_MU_DEG 500\nFS_TIMEOUT_S,2.0  # comment\n")
    applied, warnings = table.load(str(path))
    assert applied == ["FS_TIMEOUT_S"] and table.get("FS_TIMEOUT_S") == 2.0
    assert any("NOPE_PARAM" in w for w in warnings)
    assert any("CMD_MU_DEG" in w for w in warnings)
    assert table.get("CMD_MU_DEG") == table.defn("CMD_MU_DEG").default


@pytest.mark.parametrize("text", ["FS_TIMEOUT_S\n", "FS_TIMEOUT_S abc\n", "FS_TIMEOUT_S nan\n",
                                  "A B C\n"])
def test_corrupt_file_raises_and_changes_nothing(table, tmp_path, text):
    path = tmp_path / "p.parm"
    path.write_text("SLW_K1 3\n" + text)
    before = table.values.copy()
    with pytest.raises(ParamFileError):
        table.load(str(path))
    assert (table.values == before).all()


def test_set_aside_keeps_the_file(tmp_path):
    path = tmp_path / "p.parm"
    path.write_text("garbage garbage garbage\n")
    dest = set_aside(str(path))
    assert not path.exists() and os.path.exists(dest)
    assert open(dest).read() == "garbage garbage garbage\n"


def test_save_is_atomic_no_temp_left(table, tmp_path):
    path = str(tmp_path / "p.parm")
    table.save(path)
    table.save(path)
    assert sorted(os.listdir(tmp_path)) == ["p.parm"]


def test_docs_params_md_is_current(table):
    with open(os.path.join(REPO, "docs", "params.md"), encoding="utf-8") as f:
        on_disk = f.read()
    assert on_disk == render_markdown(table), (
        "docs/params.md is stale: run python -m fc.params --write-docs")


def test_every_unit_is_in_the_vocabulary_and_an_unknown_unit_is_refused(table):
    from fc.params import UNITS, ParamDef
    # GIVEN the full table; THEN each unit it uses is in the vocabulary, which explains it
    assert {d.unit for d in table.defs} <= set(UNITS)
    assert all(UNITS[u] for u in UNITS)
    # WHEN a table is built with a unit outside the vocabulary; THEN it is refused by name
    with pytest.raises(ValueError, match="furlong"):
        ParamTable([ParamDef("X_LEN", 1.0, 0.0, 2.0, "furlong", "test", "a length")])


def test_one_rule_for_the_table_the_law_and_the_guidance():
    import numpy as np
    from fc.control.params import LAW_PARAMS, check_value
    from fc.guidance.params import GUIDANCE_PARAMS
    from fc.guidance.params import check_value as guidance_check
    table = build_table()
    # GIVEN each parameter and values at, just beyond (as float32) and outside its bounds;
    # THEN the fc's table and the owner's check accept and refuse the same values, alike
    for owner, check in ((LAW_PARAMS, check_value), (GUIDANCE_PARAMS, guidance_check)):
        for p in owner:
            span = p.max - p.min
            for v in (p.min, p.max, float(np.float32(p.min)), float(np.float32(p.max)),
                      p.min - 0.01 * span - 1e-3, p.max + 0.01 * span + 1e-3, math.nan):
                reason = table.check(p.name, v)
                try:
                    check(p.name, v)
                    owner_ok = True
                except ValueError:
                    owner_ok = False
                if p.name != "CO_FAC_EQ":
                    assert (reason is None) == owner_ok, (p.name, v, reason)
