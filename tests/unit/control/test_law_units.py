"""Unit tests of the control law's parts (fc/control): kinematics, projection, factors,
allocation, observer, parameters, and no allocation after warm-up."""
from __future__ import annotations

import math
import os
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from fc.control import kernels as K
from fc.control import layout as L
from fc.control.law import AttitudeLaw
from fc.control.params import (LAW_PARAMS, P_CO_ENABLE, P_CO_FAC_EQ, P_CO_K1,
                               P_CO_LAM_MAX, P_N, PARAM_INDEX, check_value, default_si_array)

DEG = math.pi / 180.0
REPO = Path(__file__).resolve().parents[3]


def paper_est(alpha_deg=1.0, beta_deg=5.0, mu_deg=0.0, p=0.0, q=0.0, r=0.0):
    """Estimated state at the paper's initial point (2200 m/s, 21 km, level)."""
    return np.array([alpha_deg * DEG, beta_deg * DEG, mu_deg * DEG, p, q, r,
                     2200.0, 21000.0, 0.0])


def g_s(alpha, beta):
    """Eq. 3 written out independently of the kernels."""
    sa, ca, tb, cb = math.sin(alpha), math.cos(alpha), math.tan(beta), math.cos(beta)
    return np.array([[-ca * tb, 1.0, -sa * tb],
                     [sa, 0.0, -ca],
                     [ca / cb, 0.0, sa / cb]])


# ---------------------------------------------------------------------------------------------
# g_s (Eq. 3)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("alpha_deg,beta_deg", [(1, 5), (5, 0), (12, -20), (-3, 40), (8, 70)])
def test_gs_inverse_and_determinant(alpha_deg, beta_deg):
    # GIVEN the state; WHEN the kernels apply g_s^-1 and g_s^T; THEN they match numpy
    a, b = alpha_deg * DEG, beta_deg * DEG
    G = g_s(a, b)
    # det g_s = -sec(beta) (paper_notes): invertible for |beta| < 90 deg
    assert np.linalg.det(G) == pytest.approx(-1.0 / math.cos(b), rel=1e-12)
    out = np.zeros(3)
    rng = np.random.default_rng(1)
    for _ in range(5):
        v = rng.normal(size=3)
        K.gs_inv_apply(a, b, v[0], v[1], v[2], out, 0)
        np.testing.assert_allclose(G @ out, v, rtol=0, atol=1e-12)
        np.testing.assert_allclose(out, np.linalg.solve(G, v), rtol=1e-10, atol=1e-12)
        K.gs_t_apply(a, b, v[0], v[1], v[2], out, 0)
        np.testing.assert_allclose(out, G.T @ v, rtol=1e-12, atol=1e-12)


def test_solve3_matches_numpy():
    rng = np.random.default_rng(2)
    a = rng.normal(size=9) * 1e7
    out = np.zeros(3)
    det = K.solve3(a, 0, 1e6, -2e6, 3e5, out, 0)
    A = a.reshape(3, 3)
    assert det == pytest.approx(np.linalg.det(A), rel=1e-10)
    np.testing.assert_allclose(out, np.linalg.solve(A, [1e6, -2e6, 3e5]), rtol=1e-9)


# ---------------------------------------------------------------------------------------------
# Projection (Eq. 30 / 36)
# ---------------------------------------------------------------------------------------------
def test_projection_identity_inside_and_bounded_outside():
    law = AttitudeLaw({"SLW_LEAK": 0.0, "SLW_GAMMA": 1.0, "REF_PF_EN": 0, "SLW_AW": 0})
    est = paper_est()
    law.reset(est)
    cmd = (5 * DEG, 0.0, 4 * DEG)
    dt = 0.01
    law.slow_step(est, cmd, dt)
    # inside the box the projection is the identity: rho = dt * Gamma * Psi_i theta_i * sigma_row
    sig = law.status[L.S_SIGMA:L.S_SIGMA + 3]
    rows = (0, 1, 2, 2)
    psi = law.nm[L.NM_PSI:L.NM_PSI + 4]
    expected = np.array([dt * 1.0 * psi[i] * sig[rows[i]] for i in range(4)])
    rho = law.x[L.X_RHO_S:L.X_RHO_S + 4]
    assert np.all(np.abs(expected) < 0.5)           # really inside the box
    assert np.any(np.abs(expected) > 0)             # and really moving
    np.testing.assert_allclose(rho, expected, rtol=1e-12, atol=1e-18)

    # with a huge gain, every estimate stays inside [-bound, bound] and some sit on it
    law.set_param("SLW_GAMMA", 1e4)
    law.set_param("SLW_TH_BND", 0.3)
    law.set_param("FST_GAMMA", 1e4)
    law.set_param("FST_TH_BND", 0.2)
    law.set_param("SLW_AW", 0)
    est2 = paper_est(alpha_deg=3, beta_deg=4, p=0.2, q=-0.1, r=0.05)
    for _ in range(200):
        law.slow_step(est2, cmd, dt)
        for _ in range(5):
            law.fast_step(est2, dt / 5)
    rho_s = law.x[L.X_RHO_S:L.X_RHO_S + 4]
    rho_f = law.x[L.X_RHO_F:L.X_RHO_F + 17]
    assert np.all(np.abs(rho_s) <= 0.3 + 1e-15)
    assert np.all(np.abs(rho_f) <= 0.2 + 1e-15)
    assert np.sum(np.abs(rho_s) == 0.3) >= 1
    assert np.sum(np.abs(rho_f) == 0.2) >= 1


# ---------------------------------------------------------------------------------------------
# Coordinated factors (Eqs. 10-14, 19)
# ---------------------------------------------------------------------------------------------
def _factor_par(eq, ks, lam_max=0.0):
    par = default_si_array()
    par[P_CO_ENABLE] = 1.0
    par[P_CO_FAC_EQ] = eq
    for i, k in enumerate(ks):
        par[P_CO_K1 + i] = k
    par[P_CO_LAM_MAX] = lam_max
    return par


@pytest.mark.parametrize("eq", [14, 19])
def test_factors_hand_computed(eq):
    # GIVEN alpha 4 deg, beta -2 deg, p 0.1, q -0.05, r 0.02 and k_i = i / 10, Delta_alpha 0.05
    a, b, p, q, r = 4 * DEG, -2 * DEG, 0.1, -0.05, 0.02
    est = np.array([a, b, 0.0, p, q, r, 2200.0, 21000.0, 0.0])
    ks = [0.1 * (i + 1) for i in range(9)]
    par = _factor_par(eq, ks)
    out = np.zeros(3)
    K.coordinated_factors(est, par, out, 0)
    k1, k2, k3, k4, k5, k6, k7, k8, k9 = ks
    lr = (k1 * p * math.tan(a) + k2 * b + k3 * p * (1 - math.cos(a)) / (math.sin(a) + 0.05)
          + k8 * b + k9 * q)
    if eq == 14:
        le, la = k4 * a + k5 * p, k6 * b + k7 * r
    else:
        le, la = k4 * a + k5 * q, k6 * b + k7 * p
    np.testing.assert_allclose(out, [le, la, lr], rtol=1e-13, atol=1e-16)
    # CO_LAMR_SCL (issue 20: the schedule's rudder share) scales lambda_r only
    par[PARAM_INDEX["CO_LAMR_SCL"]] = 0.4
    K.coordinated_factors(est, par, out, 0)
    np.testing.assert_allclose(out, [le, la, 0.4 * lr], rtol=1e-13, atol=1e-16)


def test_factors_zero_when_uncoordinated_and_clamped():
    est = paper_est(alpha_deg=10, beta_deg=10, p=1.0, q=1.0, r=1.0)
    par = _factor_par(14, [1.0] * 9, lam_max=0.5)
    out = np.zeros(3)
    K.coordinated_factors(est, par, out, 0)
    assert np.all(np.abs(out) <= 0.5) and np.max(np.abs(out)) == 0.5
    par[P_CO_ENABLE] = 0.0
    K.coordinated_factors(est, par, out, 0)
    assert np.all(out == 0.0)


# ---------------------------------------------------------------------------------------------
# Allocation (Eqs. 44-47)
# ---------------------------------------------------------------------------------------------
def _alloc_setup(coordinated=True, surf=0, overrides=None):
    law = AttitudeLaw({"CO_ENABLE": int(coordinated), "CO_SURF": surf, **(overrides or {})})
    est = paper_est(alpha_deg=3, beta_deg=2, p=0.05, q=0.02, r=-0.03)
    K.coordinated_factors(est, law.par, law.status, L.S_LAMBDA)
    from fc.control.nominal import eval_model
    eval_model(est, law.par, law.tab, law.atm, law.grid, law.nm)
    fb = K.coordinated_matrix(law.par, law.nm, law.status, L.S_LAMBDA)
    return law, fb


@pytest.mark.parametrize("co_map", [0, 1])
def test_allocator_exact_when_unsaturated(co_map):
    law, fb = _alloc_setup(coordinated=True, surf=0, overrides={"CO_MAP": co_map})
    assert fb == 0.0
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    lam = law.status[L.S_LAMBDA:L.S_LAMBDA + 3]
    assert np.any(lam != 0)
    if co_map == 0:
        # Eq. 45 with CO_NORM 0: the factors scale the printed diagonal entries
        np.testing.assert_allclose(np.diag(G), np.diag(Gf) * (1 + lam), rtol=1e-12)
        off = ~np.eye(3, dtype=bool)
        np.testing.assert_array_equal(G[off], Gf[off])
    else:
        # the loops of the prose: roll row x (1 + lambda_a), pitch row x (1 + lambda_e),
        # yaw row x (1 + lambda_r)
        scale = np.array([1 + lam[1], 1 + lam[0], 1 + lam[2]])
        np.testing.assert_allclose(G, Gf * scale[:, None], rtol=1e-12)
    mc = np.array([1.0e6, -2.0e6, 5.0e5])
    delta = np.zeros(3)
    sat = K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, delta, law.status)
    assert sat == 0.0
    np.testing.assert_allclose(G @ delta, mc, rtol=1e-10)
    np.testing.assert_allclose(law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3], 0, atol=1e-6)
    assert np.all(law.status[L.S_SAT:L.S_SAT + 3] == 0)


def test_allocator_reports_shortfall_and_keeps_direction():
    law, _ = _alloc_setup(coordinated=True, surf=0)
    law.set_param("ALLOC_MODE", 1)
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    mc = np.array([2.0e7, -1.0e7, 8.0e6])         # far beyond +-20 deg
    raw = np.linalg.solve(G, mc)
    assert np.max(np.abs(raw)) > 20 * DEG
    delta = np.zeros(3)
    sat = K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, delta, law.status)
    assert sat == 1.0
    assert np.max(np.abs(delta)) == pytest.approx(20 * DEG, rel=1e-12)
    achieved = G @ delta
    # direction kept: achieved = s * M_c with s = 20 deg / max|raw|
    s = 20 * DEG / np.max(np.abs(raw))
    np.testing.assert_allclose(achieved, s * mc, rtol=1e-9)
    np.testing.assert_allclose(law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3], (1 - s) * mc,
                               rtol=1e-9)
    assert law.status[L.S_ALLOC_SCALE] == pytest.approx(s)
    flags = law.status[L.S_SAT:L.S_SAT + 3]
    np.testing.assert_array_equal(flags, (np.abs(raw) > 20 * DEG).astype(float))

    # clip mode (the printed paper): per-surface clip, shortfall reported, direction lost
    law.set_param("ALLOC_MODE", 0)
    K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, delta, law.status)
    np.testing.assert_allclose(delta, np.clip(raw, -20 * DEG, 20 * DEG), rtol=1e-12)
    np.testing.assert_allclose(law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3], mc - G @ delta,
                               rtol=1e-9)


def _weighted_shortfall(law, G, mc, delta):
    """sum_i w_i (G delta - M_c)_i^2 with the prioritised mode's weights (per angular
    acceleration: w_i = ALLOC_W_i / I_i^2)."""
    w = np.array([law.get_param("ALLOC_W_ROLL") / law.get_param("MDL_IXX") ** 2,
                  law.get_param("ALLOC_W_PITCH") / law.get_param("MDL_IYY") ** 2,
                  law.get_param("ALLOC_W_YAW") / law.get_param("MDL_IZZ") ** 2])
    r = G @ delta - mc
    return float(np.sum(w * r * r)), w


@pytest.mark.parametrize("mc", [(2.0e7, -1.0e7, 8.0e6), (-3.0e6, 4.0e7, -2.0e7),
                                (1.0e6, -2.0e6, 3.0e7)], ids=["roll", "pitch", "yaw"])
def test_prioritised_allocation_holds_the_worst_surface_and_reoptimises_the_rest(mc):
    """ALLOC_MODE 2 (the default): the surface furthest beyond its limit in the coordinated
    allocation g_Gamma^-1 M_c is held at the limit, the free ones solve the weighted least
    squares of the *physical* shortfall g_f_delta delta - M_c (their gradient is 0; with the
    surfaces short the coordinated reshaping is not kept, docs/control_law.md s. 13), and that
    weighted shortfall is no larger than scaling's or clipping's. The unallocated moment is
    reported in the coordinated matrix's terms, as in the other modes."""
    law, _ = _alloc_setup(coordinated=True, surf=0)
    assert law.get_param("ALLOC_MODE") == 2
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    assert not np.allclose(G, Gf)                       # the factors are acting
    mc = np.array(mc)
    raw = np.linalg.solve(G, mc)
    assert np.max(np.abs(raw)) > 20 * DEG
    delta = np.zeros(3)
    sat = K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, delta, law.status)
    assert sat == 1.0
    lim = 20 * DEG
    assert np.all(np.abs(delta) <= lim * (1 + 1e-12))
    held = np.isclose(np.abs(delta), lim, rtol=1e-12)
    assert held[np.argmax(np.abs(raw))], "the worst surface is held at its limit"
    j, w = _weighted_shortfall(law, Gf, mc, delta)
    free = ~held
    grad = Gf.T @ (w * (Gf @ delta - mc))
    ref = np.abs(Gf.T) @ (w * (np.abs(Gf) @ np.abs(delta) + np.abs(mc)))
    assert np.all(np.abs(grad[free]) <= 1e-9 * ref[free])
    np.testing.assert_allclose(law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3], mc - G @ delta,
                               rtol=1e-9, atol=1e-3)
    assert law.status[L.S_ALLOC_SCALE] == 1.0           # no common scale (as clipping)
    for mode in (0, 1):
        law.set_param("ALLOC_MODE", mode)
        other = np.zeros(3)
        K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, other, law.status)
        assert j <= _weighted_shortfall(law, Gf, mc, other)[0] * (1 + 1e-9), mode


def test_prioritised_allocation_serves_the_yaw_axis_first():
    """With the default weights (yaw 300, pitch 10, roll 1 per angular acceleration) the yaw
    shortfall is smaller than with equal weights, and than with scaling."""
    law, _ = _alloc_setup(coordinated=True, surf=0)
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    mc = np.array([2.0e7, -1.0e7, 8.0e6])
    out = {}
    for tag, sets in (("prio", {}), ("equal", {"ALLOC_W_YAW": 1.0, "ALLOC_W_PITCH": 1.0}),
                      ("scale", {"ALLOC_MODE": 1})):
        for k, v in sets.items():
            law.set_param(k, v)
        d = np.zeros(3)
        K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, d, law.status)
        out[tag] = abs((G @ d - mc)[2])
        law.set_param("ALLOC_MODE", 2)
        law.set_param("ALLOC_W_YAW", 300.0)
        law.set_param("ALLOC_W_PITCH", 10.0)
    assert out["prio"] < out["equal"] and out["prio"] < out["scale"], out


def test_yaw_escalation_scale_is_the_yaw_weight_times_the_scale():
    """allocate's w_yaw_scale (the yaw escalation, ALLOC_YAW_T) multiplies ALLOC_W_YAW in the
    re-solve: scale 3 allocates as ALLOC_W_YAW x 3 does, and leaves a smaller yaw shortfall
    than scale 1."""
    law, _ = _alloc_setup(coordinated=True, surf=0)
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    mc = np.array([2.0e7, -1.0e7, 8.0e6])
    one, three, ref = np.zeros(3), np.zeros(3), np.zeros(3)
    K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, one, law.status, 1.0)
    K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, three, law.status, 3.0)
    law.set_param("ALLOC_W_YAW", 3 * law.get_param("ALLOC_W_YAW"))
    K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, ref, law.status, 1.0)
    np.testing.assert_allclose(three, ref, rtol=1e-12, atol=1e-15)
    assert abs((Gf @ three - mc)[2]) < abs((Gf @ one - mc)[2])


@pytest.mark.parametrize("r_rad_s", [0.05, 0.5], ids=["rudder-alone", "all-surfaces"])
def test_yaw_escalation_time_counts_only_while_the_rudder_alone_is_short(r_rad_s):
    """The fast loop's escalation time x[X_YAW_T] grows by the fast step while the rudder alone
    is asked beyond its limit (the elevons within theirs), and counts down to 0 otherwise;
    the re-solve's yaw weight is ALLOC_W_YAW x min(1 + t / ALLOC_YAW_T, ALLOC_YAW_MAX)."""
    law = AttitudeLaw({})
    assert law.get_param("ALLOC_YAW_T") > 0.0
    law.reset(paper_est(alpha_deg=3, beta_deg=2))
    cmd = np.radians([3.0, 2.0, 0.0])
    law.cycle(paper_est(alpha_deg=3, beta_deg=2), cmd, 0.01, 0.002)
    est = paper_est(alpha_deg=3, beta_deg=2, r=r_rad_s)
    seen = set()
    for k in range(60):
        if k == 40:
            est = paper_est(alpha_deg=3, beta_deg=2)      # the demand gone: counts down
        before = law.x[L.X_YAW_T]
        law.fast_step(est, 0.002)
        flags = tuple(law.status[L.S_SAT:L.S_SAT + 3])
        seen.add(flags)
        if flags == (0.0, 0.0, 1.0):
            assert law.x[L.X_YAW_T] == pytest.approx(before + 0.002)
        else:
            assert law.x[L.X_YAW_T] == pytest.approx(max(before - 0.002, 0.0))
    # both rules were exercised: the rudder alone short, and (the larger demand, once the
    # rate filter has passed it) every surface short
    assert (0.0, 0.0, 1.0) in seen, seen
    assert ((1.0, 1.0, 1.0) in seen) == (r_rad_s == 0.5), seen


@pytest.mark.parametrize("yaw_t_s,yaw_max", [(0.05, 10.0), (0.004, 3.0), (0.0, 10.0)],
                         ids=["growing", "capped", "off"])
def test_yaw_escalation_weighs_the_re_solve_by_the_time_on_the_limit(yaw_t_s, yaw_max):
    """Each fast step's surface command is allocate(..., w_yaw_scale) with w_yaw_scale =
    min(1 + t / ALLOC_YAW_T, ALLOC_YAW_MAX), t the escalation time before the step, then the
    rate-aware limit: rebuilt here from the step's own M_c and E, and it differs from the
    command that the unescalated weight gives. ALLOC_YAW_T 0: the weight stays ALLOC_W_YAW
    although the time is counted."""
    law = AttitudeLaw({"ALLOC_YAW_T": yaw_t_s, "ALLOC_YAW_MAX": yaw_max})
    law.reset(paper_est(alpha_deg=3, beta_deg=2))
    law.cycle(paper_est(alpha_deg=3, beta_deg=2), np.radians([3.0, 2.0, 0.0]), 0.01, 0.002)
    est = paper_est(alpha_deg=3, beta_deg=2, r=0.05)
    checked = differed = 0
    for _ in range(40):
        before = law.x.copy()
        law.fast_step(est, 0.002)
        if tuple(law.status[L.S_SAT:L.S_SAT + 3]) != (0.0, 0.0, 1.0) or before[L.X_YAW_T] == 0:
            continue
        mc = law.status[L.S_M_C:L.S_M_C + 3]
        e = float(law.status[L.S_E_COUP])
        scale = min(1.0 + before[L.X_YAW_T] / yaw_t_s, yaw_max) if yaw_t_s > 0 else 1.0
        out = {}
        for tag, sc in (("escalated", scale), ("plain", 1.0)):
            d = np.zeros(3)
            st = law.status.copy()
            xx = before.copy()
            K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], e, d, st, sc)
            K.rate_limit_command(law.par, law.nm, xx, e, 0.002, d, st)
            out[tag] = d
        np.testing.assert_allclose(law.x[L.X_DCMD:L.X_DCMD + 3], out["escalated"], rtol=1e-12,
                                   atol=1e-15)
        checked += 1
        differed += not np.allclose(out["escalated"], out["plain"], rtol=1e-9, atol=1e-12)
    assert checked >= 10, checked
    assert (differed >= checked // 2) if yaw_t_s > 0 else differed == 0, (checked, differed)


@pytest.mark.parametrize("mc", [(1.2e7, -6.0e6, 4.8e6), (6.0e5, -1.2e6, 1.8e7)],
                         ids=["roll", "yaw"])
def test_prioritised_allocation_with_the_interconnect_stays_within_limits(mc):
    """CO_SURF 1 (Eq. 47 interconnect, u1 = d1 - E d2): the limits hold on the surfaces after
    Eq. 47, the unallocated moment is reported in the allocation's variables, and the free
    surfaces are optimal for the physical matrix acting on the surfaces, G_d = g_f_delta T^-1."""
    law, _ = _alloc_setup(coordinated=True, surf=1)
    assert law.get_param("ALLOC_MODE") == 2
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    mc = np.array(mc)
    delta = np.zeros(3)
    e = 0.7
    sat = K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], e, delta, law.status)
    assert sat == 1.0
    lim = 20 * DEG
    assert np.all(np.abs(delta) <= lim * (1 + 1e-12))
    u = np.array([delta[0], delta[1] - e * delta[2], delta[2]])
    np.testing.assert_allclose(law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3], mc - G @ u,
                               rtol=1e-9, atol=1e-3)
    t_inv = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -e], [0.0, 0.0, 1.0]])
    gd = Gf @ t_inv
    _, w = _weighted_shortfall(law, Gf, mc, delta)
    free = ~np.isclose(np.abs(delta), lim, rtol=1e-12)
    assert free.any()
    grad = gd.T @ (w * (gd @ delta - mc))
    ref = np.abs(gd.T) @ (w * (np.abs(gd) @ np.abs(delta) + np.abs(mc)))
    assert np.all(np.abs(grad[free]) <= 1e-9 * ref[free])


def test_prioritised_on_small_hand_made_matrices():
    """allocation.prioritised by hand, at unit scale (weights 1, limit 1): the worst surface
    held, the next re-solved, and the degenerate cases (two identical free columns) leave the
    free surfaces at 0 instead of dividing by zero."""
    from fc.control.allocation import prioritised
    half = np.diag([0.5, 0.5, 0.5]).ravel()
    # diagonal: d0 held at +1, d1 and d2 re-solved exactly
    m = 0.5 * np.array([3.0, 0.5, 0.2])
    d = prioritised(half, 0, 0.0, *m, 1.0, 1.0, 1.0, 1.0, 3.0, 0.5, 0.2)
    np.testing.assert_allclose(d, (1.0, 0.5, 0.2), rtol=1e-12)
    # two surfaces beyond: d0 held, then d2 held, d1 alone (one free column)
    m = 0.5 * np.array([3.0, 0.5, 2.5])
    d = prioritised(half, 0, 0.0, *m, 1.0, 1.0, 1.0, 1.0, 3.0, 0.5, 2.5)
    np.testing.assert_allclose(d, (1.0, 0.5, 1.0), rtol=1e-12)
    # identical free columns: the 2x2 normal equations are singular, the free surfaces 0
    a = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).ravel()
    d = prioritised(a, 0, 0.0, 0.2, 0.2, 3.0, 1.0, 1.0, 1.0, 1.0, 0.1, 0.1, 3.0)
    assert d == (0.0, 0.0, 1.0)
    # the interconnect's third column G2 - e G1 (e = 0.5): with d1 held the rudder solves
    # its own column
    a = np.eye(3).ravel()
    d = prioritised(a, 0, 0.5, 0.0, 3.0, 0.2, 1.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.2)
    # columns: c0 = (1,0,0), c1 = (0,1,0), c2 = (0,-0.5,1); d1 held at 1, then
    # min (d0)^2 + (1 - 0.5 d2 - 3)^2 + (d2 - 0.2)^2: d0 = 0, d2 = (0.2 - 1) / 1.25
    np.testing.assert_allclose(d, (0.0, 1.0, (0.2 - 1.0) / 1.25), rtol=1e-12)
    # a rudder with pitch effectiveness (G12 = 0.5) that the interconnect cancels exactly
    a = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.5], [0.0, 0.0, 1.0]]).ravel()
    d = prioritised(a, 0, 0.5, 0.0, 3.0, 0.2, 1.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.2)
    np.testing.assert_allclose(d, (0.0, 1.0, 0.2), rtol=1e-12)


def test_surface_coordination_eq47():
    law, _ = _alloc_setup(coordinated=True, surf=1)
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    mc = np.array([1.0e6, -2.0e6, 5.0e5])
    raw = np.linalg.solve(G, mc)
    delta = np.zeros(3)
    K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, delta, law.status)
    np.testing.assert_allclose(delta, [raw[0], raw[1] + 0.7 * raw[2], raw[2]], rtol=1e-12)
    law.set_param("CO_SURF", 2)
    K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, delta, law.status)
    np.testing.assert_allclose(delta, [raw[0], 0.7 * raw[2], raw[2]], rtol=1e-12)


def test_coordinated_matrix_guard_rejects_sign_flip():
    # lambda_e = -1.5 (CO_NORM 0, no clamp) flips the sign of the (roll, left elevon) entry
    law, _ = _alloc_setup(coordinated=True, surf=0, overrides={"CO_LAM_MAX": 0, "CO_MAP": 0})
    lam = np.array([-1.5, 0.0, 0.0])
    fb = K.coordinated_matrix(law.par, law.nm, lam, 0)
    assert fb == 1.0
    np.testing.assert_array_equal(law.nm[L.NM_GCO:L.NM_GCO + 9], law.nm[L.NM_GFD:L.NM_GFD + 9])
    # and with the axis mapping, lambda_e = -1.5 flips the pitch row
    law.set_param("CO_MAP", 1)
    assert K.coordinated_matrix(law.par, law.nm, lam, 0) == 1.0


# ---------------------------------------------------------------------------------------------
# Disturbance observer (Eq. 37) on a toy double integrator
# ---------------------------------------------------------------------------------------------
def test_observer_converges_to_constant_disturbance():
    # GIVEN theta'' = u + d per axis, d constant and unknown, u = PD - d_hat
    d = np.array([0.7, -0.3, 0.05])        # rad/s^2
    c, dt = 10.0, 0.002
    x = np.zeros(L.X_N)
    theta = np.array([0.1, -0.2, 0.05])
    w = np.zeros(3)
    c_d = K.dob_gain(c, dt)
    x[L.X_Z:L.X_Z + 3] = -c_d * w
    for _ in range(int(5.0 / dt)):
        dh = np.array(K.dob_estimate(x, c_d, w[0], w[1], w[2]))
        u = -4.0 * theta - 4.0 * w - dh
        K.dob_update(x, c_d, dt, u[0], u[1], u[2], w[0], w[1], w[2])
        # plant: exact integration of a constant acceleration over dt
        acc = u + d
        theta = theta + w * dt + 0.5 * acc * dt * dt
        w = w + acc * dt
    dh = np.array(K.dob_estimate(x, c_d, w[0], w[1], w[2]))
    # THEN d_hat -> d: after 5 s = 50 time constants the error is below 1e-9 of the step
    np.testing.assert_allclose(dh, d, rtol=0, atol=1e-9)
    # and the compensated loop regulates theta to 0 (PD poles at -2, -2)
    assert np.max(np.abs(theta)) < 1e-3


# ---------------------------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------------------------
def test_param_table_contract():
    assert len(LAW_PARAMS) == P_N
    names = [p.name for p in LAW_PARAMS]
    assert len(set(names)) == len(names)
    for p in LAW_PARAMS:
        assert len(p.name) <= 16 and p.name.isupper(), p.name
        assert p.unit and p.description and p.group
        assert p.min <= p.default <= p.max
    assert "CO_ENABLE" in PARAM_INDEX


def test_set_param_converts_units_and_rejects_bad_values():
    law = AttitudeLaw()
    law.set_param("ACT_MAX", 15.0)
    assert law.par[PARAM_INDEX["ACT_MAX"]] == pytest.approx(15 * DEG)
    assert law.get_param("ACT_MAX") == 15.0
    with pytest.raises(KeyError):
        law.set_param("NO_SUCH_PARAM", 1.0)
    with pytest.raises(ValueError):
        law.set_param("ACT_MAX", 90.0)
    with pytest.raises(ValueError):
        law.set_param("CO_SURF", 1.5)
    with pytest.raises(ValueError):
        check_value("CO_FAC_EQ", 15)
    with pytest.raises(ValueError):
        law.set_param("DOB_C", float("nan"))
    with pytest.raises(ValueError):
        AttitudeLaw({"SLW_KAPPA": -1})
    with pytest.raises(ValueError):
        law.reset(np.zeros(5))


def test_reset_starts_at_state():
    law = AttitudeLaw()
    est = paper_est(p=0.1, q=-0.2, r=0.3)
    law.reset(est, np.array([0.01, 0.02, 0.03]))
    np.testing.assert_allclose(law.x[L.X_PF:L.X_PF + 3], est[:3])
    np.testing.assert_allclose(law.x[L.X_CF:L.X_CF + 3], est[3:6])
    np.testing.assert_allclose(law.x[L.X_DM:L.X_DM + 3], [0.01, 0.02, 0.03])
    np.testing.assert_allclose(law.delta_cmd_rad, [0.01, 0.02, 0.03])
    # with the prefilter on and the command equal to the state, nothing moves
    law.slow_step(est, est[:3], 0.01)
    np.testing.assert_allclose(law.status[L.S_E1:L.S_E1 + 3], 0, atol=1e-15)


# ---------------------------------------------------------------------------------------------
# No allocation after warm-up
# ---------------------------------------------------------------------------------------------
def _run_law(law, est, n):
    cmd = (5 * DEG, 0.0, 4 * DEG)
    for _ in range(n):
        law.slow_step(est, cmd, 0.01)
        for _ in range(5):
            law.fast_step(est, 0.002)


@pytest.mark.parametrize("coordinated", [0, 1])
def test_no_python_allocation_after_warmup(coordinated):
    law = AttitudeLaw({"CO_ENABLE": coordinated})
    est = paper_est()
    law.reset(est)
    _run_law(law, est, 20)                      # warm-up (compilation, caches)
    tracemalloc.start()
    try:
        snap0 = tracemalloc.take_snapshot()
        _run_law(law, est, 2000)
        snap1 = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    filt = [tracemalloc.Filter(True, "*fc/control/*")]
    growth = sum(s.size_diff for s in snap1.filter_traces(filt).compare_to(
        snap0.filter_traces(filt), "filename"))
    # 12000 loop calls: any per-call allocation kept alive would show as >= 12000 bytes
    assert growth < 1024, growth


def test_no_numba_allocation_after_warmup():
    """The kernels allocate nothing per step (numba runtime statistics, fresh process).

    Passing a numpy array into a numba function costs one runtime record per argument at
    the call boundary; so one call of ``cycle_kernel`` running 1 fast step and one running
    2000 must count exactly the same allocations, and none may stay alive.
    """
    code = (
        "import numpy as np\n"
        "from numba.core.runtime import rtsys\n"
        "from fc.control.law import AttitudeLaw\n"
        "from fc.control.kernels import cycle_kernel\n"
        "law = AttitudeLaw()\n"
        "est = np.array([0.0175, 0.0873, 0.0, 0.0, 0.0, 0.0, 2200.0, 21000.0, 0.0])\n"
        "law.reset(est)\n"
        "k = law.kernel_args()\n"
        "cmd = np.array([0.0873, 0.0, 0.0698])\n"
        "def run(n):\n"
        "    cycle_kernel(est, cmd, 0.01, 0.002, n, k['par'], k['x'], k['nm'], k['st'],\n"
        "                 k['tab'], k['atm'], k['grid'], k['delta'])\n"
        "run(1)\n"
        "a = rtsys.get_allocation_stats()\n"
        "run(1)\n"
        "b = rtsys.get_allocation_stats()\n"
        "run(2000)\n"
        "c = rtsys.get_allocation_stats()\n"
        "print(b.alloc - a.alloc, c.alloc - b.alloc, c.alloc - c.free)\n"
    )
    env = dict(os.environ, NUMBA_NRT_STATS="1", PYTHONPATH=str(REPO))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, cwd=REPO, timeout=240)
    assert out.returncode == 0, out.stderr
    one, many, alive = (int(v) for v in out.stdout.split())
    assert one == many, out.stdout          # independent of the number of steps
    assert one <= 13, out.stdout            # at most one per array argument (13 args)
    assert alive == 0, out.stdout


# ---------------------------------------------------------------------------------------------
# Input filters, API contract, stale-cache guard
# ---------------------------------------------------------------------------------------------
def test_input_filter_passes_dc_and_attenuates_noise():
    x = np.zeros(4)
    dt, fc = 0.002, 20.0
    # DC: a constant converges to itself
    for _ in range(500):
        y = K.lowpass2_step(1.5, dt, fc, x, 0, 1, False)
    assert y == pytest.approx(1.5, rel=1e-9)
    # white noise at 500 Hz: two 1st-order sections at 20 Hz cut the rms by > 3x
    rng = np.random.default_rng(3)
    u = rng.normal(size=20000)
    x[:] = 0.0
    out = np.array([K.lowpass2_step(v, dt, fc, x, 0, 1, False) for v in u])
    assert np.std(out[1000:]) < np.std(u) / 3.0
    # off (cutoff 0): pass-through
    assert K.lowpass2_step(0.3, dt, 0.0, x, 0, 1, False) == 0.3
    # angles: filtering across +-pi stays near pi, not near 0
    x[:] = math.pi - 0.01
    for _ in range(50):
        y = K.lowpass2_step(-math.pi + 0.01, dt, fc, x, 0, 1, True)
    assert abs(abs(y) - math.pi) < 0.02


def test_attitude_law_api_contract():
    """docs/architecture.md section 11."""
    from fc.control.law import STATUS_N
    law = AttitudeLaw({"CO_ENABLE": 0})
    est = paper_est()
    law.reset(est)
    law.slow_step(est, (5 * DEG, 0.0, 4 * DEG), 0.01)
    law.fast_step(est, 0.002)
    assert law.delta_cmd_rad.shape == (3,) and law.delta_cmd_rad.dtype == np.float64
    assert law.status.shape == (STATUS_N,) == (len(law.STATUS_NAMES),)
    assert np.all(np.isfinite(law.status)) and np.any(law.delta_cmd_rad != 0)
    assert set(law.kernel_args()) >= {"par", "x", "nm", "st", "tab", "atm", "grid", "delta"}
    assert law.kernel_args()["delta"] is law.delta_cmd_rad
    d = law.status_dict()
    assert d["lambda_e"] == 0.0 and "M_c_m_Nm" in d


def test_every_law_module_cache_depends_on_every_law_module(monkeypatch):
    import fc
    calls = {}
    monkeypatch.setattr(fc, "_drop_stale", lambda f, deps: calls.setdefault(Path(f).name,
                                                                             {Path(d).name for d in deps}))
    fc._drop_stale_law_caches()
    law = {p.name for p in (Path(fc.__file__).parent / "control").glob("*.py")}
    # GIVEN the split law; THEN fc/__init__ checks each law module's numba cache against
    # every law module (a kernel freezes its siblings' constants and inlines their functions)
    assert {"kernels.py", "slow_loop.py", "fast_loop.py", "factors.py", "allocation.py",
            "observer.py", "kinematics.py", "filters.py", "linalg3.py", "options.py"} <= law
    assert set(calls) == law and all(deps == law for deps in calls.values())


@pytest.mark.parametrize("name, values", [
    ("CO_FAC_EQ", ("FAC_EQ14", "FAC_EQ19")),
    ("CO_NORM", ("NORM_RELATIVE", "NORM_COEFFICIENT", "NORM_LITERAL")),
    ("CO_MAP", ("MAP_DIAGONAL", "MAP_PROSE")),
    ("CO_SURF", ("SURF_OFF", "SURF_INTERCONNECT", "SURF_LITERAL")),
    ("ALLOC_MODE", ("ALLOC_CLIP", "ALLOC_SCALE", "ALLOC_PRIO")),
    ("DOB_ACHIEVED", ("DOB_MOMENT_MC", "DOB_MOMENT_GFD", "DOB_MOMENT_GCO")),
])
def test_named_options_are_the_values_the_table_accepts(name, values):
    from fc.control import options
    prm = LAW_PARAMS[PARAM_INDEX[name]]
    named = [getattr(options, v) for v in values]
    # GIVEN an integer option; THEN each named value is accepted by the table, they differ,
    # and they span its range (no value the table accepts is left unnamed)
    assert prm.integer and len(set(named)) == len(named)
    for v in named:
        assert check_value(name, v) == v
    assert min(named) == prm.min and max(named) == prm.max
    par = default_si_array()
    for v in named:
        par[PARAM_INDEX[name]] = float(v)
        assert options.option(par, PARAM_INDEX[name]) == v


def test_bad_input_holds_the_last_command():
    law = AttitudeLaw()
    est = paper_est()
    law.reset(est)
    _run_law(law, est, 5)
    held = law.delta_cmd_rad.copy()
    x0 = law.x.copy()
    bad = est.copy()
    bad[L.E_Q] = np.nan
    law.slow_step(bad, (5 * DEG, 0.0, 4 * DEG), 0.01)
    law.fast_step(bad, 0.002)
    assert law.status[L.S_INPUT_BAD] == 1.0
    np.testing.assert_array_equal(law.delta_cmd_rad, held)
    np.testing.assert_array_equal(law.x, x0)
    law.fast_step(est, 0.0)                      # dt = 0: rejected too
    assert law.status[L.S_INPUT_BAD] == 1.0
    law.slow_step(est, (float("inf"), 0.0, 0.0), 0.01)
    assert law.status[L.S_INPUT_BAD] == 1.0
    # good input again: flies on, state finite
    _run_law(law, est, 5)
    assert law.status[L.S_INPUT_BAD] == 0.0 and np.all(np.isfinite(law.x))


def test_allocator_properties_hypothesis():
    """For any moment demand: |delta| <= limit, and when scaled the achieved moment keeps
    M_c's direction (g_Gamma delta = s M_c, 0 < s <= 1)."""
    from hypothesis import given, settings, strategies as st_

    law, _ = _alloc_setup(coordinated=True, surf=0)
    law.set_param("ALLOC_MODE", 1)
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3).copy()
    lim = 20 * DEG
    delta = np.zeros(3)
    moment = st_.floats(min_value=-5e7, max_value=5e7, allow_nan=False)

    @settings(max_examples=200, deadline=None)
    @given(moment, moment, moment)
    def check(m0, m1, m2):
        sat = K.allocate(law.par, law.nm, m0, m1, m2, 0.7, delta, law.status)
        assert np.all(np.abs(delta) <= lim * (1 + 1e-12))
        mc = np.array([m0, m1, m2])
        s = law.status[L.S_ALLOC_SCALE]
        assert 0.0 < s <= 1.0 or not np.any(mc)
        np.testing.assert_allclose(G @ delta, s * mc, rtol=1e-8, atol=1e-3)
        assert (sat == 1.0) == (s < 1.0)

    check()


def test_prioritised_allocator_properties_hypothesis():
    """ALLOC_MODE 2, any moment demand: |delta| <= limit; exact (g_Gamma^-1 M_c) where within
    the limits; beyond them the surfaces not at a limit leave no weighted physical shortfall
    (g_f_delta delta - M_c) to gain (gradient 0), and that shortfall is no larger than
    scaling's."""
    from hypothesis import given, settings, strategies as st_

    law, _ = _alloc_setup(coordinated=True, surf=0)
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3).copy()
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3).copy()
    lim = 20 * DEG
    delta = np.zeros(3)
    other = np.zeros(3)
    moment = st_.floats(min_value=-5e7, max_value=5e7, allow_nan=False)

    @settings(max_examples=200, deadline=None)
    @given(moment, moment, moment)
    def check(m0, m1, m2):
        law.set_param("ALLOC_MODE", 2)
        sat = K.allocate(law.par, law.nm, m0, m1, m2, 0.7, delta, law.status)
        assert np.all(np.abs(delta) <= lim * (1 + 1e-12))
        mc = np.array([m0, m1, m2])
        raw = np.linalg.solve(G, mc)
        if sat == 0.0:
            np.testing.assert_allclose(delta, raw, rtol=1e-9, atol=1e-12)
            return
        j, w = _weighted_shortfall(law, Gf, mc, delta)
        free = ~np.isclose(np.abs(delta), lim, rtol=1e-12)
        grad = Gf.T @ (w * (Gf @ delta - mc))
        ref = np.abs(Gf.T) @ (w * (np.abs(Gf) @ np.abs(delta) + np.abs(mc)))
        assert np.all(np.abs(grad[free]) <= 1e-8 * ref[free])
        law.set_param("ALLOC_MODE", 1)
        K.allocate(law.par, law.nm, m0, m1, m2, 0.7, other, law.status)
        assert j <= _weighted_shortfall(law, Gf, mc, other)[0] * (1 + 1e-9) + 1e-30

    check()


def test_slow_step_writes_the_complementary_filter_model_term():
    """Issue 20 V8: the slow step leaves f1 + Psi^T theta_hat (Eqs. 26, 23) in x[X_FKIN:] for
    the fast rate's complementary attitude filter; written out here from Eq. 26 by hand
    (adaptation off, so theta_hat = theta_nom)."""
    law = AttitudeLaw({"SLW_GAMMA": 0.0})
    est = paper_est(alpha_deg=3, beta_deg=2, mu_deg=10, p=0.01, q=0.02, r=-0.01)
    est[L.E_GAMMA] = 2 * DEG
    law.reset(est)
    law.slow_step(est, (5 * DEG, 0.0, 4 * DEG), 0.01)
    g = law.nm[L.NM_G]
    b, m, v, gam = est[L.E_BETA], est[L.E_MU], est[L.E_V], est[L.E_GAMMA]
    f1 = np.array([g * math.cos(gam) * math.cos(m) / (v * math.cos(b)),
                   g * math.cos(gam) * math.sin(m) / v,
                   -g * math.cos(gam) * math.cos(m) * math.sin(b) / (math.cos(b) * v)])
    psi = law.nm[L.NM_PSI:L.NM_PSI + 4]
    want = f1 + np.array([psi[0], psi[1], psi[2] + psi[3]])
    assert np.all(psi[:3] != 0.0)
    np.testing.assert_allclose(law.x[L.X_FKIN:L.X_FKIN + 3], want, rtol=1e-12)


@pytest.mark.parametrize("ang_hz, cf_hz, filtered", [(0.0, 1.0, True), (0.5, 0.0, True),
                                                     (0.0, 0.0, False)])
def test_tracking_error_reads_the_attitude_filter_when_either_is_on(ang_hz, cf_hz, filtered):
    """e1 (Eq. 27) takes Omega from the attitude filter's output x[X_AF2:] when the low-pass
    (FLT_ANG_HZ) or the complementary filter (FLT_ANG_CF) is on, however slow, and from the
    estimate when both are off."""
    from fc.control.slow_loop import tracking_error
    par = default_si_array()
    par[PARAM_INDEX["FLT_ANG_HZ"]] = ang_hz
    par[PARAM_INDEX["FLT_ANG_CF"]] = cf_hz
    x = AttitudeLaw().x.copy()
    x[L.X_AF2:L.X_AF2 + 3] = (0.3, 0.2, 0.1)
    x[L.X_PF:L.X_PF + 3] = 0.0
    est = paper_est(alpha_deg=1, beta_deg=2, mu_deg=3)
    e = tracking_error(est, par, x, False)
    src = (0.3, 0.2, 0.1) if filtered else est[:3]
    np.testing.assert_allclose(e, src, rtol=1e-12)


def test_the_printed_law_runs_no_attitude_filter():
    """PAPER_LITERAL: the fast loop's input filters pass alpha, beta, mu through (no
    complementary filter at its default 1 Hz, no low-pass)."""
    from fc.control.fast_loop import input_filters
    par = default_si_array()
    assert par[PARAM_INDEX["FLT_ANG_CF"]] > 0.0
    x = AttitudeLaw().x.copy()
    x[L.X_AF2:L.X_AF2 + 3] = (0.3, 0.2, 0.1)
    est = paper_est(alpha_deg=1, beta_deg=2, mu_deg=3, p=0.1, q=0.1, r=0.1)
    x0 = x.copy()
    input_filters(est, 0.002, par, x, True)
    np.testing.assert_array_equal(x[L.X_AF2:L.X_AF2 + 3], est[:3])
    # and the default law runs the complementary filter at its default 1 Hz
    from fc.control.fast_loop import complementary_attitude_step
    x1 = x0.copy()
    x2 = x0.copy()
    input_filters(est, 0.002, par, x1, False)
    complementary_attitude_step(est, 0.002, par[PARAM_INDEX["FLT_ANG_CF"]], x2)
    np.testing.assert_array_equal(x1[L.X_AF2:L.X_AF2 + 3], x2[L.X_AF2:L.X_AF2 + 3])
    assert not np.allclose(x1[L.X_AF2:L.X_AF2 + 3], est[:3])


def test_cycle_equals_slow_then_fast():
    a = AttitudeLaw()
    b = AttitudeLaw()
    est = paper_est(p=0.01, q=-0.02, r=0.03)
    a.reset(est)
    b.reset(est)
    cmd = (5 * DEG, 0.0, 4 * DEG)
    for _ in range(20):
        a.slow_step(est, cmd, 0.01)
        a.fast_step(est, 0.002)
        b.cycle(est, cmd, 0.01, 0.002)
    np.testing.assert_array_equal(a.delta_cmd_rad, b.delta_cmd_rad)
    np.testing.assert_array_equal(a.x, b.x)


@pytest.mark.parametrize("zeta", [0.5, 0.9, 1.0, 1.5])
def test_second_order_filter_is_exact(zeta):
    """The filters' discretisation equals the continuous response (scipy expm) and stays
    stable for wn dt = 1.6 (a 25 Hz loop with the 40 rad/s command filter)."""
    from scipy.linalg import expm
    wn, dt = 40.0, 0.04
    phi = np.array(K.second_order_phi(dt, wn, zeta))
    A = np.array([[0.0, 1.0], [-wn * wn, -2 * zeta * wn]])
    np.testing.assert_allclose(phi, expm(A * dt).ravel(), rtol=1e-9, atol=1e-12)
    x = np.zeros(2)
    for _ in range(100):
        K.second_order_step(1.0, phi, x, 0, 1)
    assert x[0] == pytest.approx(1.0, abs=1e-9) and abs(x[1]) < 1e-9


def test_bounds_survive_float32_round_trip():
    import struct
    for p in LAW_PARAMS:
        for v in (p.min, p.max, p.default):
            v32 = struct.unpack("<f", struct.pack("<f", v))[0]
            assert p.min <= check_value(p.name, v32) <= p.max, (p.name, v, v32)
