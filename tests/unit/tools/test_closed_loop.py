"""Closed loop in process (no UDP): the control law flies the plant_sim dynamics.

tools.sitl.closed_loop.simulate runs the law's kernels and the plant's RK4 frames in one numba
loop (truth-fed estimated state). Runs are 8 s of sim time: the paper's steps settle in
about 2-3 s (measured), so the last 1 s window of final_error_deg is well after settling,
and overshoot and settling time equal those of the 20 s runs of docs/control_law.md.
Bounds are justified next to each assertion; ``test_documented_figures`` pins the figures
that docs/control_law.md section 9 reports, with stated tolerances.

Every run here flies the paper's law as section 9 documents it: the paper's fixed gains
(CTL_SCHED 0) without the complementary attitude filter (FLT_ANG_CF 0), with the allocation
scaling the deflection vector (ALLOC_MODE 1), the law these figures were measured on before
issue 20; the default law since issue 20 (the gain schedule and the
1 Hz complementary filter) is flown in tests/unit/tools/test_schedule_corridor.py.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from tools.sitl.closed_loop import simulate as _simulate

#: the paper's law (docs/control_law.md section 9): its fixed gains ("Scheduling": CTL_SCHED 0),
#: no complementary attitude filter (FLT_ANG_CF 0) and the vector-scaling allocation
#: (ALLOC_MODE 1): the law before issue 20
PAPER_GAINS = {"CTL_SCHED": 0, "FLT_ANG_CF": 0, "ALLOC_MODE": 1}


def simulate(scenario, *, law_overrides=None, **kw):
    """tools.sitl.closed_loop.simulate with the paper's law (overridable)."""
    return _simulate(scenario, law_overrides={**PAPER_GAINS, **(law_overrides or {})}, **kw)

DURATION_S = 8.0
DEG = math.pi / 180.0


def _figures(res):
    m = res.metrics()
    return m, {ch: m[ch] for ch in ("alpha", "beta", "mu")}


@pytest.mark.parametrize("coordinated", [True, False], ids=["co", "unco"])
@pytest.mark.parametrize("shaping", ["steps", "prefilter"])
def test_paper_scenario_tracks(coordinated, shaping):
    # GIVEN the paper's case: +20 % force / -20 % moment coefficients, sinusoidal disturbance
    res = simulate("paper", coordinated=coordinated, command_shaping=shaping,
                   duration_s=DURATION_S)
    m, ch = _figures(res)
    # THEN no divergence and every channel settles on its command
    assert not res.diverged
    for name, c in ch.items():
        # final error over the last 1 s: the disturbance leaves a sinusoidal residual
        # (measured ~0.02 deg); 0.1 deg is 2.5 % of the 4 deg steps and 5x the measured value
        assert c.final_error_deg < 0.1, (name, c)
        # settled (tools.metrics band: 5 % of the step, at least 0.1 deg) well within the
        # run (measured 1.9-3.1 s); the figures themselves are pinned below
        assert c.settling_time_s is not None and c.settling_time_s < 6.0, (name, c)
    if shaping == "steps":
        # the paper's gains give ~13 % on an ideal inversion; the omega_c limit (3 deg/s)
        # slows the steps down, measured 2-8 %; bound 20 % (alpha, beta) and 30 % for mu, whose
        # step starts with a wrong-way excursion from the initial 5 deg sideslip's roll moment
        assert ch["alpha"].overshoot_pct < 20.0
        assert ch["beta"].overshoot_pct < 20.0
        assert ch["mu"].overshoot_pct < 30.0
    else:
        # the prefilter removes the step overshoot (measured < 1 %); 5 % leaves room for the
        # disturbance and the model error
        for name, c in ch.items():
            assert c.overshoot_pct < 5.0, (name, c)
    # bounded surfaces, and no time spent on a limit (measured 0 s; the allocator's scaling
    # and the omega_c limit keep every surface inside +-20 deg)
    for name, peak in m["surfaces"]["peak_deg"].items():
        assert peak <= 20.0 + 1e-9, name
    assert m["surfaces"]["saturated_s"] < 0.2
    # the law's status stays finite
    assert np.all(np.isfinite(res.status))


@pytest.mark.parametrize("coordinated", [True, False], ids=["co", "unco"])
def test_nominal_scenario_tracks_exactly(coordinated):
    # GIVEN the nominal vehicle (the controller's own model), no disturbance, no noise
    res = simulate("nominal", coordinated=coordinated, command_shaping="steps",
                   duration_s=DURATION_S)
    _, ch = _figures(res)
    assert not res.diverged
    for name, c in ch.items():
        # nothing to reject: the integral drives the error to ~0 (measured < 0.002 deg)
        assert c.final_error_deg < 0.01, (name, c)
        assert c.overshoot_pct < 20.0, (name, c)


def test_coordination_changes_the_allocation():
    # the factors must act (CO_NORM 0: relative to the diagonal), yet both variants fly
    co = simulate("paper", coordinated=True, duration_s=3.0)
    un = simulate("paper", coordinated=False, duration_s=3.0)
    lam_co = co.status[:, co.status_names.index("lambda_e"):
                       co.status_names.index("lambda_e") + 3]
    lam_un = un.status[:, un.status_names.index("lambda_e"):
                       un.status_names.index("lambda_e") + 3]
    assert np.max(np.abs(lam_un)) == 0.0
    assert np.max(np.abs(lam_co)) > 0.05          # alpha 5 deg alone gives lambda_e 0.087
    # the surfaces differ by more than the wire's 0.04 deg quantisation
    assert np.max(np.abs(co.delta_cmd_rad - un.delta_cmd_rad)) > 0.5 * DEG
    assert co.status_col("co_fallback").max() == 0.0


def test_paper_literal_law_saturates():
    """The printed law (no omega_c limit, no freeze, observer fed M_c, clipped allocation)
    saturates the surfaces on the paper's case and diverges (paper_notes, last section)."""
    res = simulate("paper", coordinated=True, duration_s=DURATION_S,
                   law_overrides={"PAPER_LITERAL": 1})
    m, _ = _figures(res)
    assert res.diverged or m["surfaces"]["saturated_s"] > 0.5


def test_eq14_factors_fly():
    # the non-default reading of D3 (the default is Eq. 19)
    res = simulate("paper", coordinated=True, duration_s=DURATION_S,
                   law_overrides={"CO_FAC_EQ": 14})
    _, ch = _figures(res)
    assert not res.diverged
    assert all(c.final_error_deg < 0.1 for c in ch.values())


def test_cg_aft_scenario():
    """X_cg 2.90 m (statically unstable in pitch and yaw), started trimmed at beta 1 deg.

    Measured: both variants track (overshoot < 6 %, final error < 0.03 deg); asserted with
    the same bounds as the paper's case.
    """
    for co in (True, False):
        res = simulate("cg_aft", coordinated=co, duration_s=DURATION_S)
        _, ch = _figures(res)
        assert not res.diverged
        for name, c in ch.items():
            assert c.final_error_deg < 0.1, (co, name, c)


@pytest.mark.parametrize("coordinated", [True, False], ids=["co", "unco"])
def test_paper_scenario_with_sensors_and_estimator(coordinated):
    """The scenario's sensor noise (0.05 deg vanes, 0.05 deg/s rates, ...) through the fc's
    estimator: the law's input filters (FLT_RATE_HZ, FLT_ANG_HZ) keep the noise off the
    surfaces. Measured: final errors 0.04-0.05 deg, overshoot < 9 %."""
    res = simulate("paper", coordinated=coordinated, duration_s=DURATION_S,
                   estimate="sensors")
    m, ch = _figures(res)
    assert not res.diverged
    for name, c in ch.items():
        # noise adds ~0.02 deg to the truth-fed residual: bound 0.1 deg as there
        assert c.final_error_deg < 0.1, (name, c)
        assert c.overshoot_pct < 20.0, (name, c)
    assert m["surfaces"]["saturated_s"] < 0.2
    # the surfaces do not chatter: rms of the frame-to-frame command change < 0.5 deg
    # (without the input filters it was 0.8-1.4 deg, beyond the 90 deg/s actuators' 0.18 deg
    # per 2 ms frame)
    late = res.t_s > 4.0
    step = np.degrees(np.diff(res.delta_cmd_rad[late], axis=0))
    assert np.max(np.sqrt(np.mean(step ** 2, axis=0))) < 0.5


def test_simulate_rejects_bad_options():
    with pytest.raises(ValueError):
        simulate("paper", command_shaping="ramp", duration_s=0.1)
    with pytest.raises(ValueError):
        simulate("paper", fast_hz=300.0, duration_s=0.1)
    with pytest.raises(ValueError):
        simulate("paper", coordinated=True, law_overrides={"CO_ENABLE": 0}, duration_s=0.1)
    with pytest.raises(KeyError):
        simulate("paper", law_overrides={"NOPE": 1}, duration_s=0.1)
    with pytest.raises(ValueError):
        simulate("paper", estimate="kalman", duration_s=0.1)


@pytest.mark.parametrize("fast_hz,slow_hz", [(250.0, 50.0), (50.0, 25.0)])
def test_slower_loops_still_fly(fast_hz, slow_hz):
    # paper_notes: results were the same for fast loops from 25 to 500 Hz and the slow loop
    # was fine at 20 Hz; the exact discretisation of the filters keeps wn dt = 0.8 stable.
    # Measured at 50/25 Hz: overshoot 12 / 9 / 17 %, final errors < 0.04 deg.
    res = simulate("paper", coordinated=True, fast_hz=fast_hz, slow_hz=slow_hz,
                   duration_s=DURATION_S)
    _, ch = _figures(res)
    assert not res.diverged
    assert all(c.final_error_deg < 0.1 for c in ch.values())


# ---------------------------------------------------------------------------------------------
# The documented figures (docs/control_law.md section 9 and D3/V3), pinned
# ---------------------------------------------------------------------------------------------
#: (scenario, variant, shaping, estimate, overrides) -> ((overshoot %, settling s) for alpha,
#: beta, mu), measured with `python -m tools.fly attitude SCENARIO --table [--estimate sensors]
#: [--set NAME=VALUE]` (20 s; these 8 s runs give the same overshoot and settling).
DOCUMENTED = {
    ("paper", "co", "steps", "truth", ()): ((3.40, 2.29), (2.26, 2.08), (4.94, 2.26)),
    ("paper", "unco", "steps", "truth", ()): ((5.46, 2.24), (2.53, 1.88), (6.96, 2.92)),
    ("paper", "co", "prefilter", "truth", ()): ((0.68, 2.55), (0.48, 2.52), (2.19, 3.05)),
    ("paper", "unco", "prefilter", "truth", ()): ((0.59, 2.45), (0.47, 2.41), (0.94, 2.62)),
    ("paper", "co", "steps", "sensors", ()): ((3.45, 2.29), (2.22, 2.07), (5.08, 2.51)),
    ("paper", "unco", "steps", "sensors", ()): ((5.19, 2.22), (2.62, 1.87), (5.61, 2.91)),
    ("paper_mirror", "co", "steps", "truth", ()): ((3.17, 2.00), (2.95, 1.74), (6.20, 2.08)),
    ("paper_mirror", "unco", "steps", "truth", ()): ((7.78, 2.81), (2.77, 1.89), (8.94, 2.93)),
    # D3: the Eq. 14 factors
    ("paper", "co", "steps", "truth", (("CO_FAC_EQ", 14),)):
        ((3.81, 2.56), (2.59, 2.33), (5.80, 2.82)),
    ("paper_mirror", "co", "steps", "truth", (("CO_FAC_EQ", 14),)):
        ((4.39, 1.76), (3.27, 1.61), (6.34, 1.91)),
    # V3: the observer fed g_Gamma delta_model (Eq. 44's coordinated moment)
    ("paper", "co", "steps", "truth", (("DOB_ACHIEVED", 2),)):
        ((5.45, 2.29), (2.57, 1.91), (6.10, 2.97)),
    ("paper_mirror", "co", "steps", "truth", (("DOB_ACHIEVED", 2),)):
        ((7.40, 2.79), (2.88, 1.85), (7.43, 2.85)),
}
#: Tolerances: the runs are deterministic (truth, or seeded noise); these absorb a change of
#: floating-point summation order (another CPU, another numba), not a change of the law.
#: Overshoot +-0.15 point (the smallest documented difference between two readings is
#: 0.3 point); settling +-0.05 s (the smallest documented difference is 0.13 s).
OVERSHOOT_TOL_PT = 0.15
SETTLING_TOL_S = 0.05
#: final error bound over the last 1 s (measured 0.021-0.025 deg truth, 0.038-0.042 sensors)
FINAL_ERROR_MAX_DEG = {"truth": 0.03, "sensors": 0.05}


@pytest.mark.parametrize("case", list(DOCUMENTED), ids=lambda c: "-".join(
    [c[0], c[1], c[2], c[3]] + [f"{k}{v}" for k, v in c[4]]))
def test_documented_figures(case):
    scenario, variant, shaping, estimate, overrides = case
    res = simulate(scenario, coordinated=(variant == "co"), command_shaping=shaping,
                   estimate=estimate, law_overrides=dict(overrides), duration_s=DURATION_S)
    m, ch = _figures(res)
    assert not res.diverged
    for (os_pct, ts_s), name in zip(DOCUMENTED[case], ("alpha", "beta", "mu")):
        c = ch[name]
        assert c.overshoot_pct == pytest.approx(os_pct, abs=OVERSHOOT_TOL_PT), (name, c)
        assert c.settling_time_s == pytest.approx(ts_s, abs=SETTLING_TOL_S), (name, c)
        assert c.final_error_deg < FINAL_ERROR_MAX_DEG[estimate], (name, c)
    assert m["surfaces"]["saturated_s"] == 0.0


def _os_ts(scenario, coordinated, overrides=()):
    _, ch = _figures(simulate(scenario, coordinated=coordinated, duration_s=DURATION_S,
                              law_overrides=dict(overrides)))
    return ({k: c.overshoot_pct for k, c in ch.items()},
            {k: c.settling_time_s for k, c in ch.items()})


@pytest.mark.parametrize("scenario", ["paper", "paper_mirror"])
def test_coordination_lowers_alpha_and_mu_overshoot_and_settles_mu_sooner(scenario):
    """The direction of coordination's effect where it is robust (docs/control_law.md D3):
    with both sideslip signs, the coordinated law overshoots less in alpha and mu (by 2.0-4.6
    points measured) and settles mu sooner (by 0.66-0.85 s). Beta is not asserted: its
    ordering flips with the sideslip sign (2.26 vs 2.53 %, 2.95 vs 2.77 %)."""
    os_co, ts_co = _os_ts(scenario, True)
    os_un, ts_un = _os_ts(scenario, False)
    assert os_co["alpha"] < os_un["alpha"] - 1.0
    assert os_co["mu"] < os_un["mu"] - 1.0
    assert ts_co["mu"] < ts_un["mu"] - 0.3


def test_eq19_beats_eq14_on_the_paper_case():
    """D3: on the paper's case the Eq. 19 factors (the default) overshoot less than Eq. 14
    in every channel and settle every channel sooner (measured 0.4/0.3/0.9 points, 0.27/0.25/
    0.56 s)."""
    os19, ts19 = _os_ts("paper", True)
    os14, ts14 = _os_ts("paper", True, (("CO_FAC_EQ", 14),))
    for ch in ("alpha", "beta", "mu"):
        assert os19[ch] < os14[ch] - 0.2, ch
        assert ts19[ch] < ts14[ch] - 0.1, ch
