"""Array layouts of the guidance loop: named index constants of its flat float64 arrays.

Arrays (all preallocated, SI)
-----------------------------
tgt : float64[TG_N]   targets: altitude, course, speed (or Mach)
gx  : float64[GX_N]   internal state (rate-limited commands, integrators, speed reference)
out : float64[GO_N]   outputs: alpha_c, beta_c, mu_c (the law's command, rad), throttle 0..1
gs  : float64[GS_N]   status record (names in GUIDANCE_STATUS_NAMES), with the limit bitfield
The estimated state is the law's ``est`` (fc.control.layout E_*), plus the course chi (rad).
"""
from __future__ import annotations

# --- targets (tgt) -------------------------------------------------------------------------
TG_H = 0         # altitude target (m)
TG_CHI = 1       # course target (rad, any value; the error is wrapped to [-pi, pi))
TG_V = 2         # airspeed target (m/s); used when TG_MACH <= 0
TG_MACH = 3      # Mach target (-); > 0 overrides TG_V with Mach x speed of sound (nominal atmosphere)
TG_N = 4

# --- outputs (out) ---------------------------------------------------------------------------
GO_ALPHA = 0     # alpha command (rad) for the attitude law
GO_BETA = 1      # beta command (rad): 0, coordinated flight
GO_MU = 2        # bank command about the velocity (rad)
GO_THR = 3       # throttle command 0..1
GO_N = 4

# --- internal state (gx) ---------------------------------------------------------------------
GX_GAM_C = 0     # rate-limited flight-path angle command (rad)
GX_ALPHA_C = 1   # rate-limited alpha command (rad)
GX_MU_C = 2      # rate-limited bank command (rad)
GX_THR_C = 3     # rate-limited throttle command (0..1)
GX_H_INT = 4     # integral of the altitude error (m s)
GX_V_INT = 5     # integral of the speed error (m)
GX_V_REF = 6     # speed reference, rate-limited toward the target (m/s)
GX_ALPHA_FF = 7  # last feed-forward alpha (rad), the start of the next inversion
GX_READY = 8     # 1 after reset
GX_G_INT = 9     # integral of the flight-path angle error (rad s)
GX_CHI_ERR_F = 10  # low-passed course error (rad)
GX_GDOT_F = 11   # low-passed gamma_c_dot (rad/s)
GX_GAM_PREV = 12  # the last step's flight-path angle (rad), for the measured gamma rate
GX_GI_SHORT_F = 13  # low-passed shortfall of the measured gamma rate against the corrected
                    # model's at the measured alpha (rad/s): the model-error check
GX_N = 14

# --- limit bitfield (gs[GS_LIMITS]): the envelope limit in force ------------------------------
LIM_ALPHA_MAX = 1 << 0
LIM_ALPHA_MIN = 1 << 1
LIM_ALPHA_RATE = 1 << 2
LIM_NZ_MAX = 1 << 3
LIM_NZ_MIN = 1 << 4
LIM_GAM_MAX = 1 << 5       # gamma_c at its upper limit (GE_GAM_MAX, or lowered by qbar)
LIM_GAM_MIN = 1 << 6
LIM_GAM_RATE = 1 << 7
LIM_QBAR_LOW = 1 << 8      # the qbar floor lowers the upper flight-path limit
LIM_QBAR_HIGH = 1 << 9     # the qbar ceiling raises the lower flight-path limit
LIM_MU_MAX = 1 << 10
LIM_MU_RATE = 1 << 11
LIM_THR_MAX = 1 << 12
LIM_THR_MIN = 1 << 13
LIM_THR_RATE = 1 << 14
LIM_ACC = 1 << 15          # the speed reference is ramping (GS_ACC_MAX)
LIM_HDOT = 1 << 16         # climb-rate demand at GA_HDOT_MAX
LIM_CHIDOT = 1 << 17       # turn-rate demand at GH_CHIDOT_MAX
LIM_INPUT_BAD = 1 << 18    # the step rejected its input (non-finite, dt outside (0, 1] s)

LIMIT_NAMES = ("alpha_max", "alpha_min", "alpha_rate", "nz_max", "nz_min", "gamma_max",
               "gamma_min", "gamma_rate", "qbar_low", "qbar_high", "mu_max", "mu_rate",
               "thr_max", "thr_min", "thr_rate", "acc", "hdot", "chidot", "input_bad")

# --- status record (gs) ------------------------------------------------------------------------
GS_LIMITS = 0        # bitfield LIM_* (as float)
GS_H_ERR = 1         # h_t - h (m)
GS_CHI_ERR = 2       # wrap(chi_t - chi) after the low-pass GH_CHI_TAU (rad)
GS_V_ERR = 3         # V_ref - V (m/s)
GS_V_REF = 4         # speed reference (m/s)
GS_HDOT_C = 5        # climb-rate demand (m/s)
GS_GAM_C = 6         # flight-path angle command (rad)
GS_GAMDOT_DES = 7    # desired gamma rate (rad/s)
GS_CL_REQ = 8        # lift coefficient asked of the inversion (after the load-factor limit)
GS_NZ_C = 9          # load factor of that lift (-)
GS_ALPHA_FF = 10     # feed-forward alpha from the nominal model's trimmed lift (rad)
GS_ALPHA_C = 11      # alpha command (rad)
GS_CHIDOT_C = 12     # turn-rate demand (rad/s)
GS_MU_C = 13         # bank command (rad)
GS_ACC_C = 14        # acceleration demand (m/s^2)
GS_THR_FF = 15       # throttle feed-forward from the nominal drag (0..1)
GS_THR_C = 16        # throttle command (0..1)
GS_QBAR = 17         # dynamic pressure of the nominal atmosphere (Pa)
GS_MACH = 18         # Mach number (-)
GS_DRAG = 19         # nominal drag (N)
GS_H_INT = 20        # altitude integral (m s)
GS_V_INT = 21        # speed integral (m)
GS_G_INT = 22        # flight-path integral (rad s)
GS_N = 23

GUIDANCE_STATUS_NAMES = (
    "limits", "h_err_m", "chi_err_rad", "V_err_m_s", "V_ref_m_s", "hdot_c_m_s", "gamma_c_rad",
    "gamma_dot_des_rad_s", "CL_req", "nz_c", "alpha_ff_rad", "alpha_c_rad", "chi_dot_c_rad_s",
    "mu_c_rad", "acc_c_m_s2", "thr_ff", "thr_c", "qbar_Pa", "mach", "drag_N", "h_int_m_s",
    "V_int_m", "gamma_int_rad_s",
)
assert len(GUIDANCE_STATUS_NAMES) == GS_N
assert len(LIMIT_NAMES) == 19
