"""The controller's nominal model (fc/control/nominal.py + data/nominal_model.npz).

The tables are generated offline from the published fits as the plant implements them; these
tests regenerate them and check the run-time model against the plant's own functions (the
plant is imported here, in the test, never by the law).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.control import layout as L
from fc.control.nominal import B_REF_M, C_REF_M, S_REF_M2, eval_model, load_tables
from fc.control.params import default_si_array, PARAM_INDEX

DEG = math.pi / 180.0


def test_committed_tables_match_regeneration():
    from tools.gen_nominal_model import compare
    # bit-for-bit up to float rounding: the generator is deterministic
    assert compare() < 1e-12


def _state(alpha_deg, beta_deg, p, q, r, V=2200.0, h=21000.0, mu_deg=0.0, gamma_deg=0.0):
    return np.array([alpha_deg * DEG, beta_deg * DEG, mu_deg * DEG, p, q, r, V, h,
                     gamma_deg * DEG])


@pytest.mark.parametrize("alpha_deg,V,h", [(1.0, 2200.0, 21000.0), (5.0, 2200.0, 21000.0),
                                          (3.3, 2400.0, 25000.0), (7.7, 1900.0, 18000.0),
                                          # the envelope's top: Mach 14 / 30 km, Mach 15 / 34 km
                                          (5.0, 4200.0, 30000.0), (3.0, 4520.0, 34000.0)])
def test_model_reproduces_plant_moments_and_effectiveness(alpha_deg, V, h):
    from plant_sim.aero import coefficients, effectiveness_matrix
    from plant_sim.atmosphere import A_N, A_RHO_KG_M3, A_SOUND_M_S, us76
    tab, atm, grid = load_tables()
    par = default_si_array()
    nm = np.zeros(L.NM_N)
    beta_deg, p, q, r = 2.0, 0.05, -0.03, 0.02
    est = _state(alpha_deg, beta_deg, p, q, r, V=V, h=h)
    eval_model(est, par, tab, atm, grid, nm)

    a = np.zeros(A_N)
    us76(h, a)
    mach = V / a[A_SOUND_M_S]
    qbar = 0.5 * a[A_RHO_KG_M3] * V * V
    # atmosphere table (100 m grid, linear): within 1e-4 relative of US76
    assert nm[L.NM_MACH] == pytest.approx(mach, rel=1e-4)
    assert nm[L.NM_QBAR] == pytest.approx(qbar, rel=1e-4)

    c = np.zeros(6)
    coefficients(alpha_deg, mach, beta_deg * DEG, p * B_REF_M / (2 * V), q * C_REF_M / (2 * V),
                 r * B_REF_M / (2 * V), 0.0, 0.0, 0.0, c)
    qS = qbar * S_REF_M2
    plant_lmn = np.array([qS * B_REF_M * c[3], qS * C_REF_M * c[4], qS * B_REF_M * c[5]])
    ixx, iyy, izz = (par[PARAM_INDEX[n]] for n in ("MDL_IXX", "MDL_IYY", "MDL_IZZ"))
    xi = nm[L.NM_XI:L.NM_XI + 17]
    # Xi^T theta_nom without the inertial-coupling entries = aerodynamic moment / inertia:
    # checks the roll/pitch/yaw ordering of theta_omega and the regressors of Eq. 24
    model_lmn = np.array([ixx * xi[1:5].sum(), iyy * xi[6:11].sum(), izz * xi[12:17].sum()])
    # bilinear table (0.25 Mach x 0.5 deg grid) vs the polynomials: within 2 % of the
    # largest moment (exact on grid nodes)
    np.testing.assert_allclose(model_lmn, plant_lmn, rtol=0,
                               atol=0.02 * np.max(np.abs(plant_lmn)))
    # inertial coupling entries (Eq. 4)
    assert ixx * xi[0] == pytest.approx((iyy - izz) * q * r)
    assert iyy * xi[5] == pytest.approx((izz - ixx) * p * r)
    assert izz * xi[11] == pytest.approx((ixx - iyy) * p * q)

    # g_f_delta (Eq. 45) vs the plant's own effectiveness matrix (x_cg 0)
    G = nm[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3)
    Gp = effectiveness_matrix(alpha_deg * DEG, mach, qbar, 0.0)
    np.testing.assert_allclose(G, Gp, rtol=0, atol=0.01 * np.max(np.abs(Gp)))
    # E (Eq. 15) = |Cl_delta_r / Cl_delta_a| in (0, 1]
    assert 0.0 < nm[L.NM_E] <= 1.0
    assert nm[L.NM_E] == pytest.approx(abs(Gp[0, 2] / Gp[0, 1]), rel=0.02)


def test_theta_omega_nominal_on_grid_node_is_exact():
    """On a table node the model equals the plant's fits to rounding."""
    from plant_sim.aero import coefficients
    from plant_sim.atmosphere import A_N, A_SOUND_M_S, us76
    tab, atm, grid = load_tables()
    a = np.zeros(A_N)
    h = 21000.0
    us76(h, a)
    mach = 7.5
    V = mach * a[A_SOUND_M_S]
    par = default_si_array()
    nm = np.zeros(L.NM_N)
    eval_model(_state(4.0, 0.0, 0.0, 0.0, 0.0, V=V, h=h), par, tab, atm, grid, nm)
    c = np.zeros(6)
    coefficients(4.0, nm[L.NM_MACH], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, c)
    # Mach from the interpolated sound speed differs from 7.5 by < 1e-4: CL, Cm at the node
    assert nm[L.NM_COEF + L.T_CL0] == pytest.approx(c[0], rel=1e-4)
    assert nm[L.NM_COEF + L.T_CPITCH0] == pytest.approx(c[4], rel=1e-3)
    assert nm[L.NM_TH_S] == nm[L.NM_COEF + L.T_CL0]


def test_tables_cover_the_plant_mach_range():
    """The table's Mach axis is the plant's hypersonic fits' range (4..24): the envelope
    (Mach 6-15) lies inside, and the law's model ends where the plant clips."""
    from plant_sim.vehicle import MACH_MAX, MACH_MIN
    _, _, grid = load_tables()
    m_top = grid[L.G_MACH0] + grid[L.G_DMACH] * (grid[L.G_NMACH] - 1)
    assert grid[L.G_MACH0] == MACH_MIN
    assert m_top == MACH_MAX


def _at_mach(mach, alpha_deg=5.0, h=30000.0):
    """The nominal model at (mach, alpha_deg, h), sound speed from the model's own table."""
    tab, atm, grid = load_tables()
    par = default_si_array()
    nm = np.zeros(L.NM_N)
    eval_model(_state(alpha_deg, 0.0, 0.0, 0.0, 0.0, V=300.0, h=h), par, tab, atm, grid, nm)
    V = mach * nm[L.NM_SOUND]
    eval_model(_state(alpha_deg, 0.0, 0.0, 0.0, 0.0, V=V, h=h), par, tab, atm, grid, nm)
    return nm


def test_mach_15_is_inside_the_model():
    """At Mach 15 the coefficients are the fits' at Mach 15 (not the old Mach-12 edge's)."""
    from plant_sim.aero import coefficients
    c = np.zeros(6)
    for mach in (12.5, 15.0):
        nm = _at_mach(mach)
        coefficients(5.0, nm[L.NM_MACH], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, c)
        assert nm[L.NM_MACH] == pytest.approx(mach, rel=1e-9)
        assert nm[L.NM_COEF + L.T_CD0] == pytest.approx(c[1], rel=1e-3)
        assert nm[L.NM_COEF + L.T_CPITCH0] == pytest.approx(c[4], rel=1e-2, abs=1e-5)
    # and the model still changes with Mach up there (a table clamped at 12 would not)
    assert _at_mach(15.0)[L.NM_COEF + L.T_CD0] != _at_mach(13.0)[L.NM_COEF + L.T_CD0]


def test_model_is_clamped_beyond_the_top_mach():
    """Beyond Mach 24 the model uses the Mach-24 edge (as the plant clips its fits)."""
    a, b = _at_mach(24.0), _at_mach(27.0)
    assert b[L.NM_MACH] > 26.9
    c = L.NM_COEF
    np.testing.assert_array_equal(a[c:c + L.T_N], b[c:c + L.T_N])
    assert np.all(np.isfinite(b))


def test_lookup_clamps_outside_the_box():
    tab, atm, grid = load_tables()
    par = default_si_array()
    nm = np.zeros(L.NM_N)
    eval_model(_state(25.0, 0.0, 0.0, 0.0, 0.0, V=5000.0, h=90000.0), par, tab, atm, grid, nm)
    assert np.all(np.isfinite(nm))
    nm2 = np.zeros(L.NM_N)
    eval_model(_state(12.0, 0.0, 0.0, 0.0, 0.0, V=5000.0, h=90000.0), par, tab, atm, grid, nm2)
    # alpha beyond the data (12 deg) uses the 12 deg column
    assert nm[L.NM_COEF + L.T_CL0] == nm2[L.NM_COEF + L.T_CL0]


@pytest.mark.parametrize("state", [
    (3.0, 2.0, 10.0, 0.05, -0.02, 0.03, 0.0),
    (5.0, -3.0, -20.0, -0.04, 0.03, -0.02, 5.0),
    (1.0, 5.0, 0.0, 0.0, 0.0, 0.0, 0.0),          # the paper's initial state
])
def test_slow_model_reproduces_plant_kinematics(state):
    """Omega_dot = f1 + Psi^T theta + g_s omega (Eqs. 20, 3, 23, 26) against the plant's own
    6-DOF integration over one physics step (nominal vehicle, zero deflection). Checks D1
    (Psi2 = +qbar S beta / (M V)) and the signs of f1 and g_s."""
    from plant_sim import dynamics as dy
    from plant_sim.scenario import load
    from plant_sim.sim import PlantSim, truth_kernel, TRUTH_N
    from fc.control.kernels import gs_apply
    a, b, m, p, q, r, g = state
    sim = PlantSim(load("nominal"))
    x, pp, w = sim.x, sim.p, sim.w
    dy.initial_state(2200.0, 21000.0, a * DEG, b * DEG, m * DEG, g * DEG, 0.0, p, q, r, x)
    x[dy.X_DL:dy.X_DL + 3] = 0.0
    x[dy.X_CMD_L:dy.X_CMD_L + 3] = 0.0
    row0 = np.zeros(TRUTH_N)
    row1 = np.zeros(TRUTH_N)
    meas = np.zeros(14)
    truth_kernel(x, pp, w, meas, row0)
    dt = float(pp[dy.P_DT])
    dy.rk4_step(x, pp, w)
    truth_kernel(x, pp, w, meas, row1)
    # central value of the derivative over the step (2nd-order accurate at the midpoint)
    plant_dot = (row1[1:4] - row0[1:4]) / dt

    tab, atm, grid = load_tables()
    par = default_si_array()
    nm = np.zeros(L.NM_N)
    mid = 0.5 * (row0[1:10] + row1[1:10])
    est = mid.copy()
    eval_model(est, par, tab, atm, grid, nm)
    al, be, mu_, V, gam = est[0], est[1], est[2], est[6], est[8]
    gv = nm[L.NM_G]
    f1 = np.array([gv * math.cos(gam) * math.cos(mu_) / (V * math.cos(be)),
                   gv * math.cos(gam) * math.sin(mu_) / V,
                   -gv * math.cos(gam) * math.cos(mu_) * math.tan(be) / V])
    psi = nm[L.NM_PSI:L.NM_PSI + 4]
    psi_t = np.array([psi[0], psi[1], psi[2] + psi[3]])
    gw = np.zeros(3)
    gs_apply(al, be, est[3], est[4], est[5], gw, 0)
    model_dot = f1 + psi_t + gw
    # neglected by the paper's model: thrust (speed hold, ~1e-4 rad/s), the deflection-free
    # table vs polynomials (interpolation), earth curvature: measured <= 2.6e-4 rad/s; bound
    # 5e-4 rad/s (0.03 deg/s),
    # against derivatives of 1e-2..1e-1 rad/s
    np.testing.assert_allclose(model_dot, plant_dot, rtol=0, atol=5e-4)
    # and the sideslip term really matters: flipping Psi2's sign would miss by more
    flipped = model_dot.copy()
    flipped[1] -= 2 * psi[1]
    if abs(psi[1]) > 1e-3:
        assert np.abs(flipped[1] - plant_dot[1]) > 1e-3
