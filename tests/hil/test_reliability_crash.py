"""Reliability promise 3 (docs/reliability.md): the controller dies, the plant carries on, the
parameter file survives.

- The fc is SIGKILLed mid-run (real time): the plant detects the silence, puts the surfaces to
  trim (``servo.no_command = "trim"`` after ``no_command_s``; the shipped cruise scenario holds
  the last command instead, which is the same detection) and keeps running
  to the end of its run; the restarted fc reloads its parameters from its file (a value set by
  the ground station before the crash is still there), resyncs on the plant's frames, is armed
  again and flies (tracking resumes).
- The parameter file is never half-written: a save interrupted at any point leaves the previous
  file intact (atomic temp file + rename), and after the SIGKILL the file parses completely.
- A corrupt parameter file is reported (STATUSTEXT to the ground station, fc.log) and kept aside
  byte for byte, never silently replaced; the fc starts on defaults.
"""
from __future__ import annotations

import math
import os
import re
import time

import numpy as np
import pytest

from fc.params import ParamTable, build_table
from tools.sitl.rig import Rig, RigConfig, steady_figures

pytestmark = [pytest.mark.hil]

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as ml  # noqa: E402

SET_NAME = "FS_RECOVER_S"     # a setting (saved to the file), not a command
SET_VALUE = 0.35


def _param_value(rig, name: str, timeout_s: float = 5.0):
    since = time.monotonic()
    rig.gcs.conn.mav.param_request_read_send(1, 1, name.encode(), -1)
    m = rig.gcs.wait(lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name, timeout_s,
                     since)
    return None if m is None else m.param_value


def _wait_file_value(rig, name: str, value: float, timeout_s: float = 5.0) -> dict | None:
    """The parameter file as parsed once it holds ``name = value`` (the fc saves at 1 Hz)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            vals = ParamTable.read_file(str(rig.params_path))
        except (OSError, ValueError):
            vals = {}
        if abs(vals.get(name, math.nan) - value) < 1e-6:
            return vals
        # wait for the next telemetry message instead of sleeping
        rig.gcs.wait(lambda m: True, 0.2, since=time.monotonic())
    return None


def _trim_scenario(tmp_path):
    """The cruise scenario (the rig's steady flight, its actuators starting at trim) with
    ``servo.no_command = "trim"`` (the plant's "trim" is its initial actuator position; holding
    an arbitrary last command for seconds makes the vehicle depart, see docs/reliability.md)."""
    from plant_sim.scenario import load
    text = open(load("cruise").path, encoding="utf-8").read()
    assert 'no_command = "hold"' in text and 'initial = "trim"' in text
    path = tmp_path / "cruise_trim.toml"
    path.write_text(text.replace('no_command = "hold"', 'no_command = "trim"'))
    return path


def test_promise3_fc_sigkill_plant_trims_restart_reloads_params_and_flies(tmp_path):
    from plant_sim.hold import damper_increments
    from plant_sim.scenario import load
    from plant_sim.trim import trim_at
    scenario = _trim_scenario(tmp_path)
    ini = load(str(scenario)).data["initial"]
    trim_rad = np.asarray(trim_at(load(str(scenario)), math.radians(ini["alpha_deg"]),
                                  math.radians(ini["beta_deg"])).deflection_rad)
    cfg = RigConfig(out=tmp_path, duration_s=60.0, seed=4, scenario=str(scenario))
    names = build_table().names
    with Rig(cfg) as rig:
        rig.start()
        assert rig.wait_plant_time(1.5, 60) is not None
        rig.gcs.conn.mav.param_set_send(1, 1, SET_NAME.encode(), SET_VALUE,
                                        ml.MAV_PARAM_TYPE_REAL32)
        saved = _wait_file_value(rig, SET_NAME, SET_VALUE)
        assert saved is not None, "the accepted PARAM_SET never reached the parameter file"
        t_kill = rig.wait_plant_time(2.5, 30)
        rc_kill = rig.fc.kill9()
        # the plant keeps running on its own for a while: its sim time goes on advancing
        t_alive = rig.wait_plant_time(t_kill + 2.0, 10)
        assert rig.plant.proc.poll() is None
        after_kill = ParamTable.read_file(str(rig.params_path))     # parses completely
        rig.start_fc()
        rig.arm_when_data_valid()
        t_restart = rig.plant_time_now()
        hb = rig.gcs.wait(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1,
                          3.0, since=time.monotonic())
        mode_after = None if hb is None else hb.custom_mode
        armed_after = hb is not None and bool(hb.base_mode & ml.MAV_MODE_FLAG_SAFETY_ARMED)
        reloaded = _param_value(rig, SET_NAME)
        assert rig.wait_plant_time(t_restart + 2.0, 30) is not None
        rcs = rig.finish(stop_plant=True)
        truth = rig.truth()
        internals = rig.internals()
        ps = rig.plant_summary()
        log = rig.fc_log()
        plant_log = (tmp_path / "plant" / "plant.log").read_text()
    assert rc_kill == -9
    assert t_alive is not None and t_alive >= t_kill + 2.0
    assert set(after_kill) == set(names) and after_kill[SET_NAME] == pytest.approx(SET_VALUE)
    assert reloaded == pytest.approx(SET_VALUE, abs=1e-6)
    assert log.count("loaded %d parameters" % len(names)) >= 1 or "loaded" in log
    assert rcs["plant"] == 0 and ps["exit_reason"] != "completed", ps   # ran until stopped
    # the plant saw the silence, said so once, and put the surfaces to its trim after
    # no_command_s (0.5 s)
    assert ps["no_command_frames"] > 0.5 * 500 * (t_alive - t_kill - 0.5)
    assert ps["no_command_episodes"] == 1
    assert plant_log.count("no servo command for") == 1 and "surfaces to trim" in plant_log
    assert plant_log.count("servo commands back after") == 1
    cmd = np.stack([truth["delta_cmd_left_rad"], truth["delta_cmd_right_rad"],
                    truth["delta_cmd_rudder_rad"]], axis=1)
    t = truth["t_s"]
    sel = (t > t_kill + 0.9) & (t < t_alive)      # 0.5 s no_command_s + scheduling margin
    held = cmd[sel]
    # the trim plus the backup damper on the rates and sideslip the plant measured (the
    # measurement of the same frame, truth's meas_* columns): plant_sim/hold.py
    damper = damper_increments(load(str(scenario)).data["servo"], truth["meas_p_rad_s"][sel],
                               truth["meas_q_rad_s"][sel], truth["meas_r_rad_s"][sel],
                               truth["meas_ssa_rad"][sel])
    assert held.shape[0] > 400 and np.abs(held - trim_rad - damper).max() < 1e-9
    # the new fc resynced and flies: the plant applies its answers again, the law commands
    # the surfaces (they leave the plant's trim). The steady-flight figures over the last
    # second are printed, not asserted: the restarted CRUISE engages at the attitude the
    # outage left (bank up to a few degrees) and ramps the bank back at GE_MU_RATE, so the
    # inner loop lags its command by the prefilter's ~1 s for a while (docs/reliability.md)
    exits = re.findall(r"exit: frames (\d+), outputs (\d+)", log)
    assert len(exits) == 1                       # only the restarted fc exited cleanly
    assert int(exits[0][0]) > 500 and int(exits[0][1]) > 500
    tail = (t > t_restart + 1.0)
    # the hold above is the trim (+ the damper) to 1e-9 rad; the law's answers leave the trim (0.93-1.2 deg
    # measured with the scheduled law: a 0.06 deg threshold, far above the hold's exactness)
    assert np.abs(cmd[tail] - trim_rad).max() > 1e-3
    assert mode_after is not None and mode_after & 0xFFFF == 4 and armed_after     # CRUISE
    fig = steady_figures(truth, internals, t[-1] - 1.0)
    print(f"\npromise 3: killed at {t_kill:.2f} s, plant alive to {t_alive:.2f} s "
          f"({ps['no_command_frames']} no-command frames), fc flying again at {t_restart:.2f} s; "
          f"steady flight over the last second: {fig}")


class _Crash(Exception):
    pass


@pytest.mark.parametrize("where", ["write", "fsync", "replace"])
def test_promise3_interrupted_save_leaves_the_previous_file_intact(tmp_path, monkeypatch, where):
    import fc.params as fp
    path = tmp_path / "params.parm"
    table = build_table()
    table.save(str(path))
    before = path.read_bytes()
    table.set("FS_TIMEOUT_S", 1.25)

    def boom(*_a, **_k):
        raise _Crash(where)

    if where == "write":
        import fc.storage as storage
        real_write_all = storage.write_all

        def half_then_crash(fd, data):       # the one write call of the fc (fc/storage.py)
            real_write_all(fd, bytes(data)[: len(data) // 2])
            raise _Crash("write")

        monkeypatch.setattr(storage, "write_all", half_then_crash)
    elif where == "fsync":
        monkeypatch.setattr(fp.os, "fsync", boom)
    else:
        monkeypatch.setattr(fp.os, "replace", boom)
    with pytest.raises(_Crash):
        table.save(str(path))
    monkeypatch.undo()
    assert path.read_bytes() == before                         # old file untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["params.parm"]   # no temp left


def test_promise3_corrupt_parameter_file_is_reported_and_kept_aside(tmp_path):
    garbage = b"FS_TIMEOUT_S 0.5\nKP_\x00\xff\xfe garbage line with three words\n"
    cfg = RigConfig(out=tmp_path, duration_s=1.0, arm="no")
    with Rig(cfg) as rig:
        rig.params_path.write_bytes(garbage)
        rig.start(plant=False)
        text = rig.gcs.wait_text("param file corrupt", 10.0)
        rc = rig.fc.stop()
        log = rig.fc_log()
    aside = [p for p in tmp_path.iterdir() if p.name.startswith("params.parm.corrupt-")]
    assert text is not None
    assert rc == 0
    assert len(aside) == 1 and aside[0].read_bytes() == garbage     # kept, byte for byte
    assert aside[0].name in log and "ERROR" in log
    fresh = ParamTable.read_file(str(rig.params_path))             # defaults, complete
    assert set(fresh) == set(build_table().names)
