"""Array layouts of the control law: named index constants for every flat float64 array.

The law works on flat, preallocated ``float64`` arrays (docs/architecture.md section 3). This
module names every slot, so the kernels read close to the paper's notation and a reader can
find what ``x[X_SIGMA + 1]`` is. Nothing here allocates per step.

Arrays
------
est : float64[E_N]     estimated state, the law's input (architecture.md section 5)
cmd : float64[3]       attitude command Omega_c = [alpha_c, beta_c, mu_c] (rad)
par : float64[P_N]     parameters in SI (fc/control/params.py owns the indices P_*)
x   : float64[X_N]     the law's internal state (integrators, filters, estimates)
nm  : float64[NM_N]    the nominal model evaluated at the current flight condition
st  : float64[S_N]     status record (sigma, e1, e2, omega_c, M_c, estimates, ...)
tab : float64[nM, nA, T_N]   nominal aerodynamic table over (Mach, alpha)
atm : float64[nH, ATM_N]     nominal atmosphere table over altitude
grid: float64[G_N]     uniform-grid definitions of ``tab`` and ``atm``
"""
from __future__ import annotations

# --- Estimated state (architecture.md section 5), filled by fc/estimator.py -----------------
E_ALPHA = 0      # angle of attack (rad)
E_BETA = 1       # sideslip (rad)
E_MU = 2         # bank angle about the velocity vector (rad)
E_P = 3          # body roll rate (rad/s)
E_Q = 4          # body pitch rate (rad/s)
E_R = 5          # body yaw rate (rad/s)
E_V = 6          # airspeed (m/s)
E_H = 7          # altitude (m)
E_GAMMA = 8      # flight-path angle (rad)
E_N = 9
E_NAMES = ("alpha_rad", "beta_rad", "mu_rad", "p_rad_s", "q_rad_s", "r_rad_s",
           "V_m_s", "h_m", "gamma_rad")

# --- Surfaces (architecture.md section 2 and 6) -----------------------------------------------
D_LEFT = 0       # left elevon  (the paper's delta_e in the winged-cone reading)
D_RIGHT = 1      # right elevon (the paper's delta_a)
D_RUDDER = 2     # rudder       (the paper's delta_r)

# --- Nominal aerodynamic table columns (tools/gen_nominal_model.py) ---------------------------
# Coefficients about the moment reference centre at zero sideslip, rates and deflections, and
# their partial derivatives. "L/D/Y" = lift/drag/side force; "ROLL/PITCH/YAW" = Cl/Cm/Cn.
T_CL0 = 0          # lift coefficient C_L(alpha, M)
T_CD0 = 1          # drag coefficient C_D(alpha, M)
T_CY0 = 2          # side-force coefficient at beta = 0 (0 for the symmetric vehicle)
T_CROLL0 = 3       # Cl at beta = 0
T_CPITCH0 = 4      # Cm(alpha, M) (the paper's C_m,a)
T_CYAW0 = 5        # Cn at beta = 0
T_CY_B = 6         # dC_Y/dbeta (1/rad)
T_CROLL_B = 7      # dCl/dbeta (1/rad)
T_CYAW_B = 8       # dCn/dbeta (1/rad)
T_CROLL_P = 9      # dCl/d(p b/2V)
T_CROLL_R = 10     # dCl/d(r b/2V)
T_CPITCH_Q = 11    # dCm/d(q c/2V)
T_CYAW_P = 12      # dCn/d(p b/2V)
T_CYAW_R = 13      # dCn/d(r b/2V)
T_DEL = 14         # control derivatives (1/rad): T_DEL + 3*k + j, k in C_* order, j surface
T_N = T_DEL + 18

# coefficient order inside the control-derivative block (as plant_sim.aero's output)
C_LIFT = 0
C_DRAG = 1
C_SIDE = 2
C_ROLL = 3
C_PITCH = 4
C_YAW = 5

# --- Nominal atmosphere table columns --------------------------------------------------------
ATM_RHO = 0      # density (kg/m^3)
ATM_SOUND = 1    # speed of sound (m/s)
ATM_G = 2        # gravity (m/s^2)
ATM_N = 3

# --- Grid definitions (uniform grids) --------------------------------------------------------
G_MACH0 = 0
G_DMACH = 1
G_NMACH = 2
G_ALPHA0 = 3     # rad
G_DALPHA = 4     # rad
G_NALPHA = 5
G_H0 = 6         # m
G_DH = 7         # m
G_NH = 8
G_N = 9

# --- Nominal model evaluated at the flight condition (nm array) ------------------------------
NM_MACH = 0
NM_QBAR = 1      # dynamic pressure (Pa)
NM_RHO = 2
NM_SOUND = 3
NM_G = 4         # gravity (m/s^2)
NM_E = 5         # surface-deflection coupling degree E (Eq. 15, effectiveness ratio)
NM_GFD = 6       # g_f_delta, 9 entries row-major: rows (l, m, n), columns surfaces (N m/rad)
NM_GCO = 15      # coordinated matrix g_Gamma_f_delta (Eq. 45), 9 entries, as used
NM_COEF = 24     # the T_N interpolated table columns
NM_TH_S = NM_COEF + T_N          # nominal theta_Omega (4)
NM_TH_F = NM_TH_S + 4            # nominal theta_omega (17)
NM_PSI = NM_TH_F + 17            # Psi^T theta contributions per entry (4): Psi_i theta_nom_i
NM_XI = NM_PSI + 4               # Xi^T theta contributions per entry (17): Xi_i theta_nom_i
NM_N = NM_XI + 17

# entries of theta_Omega (Eq. 22: theta_1, theta_2, theta_3 = [C_Y_beta, C_L])
TH_S_N = 4
# entries of theta_omega ordered roll (5), pitch (6), yaw (6) (paper_notes: so that
# Xi^T theta_omega reproduces f_p, f_q, f_r; Eq. 22 lists them yaw, pitch, roll)
TH_F_ROLL = 0
TH_F_PITCH = 5
TH_F_YAW = 11
TH_F_N = 17

# --- Internal state (x array) ------------------------------------------------------------------
X_INT_E1 = 0         # integral of e1 (rad s), 3
X_PF = 3             # reference prefilter output Omega_c (rad), 3
X_PF_DOT = 6         # its derivative (rad/s), 3
X_OMC = 9            # virtual rate command omega_c after the limit (rad/s), 3
X_CF = 12            # command-filtered omega_c (rad/s), 3
X_CF_DOT = 15        # its derivative (rad/s^2), 3
X_RHO_S = 18         # relative adaptive estimate of theta_Omega, 4
X_RHO_F = 22         # relative adaptive estimate of theta_omega, 17
X_Z = 39             # disturbance-observer state z (rad/s^2), 3
X_DM = 42            # the controller's model of the actual deflections (rad), 3
X_SIGMA = 45         # last sliding variable sigma (rad), 3
X_SAT = 48           # 1 if a surface saturated in the last fast step
X_LIM = 49           # 1 if omega_c was limited in the last slow step
X_DCMD = 50          # last surface command (rad), 3
X_XI = 53            # command-filter compensation xi of sigma (rad), 3
X_AF1 = 56           # input filter of alpha, beta, mu, stage 1 (rad), 3
X_AF2 = 59           # stage 2 (the filtered value), 3
X_WF1 = 62           # input filter of p, q, r, stage 1 (rad/s), 3
X_WF2 = 65           # stage 2 (the filtered value), 3
X_EF = 68            # the fast loop's effective state: est with p, q, r filtered, E_N
X_FF1 = X_EF + E_N   # the observer's model acceleration through the same filter, stage 1, 3
X_FF2 = X_FF1 + 3    # stage 2, 3
X_FKIN = X_FF2 + 3   # f1 + Psi^T theta_hat of the last slow step (rad/s), 3: the complementary
                     # attitude filter's model term (FLT_ANG_CF)
X_YAW_T = X_FKIN + 3 # time the rudder alone has been asked beyond its limit (s), 1: the
                     # allocation's yaw escalation (ALLOC_YAW_T)
X_N = X_YAW_T + 1

# --- Status record (st array) ------------------------------------------------------------------
S_SIGMA = 0          # 3
S_E1 = 3             # 3
S_E2 = 6             # 3
S_OMEGA_C = 9        # 3  (limited, before the command filter)
S_OMEGA_CF = 12      # 3  (after the command filter)
S_M_C = 15           # 3  commanded moment (N m)
S_M_UNALLOC = 18     # 3  unallocated moment M_c - g_Gamma_f_delta delta (N m)
S_D_HAT = 21         # 3  disturbance estimate (rad/s^2)
S_LAMBDA = 24        # 3  coordinated factors lambda_e, lambda_a, lambda_r
S_E_COUP = 27        # surface coupling degree E used
S_SAT = 28           # 3  per-surface saturation flags (1 = requested beyond the limit)
S_SAT_ANY = 31
S_OMC_LIM = 32       # 1 if omega_c was limited
S_FROZEN = 33        # 1 if the integral and adaptation were frozen
S_ALLOC_SCALE = 34   # direction-preserving scale applied (1 = none)
S_CO_FALLBACK = 35   # 1 if the coordinated matrix was rejected (singular / sign flip)
S_DELTA_CMD = 36     # 3 surface command (rad)
S_DELTA_MODEL = 39   # 3 the controller's model of the achieved deflection (rad)
S_OMEGA_REF = 42     # 3 Omega_c after the prefilter (rad)
S_MACH = 45
S_QBAR = 46
S_RHO_S = 47         # 4 relative estimates of theta_Omega
S_RHO_F = 51         # 17 relative estimates of theta_omega
S_XI = 68            # 3 compensation xi: sigma_bar = sigma - xi (rad)
S_INPUT_BAD = 71     # 1 if the last step rejected its input (non-finite est/cmd, dt <= 0)
S_ALLOC_RATE = 72    # rate-aware allocation: scale of the command's change this step (1 = none)
S_N = 73

STATUS_NAMES = (
    "sigma_alpha_rad", "sigma_beta_rad", "sigma_mu_rad",
    "e1_alpha_rad", "e1_beta_rad", "e1_mu_rad",
    "e2_p_rad_s", "e2_q_rad_s", "e2_r_rad_s",
    "omega_c_p_rad_s", "omega_c_q_rad_s", "omega_c_r_rad_s",
    "omega_cf_p_rad_s", "omega_cf_q_rad_s", "omega_cf_r_rad_s",
    "M_c_l_Nm", "M_c_m_Nm", "M_c_n_Nm",
    "M_unalloc_l_Nm", "M_unalloc_m_Nm", "M_unalloc_n_Nm",
    "d_hat_p_rad_s2", "d_hat_q_rad_s2", "d_hat_r_rad_s2",
    "lambda_e", "lambda_a", "lambda_r",
    "E_coupling",
    "sat_left", "sat_right", "sat_rudder",
    "sat_any", "omega_c_limited", "adapt_frozen", "alloc_scale", "co_fallback",
    "delta_cmd_left_rad", "delta_cmd_right_rad", "delta_cmd_rudder_rad",
    "delta_model_left_rad", "delta_model_right_rad", "delta_model_rudder_rad",
    "alpha_ref_rad", "beta_ref_rad", "mu_ref_rad",
    "mach", "qbar_Pa",
    "rho_CL_alpha", "rho_CYb_beta", "rho_CYb_mu", "rho_CL_mu",
    "rho_roll_Iyy_Izz", "rho_roll_Ixxdot", "rho_roll_Clb", "rho_roll_Clp", "rho_roll_Clr",
    "rho_pitch_Izz_Ixx", "rho_pitch_Iyydot", "rho_pitch_Cm", "rho_pitch_Cmq", "rho_pitch_CD",
    "rho_pitch_CL",
    "rho_yaw_Ixx_Iyy", "rho_yaw_Izzdot", "rho_yaw_Cnb", "rho_yaw_Cnp", "rho_yaw_Cnr",
    "rho_yaw_CYb",
    "xi_alpha_rad", "xi_beta_rad", "xi_mu_rad",
    "input_bad",
    "alloc_rate_scale",
)

assert len(STATUS_NAMES) == S_N, (len(STATUS_NAMES), S_N)
assert NM_N < 200
