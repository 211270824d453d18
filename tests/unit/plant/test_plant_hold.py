"""The plant's hold on a silent fc with its backup damper (plant_sim/hold.py, issue 22).

In process, lockstep-friendly (no wall clock): the cruise plant flies the commands of an fc
that then falls silent, frame by frame as the real-time process does it (the last command kept
for ``no_command_s``, then ``SilentHold.output``). Before the damper a held surface a tenth
of a degree off the trim rolled the vehicle off: a 10 s plant-link blackout in real time
reached |mu| 119 deg (docs/reliability.md table A)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from plant_sim.hold import SilentHold
from plant_sim.modes import closed_loop, damper_gain, held_offset_bank_deg, linear_model
from plant_sim.scenario import load
from plant_sim.sim import PlantSim

DEG = math.pi / 180.0
#: the law's commands before the silence, off the moment trim (deg; left, right, rudder): the
#: mean a loaded fc leaves behind is not the trim (0.2 deg of rudder banks the open-loop
#: airframe 36 deg in 10 s: python -m plant_sim modes --scenario cruise)
BIAS_DEG = np.array([0.1, -0.1, 0.2])
#: +- chatter of the law around its mean, alternating frame by frame, deg
CHATTER_DEG = np.array([0.5, 0.5, 0.5])
#: the last command before the silence, a transient of the law (deg from the trim; as logged
#: at a cut in a real-time blackout run: 4.12 / 5.08 / -0.56 deg against a 4.77 deg trim)
LAST_DEG = np.array([-0.65, 0.31, -0.56])


def _fall_silent(sc, flown_s=3.0, silent_s=10.0):
    """Truth columns from the silence's start: the hold has seen ``flown_s`` of the law's
    commands (trim + BIAS_DEG +- CHATTER_DEG, then LAST_DEG), the plant at the cruise trim
    (where the law had it) keeps the last command for ``no_command_s``, then ``silent_s`` of
    the hold."""
    sim = PlantSim(sc)
    hold = SilentHold(sc.data["servo"], sim.trim_rad, sim.frame_dt_s)
    row = np.zeros(sim.TRUTH_N)
    rows = []
    cmd = np.zeros(3)
    for k in range(int(round(flown_s / sim.frame_dt_s))):
        sign = 1.0 if k % 2 else -1.0
        cmd[:] = sim.trim_rad + (BIAS_DEG + sign * CHATTER_DEG) * DEG
        hold.command_received(cmd)
    last = sim.trim_rad + LAST_DEG * DEG
    hold.command_received(last)
    sim.measure(sim.last_meas)
    n_keep = int(round(sc.data["servo"]["no_command_s"] / sim.frame_dt_s))
    for _ in range(n_keep):                     # the process keeps the last command meanwhile
        sim.frame(last, row)
        rows.append(row.copy())
    hold.engage(last)
    for _ in range(int(round(silent_s / sim.frame_dt_s))):
        hold.output(sim.last_meas, cmd)
        sim.frame(cmd, row)
        rows.append(row.copy())
    a = np.array(rows)
    return {n: a[:, i] for i, n in enumerate(sim.TRUTH_NAMES)}


def _undamped(sc):
    sv = sc.data["servo"]
    for k in ("backup_p_gain_s", "backup_q_gain_s", "backup_r_gain_s", "backup_beta_gain"):
        sv[k] = 0.0
    return sc


def test_a_silent_fc_for_10_s_from_the_cruise_keeps_the_vehicle_out_of_a_departure():
    """GIVEN the cruise, the law's commands off the trim and a transient as its last word,
    WHEN the fc is silent for 10 s of sim time, THEN the hold with its damper keeps |mu| under
    10 deg, alpha within the envelope, no surface on its limit."""
    t = _fall_silent(load("cruise"))
    mu = np.degrees(np.abs(t["mu_rad"]))
    alpha = np.degrees(t["alpha_rad"])
    d = np.degrees(np.abs(np.stack([t["delta_left_rad"], t["delta_right_rad"],
                                    t["delta_rudder_rad"]])))
    print(f"\ndamped: max |mu| {mu.max():.2f} deg, alpha {alpha.min():.2f}..{alpha.max():.2f} "
          f"deg, max |delta| {d.max():.2f} deg")
    assert mu.max() < 10.0
    assert 0.0 < alpha.min() and alpha.max() < 10.0
    assert d.max() < 19.9


def test_without_the_damper_the_same_silence_departs():
    """The case above is the problem, not a quiet one: the same silence with the backup gains
    at 0 (the hold before the damper) banks past 10 deg."""
    t = _fall_silent(_undamped(load("cruise")))
    mu = np.degrees(np.abs(t["mu_rad"]))
    print(f"\nundamped: max |mu| {mu.max():.1f} deg")
    assert mu.max() > 10.0


def test_the_damper_acts_only_in_a_silence_and_adds_the_measured_rates_to_the_base():
    sc = load("cruise")
    sv = sc.data["servo"]
    trim = np.array([0.08, 0.08, 0.0])
    hold = SilentHold(sv, trim, 0.002)
    for _ in range(100):
        hold.command_received(np.array([0.1, 0.1, 0.01]))
    hold.engage(np.array([0.5, -0.5, 0.3]))            # the last command: not the base
    np.testing.assert_allclose(hold.base_rad, [0.1, 0.1, 0.01], atol=1e-12)
    meas = np.zeros(14)
    out = np.zeros(3)
    hold.output(meas, out)
    np.testing.assert_allclose(out, hold.base_rad, atol=0)      # level and steady: the base
    from hyfc_wire.layout import M_P, M_Q, M_R, M_SSA
    meas[M_P], meas[M_Q], meas[M_R], meas[M_SSA] = 0.01, 0.02, 0.03, 0.004
    hold.output(meas, out)
    kp, kq, kr, kb = (sv["backup_p_gain_s"], sv["backup_q_gain_s"], sv["backup_r_gain_s"],
                      sv["backup_beta_gain"])
    np.testing.assert_allclose(out - hold.base_rad, [kp * 0.01 - kq * 0.02,
                                                     -kp * 0.01 - kq * 0.02,
                                                     kr * 0.03 - kb * 0.004], atol=1e-15)
    meas[M_P] = 10.0                                           # clipped to the authority
    hold.output(meas, out)
    assert out[0] - hold.base_rad[0] == pytest.approx(sv["backup_authority_deg"] * DEG)
    meas[M_R] = math.nan                                       # a bad sample adds nothing
    hold.output(meas, out)
    np.testing.assert_allclose(out, hold.base_rad, atol=0)
    hold.to_trim = True                                        # no_command = "trim"
    hold.engage(np.zeros(3))
    np.testing.assert_allclose(hold.base_rad, trim, atol=0)


def test_the_gains_damp_every_lateral_mode_of_the_linear_model():
    """The signs of hold.py agree with the plant's control derivatives: with the cruise's gains
    every mode but the phugoid (untouched, +0.0002 1/s) decays, the Dutch roll, the roll and the
    short period at least 0.2 1/s (open loop 0.06 1/s), and the held-offset bank falls five-fold."""
    sc = load("cruise")
    m = linear_model(sc)
    k = damper_gain(sc.data["servo"], m.V_m_s)
    ol = np.linalg.eigvals(m.a)
    cl = np.linalg.eigvals(closed_loop(m, k))
    assert max(e.real for e in cl if abs(e) > 0.01) < 0.0         # the phugoid excluded
    assert max(e.real for e in ol if abs(e) > 0.5) > -0.1
    assert max(e.real for e in cl if abs(e) > 0.5) < -0.2       # Dutch roll, roll, short period
    off = np.array([0.0, 0.0, 0.2 * DEG])
    assert held_offset_bank_deg(m, k, off, 10.0) < 0.2 * held_offset_bank_deg(m, 0 * k, off, 10.0)
