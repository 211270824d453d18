"""tools/evidence/margins/inproc.py: the injection block and the margin finders (issue 15, point 4).

The finders are checked on a loop whose margins are known in closed form,
L(s) = K / (s (s + 1) (s + 2)): phase -180 deg at w = sqrt(2) rad/s where |G| = 1/6, so the
gain margin is 6 / K; the phase margin and crossover follow from |L(jw)| = 1.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from tools.evidence.margins import inproc as M

K_LOOP = 2.0
DT = 0.01


def _analytic():
    w = np.geomspace(0.05, 10.0, 200001)
    lv = K_LOOP / (1j * w * (1j * w + 1) * (1j * w + 2))
    i = int(np.argmin(np.abs(np.abs(lv) - 1.0)))
    return w[i], 180.0 + math.degrees(np.angle(lv[i]))


def _fly_linear(inj, t_end=60.0, x0=(1.0, 0.0, 0.0)):
    """x' = A x + B u, y = x1 (G = 1/(s(s+1)(s+2))), u = inject(-K y); ZOH at DT."""
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -2.0, -3.0]])
    b = np.array([0.0, 0.0, 1.0])
    big = np.zeros((4, 4))
    big[:3, :3] = a * DT
    big[:3, 3] = b * DT
    e = expm(big)
    ad, bd = e[:3, :3], e[:3, 3]
    n = int(round(t_end / DT))
    x = np.array(x0, float)
    ring = np.zeros((M.RING_MAX, 3))
    aps = np.zeros((3, 3))
    v_in = np.zeros(3)
    v_out = np.zeros(3)
    ys, uc, uo = np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        v_in[1] = -K_LOOP * x[0]
        M.inject(inj, v_in, k * DT, DT, k, ring, aps, v_out)
        ys[k], uc[k], uo[k] = x[0], v_in[1], v_out[1]
        x = ad @ x + bd * v_out[1]
    return np.arange(n) * DT, ys, uc, uo


def _linear_stable(inj) -> bool:
    _, y, _, _ = _fly_linear(inj)
    n10 = int(10.0 / DT)
    return bool(np.abs(y[-n10:]).max() < np.abs(y[-2 * n10:-n10]).max())


def test_ring_buffer_delays_by_exactly_n_samples_in_the_selected_channel_only():
    n = 7
    inj = M.make_inj("delay", "pitch", delay_frames=n)
    ring = np.zeros((M.RING_MAX, 3))
    aps = np.zeros((3, 3))
    out = np.zeros(3)
    got = []
    for k in range(30):
        v = np.array([100.0 + k, 1.0 + k, -k])
        M.inject(inj, v, k * 1e-3, 1e-3, k, ring, aps, out)
        got.append(out.copy())
        assert out[0] == v[0] and out[2] == v[2]          # roll, yaw untouched
    pitch = np.array(got)[:, 1]
    assert np.all(pitch[:n] == 1.0)                         # primed with the first input
    assert np.array_equal(pitch[n:], 1.0 + np.arange(30 - n))


def test_allpass_has_unit_gain_and_the_requested_lag():
    w = 3.0
    phi = math.radians(40.0)
    dt = 1e-3
    inj = M.make_inj("allpass", "all", allpass_a=M.allpass_a_for(phi, w))
    ring = np.zeros((M.RING_MAX, 3))
    aps = np.zeros((3, 3))
    out = np.zeros(3)
    t = np.arange(int(20.0 / dt)) * dt
    y = np.empty_like(t)
    for k, tk in enumerate(t):
        M.inject(inj, np.full(3, math.sin(w * tk)), tk, dt, k, ring, aps, out)
        y[k] = out[0]
    # -L = V_c / V_out: with v_c = y (output) and v_out = the input sine, the ratio is H(jw)
    h = -M.loop_transfer(t, y, np.sin(w * t), w, 10.0)
    assert abs(abs(h) - 1.0) < 1e-3
    assert math.degrees(np.angle(h)) == pytest.approx(-40.0, abs=0.2)


def test_gain_margin_by_bisection_matches_the_analytic_6_over_k():
    good, bad = M.bisect_boundary(lambda k: _linear_stable(M.make_inj("gain", "pitch", gain=k)),
                                  1.0, 8.0, 0.01)
    assert good < bad
    assert 0.5 * (good + bad) == pytest.approx(6.0 / K_LOOP, rel=0.02)


def test_sweep_gives_the_analytic_crossover_phase_margin_and_gain_margin():
    wc, pm = _analytic()
    omegas = np.geomspace(0.3, 4.0, 16)
    lv = []
    for w in omegas:
        inj = M.make_inj("sine", "pitch", amp_rad=0.1, omega_rad_s=w, t_on_s=0.0)
        t, _, uc, uo = _fly_linear(inj, t_end=50.0, x0=(0.0, 0.0, 0.0))
        lv.append(M.loop_transfer(t, uc, uo, w, 25.0))
    cr = M.crossings(omegas, lv)
    assert cr["omega_c"] == pytest.approx(wc, rel=0.05)
    assert cr["pm_deg"] == pytest.approx(pm, abs=2.0)
    assert cr["omega_180"] == pytest.approx(math.sqrt(2.0), rel=0.05)
    assert cr["gm_db"] == pytest.approx(20 * math.log10(6.0 / K_LOOP), abs=0.5)


def test_delay_margin_matches_phase_margin_over_crossover():
    wc, pm = _analytic()
    good, bad = M.scan_boundary(
        lambda n: _linear_stable(M.make_inj("delay", "pitch", delay_frames=int(round(n)))),
        np.arange(0, 200, 10), 1.0)
    expected_frames = math.radians(pm) / wc / DT
    assert good <= expected_frames + 1.5 and bad >= expected_frames - 1.5


def test_nonlinear_loop_is_stable_nominally_and_a_large_pitch_gain_breaks_it():
    """With the paper's fixed gains (CTL_SCHED 0: whole-command pitch gain margin x2.3-2.9,
    docs/margins.md) a pitch gain of 8 breaks the loop; the scheduled law's margin about
    trim is x12 (issue 20), so it is the paper's law that checks the verdict here."""
    sc = M.margin_scenario()
    paper = {"CTL_SCHED": 0}
    nominal = M.fly(sc, M.make_inj(), duration_s=12.0, law_overrides=paper)
    assert not nominal.diverged and M.stable(nominal)
    # the law's command reaches the plant unchanged without a perturbation
    assert np.array_equal(nominal.v_c_rad, nominal.v_out_rad)
    broken = M.fly(sc, M.make_inj("gain", "pitch", gain=8.0), duration_s=12.0,
                   law_overrides=paper)
    assert not M.stable(broken)


def test_margin_scenario_options():
    sc = M.margin_scenario(point=(8.0, 26e3), sensor_noise=False)
    assert sc.data["timing"]["frame_hz"] == 1000.0
    assert sc.data["disturbance"]["enabled"] is False
    assert sc.data["initial"]["h_m"] == 26e3
    assert all(v == 0.0 for v in sc.data["sensors"]["noise"].values())
    assert M.margin_scenario(disturbance=True).data["disturbance"]["enabled"] is True
    assert M.margin_scenario(initial_beta_deg=0.0).data["initial"]["beta_deg"] == 0.0
    assert M.margin_scenario().data["initial"]["beta_deg"] == 5.0


def test_grid_table_checks_the_issue_20_targets(tmp_path):
    """`python -m tools.evidence.margins table DIR...`: one row per variant and channel, 'yes' only when
    all-pass PM >= 45 deg, gain about trim >= 6 dB up and down and the all-channel delay
    >= 50 ms; a variant without results (unperturbed loop unstable) reads 0 ms, 'no'."""
    import json

    def res(ch, pm, up, down):
        return {"channel": ch, "coordinated": True, "pm_allpass_deg": [pm, pm + 1],
                "gain_ac_up": [up, up * 1.01], "gain_ac_down": [down, down * 0.99]}
    j = {"point": "8,26", "frame_dt_s": 0.001, "overrides": {}, "initial_beta_deg": None,
         "results": [res("roll", 50.0, 2.0 ** 0.5 * 2.0, 0.4), res("pitch", 44.0, 4.0, 0.3),
                     res("yaw", 50.0, 1.9, 0.3)],
         "delays": {"co/all": [60, 61], "unco/all": [0, 0]}}
    (tmp_path / "margins.json").write_text(json.dumps(j))
    rows = [r for r in M.grid_table([tmp_path]).splitlines()[2:]]
    assert [r.split("|")[4].strip() for r in rows] == ["roll", "pitch", "yaw", "all"]
    assert [r.rstrip(" |").split("|")[-1].strip()[:3] for r in rows] == [
        "yes", "no", "no", "no:"]
    assert "| 98 |" in rows[0]                                   # Mach 8 / 26 km, US76


def test_trim_verdict_says_where_the_airframe_cannot_hold_the_initial_state(tmp_path):
    """Issue 20 item 2: at Mach 14 / 30 km the paper's initial sideslip (5 deg) cannot be
    trimmed within the surfaces' +-20 deg (the rudder at its limit; the largest trimmable
    initial sideslip is about 3.4 deg), at the paper's point it can; the margins table gives
    the reason on the row of a variant whose unperturbed loop failed."""
    import json
    v = M.trim_verdict(M.margin_scenario(point=(14.0, 30e3)))
    assert not v["ini_ok"] and v["cmd_ok"]
    assert "rudder" in v["ini_at_limit"]
    assert 3.0 < v["beta0_max_deg"] < 4.0
    assert "cannot trim the initial state" in v["text"]
    paper = M.trim_verdict(M.margin_scenario())
    assert paper["ini_ok"] and paper["beta0_max_deg"] is None
    j = {"point": "14,30", "frame_dt_s": 0.001, "overrides": {}, "initial_beta_deg": None,
         "results": [], "delays": {"co/all": [0, 0]}, "trim": v}
    (tmp_path / "margins.json").write_text(json.dumps(j))
    row = M.grid_table([tmp_path]).splitlines()[2]
    assert "not stable" in row and "largest initial sideslip it trims is +3.4" in row


@pytest.mark.parametrize("bad", ["FOO=1", "ALLOC_W_YAW=abc", "ALLOC_W_YAW", "ALLOC_W_YAW=1e9"])
def test_a_bad_set_is_refused_before_anything_flies(bad, tmp_path, capsys):
    """--set is checked against the law's table (fc.control.params.parse_sets): an unknown
    name, a non-number, a missing value or one outside the range ends with a usage error that
    names it, and no run directory is written."""
    out = tmp_path / "m"
    with pytest.raises(SystemExit) as e:
        M.main(["--set", bad, "--point", "8,26", "--out", str(out)])
    assert e.value.code == 2
    assert "--set" in capsys.readouterr().err
    assert not out.exists()


def test_fly_refuses_a_bad_set():
    from tools import fly
    with pytest.raises(SystemExit) as e:
        fly.main(["attitude", "--set", "NOT_A_PARAM=1", "--duration", "0.1"])
    assert "NOT_A_PARAM" in str(e.value.code)
