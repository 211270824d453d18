"""One step of each loop against the paper's equations, computed by hand (numpy, here).

Each test presets the law's internal state (integrals, estimates, observer, filters) to
values that make every term of the equation non-zero and distinct, runs ONE step of the
kernel, and compares with Eqs. 26-30 (slow loop), 35-37 (fast loop), 44-46 (allocation)
and the deviations V1-V3 written out independently in this file. A sign flip or a dropped
term in any equation changes the result by far more than the 1e-9 relative tolerance.
The kernels are called directly, so these tests also run with NUMBA_DISABLE_JIT=1, which
is how ``python -m tools.evidence.mutate`` runs them against each mutant (docs/mutation_report.md).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.control import kernels as K
from fc.control import layout as L
from fc.control.law import AttitudeLaw

DEG = math.pi / 180.0
RTOL = 1e-9


def g_s(alpha, beta):
    """Eq. 3 written out independently of the kernels."""
    sa, ca, tb, cb = math.sin(alpha), math.cos(alpha), math.tan(beta), math.cos(beta)
    return np.array([[-ca * tb, 1.0, -sa * tb],
                     [sa, 0.0, -ca],
                     [ca / cb, 0.0, sa / cb]])


def _est(alpha_deg=3.0, beta_deg=2.0, mu_deg=10.0, p=0.02, q=-0.015, r=0.01,
         gamma_deg=3.0):
    return np.array([alpha_deg * DEG, beta_deg * DEG, mu_deg * DEG, p, q, r, 2200.0,
                     21000.0, gamma_deg * DEG])


def _call_slow(law, est, cmd, dt):
    k = law.kernel_args()
    K.slow_kernel(est, np.asarray(cmd, dtype=np.float64), dt, k["par"], k["x"], k["nm"],
                  k["st"], k["tab"], k["atm"], k["grid"])


def _call_fast(law, est, dt):
    k = law.kernel_args()
    K.fast_kernel(est, dt, k["par"], k["x"], k["nm"], k["st"], k["tab"], k["atm"],
                  k["grid"], k["delta"])


# ---------------------------------------------------------------------------------------------
# Slow loop: Eqs. 26, 27, 29, 30 (+ V1 limit, V1b compensation, V2 freeze)
# ---------------------------------------------------------------------------------------------
SLOW_BASE = {"CTL_SCHED": 0, "FLT_ANG_HZ": 0, "SLW_K1": 3, "SLW_K2": 4, "SLW_K3": 6, "SLW_KAPPA": 5,
             "SLW_GAMMA": 0.8, "SLW_LEAK": 0.7, "SLW_OMC_MAX": 0, "SLW_TH_BND": 0.5}
INT0 = np.array([0.011, -0.023, 0.007])          # integral of e1 (rad s)
RHO0 = np.array([0.1, -0.2, 0.05, 0.15])         # relative estimates of theta_Omega
XI0 = np.array([0.004, -0.003, 0.006])           # V1b compensation state (rad)
PF0 = [2 * DEG, 1 * DEG, 6 * DEG]                # prefilter output, away from the command
PFD0 = [0.03, -0.02, 0.05]                       # and moving (rad/s)


def _law_preset(overrides, est, preset):
    """A law reset at ``est`` with its internal state x[index:] set per ``preset``."""
    law = AttitudeLaw(overrides)
    law.reset(est)
    for index, values in preset.items():
        v = np.atleast_1d(np.asarray(values, dtype=np.float64))
        law.x[index:index + v.size] = v
    return law


def _slow_setup(overrides, est, lim_prev=0.0):
    # the prefilter starts away from the command and moving, so Omega_c_dot != 0
    return _law_preset({**SLOW_BASE, **overrides}, est, {
        L.X_INT_E1: INT0, L.X_RHO_S: RHO0, L.X_XI: XI0, L.X_LIM: lim_prev,
        L.X_PF: PF0, L.X_PF_DOT: PFD0})


def _slow_expected(law, est, dt, int_e1, frozen=False):
    """omega_c (before any limit) and sigma by Eqs. 26-29, from the law's own reference
    (the prefilter's output after the step) and nominal model (tested elsewhere)."""
    par = law.params()
    Kg = np.array([par["SLW_K1"], par["SLW_K2"], par["SLW_K3"]])
    kap = par["SLW_KAPPA"]
    alpha, beta, mu, V, gam = est[0], est[1], est[2], est[6], est[8]
    ref = law.x[L.X_PF:L.X_PF + 3]
    ref_dot = law.x[L.X_PF_DOT:L.X_PF_DOT + 3]
    e1 = np.array([alpha - ref[0], beta - ref[1],
                   (mu - ref[2] + math.pi) % (2 * math.pi) - math.pi])
    integ = int_e1 if frozen else int_e1 + e1 * dt              # Eq. 27's integral (V2)
    sigma = e1 + Kg * integ                                      # Eq. 27
    g = law.nm[L.NM_G]
    cb = math.cos(beta)
    f1 = np.array([g * math.cos(gam) * math.cos(mu) / (V * cb),          # Eq. 26
                   g * math.cos(gam) * math.sin(mu) / V,
                   -g * math.cos(gam) * math.cos(mu) * math.sin(beta) / (cb * V)])
    psi = law.nm[L.NM_PSI:L.NM_PSI + 4]
    th = psi * (1.0 + RHO0)                                      # Psi_i theta_hat_i
    psi_t_theta = np.array([th[0], th[1], th[2] + th[3]])        # Eq. 23: rows a, b, mu
    v = kap * sigma + f1 + psi_t_theta - ref_dot + Kg * e1
    omega_c = -np.linalg.solve(g_s(alpha, beta), v)              # Eq. 29
    return e1, integ, sigma, omega_c


def _rho_expected(law, sigma_rows, dt):
    """Eq. 30 (relative form, D4/D5): rho+ = rho + dt Gamma1 (Psi_i theta_i sigma_row
    - lambda rho)."""
    par = law.params()
    psi = law.nm[L.NM_PSI:L.NM_PSI + 4]
    rows = sigma_rows[[0, 1, 2, 2]]
    return RHO0 + dt * par["SLW_GAMMA"] * (psi * rows - par["SLW_LEAK"] * RHO0)


@pytest.mark.parametrize("prefilter", [0, 1])
def test_slow_step_matches_eqs_26_to_30(prefilter):
    # GIVEN a state with every term of Eq. 29 non-zero (gamma, mu, beta != 0), estimates and
    # integrals away from 0, and (prefilter on) a moving reference
    est = _est()
    law = _slow_setup({"REF_PF_EN": prefilter}, est)
    dt = 0.01
    cmd = [5 * DEG, -1 * DEG, 14 * DEG]
    # WHEN one slow step runs
    _call_slow(law, est, cmd, dt)
    # THEN sigma, omega_c and the estimates are those of Eqs. 26-30
    e1, integ, sigma, omega_c = _slow_expected(law, est, dt, INT0)
    if not prefilter:
        np.testing.assert_allclose(law.x[L.X_PF:L.X_PF + 3], cmd, rtol=0, atol=0)
        np.testing.assert_allclose(law.x[L.X_PF_DOT:L.X_PF_DOT + 3], 0.0, atol=0)
    else:
        # the reference prefilter (D11): one exact step of y'' = wn^2 (u - y) - 2 zeta wn y'
        # from the preset state toward the command (the bank the short way round)
        phi = np.array(K.second_order_phi(dt, 2.0, 1.0))
        y0, v0 = np.array(PF0), np.array(PFD0)
        u = np.array(cmd)
        u[2] = y0[2] + ((cmd[2] - y0[2] + math.pi) % (2 * math.pi) - math.pi)
        np.testing.assert_allclose(law.x[L.X_PF:L.X_PF + 3],
                                   u + phi[0] * (y0 - u) + phi[1] * v0, rtol=RTOL)
        np.testing.assert_allclose(law.x[L.X_PF_DOT:L.X_PF_DOT + 3],
                                   phi[2] * (y0 - u) + phi[3] * v0, rtol=RTOL)
    np.testing.assert_allclose(law.status[L.S_E1:L.S_E1 + 3], e1, rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_INT_E1:L.X_INT_E1 + 3], integ, rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_SIGMA:L.X_SIGMA + 3], sigma, rtol=RTOL)
    np.testing.assert_allclose(law.status[L.S_SIGMA:L.S_SIGMA + 3], sigma, rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_OMC:L.X_OMC + 3], omega_c, rtol=RTOL)
    np.testing.assert_allclose(law.status[L.S_OMEGA_C:L.S_OMEGA_C + 3], omega_c, rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_RHO_S:L.X_RHO_S + 4], _rho_expected(law, sigma, dt),
                               rtol=RTOL)
    assert law.x[L.X_LIM] == 0.0 and law.status[L.S_OMC_LIM] == 0.0
    # the compensation state is off (SLW_CFB 0): reset to 0, sigma_bar = sigma
    np.testing.assert_array_equal(law.x[L.X_XI:L.X_XI + 3], 0.0)
    assert law.status[L.S_FROZEN] == 0.0 and law.status[L.S_INPUT_BAD] == 0.0


def test_slow_step_mu_error_wraps():
    # mu 179 deg commanded -179 deg: the error is -2 deg, not 358 deg
    est = _est(mu_deg=179.0)
    law = _slow_setup({"REF_PF_EN": 0}, est)
    _call_slow(law, est, [5 * DEG, -1 * DEG, -179 * DEG], 0.01)
    assert law.status[L.S_E1 + 2] == pytest.approx(-2 * DEG, rel=1e-9)


def test_slow_step_limit_scales_and_freezes():
    """V1: omega_c scaled so its largest component is SLW_OMC_MAX (direction kept);
    V2: while limited the integral (previous step limited) and Eq. 30 are frozen."""
    est = _est()
    lim_deg = 0.5
    law = _slow_setup({"REF_PF_EN": 0, "SLW_OMC_MAX": lim_deg, "SLW_AW": 1}, est,
                      lim_prev=1.0)
    dt = 0.01
    _call_slow(law, est, [5 * DEG, -1 * DEG, 14 * DEG], dt)
    # the integral was frozen (the previous step was limited): Eq. 27 without e1 dt
    _, integ, sigma, omega_c = _slow_expected(law, est, dt, INT0, frozen=True)
    np.testing.assert_array_equal(law.x[L.X_INT_E1:L.X_INT_E1 + 3], INT0)
    np.testing.assert_allclose(law.x[L.X_SIGMA:L.X_SIGMA + 3], sigma, rtol=RTOL)
    big = np.max(np.abs(omega_c))
    assert big > lim_deg * DEG                       # really limited
    np.testing.assert_allclose(law.x[L.X_OMC:L.X_OMC + 3], omega_c * (lim_deg * DEG / big),
                               rtol=RTOL)
    assert law.x[L.X_LIM] == 1.0
    np.testing.assert_array_equal(law.x[L.X_RHO_S:L.X_RHO_S + 4], RHO0)   # Eq. 30 frozen
    assert law.status[L.S_FROZEN] == 1.0


@pytest.mark.parametrize("flag", ["limited", "saturated"])
def test_slow_step_integral_frozen_after_a_limited_or_saturated_step(flag):
    """V2: the integral of e1 and Eq. 30 stop while the previous step limited omega_c or a
    surface saturated."""
    est = _est()
    law = _slow_setup({"REF_PF_EN": 0, "SLW_AW": 1}, est)
    law.x[L.X_LIM if flag == "limited" else L.X_SAT] = 1.0
    dt = 0.01
    _call_slow(law, est, [5 * DEG, -1 * DEG, 14 * DEG], dt)
    _, _, _, omega_c = _slow_expected(law, est, dt, INT0, frozen=True)
    np.testing.assert_array_equal(law.x[L.X_INT_E1:L.X_INT_E1 + 3], INT0)
    np.testing.assert_allclose(law.x[L.X_OMC:L.X_OMC + 3], omega_c, rtol=RTOL)
    np.testing.assert_array_equal(law.x[L.X_RHO_S:L.X_RHO_S + 4], RHO0)
    assert law.status[L.S_FROZEN] == 1.0 and law.x[L.X_LIM] == 0.0


def test_slow_step_limit_now_freezes_eq30_only():
    """V2: omega_c limited in this step freezes Eq. 30 but not this step's integral."""
    est = _est()
    law = _slow_setup({"REF_PF_EN": 0, "SLW_OMC_MAX": 0.5, "SLW_AW": 1}, est)
    dt = 0.01
    _call_slow(law, est, [5 * DEG, -1 * DEG, 14 * DEG], dt)
    _, integ, _, _ = _slow_expected(law, est, dt, INT0)
    np.testing.assert_allclose(law.x[L.X_INT_E1:L.X_INT_E1 + 3], integ, rtol=RTOL)
    np.testing.assert_array_equal(law.x[L.X_RHO_S:L.X_RHO_S + 4], RHO0)
    assert law.x[L.X_LIM] == 1.0 and law.status[L.S_OMC_LIM] == 1.0


@pytest.mark.parametrize("kappa", [5.0, 0.5, 0.0])
def test_slow_step_compensation_decays_when_not_limited(kappa):
    """V1b without a limit: xi+ = e^(-kappa dt) xi (xi + 0 dt for kappa 0)."""
    est = _est()
    law = _slow_setup({"REF_PF_EN": 0, "SLW_CFB": 1, "SLW_KAPPA": kappa}, est)
    dt = 0.01
    _call_slow(law, est, [5 * DEG, -1 * DEG, 14 * DEG], dt)
    np.testing.assert_allclose(law.x[L.X_XI:L.X_XI + 3], math.exp(-kappa * dt) * XI0,
                               rtol=RTOL)


def test_slow_step_compensation_kappa_zero_integrates():
    """V1b with kappa1 = 0: xi+ = xi + dt g_s (omega_c_lim - omega_c)."""
    est = _est()
    law = _slow_setup({"REF_PF_EN": 0, "SLW_CFB": 1, "SLW_KAPPA": 0, "SLW_OMC_MAX": 0.5,
                       "SLW_AW": 0}, est)
    dt = 0.01
    _call_slow(law, est, [5 * DEG, -1 * DEG, 14 * DEG], dt)
    _, _, _, omega_c = _slow_expected(law, est, dt, INT0)
    s = 0.5 * DEG / np.max(np.abs(omega_c))
    xi = XI0 + dt * g_s(est[0], est[1]) @ ((s - 1.0) * omega_c)
    np.testing.assert_allclose(law.x[L.X_XI:L.X_XI + 3], xi, rtol=RTOL)


def test_slow_step_command_filter_compensation():
    """V1b: sigma_bar = sigma - xi feeds Eq. 30; xi+ = e^(-kappa dt) xi + (1 - e^(-kappa dt))
    / kappa g_s (omega_c_lim - omega_c)."""
    est = _est()
    lim_deg = 0.5
    law = _slow_setup({"REF_PF_EN": 0, "SLW_OMC_MAX": lim_deg, "SLW_AW": 0, "SLW_CFB": 1},
                      est)
    dt = 0.01
    _call_slow(law, est, [5 * DEG, -1 * DEG, 14 * DEG], dt)
    _, _, sigma, omega_c = _slow_expected(law, est, dt, INT0)
    s = lim_deg * DEG / np.max(np.abs(omega_c))
    kap = 5.0
    xi = (math.exp(-kap * dt) * XI0
          + (1 - math.exp(-kap * dt)) / kap * g_s(est[0], est[1]) @ ((s - 1.0) * omega_c))
    np.testing.assert_allclose(law.x[L.X_XI:L.X_XI + 3], xi, rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_SIGMA:L.X_SIGMA + 3], sigma - XI0, rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_RHO_S:L.X_RHO_S + 4],
                               _rho_expected(law, sigma - XI0, dt), rtol=RTOL)


def test_gs_apply_matches_eq3():
    out = np.zeros(3)
    for a, b in ((3 * DEG, 2 * DEG), (-8 * DEG, 30 * DEG)):
        w = np.array([0.3, -0.7, 0.2])
        K.gs_apply(a, b, w[0], w[1], w[2], out, 0)
        np.testing.assert_allclose(out, g_s(a, b) @ w, rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# Fast loop: Eqs. 35, 36, 37, 46 and the controller's actuator model
# ---------------------------------------------------------------------------------------------
FAST_BASE = {"FLT_RATE_HZ": 0, "FLT_ANG_HZ": 0, "FST_KAPPA": 7, "FST_GAMMA": 0.8,
             "FST_LEAK": 0.3, "DOB_C": 10, "ACT_TAU": 0.02, "ACT_RATE": 90, "SLW_AW": 1}
OMC0 = np.array([0.01, -0.02, 0.015])            # omega_c from the slow loop (rad/s)
CF0 = np.array([0.012, -0.018, 0.01])            # command filter state (rad/s)
CFD0 = np.array([0.05, -0.03, 0.02])             # its derivative (rad/s^2)
SIG0 = np.array([0.01, -0.005, 0.02])            # sigma from the slow loop (rad)
Z0 = np.array([-0.3, 0.25, -0.12])               # observer state (rad/s^2)
DM0 = np.array([0.02, 0.05, -0.01])              # modelled deflections (rad)
RHOF0 = np.linspace(-0.2, 0.25, 17)              # relative estimates of theta_omega


def _fast_setup(overrides, est):
    return _law_preset({**FAST_BASE, **overrides}, est, {
        L.X_OMC: OMC0, L.X_CF: CF0, L.X_CF_DOT: CFD0, L.X_SIGMA: SIG0, L.X_Z: Z0, L.X_DM: DM0,
        L.X_RHO_F: RHOF0, L.X_SAT: 0.0})


def _fast_expected(law, est, dt, observer=True, w=None):
    """(M_c, e2, d_hat, Xi^T theta_hat per axis, c_d, omega_cf, inertia) by Eqs. 35, 37;
    ``w``: the rates the law uses (default: est's, i.e. no input filter)."""
    par = law.params()
    wn, zeta = par["FST_CF_WN"], par["FST_CF_ZETA"]
    phi = np.array(K.second_order_phi(dt, wn, zeta))     # checked against expm elsewhere
    e = CF0 - OMC0
    cf = OMC0 + phi[0] * e + phi[1] * CFD0
    cf_dot = phi[2] * e + phi[3] * CFD0
    w = est[3:6] if w is None else w
    e2 = w - cf
    xi = law.nm[L.NM_XI:L.NM_XI + 17] * (1.0 + RHOF0)
    xth = np.array([xi[:L.TH_F_PITCH].sum(), xi[L.TH_F_PITCH:L.TH_F_YAW].sum(),
                    xi[L.TH_F_YAW:].sum()])
    c = par["DOB_C"]
    c_d = (1.0 - math.exp(-c * dt)) / dt
    d_hat = Z0 + c_d * w if observer else np.zeros(3)           # Eq. 37: d_hat = z + Q
    inertia = np.array([par["MDL_IXX"], par["MDL_IYY"], par["MDL_IZZ"]])
    gst = g_s(est[0], est[1]).T @ SIG0
    mc = -inertia * (par["FST_KAPPA"] * e2 + xth + d_hat + gst - cf_dot)   # Eq. 35
    return mc, e2, d_hat, xth, c_d, cf, inertia


def _actuator_expected(law, delta, dt):
    par = law.params()
    lim = par["ACT_MAX"] * DEG
    a = 1.0 - math.exp(-dt / par["ACT_TAU"])
    rmax = par["ACT_RATE"] * DEG * dt
    step = np.clip(a * (np.clip(delta, -lim, lim) - DM0), -rmax, rmax)
    return np.clip(DM0 + step, -lim, lim)


@pytest.mark.parametrize("coordinated,dob_in,extra", [
    (0, 1, {}), (1, 1, {}), (1, 2, {}), (1, 0, {}),
    # the printed law ignores the filters, the observer's input option and the freeze
    (1, 0, {"PAPER_LITERAL": 1, "FLT_RATE_HZ": 20, "FLT_ANG_HZ": 20, "DOB_ACHIEVED": 1}),
    (1, 1, {"DOB_ENABLE": 0})],
    ids=["unco", "co-physical", "co-eq44", "co-Mc", "literal", "no-observer"])
def test_fast_step_matches_eqs_35_to_37(coordinated, dob_in, extra):
    # GIVEN a state with every term of Eq. 35 non-zero and the observer, estimates and
    # actuator model away from their reset values
    est = _est(p=0.02, q=-0.015, r=0.01)
    law = _fast_setup({"CO_ENABLE": coordinated, "DOB_ACHIEVED": dob_in, **extra}, est)
    observer = extra.get("DOB_ENABLE", 1) == 1
    dt = 0.002
    # WHEN one fast step runs
    _call_fast(law, est, dt)
    mc, e2, d_hat, xth, c_d, cf, inertia = _fast_expected(law, est, dt, observer)
    assert law.status[L.S_INPUT_BAD] == 0.0 and law.status[L.S_ALLOC_SCALE] == 1.0
    if "PAPER_LITERAL" in extra:                       # no input filter under the printed law
        np.testing.assert_array_equal(law.x[L.X_AF2:L.X_AF2 + 3], est[0:3])
        np.testing.assert_array_equal(law.x[L.X_WF2:L.X_WF2 + 3], est[3:6])
    # THEN Eq. 35: M_c
    np.testing.assert_allclose(law.status[L.S_M_C:L.S_M_C + 3], mc, rtol=RTOL)
    np.testing.assert_allclose(law.status[L.S_E2:L.S_E2 + 3], e2, rtol=RTOL)
    np.testing.assert_allclose(law.status[L.S_D_HAT:L.S_D_HAT + 3], d_hat, rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_CF:L.X_CF + 3], cf, rtol=RTOL)
    # Eq. 46: delta = g_Gamma^-1 M_c (unsaturated here), g_Gamma = g_f_delta when uncoordinated
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    if coordinated:
        lam = law.status[L.S_LAMBDA:L.S_LAMBDA + 3]
        assert np.all(lam != 0.0)
        np.testing.assert_allclose(G, Gf * np.array([1 + lam[1], 1 + lam[0], 1 + lam[2]])[:, None],
                                   rtol=1e-12)
    else:
        np.testing.assert_array_equal(G, Gf)
    delta = np.linalg.solve(G, mc)
    assert np.max(np.abs(delta)) < 20 * DEG
    np.testing.assert_allclose(law.delta_cmd_rad, delta, rtol=1e-9)
    # the controller's actuator model: limit, first-order lag, rate limit
    dm = _actuator_expected(law, delta, dt)
    np.testing.assert_allclose(law.x[L.X_DM:L.X_DM + 3], dm, rtol=RTOL)
    # Eq. 37: z+ = (1 - c_d dt) z - c_d dt (f + c_d omega), f = Xi^T theta_hat + g_f M with
    # M the moment fed to the observer (DOB_ACHIEVED: 0 M_c, 1 g_f_delta delta_model,
    # 2 g_Gamma delta_model; delta_model averaged over the step)
    avg = 0.5 * (DM0 + dm)
    m = {0: mc, 1: Gf @ avg, 2: G @ avg}[dob_in]
    f = xth + m / inertia
    a = c_d * dt
    z = (1.0 - a) * Z0 - a * (f + c_d * est[3:6]) if observer else Z0
    np.testing.assert_allclose(law.x[L.X_Z:L.X_Z + 3], z, rtol=RTOL)
    # Eq. 36 (relative form): rho+ = rho + dt Gamma2 (Xi_i theta_i e2_axis - lambda rho)
    par = law.params()
    axis = np.array([0] * L.TH_F_PITCH + [1] * (L.TH_F_YAW - L.TH_F_PITCH)
                    + [2] * (L.TH_F_N - L.TH_F_YAW))
    rho = RHOF0 + dt * par["FST_GAMMA"] * (law.nm[L.NM_XI:L.NM_XI + 17] * e2[axis]
                                           - par["FST_LEAK"] * RHOF0)
    np.testing.assert_allclose(law.x[L.X_RHO_F:L.X_RHO_F + 17], rho, rtol=RTOL)


def test_fast_step_eq36_frozen_while_limited():
    est = _est()
    law = _fast_setup({"CO_ENABLE": 0}, est)
    law.x[L.X_LIM] = 1.0
    _call_fast(law, est, 0.002)
    np.testing.assert_array_equal(law.x[L.X_RHO_F:L.X_RHO_F + 17], RHOF0)
    assert law.status[L.S_FROZEN] == 1.0


def test_observer_reads_the_disturbance_with_the_right_sign():
    """Eq. 37 on the law's own fast loop: a body that accelerates by exactly the modelled
    acceleration plus d gives d_hat -> d (the observer's state after many steps)."""
    est = _est(p=0.0, q=0.0, r=0.0)
    law = _fast_setup({"CO_ENABLE": 0, "FST_GAMMA": 0}, est)
    law.x[L.X_Z:L.X_Z + 3] = -10.0 * est[3:6]            # d_hat = 0 at the start
    law.x[L.X_SIGMA:L.X_SIGMA + 3] = 0.0
    d = np.array([0.4, -0.2, 0.1])                       # rad/s^2
    dt = 0.002
    inertia = np.array([1.36e6, 1.5e7, 1.36e7])
    w = est[3:6].copy()
    for _ in range(1500):                                # 3 s = 30 observer time constants
        e = est.copy()
        e[3:6] = w
        law.x[L.X_OMC:L.X_OMC + 3] = w                   # hold omega_c at omega: tiny M_c
        dm_before = law.x[L.X_DM:L.X_DM + 3].copy()
        _call_fast(law, e, dt)
        # the body: the model's acceleration with the deflection the observer assumes, + d
        xi = law.nm[L.NM_XI:L.NM_XI + 17] * (1.0 + RHOF0)     # Xi^T theta_hat
        xth = np.array([xi[:5].sum(), xi[5:11].sum(), xi[11:].sum()])
        Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
        avg = 0.5 * (dm_before + law.x[L.X_DM:L.X_DM + 3])
        w = w + (xth + (Gf @ avg) / inertia + d) * dt
    np.testing.assert_allclose(law.status[L.S_D_HAT:L.S_D_HAT + 3], d, rtol=0, atol=1e-6)


# ---------------------------------------------------------------------------------------------
# Eq. 45 normalisations (CO_NORM 1 and 2) and the allocation's literal clip path
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("norm", [0, 1, 2])
def test_coordinated_matrix_normalisations(norm):
    law = AttitudeLaw({"CO_MAP": 0, "CO_NORM": norm, "CO_DET_MIN": 0.2})
    est = _est()
    from fc.control.nominal import B_REF_M, C_REF_M, S_REF_M2, eval_model
    eval_model(est, law.par, law.tab, law.atm, law.grid, law.nm)
    lam = np.array([2e-4, -3e-4, 5e-4])
    assert K.coordinated_matrix(law.par, law.nm, lam, 0) == 0.0
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    qS = law.nm[L.NM_QBAR] * S_REF_M2
    add = {0: lam * np.diag(Gf), 1: lam * qS * np.array([B_REF_M, C_REF_M, B_REF_M]),
           2: lam}[norm]
    np.testing.assert_allclose(G, Gf + np.diag(add), rtol=1e-13)


def test_factor_singularity_guard_keeps_sign():
    """Eq. 12's denominator sin(alpha) + Delta_alpha is kept >= 1e-6 in magnitude."""
    par = AttitudeLaw({"CO_DALPHA": 0.05, "CO_LAM_MAX": 0}).par
    out = np.zeros(3)
    alpha = -math.asin(0.05)                             # sin(alpha) + Delta_alpha = 0
    est = np.array([alpha, 0.0, 0.0, 1e-7, 0.0, 0.0, 2200.0, 21000.0, 0.0])
    K.coordinated_factors(est, par, out, 0)
    k1 = k3 = 1.0
    lr = k1 * 1e-7 * math.tan(alpha) + k3 * 1e-7 * (1 - math.cos(alpha)) / 1e-6
    assert out[2] == pytest.approx(lr, rel=1e-6)


@pytest.mark.parametrize("den", [1e-8, -1e-8, 1.5e-6])
def test_factor_singularity_guard_sign_on_each_side(den):
    """The guard keeps the sign of sin(alpha) + Delta_alpha: +1e-6 above, -1e-6 below,
    and leaves a denominator of 1e-6 or more alone."""
    dal = 0.05
    par = AttitudeLaw({"CO_DALPHA": dal, "CO_LAM_MAX": 0}).par
    alpha = math.asin(den - dal)
    p = 1e-7
    est = np.array([alpha, 0.0, 0.0, p, 0.0, 0.0, 2200.0, 21000.0, 0.0])
    out = np.zeros(3)
    K.coordinated_factors(est, par, out, 0)
    guarded = den if abs(den) >= 1e-6 else math.copysign(1e-6, den)
    lr = p * math.tan(alpha) + p * (1 - math.cos(alpha)) / guarded
    assert out[2] == pytest.approx(lr, rel=1e-6)


def test_factor_clamp_both_signs_and_inside():
    """V5: abs(lambda_i) <= CO_LAM_MAX, each sign, and no change inside the bound."""
    par = AttitudeLaw({"CO_LAM_MAX": 0.5, "CO_FAC_EQ": 19}).par
    out = np.zeros(3)
    big = np.array([-20 * DEG, -25 * DEG, 0.0, -1.0, -1.0, 0.0, 2200.0, 21000.0, 0.0])
    K.coordinated_factors(big, par, out, 0)
    np.testing.assert_array_equal(out, [-0.5, -0.5, -0.5])
    small = np.array([2 * DEG, -1 * DEG, 0.0, 0.01, -0.02, 0.0, 2200.0, 21000.0, 0.0])
    K.coordinated_factors(small, par, out, 0)
    assert np.all(np.abs(out) < 0.5)
    le = 2 * DEG - 0.02
    la = -1 * DEG + 0.01
    assert out[0] == pytest.approx(le, rel=1e-12) and out[1] == pytest.approx(la, rel=1e-12)


def _matrix_law(**overrides):
    law = AttitudeLaw({"CO_MAP": 1, **overrides})
    from fc.control.nominal import eval_model
    eval_model(_est(), law.par, law.tab, law.atm, law.grid, law.nm)
    return law


@pytest.mark.parametrize("scales,accepted", [
    ((0.4, 0.4, 0.4), False),          # det ratio 0.064 < 0.2, each diagonal ratio 0.4
    ((0.1, 3.0, 3.0), False),          # det ratio 0.9, one diagonal ratio 0.1 < 0.2
    ((0.5, 0.7, 0.9), True),           # det ratio 0.315, diagonal ratios >= 0.5
])
def test_coordinated_matrix_guard_ratios(scales, accepted):
    """V5: g_Gamma is used only if det(g_Gamma)/det(g_f_delta) and each g_Gamma_ii /
    g_f_delta_ii are >= CO_DET_MIN (0.2). With CO_MAP 1 the rows are scaled by 1 + lambda
    (roll 1 + lambda_a, pitch 1 + lambda_e, yaw 1 + lambda_r)."""
    law = _matrix_law()
    roll, pitch, yaw = scales
    lam = np.array([pitch - 1.0, roll - 1.0, yaw - 1.0])
    fb = K.coordinated_matrix(law.par, law.nm, lam, 0)
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    G = law.nm[L.NM_GCO:L.NM_GCO + 9].reshape(3, 3)
    assert fb == (0.0 if accepted else 1.0)
    expected = Gf * np.array(scales)[:, None] if accepted else Gf
    np.testing.assert_allclose(G, expected, rtol=1e-12)


@pytest.mark.parametrize("ratio,accepted", [(1.5e-9, True), (0.5e-9, False), (-0.7, True)])
def test_coordinated_matrix_guard_literal(ratio, accepted):
    """PAPER_LITERAL: only a (numerically) singular g_Gamma is rejected: det ratio
    abs(det_c / det_g) > 1e-9; a sign flip passes."""
    law = _matrix_law(PAPER_LITERAL=1)
    lam = np.array([ratio - 1.0, 0.0, 0.0])            # pitch row x ratio
    fb = K.coordinated_matrix(law.par, law.nm, lam, 0)
    assert fb == (0.0 if accepted else 1.0)


def test_allocation_without_authority():
    """A singular g_Gamma (no authority): neutral surfaces, every flag set, scale 0, the
    whole M_c unallocated."""
    law = _matrix_law()
    law.nm[L.NM_GCO:L.NM_GCO + 9] = 0.0
    delta = np.ones(3)
    sat = K.allocate(law.par, law.nm, 1e5, -2e5, 3e5, 0.7, delta, law.status)
    assert sat == 1.0 and law.status[L.S_SAT_ANY] == 1.0
    np.testing.assert_array_equal(delta, 0.0)
    np.testing.assert_array_equal(law.status[L.S_SAT:L.S_SAT + 3], 1.0)
    np.testing.assert_array_equal(law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3],
                                  [1e5, -2e5, 3e5])
    assert law.status[L.S_ALLOC_SCALE] == 0.0


def test_allocation_unsaturated_reports_scale_one():
    law = _matrix_law()
    K.coordinated_matrix(law.par, law.nm, np.zeros(3), 0)
    delta = np.zeros(3)
    assert K.allocate(law.par, law.nm, 1e5, -2e5, 3e5, 0.7, delta, law.status) == 0.0
    assert law.status[L.S_ALLOC_SCALE] == 1.0 and law.status[L.S_SAT_ANY] == 0.0


@pytest.mark.parametrize("mode", [1, 0])
def test_allocation_saturated_dense_matrix(mode):
    """Eq. 46 with saturation on a dense g_Gamma (every entry non-zero, unlike the
    winged-cone's, whose rudder has no pitch effectiveness): ALLOC_MODE 1 scales the whole
    vector, 0 clips each surface; the unallocated moment is M_c - g_Gamma delta_sat."""
    law = _matrix_law(ALLOC_MODE=mode)
    rng = np.random.default_rng(4)
    G = rng.normal(size=(3, 3)) * 1e7 + np.diag([3e7, -3e7, 3e7])
    law.nm[L.NM_GCO:L.NM_GCO + 9] = G.ravel()
    mc = np.array([9e6, 8e6, -7e6])
    raw = np.linalg.solve(G, mc)
    lim = 20 * DEG
    mc = mc * (3 * lim / np.max(np.abs(raw)))          # 3x beyond the limit
    raw = np.linalg.solve(G, mc)
    assert np.any(raw < -lim) and np.any(raw > lim)    # both signs beyond the limit
    delta = np.zeros(3)
    assert K.allocate(law.par, law.nm, mc[0], mc[1], mc[2], 0.7, delta, law.status) == 1.0
    sat = raw * (lim / np.max(np.abs(raw))) if mode else np.clip(raw, -lim, lim)
    np.testing.assert_allclose(delta, sat, rtol=1e-12)
    np.testing.assert_allclose(law.status[L.S_M_UNALLOC:L.S_M_UNALLOC + 3], mc - G @ sat,
                               rtol=1e-9)
    np.testing.assert_array_equal(law.status[L.S_SAT:L.S_SAT + 3],
                                  (np.abs(raw) > lim).astype(float))


@pytest.mark.parametrize("tau", [0.0, 0.05])
def test_actuator_model_lag_rate_and_limit(tau):
    """The controller's actuator model: first-order lag (none for tau 0), rate limit,
    position limit, from a preset state."""
    law = AttitudeLaw({"ACT_TAU": tau, "ACT_RATE": 90, "ACT_MAX": 20})
    law.x[L.X_DM:L.X_DM + 3] = [0.01, -0.02, 0.3]
    target = np.array([0.0105, -0.5, 0.6])                 # small, rate-limited, beyond limit
    dt = 0.002
    K.actuator_model_step(law.par, law.x, target, dt)
    a = 1.0 if tau == 0.0 else 1.0 - math.exp(-dt / tau)
    lim, rmax = 20 * DEG, 90 * DEG * dt
    x0 = np.array([0.01, -0.02, 0.3])
    exp = np.clip(x0 + np.clip(a * (np.clip(target, -lim, lim) - x0), -rmax, rmax), -lim, lim)
    np.testing.assert_allclose(law.x[L.X_DM:L.X_DM + 3], exp, rtol=1e-12)
    if tau == 0.0:
        assert law.x[L.X_DM] == pytest.approx(0.0105, rel=1e-12)


def _lp2(u, x1, x2, fc_hz, dt, wrap=False):
    """Two 1st-order sections, exact discretisation (V7), written out here."""
    a = 1.0 - math.exp(-2 * math.pi * fc_hz * dt)
    w = (lambda v: (v + math.pi) % (2 * math.pi) - math.pi) if wrap else (lambda v: v)
    y1 = w(x1 + a * w(u - x1))
    y2 = w(x2 + a * w(y1 - x2))
    return y1, y2


def test_fast_step_input_filters():
    """V7: p, q, r through two 1st-order sections before the whole fast loop; alpha, beta,
    mu through the same for the slow loop; the observer's model acceleration through the
    rates' filter (each from a preset filter state)."""
    est = _est(mu_deg=179.9, p=0.02, q=-0.015, r=0.01)
    fr, fa = 20.0, 15.0
    wf1, wf2 = np.array([0.01, -0.01, 0.02]), np.array([0.005, -0.02, 0.015])
    af1 = np.array([2.5 * DEG, 2.2 * DEG, -179.5 * DEG])
    af2 = np.array([2.0 * DEG, 2.5 * DEG, 179.0 * DEG])
    ff1, ff2 = np.array([0.3, -0.2, 0.1]), np.array([0.25, -0.1, 0.05])
    law = _fast_setup({"CO_ENABLE": 0, "FLT_RATE_HZ": fr, "FLT_ANG_HZ": fa, "FLT_ANG_CF": 0}, est)
    for idx, v in ((L.X_WF1, wf1), (L.X_WF2, wf2), (L.X_AF1, af1), (L.X_AF2, af2),
                   (L.X_FF1, ff1), (L.X_FF2, ff2)):
        law.x[idx:idx + 3] = v
    dt = 0.002
    _call_fast(law, est, dt)
    w = np.array([_lp2(est[3 + i], wf1[i], wf2[i], fr, dt) for i in range(3)])
    ang = np.array([_lp2(est[i], af1[i], af2[i], fa, dt, wrap=(i == 2)) for i in range(3)])
    np.testing.assert_allclose(law.x[L.X_WF1:L.X_WF1 + 3], w[:, 0], rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_WF2:L.X_WF2 + 3], w[:, 1], rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_AF1:L.X_AF1 + 3], ang[:, 0], rtol=RTOL)
    np.testing.assert_allclose(law.x[L.X_AF2:L.X_AF2 + 3], ang[:, 1], rtol=RTOL)
    mc, e2, d_hat, xth, c_d, _, inertia = _fast_expected(law, est, dt, w=w[:, 1])
    np.testing.assert_allclose(law.status[L.S_M_C:L.S_M_C + 3], mc, rtol=RTOL)
    Gf = law.nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    dm = _actuator_expected(law, law.delta_cmd_rad, dt)
    f_in = xth + Gf @ (0.5 * (DM0 + dm)) / inertia
    f = np.array([_lp2(f_in[i], ff1[i], ff2[i], fr, dt) for i in range(3)])
    np.testing.assert_allclose(law.x[L.X_FF2:L.X_FF2 + 3], f[:, 1], rtol=RTOL)
    a = c_d * dt
    np.testing.assert_allclose(law.x[L.X_Z:L.X_Z + 3],
                               (1 - a) * Z0 - a * (f[:, 1] + c_d * w[:, 1]), rtol=RTOL)


def test_slow_step_reads_the_filtered_angles():
    """V7: with FLT_ANG_HZ > 0 the slow loop's e1 uses the angle filter's output (run by
    the fast loop), not est; the printed law (PAPER_LITERAL) uses est and no prefilter."""
    est = _est()
    filt = np.array([2.5 * DEG, 1.5 * DEG, 9 * DEG])
    for literal, cutoff_hz in ((0, 20.0), (0, 0.5), (1, 20.0)):
        law = _slow_setup({"REF_PF_EN": 1, "FLT_ANG_HZ": cutoff_hz, "PAPER_LITERAL": literal},
                          est)
        law.x[L.X_AF2:L.X_AF2 + 3] = filt
        cmd = [5 * DEG, -1 * DEG, 14 * DEG]
        _call_slow(law, est, cmd, 0.01)
        ref = law.x[L.X_PF:L.X_PF + 3]
        if literal:
            np.testing.assert_array_equal(ref, cmd)                 # steps
        seen = est[0:3] if literal else filt
        np.testing.assert_allclose(law.status[L.S_E1:L.S_E1 + 3], seen - ref, rtol=RTOL)


def test_fast_step_eq36_frozen_while_a_surface_saturates():
    """V2: a fast step whose allocation saturates freezes Eq. 36."""
    est = _est()
    law = _fast_setup({"CO_ENABLE": 0, "SLW_AW": 1}, est)
    law.x[L.X_Z:L.X_Z + 3] = [200.0, -200.0, 200.0]          # a huge disturbance estimate
    _call_fast(law, est, 0.002)
    assert law.x[L.X_SAT] == 1.0 and law.status[L.S_SAT_ANY] == 1.0
    np.testing.assert_array_equal(law.x[L.X_RHO_F:L.X_RHO_F + 17], RHOF0)
    assert law.status[L.S_FROZEN] == 1.0


@pytest.mark.parametrize("co_e", [0.0, 1.0, 0.4])
def test_surface_coupling_degree_as_used(co_e):
    """Eq. 15 / D8: E from the nominal model when CO_E is 0, else CO_E."""
    est = _est()
    law = _fast_setup({"CO_E": co_e}, est)
    _call_fast(law, est, 0.002)
    expected = law.nm[L.NM_E] if co_e == 0.0 else co_e
    assert law.status[L.S_E_COUP] == expected
    assert 0.0 < law.nm[L.NM_E] < 1.0 and law.nm[L.NM_E] != co_e


def test_bad_input_sets_and_clears_the_flag_in_each_loop():
    est = _est()
    law = _fast_setup({}, est)
    bad = est.copy()
    bad[L.E_P] = np.nan
    _call_fast(law, bad, 0.002)
    assert law.status[L.S_INPUT_BAD] == 1.0
    _call_fast(law, est, 0.002)
    assert law.status[L.S_INPUT_BAD] == 0.0
    _call_slow(law, bad, [0.0, 0.0, 0.0], 0.01)
    assert law.status[L.S_INPUT_BAD] == 1.0
    _call_slow(law, est, [0.0, 0.0, 0.0], 0.01)
    assert law.status[L.S_INPUT_BAD] == 0.0


def test_small_but_regular_matrices_are_used():
    """Only an exactly singular matrix means "no authority": a regular g_f_delta with a
    small determinant (here 1e-3, e.g. at a very low dynamic pressure) is used as it is."""
    law = _matrix_law()
    law.nm[L.NM_GFD:L.NM_GFD + 9] = (0.1 * np.eye(3)).ravel()
    assert K.coordinated_matrix(law.par, law.nm, np.zeros(3), 0) == 0.0
    delta = np.zeros(3)
    assert K.allocate(law.par, law.nm, 0.001, -0.002, 0.0005, 0.7, delta, law.status) == 0.0
    np.testing.assert_allclose(delta, [0.01, -0.02, 0.005], rtol=1e-12)
