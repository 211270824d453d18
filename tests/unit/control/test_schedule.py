"""The gain schedule (fc/control/schedule.py): interpolation, clamping at the table's edges,
continuity, bumpless application, and the SCH_* parameters reaching the law (issue 20)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.control import layout as L
from fc.control.law import AttitudeLaw
from fc.control.params import (
    LAW_PARAMS, PARAM_INDEX, P_DOB_C, P_FLT_ANG_HZ, P_FLT_RATE_HZ, P_FST_CF_WN, P_FST_KAPPA,
    P_SCH_AUTH, P_SCH_M, P_SCH_Q, P_SLW_K1, P_SLW_KAPPA, P_SLW_OMC_MAX, SCHED_FAMILIES,
    SCHEDULED_NAMES,
    default_si_array,
)
from fc.control.schedule import apply_schedule, mach_index, schedule_index
from fc.control.schedule_data import (
    SCHED_AUTH, SCHED_MACH, SCHED_N, SCHED_QUANTITIES, load_schedule,
)

DEG = math.pi / 180.0
TAB = load_schedule()
NODES_PA = TAB["qbar_kpa"] * 1e3
MACH_NODES = TAB[SCHED_MACH[0]]
MACH_FACTOR = TAB[SCHED_MACH[1]]
AUTH = TAB[SCHED_AUTH]
#: the authority axis off (SCH_AUTH_n = 1): the dynamic-pressure table alone, as the tests of
#: the qbar axis need it
AUTH_OFF = {f"SCH_AUTH_{i}": 1.0 for i in range(1, SCHED_N + 1)}
#: a Mach number where the airframe is directionally stable: the rate-command limit's Mach
#: factor is 1 there, so the dynamic-pressure table alone decides
MACH_STABLE = 7.0
# (SI slot the schedule writes, npz name, SI scale)
TARGETS = ((P_SLW_KAPPA, "kappa1", 1.0), (P_SLW_K1, "K", 1.0), (P_SLW_K1 + 1, "K", 1.0),
           (P_SLW_K1 + 2, "K", 1.0), (P_FST_KAPPA, "kappa2", 1.0), (P_DOB_C, "dob_c", 1.0),
           (P_FST_CF_WN, "cf_wn", 1.0), (P_FLT_RATE_HZ, "flt_rate_hz", 1.0),
           (P_FLT_ANG_HZ, "flt_ang_hz", 1.0), (P_SLW_OMC_MAX, "omc_max_deg_s", DEG))


def scheduled_par(qbar_pa: float, mach: float = MACH_STABLE, authority: bool = False
                  ) -> np.ndarray:
    """A default parameter array after the schedule was applied at ``qbar_pa`` and ``mach``
    (with the authority axis off unless ``authority``)."""
    par = default_si_array()
    if not authority:
        par[P_SCH_AUTH:P_SCH_AUTH + SCHED_N] = 1.0
    apply_schedule(qbar_pa, mach, par, np.zeros(L.X_N))
    return par


def expected(name: str, qbar_pa: float) -> float:
    """The table's value, interpolated independently (numpy, clamped at the ends)."""
    return float(np.interp(qbar_pa, NODES_PA, TAB[name]))


def test_the_parameter_defaults_are_the_committed_table():
    assert PARAM_INDEX["CTL_SCHED"] < PARAM_INDEX["SCH_Q_1"]
    for i in range(SCHED_N):
        assert LAW_PARAMS[PARAM_INDEX[f"SCH_Q_{i + 1}"]].default == pytest.approx(
            TAB["qbar_kpa"][i])
        for prefix, key, *_ in SCHED_FAMILIES:
            assert LAW_PARAMS[PARAM_INDEX[f"{prefix}{i + 1}"]].default == pytest.approx(
                TAB[key][i])
    assert {f[1] for f in SCHED_FAMILIES} == {q[0] for q in SCHED_QUANTITIES}
    assert LAW_PARAMS[PARAM_INDEX["CTL_SCHED"]].default == 1.0


@pytest.mark.parametrize("i", range(SCHED_N))
def test_at_each_node_the_law_takes_that_nodes_values(i):
    """GIVEN the dynamic pressure of node i THEN every scheduled slot holds node i's value
    (a schedule indexed one node off, or with the fraction reversed, fails here)."""
    par = scheduled_par(NODES_PA[i])
    for slot, name, scale in TARGETS:
        assert par[slot] == pytest.approx(TAB[name][i] * scale, rel=1e-12), (i, name)


@pytest.mark.parametrize("frac", [0.25, 0.5, 0.9])
def test_between_nodes_the_values_are_interpolated_linearly(frac):
    for i in range(SCHED_N - 1):
        q = NODES_PA[i] + frac * (NODES_PA[i + 1] - NODES_PA[i])
        k, f = schedule_index(q, default_si_array())
        assert (k, f) == (i, pytest.approx(frac))
        par = scheduled_par(q)
        for slot, name, scale in TARGETS:
            assert par[slot] == pytest.approx(expected(name, q) * scale, rel=1e-12)


@pytest.mark.parametrize("q_pa", [0.0, 1.0, -5.0, math.nan, 0.5 * NODES_PA[0]])
def test_below_the_first_node_the_first_nodes_values_hold(q_pa):
    assert schedule_index(q_pa, default_si_array()) == (0, 0.0)
    par = scheduled_par(q_pa)
    for slot, name, scale in TARGETS:
        assert par[slot] == pytest.approx(TAB[name][0] * scale, rel=1e-12)


@pytest.mark.parametrize("q_pa", [NODES_PA[-1], 2.0 * NODES_PA[-1], 1e9, math.inf])
def test_above_the_last_node_the_last_nodes_values_hold(q_pa):
    assert schedule_index(q_pa, default_si_array()) == (SCHED_N - 2, 1.0)
    par = scheduled_par(q_pa)
    for slot, name, scale in TARGETS:
        assert par[slot] == pytest.approx(TAB[name][-1] * scale, rel=1e-12)


def test_the_schedule_is_continuous_in_dynamic_pressure():
    """No jump anywhere (nodes included): over a fine sweep each value moves by at most the
    table's steepest slope times the step."""
    qs = np.linspace(0.5 * NODES_PA[0], 1.2 * NODES_PA[-1], 4001)
    dq = qs[1] - qs[0]
    for slot, name, scale in TARGETS:
        v = np.array([scheduled_par(q)[slot] for q in qs])
        slope = np.max(np.abs(np.diff(TAB[name] * scale) / np.diff(NODES_PA)))
        tol = 1e-12 * max(1.0, float(np.max(np.abs(v))))
        assert np.max(np.abs(np.diff(v))) <= slope * dq * (1 + 1e-9) + tol, name


def test_non_increasing_nodes_do_not_break_the_kernel():
    """A ground station may write nodes out of order: the kernel stays finite and in range."""
    par = default_si_array()
    par[P_SCH_Q:P_SCH_Q + SCHED_N] = par[P_SCH_Q:P_SCH_Q + SCHED_N][::-1]
    for q in (0.0, 5e4, 1e5, 3e5, 1e6):
        k, f = schedule_index(q, par)
        assert 0 <= k <= SCHED_N - 2 and 0.0 <= f <= 1.0


def test_application_is_bumpless_for_the_integral_and_the_observer():
    """K int(e1) and d_hat = z + c omega keep their values when the gains change."""
    par = default_si_array()
    par[P_SCH_AUTH:P_SCH_AUTH + SCHED_N] = 1.0
    x = np.zeros(L.X_N)
    x[L.X_INT_E1:L.X_INT_E1 + 3] = (0.01, -0.02, 0.03)
    x[L.X_Z:L.X_Z + 3] = (0.1, 0.2, -0.3)
    x[L.X_EF + L.E_P:L.X_EF + L.E_P + 3] = (0.05, -0.04, 0.02)
    k_int = par[P_SLW_K1:P_SLW_K1 + 3] * x[L.X_INT_E1:L.X_INT_E1 + 3]
    d_hat = x[L.X_Z:L.X_Z + 3] + par[P_DOB_C] * x[L.X_EF + L.E_P:L.X_EF + L.E_P + 3]
    node = next(i for i in range(SCHED_N)
                if TAB["K"][i] != par[P_SLW_K1] and TAB["dob_c"][i] != par[P_DOB_C])
    apply_schedule(NODES_PA[node], MACH_STABLE, par, x)
    assert par[P_SLW_K1] == TAB["K"][node] and par[P_DOB_C] == TAB["dob_c"][node]
    np.testing.assert_allclose(par[P_SLW_K1:P_SLW_K1 + 3] * x[L.X_INT_E1:L.X_INT_E1 + 3],
                               k_int, rtol=1e-12)
    np.testing.assert_allclose(
        x[L.X_Z:L.X_Z + 3] + par[P_DOB_C] * x[L.X_EF + L.E_P:L.X_EF + L.E_P + 3], d_hat,
        rtol=1e-12)


def test_the_mach_axis_defaults_are_the_committed_table():
    for i in range(SCHED_N):
        assert LAW_PARAMS[PARAM_INDEX[f"SCH_M_{i + 1}"]].default == MACH_NODES[i]
        assert LAW_PARAMS[PARAM_INDEX[f"SCH_OMCF_{i + 1}"]].default == pytest.approx(
            MACH_FACTOR[i], rel=1e-12)
    # appended after the dynamic-pressure table: the earlier parameters keep their slots
    assert PARAM_INDEX["SCH_M_1"] > PARAM_INDEX[f"SCH_OMC_{SCHED_N}"]


@pytest.mark.parametrize("mach", [0.0, 4.0, 6.0, 7.4, 8.0, 8.04, math.nan])
def test_up_to_mach_8_the_rate_limit_is_the_dynamic_pressure_tables(mach):
    """The airframe is directionally stable up to Mach 8.044 (Cn_beta >= 0 in the nominal
    model; the second Mach node): the Mach factor is exactly 1 there, so every point whose
    estimated Mach stays below it flies the values it flew before the Mach axis (docs/margins.md
    s. 6b; the Mach 8 / 30 km flights reach Mach 8.002)."""
    for q in (*NODES_PA, 0.5 * (NODES_PA[2] + NODES_PA[3])):
        par = scheduled_par(q, mach)
        # (to the last bits: the interpolation's rounding differs from the test's; a factor
        # other than 1 is a relative change far above 1e-12)
        assert par[P_SLW_OMC_MAX] == pytest.approx(expected("omc_max_deg_s", q) * DEG,
                                                   rel=1e-12)
        for slot, name, scale in TARGETS:
            assert par[slot] == pytest.approx(expected(name, q) * scale, rel=1e-12)


@pytest.mark.parametrize("mach", [8.5, 9.0, 10.0, 11.3, 12.0, 13.0, 14.0, 14.6, 15.0, 17.0, 25.0])
def test_above_mach_8_the_rate_limit_takes_the_mach_factor(mach):
    """GIVEN a Mach number THEN SLW_OMC_MAX = the dynamic-pressure value x the Mach factor
    interpolated linearly between the Mach nodes (clamped above the last); the other
    scheduled values do not depend on Mach. A Mach index one node off fails here."""
    fac = float(np.interp(mach, MACH_NODES, MACH_FACTOR))
    assert fac < 1.0
    for q in (NODES_PA[1], NODES_PA[4], 2.2e5):
        par = scheduled_par(q, mach)
        assert par[P_SLW_OMC_MAX] == pytest.approx(expected("omc_max_deg_s", q) * DEG * fac,
                                                   rel=1e-12)
        for slot, name, scale in TARGETS[:-1]:
            assert par[slot] == pytest.approx(expected(name, q) * scale, rel=1e-12)
    k, f = mach_index(mach, default_si_array())
    assert 0 <= k <= SCHED_N - 2 and MACH_NODES[k] <= min(mach, MACH_NODES[-1]) <= MACH_NODES[k + 1]


def test_the_mach_factor_falls_with_the_directional_instability():
    """The committed factors: 1 where the nominal airframe is directionally stable, then
    falling with Mach as Cn_beta goes negative (tools.schedule_design.omc_mach_factor)."""
    from tools.schedule_design import directional_instability, omc_mach_factor
    for m, f in zip(MACH_NODES, MACH_FACTOR):
        a_dir, _ = directional_instability(m)
        assert f == pytest.approx(omc_mach_factor(m), rel=1e-12)
        assert (f == 1.0) == (a_dir <= 0.0)
    assert np.all(np.diff(MACH_FACTOR) <= 0.0) and MACH_FACTOR[-1] < 0.6


def test_nodes_written_out_of_order_leave_the_mach_axis_finite():
    par = default_si_array()
    par[P_SCH_M:P_SCH_M + SCHED_N] = par[P_SCH_M:P_SCH_M + SCHED_N][::-1]
    for m in (0.0, 7.0, 12.0, 30.0):
        k, f = mach_index(m, par)
        assert 0 <= k <= SCHED_N - 2 and 0.0 <= f <= 1.0


def test_the_authority_axis_defaults_are_the_committed_table():
    for i in range(SCHED_N):
        assert LAW_PARAMS[PARAM_INDEX[f"SCH_AUTH_{i + 1}"]].default == pytest.approx(
            AUTH[i], rel=1e-12)
    # appended after the Mach factor: the earlier parameters keep their slots
    assert PARAM_INDEX["SCH_AUTH_1"] > PARAM_INDEX[f"SCH_OMCF_{SCHED_N}"]


def test_the_authority_factor_is_the_least_effective_channels_ratio():
    """The committed factors: the least effective channel's effectiveness at each Mach node
    over the least over Mach 6-15 (tools.schedule_design.authority_factor): >= 1, falling with
    Mach, 1 at Mach 15 where the rudder is weakest (the nodes were designed there)."""
    from tools.schedule_design import authority_factor
    for m, a in zip(MACH_NODES, AUTH):
        assert a == pytest.approx(max(authority_factor(m), 1.0), rel=1e-12)
        # the ratio does not depend on the dynamic pressure (both scale with it)
        assert authority_factor(m, 50e3) == pytest.approx(authority_factor(m, 250e3), rel=1e-9)
    assert np.all(AUTH >= 1.0) and np.all(np.diff(AUTH) < 0.0)
    assert AUTH[-1] == 1.0 and AUTH[0] > 1.4


@pytest.mark.parametrize("mach", [0.0, 6.0, 7.4, 7.5, 9.0, 12.0, 14.5, 15.0, 20.0, math.nan])
def test_the_gains_are_read_at_the_dynamic_pressure_times_the_authority_factor(mach):
    """GIVEN a Mach number THEN every scheduled gain and filter is the qbar table's value at
    qbar x SCH_AUTH(Mach) (interpolated between the Mach nodes, clamped at the ends; NaN ->
    the first node), and SLW_OMC_MAX keeps the plain dynamic pressure (times the Mach
    factor). A lookup at the plain dynamic pressure, or an authority index one node off,
    fails here."""
    m = MACH_NODES[0] if math.isnan(mach) else mach
    auth = float(np.interp(m, MACH_NODES, AUTH))
    fac = float(np.interp(m, MACH_NODES, MACH_FACTOR))
    for q in (0.5 * NODES_PA[0], NODES_PA[1], 4.0e4, 6.3e4, NODES_PA[3], 2.2e5, NODES_PA[-1]):
        par = scheduled_par(q, mach, authority=True)
        for slot, name, scale in TARGETS[:-1]:
            assert par[slot] == pytest.approx(expected(name, q * auth) * scale, rel=1e-12), (
                name, q)
        assert par[P_SLW_OMC_MAX] == pytest.approx(expected("omc_max_deg_s", q) * DEG * fac,
                                                   rel=1e-12)


def test_at_the_cruise_the_gains_are_those_of_a_higher_node():
    """The cruise (Mach 7.5, 63 kPa) flies the gains the table gives at about 93 kPa: the
    rudder there is 1.48 times as effective as at Mach 15, which the nodes were sized on."""
    par = scheduled_par(6.3e4, 7.5, authority=True)
    q_eff = 6.3e4 * float(np.interp(7.5, MACH_NODES, AUTH))
    assert 9.0e4 < q_eff < 9.6e4
    assert par[P_DOB_C] == pytest.approx(expected("dob_c", q_eff), rel=1e-12)
    assert par[P_SLW_KAPPA] > expected("kappa1", 6.3e4) * 1.2


def _est_at(qbar_pa: float, law: AttitudeLaw) -> np.ndarray:
    """An estimated state at Mach 8 whose nominal dynamic pressure is ``qbar_pa``."""
    from tools.schedule_design import altitude_for, atm_at
    h = altitude_for(8.0, qbar_pa, law.atm, law.grid)
    est = np.zeros(L.E_N)
    est[L.E_ALPHA] = 5 * DEG
    est[L.E_V] = 8.0 * atm_at(h, law.atm, law.grid)[L.ATM_SOUND]
    est[L.E_H] = h
    return est


def test_the_sch_parameters_reach_the_law_through_its_estimated_air_data():
    """GIVEN a law whose SCH_KAP2_3 is set by name WHEN it flies a slow step at node 3's
    dynamic pressure (from the estimated airspeed and altitude) THEN kappa2 in use is that
    value; at CTL_SCHED 0 the fixed FST_KAPPA is back."""
    law = AttitudeLaw({"SCH_KAP2_3": 7.25, "FST_KAPPA": 5.0, **AUTH_OFF})
    est = _est_at(NODES_PA[2], law)
    law.reset(est)
    law.slow_step(est, (5 * DEG, 0.0, 0.0), 0.01)
    assert law.status_dict()["qbar_Pa"] == pytest.approx(NODES_PA[2], rel=1e-6)
    assert law.par[P_FST_KAPPA] == pytest.approx(7.25, rel=1e-6)
    assert law.par[P_SLW_KAPPA] == pytest.approx(TAB["kappa1"][2], rel=1e-5)
    law.set_param("CTL_SCHED", 0)
    for name in SCHEDULED_NAMES:
        assert law.par[PARAM_INDEX[name]] == pytest.approx(
            LAW_PARAMS[PARAM_INDEX[name]].default * LAW_PARAMS[PARAM_INDEX[name]].si_scale)
    law.slow_step(est, (5 * DEG, 0.0, 0.0), 0.01)
    assert law.par[P_FST_KAPPA] == 5.0                        # the paper's fixed gain
    law.set_param("CTL_SCHED", 1)
    law.slow_step(est, (5 * DEG, 0.0, 0.0), 0.01)
    assert law.par[P_FST_KAPPA] == pytest.approx(7.25, rel=1e-6)


def test_paper_literal_flies_the_papers_gains():
    law = AttitudeLaw({"PAPER_LITERAL": 1})
    est = _est_at(NODES_PA[1], law)
    law.reset(est)
    law.slow_step(est, (5 * DEG, 0.0, 0.0), 0.01)
    assert law.par[P_SLW_KAPPA] == 5.0 and law.par[P_SLW_K1] == 4.0
    assert law.par[P_DOB_C] == 10.0
