"""What the adaptive laws (Eqs. 30 and 36) do, seen from outside: behavioural tests.

The equation tests (test_law_equations.py) check one step of each adaptive law against the
equation written out again. These tests check what the adaptation is for, in a short seeded
closed loop in process: under a known constant error of the force or moment coefficients,
the estimate moves the way that error implies, fast enough, and tracking is better with the
adaptation on than off. The sign-flip and gain-halving mutants of Eqs. 30 and 36
(tools.evidence.mutate.NAMED) fail them.

The plant is the law's own model (Eqs. 20-26: Omega_dot = f1 + Psi^T theta_Omega + g_s omega,
omega_dot = Xi^T theta_omega + g_f g_f_delta delta) with the true parameters off the nominal
ones by a known factor: theta_true_i = theta_nom_i (1 + err) for the entries that are
aerodynamic coefficients (the inertia-ratio entries stay exact). So the right answer is known:
rho_i -> err, and the estimated model's correction Xi_i theta_nom_i rho_i should move toward
the true one, Xi_i theta_nom_i err. The surfaces act at once (no actuator model), the
disturbance observer is off (it would absorb the model error before the adaptation sees it)
and the vehicle starts at the command (alpha 5 deg, beta 0, mu 0, V 2200 m/s, 21 km), so
what the loop has to correct is the model error alone. Explicit Euler at the fast rate
(500 Hz), slow loop at 100 Hz, 3 s: about a second per flight without numba (NUMBA_DISABLE_JIT,
as tools.evidence.mutate runs them).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.control import layout as L
from fc.control.kinematics import gs
from fc.control.law import AttitudeLaw
from fc.control.nominal import eval_model
from fc.control.params import P_MDL_IXX, P_MDL_IYY, P_MDL_IZZ
from fc.control.slow_loop import f1_gravity

DEG = math.pi / 180.0
DT_FAST_S = 0.002
N_SLOW = 5                      # slow loop every 5th fast step: 100 Hz
T_S = 3.0
RHO_F_NAMES = L.STATUS_NAMES[L.S_RHO_F:L.S_RHO_F + L.TH_F_N]
#: theta_omega entries that are aerodynamic coefficients (the rest are inertia ratios and
#: inertia rates): only these carry the moment/force coefficient error
COEF_F = np.array([0.0 if n.split("_", 2)[2][0] == "I" else 1.0 for n in RHO_F_NAMES])
I_CM = RHO_F_NAMES.index("rho_pitch_Cm")
I_CL_ALPHA = 0                  # rho_CL_alpha: theta_Omega's lift entry (alpha row)
PITCH = slice(L.TH_F_PITCH, L.TH_F_YAW)

#: the flights' law settings: the observer off (see the module docstring), and the paper's
#: fixed gains (CTL_SCHED 0: the bounds below were measured with them; the schedule, issue 20,
#: sets kappa2, K and the filters from the dynamic pressure instead)
BASE = {"DOB_ENABLE": 0, "CTL_SCHED": 0}
#: Gamma1 raised for the slow-loop test: at the default 20 (1/rad^2) the slow estimate moves
#: by less than 1e-3 in 3 s here (Psi_i theta_i is about 0.015 rad/s and sigma about 1e-4 rad
#: once the fast loop holds the command): too little for any figure to show a halved gain.
SLW_GAMMA_TEST = 2000.0


def fly(err_force: float, err_moment: float, overrides: dict) -> dict:
    """Hold alpha 5 deg for T_S with the law flying its own model, whose aerodynamic
    coefficients are off by the factors (1 + err_force) (theta_Omega and the force entries
    of theta_omega) and (1 + err_moment) (the moment entries). Returns time histories:
    t_s (n,), rho_s (n, 4), rho_f (n, 17), xi (n, 17) (Xi_i theta_nom_i, rad/s^2), psi (n, 4)
    (Psi_i theta_nom_i, rad/s), e1 (n, 3) rad, e2 (n, 3) rad/s."""
    law = AttitudeLaw(dict(BASE, **overrides))
    k = law.kernel_args()
    par = k["par"]
    nm_true = np.zeros_like(k["nm"])
    inertia = np.array([par[P_MDL_IXX], par[P_MDL_IYY], par[P_MDL_IZZ]])
    force = np.array(["CD" in n or "CL" in n or "CYb" in n for n in RHO_F_NAMES])
    err_f = COEF_F * np.where(force, err_force, err_moment)
    est = np.zeros(L.E_N)
    est[L.E_ALPHA] = 5.0 * DEG
    est[L.E_V] = 2200.0
    est[L.E_H] = 21000.0
    cmd = np.array([5.0 * DEG, 0.0, 0.0])
    law.reset(est)
    n = int(round(T_S / DT_FAST_S))
    out = {"t_s": np.arange(1, n + 1) * DT_FAST_S, "rho_s": np.zeros((n, 4)),
           "rho_f": np.zeros((n, L.TH_F_N)), "xi": np.zeros((n, L.TH_F_N)),
           "psi": np.zeros((n, 4)), "e1": np.zeros((n, 3)), "e2": np.zeros((n, 3))}
    dt = DT_FAST_S
    for i in range(n):
        if i % N_SLOW == 0:
            law.slow_step(est, cmd, N_SLOW * dt)
        law.fast_step(est, dt)
        eval_model(est, par, k["tab"], k["atm"], k["grid"], nm_true)
        a, b, mu = est[L.E_ALPHA], est[L.E_BETA], est[L.E_MU]
        p, q, r = est[L.E_P], est[L.E_Q], est[L.E_R]
        f1 = f1_gravity(nm_true[L.NM_G], b, mu, est[L.E_V], est[L.E_GAMMA])
        psi = nm_true[L.NM_PSI:L.NM_PSI + 4] * (1.0 + err_force)
        g = gs(a, b, p, q, r)
        xi = nm_true[L.NM_XI:L.NM_XI + L.TH_F_N] * (1.0 + err_f)
        moment = nm_true[L.NM_GFD:L.NM_GFD + 9].reshape(3, 3) @ law.delta_cmd_rad
        est[L.E_ALPHA] += dt * (f1[0] + psi[0] + g[0])
        est[L.E_BETA] += dt * (f1[1] + psi[1] + g[1])
        est[L.E_MU] += dt * (f1[2] + psi[2] + psi[3] + g[2])
        est[L.E_P] += dt * (xi[:L.TH_F_PITCH].sum() + moment[0] / inertia[0])
        est[L.E_Q] += dt * (xi[PITCH].sum() + moment[1] / inertia[1])
        est[L.E_R] += dt * (xi[L.TH_F_YAW:].sum() + moment[2] / inertia[2])
        out["rho_s"][i] = law.x[L.X_RHO_S:L.X_RHO_S + 4]
        out["rho_f"][i] = law.x[L.X_RHO_F:L.X_RHO_F + L.TH_F_N]
        out["xi"][i] = nm_true[L.NM_XI:L.NM_XI + L.TH_F_N]
        out["psi"][i] = nm_true[L.NM_PSI:L.NM_PSI + 4]
        out["e1"][i] = law.status[L.S_E1:L.S_E1 + 3]
        out["e2"][i] = law.status[L.S_E2:L.S_E2 + 3]
    return out


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _at(run: dict, t_s: float) -> int:
    return int(round(t_s / DT_FAST_S)) - 1


@pytest.fixture(scope="module")
def moment_error():
    """Moment coefficients 20 % below the model's (the paper's -20 %), forces exact."""
    return fly(0.0, -0.2, {})


@pytest.fixture(scope="module")
def force_error():
    """Force coefficients 20 % above the model's (the paper's +20 %), moments exact."""
    return fly(0.2, 0.0, {})


def test_fast_estimate_moves_toward_a_moment_error(moment_error):
    """Eq. 36: with Cm 20 % weaker than modelled, rho_Cm goes negative from the start and the
    pitch model's correction sum_i Xi_i theta_i rho_i grows toward the true one,
    sum_i Xi_i theta_i err, at the rate Gamma2 sets.

    Measured (this flight, FST_GAMMA 5): the correction is 6.9 % of the true one at 1 s
    and 13.8 % at 3 s, rho_Cm -0.028 at 3 s; with Gamma2 halved 3.9 % at 1 s; with the
    adaptation's sign flipped rho_Cm goes positive. Asserted: >= 5.5 % at 1 s (a 20 %
    margin below the measured figure), never past the truth, rho_Cm < 0 throughout after
    0.25 s (the first 0.1 s of the transient push it slightly positive) and falling."""
    run = moment_error
    corr = (run["xi"][:, PITCH] * run["rho_f"][:, PITCH]).sum(axis=1)
    truth = -0.2 * (run["xi"][:, PITCH] * COEF_F[PITCH]).sum(axis=1)
    share = corr / truth
    rho_cm = run["rho_f"][:, I_CM]
    assert np.all(rho_cm[_at(run, 0.25):] < 0.0)
    assert rho_cm[-1] < rho_cm[_at(run, 1.0)] < rho_cm[_at(run, 0.5)]
    assert share[_at(run, 1.0)] >= 0.055, share[_at(run, 1.0)]
    assert np.all(share[_at(run, 0.1):] <= 1.0)


def test_slow_estimate_moves_toward_a_force_error_with_its_time_constant(force_error):
    """Eq. 30: with the lift 20 % stronger than modelled, rho_CL_alpha goes positive and
    approaches its equilibrium with the time constant that Gamma1 and the leakage set,
    1 / (Gamma1 lambda_Omega) = 0.5 s at the defaults.

    The equilibrium itself is tiny, rho = Psi^2 err / (kappa1 lambda_Omega) ~ 3e-4 here,
    whatever Gamma1 (the leakage dominates a regressor Psi_i theta_i of about 0.015 rad/s):
    so the behaviour a wrong gain changes is how fast the estimate gets there. Measured
    (SLW_GAMMA 20): rho(0.5 s) / rho(3 s) = 0.46, rho(3 s) = 2.8e-4; with Gamma1 halved
    0.29; doubled 0.68; with the sign flipped rho goes negative. Asserted: rho > 0 after
    0.1 s and rho(0.5 s) / rho(3 s) in [0.37, 0.60]."""
    run = force_error
    rho = run["rho_s"][:, I_CL_ALPHA]
    assert np.all(rho[_at(run, 0.1):] > 0.0)
    ratio = rho[_at(run, 0.5)] / rho[-1]
    assert 0.37 <= ratio <= 0.60, ratio


def test_adaptation_lowers_the_tracking_error():
    """Both errors at once (the paper's +20 % forces, -20 % moments): the rate-tracking error
    e2 and the alpha error e1 are smaller with the adaptive laws on than with Gamma1 =
    Gamma2 = 0. Measured (this flight): rms e2 (all axes) 4.81e-3 vs 5.55e-3 rad/s (-13 %),
    rms e1 alpha 2.51e-4 vs 2.63e-4 rad (-4.5 %). Asserted: e2 at most 0.92x, e1 at most
    0.98x the figure without adaptation."""
    on = fly(0.2, -0.2, {})
    off = fly(0.2, -0.2, {"SLW_GAMMA": 0.0, "FST_GAMMA": 0.0})
    assert rms(on["e2"]) <= 0.92 * rms(off["e2"]), (rms(on["e2"]), rms(off["e2"]))
    assert rms(on["e1"][:, 0]) <= 0.98 * rms(off["e1"][:, 0]), (rms(on["e1"][:, 0]),
                                                                  rms(off["e1"][:, 0]))
