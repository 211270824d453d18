"""The guidance (outer) loop as njit kernels over flat preallocated arrays (docs/guidance.md).

Targets (altitude, course, speed or Mach) in, the attitude command of the paper's law
(alpha_c, beta_c = 0, mu_c) and a throttle command out, at the guidance's own fixed rate
(the caller steps it with dt, e.g. 50 Hz). Pure: no I/O, clocks, logging; nothing allocates.

Per step (SI; chi the course, gamma the flight-path angle, qbar and Mach from the nominal
atmosphere of fc.control.nominal):
- speed reference V_ref -> V_t (or Mach_t a(h)) at most GS_ACC_MAX per second;
- altitude: hdot_c = clip(K_h e_h + clip(K_hi int e_h, +-HI_MAX), +-HDOT_MAX) (e_h
  integrated only within +-GA_HI_ZONE),
  gamma_c = asin(hdot_c / V) within the envelope's flight-path limits (GE_GAM_MAX, narrowed by
  the dynamic-pressure ramps), rate-limited (GE_GAM_RATE); its rate gamma_c_dot through a
  first-order low-pass (GA_GDOT_TAU) as feed-forward;
- flight path -> lift: e_gamma = gamma_c - gamma; the load factor asked for,
  n = ((g - V^2/(R+h)) cos gamma + V (gamma_c_dot + K_gam e_gamma)) / (g cos mu), within [GE_NZ_MIN +
  GE_NZ_MARGIN, GE_NZ_MAX - GE_NZ_MARGIN]; then the model-error correction gi = clip(K_gami int e_gamma, +-GI_MAX),
  a relative lift correction V gi / g (at 1 g, the gamma rate it is worth):
  C_L,req = (n m g (1 + V gi / g) - T_est sin(alpha)) / (qbar S) (T_est the engine
  model's thrust at the last throttle command; e_gamma integrated only within +-GA_GI_ZONE);
- lift -> alpha (feed-forward): the nominal model's trimmed lift C_L,trim(alpha, Mach) =
  C_L0 + C_L,delta delta_trim with the symmetric elevon delta_trim that zeroes the nominal
  pitching moment, inverted by Newton's method; alpha_c within [GE_ALPHA_MIN, GE_ALPHA_MAX]
  less GE_ALPHA_MARGIN at each end, rate-limited (GE_ALPHA_RATE);
- course -> bank (coordinated turn): chi_dot_c = clip(K_chi e_chi, +-CHIDOT_MAX), e_chi =
  wrap(chi_t - chi) through a first-order low-pass (GH_CHI_TAU),
  mu_c = atan(V chi_dot_c cos(gamma) / g), |mu_c| <= min(GE_MU_MAX - GE_MU_MARGIN,
  acos(1 / (GE_NZ_MAX - GE_NZ_MARGIN))), rate-limited (GE_MU_RATE); beta_c = 0;
- speed -> throttle: a_c = V_ref_dot + K_V e_V + clip(K_VI int e_V, +-VI_MAX),
  T_req = D_nom + m g sin(gamma) + m a_c, throttle = T_req / (cos(alpha) cos(beta) C_T,max qbar S)
  within [0, min(1, T_max / (C_T,max qbar S))], rate-limited (GE_THR_RATE).
The three integrals freeze while a limit blocks their loop in the error's direction (anti-windup)
or the error is outside their zone, except that an integral opposing its error always unwinds
toward zero (never past it): a value taken up in a transient cannot latch a loop at its limit.
The limit in force is a bitfield (layout LIM_*) in the status record.
The envelope limits (GE_NZ_*, GE_MU_MAX, GE_ALPHA_*) bound the achieved values: the commands
stay a margin (GE_*_MARGIN) inside them, room for the inner loop's tracking error, so the
limit bits are set when the command reaches the limit less its margin.
"""
from __future__ import annotations

import math

from numba import carray, njit

from fc.control.layout import (ATM_G, ATM_RHO, ATM_SOUND, C_DRAG, C_LIFT, C_PITCH, E_ALPHA,
                               E_BETA, E_GAMMA, E_H, E_MU, E_N, E_V, T_CD0, T_CL0, T_CPITCH0,
                               T_DEL, T_N)
from fc.control.nominal import C_REF_M, S_REF_M2, interp_atmosphere, interp_table
from fc.guidance import layout as _layout, params as _params
from fc.guidance.layout import (
    GO_ALPHA, GO_BETA, GO_MU, GO_THR, GS_ACC_C, GS_ALPHA_C, GS_ALPHA_FF, GS_CHI_ERR,
    GS_CHIDOT_C, GS_CL_REQ, GS_DRAG, GS_G_INT, GS_GAM_C, GS_GAMDOT_DES, GS_H_ERR, GS_H_INT, GS_HDOT_C,
    GS_LIMITS, GS_MACH, GS_MU_C, GS_NZ_C, GS_QBAR, GS_THR_C, GS_THR_FF, GS_V_ERR, GS_V_INT,
    GS_V_REF, GX_ALPHA_C, GX_ALPHA_FF, GX_CHI_ERR_F, GX_G_INT, GX_GAM_PREV, GX_GDOT_F, GX_GAM_C,
    GX_GI_SHORT_F, GX_H_INT, GX_MU_C, GX_READY, GX_THR_C,
    GX_V_INT, GX_V_REF, LIM_ACC, LIM_ALPHA_MAX, LIM_ALPHA_MIN, LIM_ALPHA_RATE, LIM_CHIDOT,
    LIM_GAM_MAX, LIM_GAM_MIN, LIM_GAM_RATE, LIM_HDOT, LIM_INPUT_BAD, LIM_MU_MAX, LIM_MU_RATE,
    LIM_NZ_MAX, LIM_NZ_MIN, LIM_QBAR_HIGH, LIM_QBAR_LOW, LIM_THR_MAX, LIM_THR_MIN,
    LIM_THR_RATE, TG_CHI, TG_H, TG_MACH, TG_V,
)
from fc.guidance.params import (
    P_GA_GDOT_TAU, P_GA_GI_MAX, P_GA_GI_ZONE, P_GA_HDOT_MAX, P_GA_HI_MAX, P_GA_HI_ZONE, P_GA_K_GAM, P_GA_K_GAMI, P_GA_K_H, P_GA_K_HI, P_GE_ALPHA_MAX,
    P_GE_ALPHA_MIN, P_GE_ALPHA_RATE, P_GE_GAM_MAX, P_GE_GAM_RATE, P_GE_MU_MAX, P_GE_MU_RATE,
    P_GE_NZ_MAX, P_GE_NZ_MIN, P_GE_QBAR_BAND, P_GE_QBAR_MAX, P_GE_QBAR_MIN, P_GE_THR_RATE,
    P_GH_CHI_TAU, P_GH_CHIDOT_MAX, P_GH_K_CHI, P_GM_CT_MAX, P_GM_T_MAX, P_GS_ACC_MAX, P_GS_K_V, P_GS_K_VI,
    P_GS_VI_MAX, P_GE_ALPHA_MARGIN, P_GE_MU_MARGIN, P_GE_NZ_MARGIN,
)
from fc.control import carrays as _carrays, layout as _claw, nominal as _nominal
from fc.control.carrays import f8p
from hyfc_wire.earth import EARTH_RADIUS_M
from hyfc_wire.numba_cache import drop_stale

drop_stale(__file__, [_layout.__file__, _params.__file__, _claw.__file__, _nominal.__file__,
                      _carrays.__file__])

# --- work array (gw) -----------------------------------------------------------------------
GW_COEF = 0              # T_N interpolated table columns
GW_ATM = T_N             # rho, speed of sound, g
GW_N = T_N + 3

ALPHA_TAB_MIN_RAD = 0.0                      # the nominal table's alpha box
ALPHA_TAB_MAX_RAD = 12.0 * math.pi / 180.0
_DALPHA_RAD = 0.25 * math.pi / 180.0         # step of the numerical lift slope
_DELTA_MAX_RAD = 20.0 * math.pi / 180.0      # trim deflection bound of the feed-forward
_COS_MU_MIN = 0.5                            # 1/cos(mu) in the lift demand at most 2
_GI_CHECK_TAU_S = 0.5                        # low-pass of the flight-path model-error check


@njit(cache=True, error_model="numpy")
def trimmed_coefficients(mach, alpha_rad, xcg_m, tab, grid, gw):
    """Nominal (C_L, C_D) at (Mach, alpha) with both elevons at the symmetric trim deflection.

    delta_trim zeroes the nominal pitching moment about the c.g.:
    C_m0 + (x_cg / c)(C_D sin a + C_L cos a) + (C_m,dL + C_m,dR) delta = 0 (clipped to
    +-20 deg); C_L = C_L0 + (C_L,dL + C_L,dR) delta, likewise C_D (control derivatives of
    the nominal table, per rad). Leaves the table row at (mach, alpha) in gw[GW_COEF:].
    """
    interp_table(mach, alpha_rad, tab, grid, gw, GW_COEF)
    cl0 = gw[GW_COEF + T_CL0]
    cd0 = gw[GW_COEF + T_CD0]
    cm0 = gw[GW_COEF + T_CPITCH0] + xcg_m / C_REF_M * (cd0 * math.sin(alpha_rad)
                                                      + cl0 * math.cos(alpha_rad))
    o = GW_COEF + T_DEL
    cm_d = gw[o + 3 * C_PITCH] + gw[o + 3 * C_PITCH + 1]
    cl_d = gw[o + 3 * C_LIFT] + gw[o + 3 * C_LIFT + 1]
    cd_d = gw[o + 3 * C_DRAG] + gw[o + 3 * C_DRAG + 1]
    d = 0.0
    if abs(cm_d) > 1e-9:
        d = -cm0 / cm_d
    d = min(max(d, -_DELTA_MAX_RAD), _DELTA_MAX_RAD)
    return cl0 + cl_d * d, cd0 + cd_d * d


@njit(cache=True, error_model="numpy")
def alpha_for_lift(cl_req, mach, alpha0_rad, xcg_m, tab, grid, gw):
    """alpha (rad) whose trimmed nominal lift coefficient is ``cl_req`` (Newton from alpha0,
    numerical slope), within the table's alpha box [0, 12] deg."""
    a = min(max(alpha0_rad, ALPHA_TAB_MIN_RAD), ALPHA_TAB_MAX_RAD)
    for _ in range(6):
        cl, _cd = trimmed_coefficients(mach, a, xcg_m, tab, grid, gw)
        a2 = a + _DALPHA_RAD if a + _DALPHA_RAD <= ALPHA_TAB_MAX_RAD else a - _DALPHA_RAD
        cl2, _cd2 = trimmed_coefficients(mach, a2, xcg_m, tab, grid, gw)
        slope = (cl2 - cl) / (a2 - a)
        if slope < 0.05:
            slope = 0.05
        a_new = min(max(a + (cl_req - cl) / slope, ALPHA_TAB_MIN_RAD), ALPHA_TAB_MAX_RAD)
        done = abs(a_new - a) < 1e-7
        a = a_new
        if done:
            break
    return a


@njit(cache=True, inline="always")
def _rate_limit(prev, target, step_max):
    """(new value, limited?) moving from prev toward target by at most step_max."""
    d = target - prev
    if d > step_max:
        return prev + step_max, True
    if d < -step_max:
        return prev - step_max, True
    return target, False


@njit(cache=True, inline="always")
def _clip_flag(v, lo, hi, bit_lo, bit_hi):
    """(v clipped to [lo, hi], the bit of the bound that held it, or 0)."""
    if v > hi:
        return hi, bit_hi
    if v < lo:
        return lo, bit_lo
    return v, 0


@njit(cache=True, inline="always")
def _inside(lo, hi, margin):
    """The command's bounds (lo + margin, hi - margin): an envelope limit [lo, hi] on the
    achieved value, the command kept ``margin`` inside it for the inner loop's tracking error
    (the midpoint if the margins cross)."""
    lo_c = lo + margin
    hi_c = hi - margin
    if lo_c > hi_c:
        lo_c = hi_c = 0.5 * (lo + hi)
    return lo_c, hi_c


@njit(cache=True, inline="always")
def _integrate(acc, err, dt_s, free):
    """An integral's next value: ``acc + err dt`` when ``free`` (inside its zone, no limit
    blocking), else only if that moves it toward zero, stopping at zero (unwinding is never
    blocked)."""
    nxt = acc + err * dt_s
    if free:
        return nxt
    if acc > 0.0 and err < 0.0:
        return max(nxt, 0.0)
    if acc < 0.0 and err > 0.0:
        return min(nxt, 0.0)
    return acc


@njit(cache=True, inline="always")
def _wrap_pi(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, error_model="numpy")
def course_from_air_data(roll_rad, pitch_rad, yaw_rad, alpha_rad, beta_rad):
    """Course chi (rad, -pi..pi) of the air-relative velocity from the ZYX Euler angles and
    alpha, beta: v_NED = C_nb v_b, v_b = (cos a cos b, sin b, sin a cos b), chi =
    atan2(v_E, v_N) (no wind: the plant's course). For an fc without a GNSS course."""
    cf, sf = math.cos(roll_rad), math.sin(roll_rad)
    ct, st = math.cos(pitch_rad), math.sin(pitch_rad)
    cp, sp = math.cos(yaw_rad), math.sin(yaw_rad)
    u = math.cos(alpha_rad) * math.cos(beta_rad)
    v = math.sin(beta_rad)
    w = math.sin(alpha_rad) * math.cos(beta_rad)
    vn = ct * cp * u + (sf * st * cp - cf * sp) * v + (cf * st * cp + sf * sp) * w
    ve = ct * sp * u + (sf * st * sp + cf * cp) * v + (cf * st * sp - sf * cp) * w
    return math.atan2(ve, vn)


@njit(cache=True, inline="always")
def _thrust_model(thr, qS, gp):
    """The guidance's engine model: T = thr C_T,max qbar S capped at T_max (N); 0 for a
    throttle that is not a number or negative (unknown)."""
    if not thr >= 0.0:
        return 0.0
    return min(thr * gp[P_GM_CT_MAX] * qS, gp[P_GM_T_MAX])


@njit(cache=True, error_model="numpy")
def _g_relieved(g, V, h):
    """g - V^2 / (R + h) (m/s^2): the gravity a level flight path's lift carries on the round
    Earth (the centrifugal relief, 8 % of g at Mach 7.5, 28 km)."""
    return g - V * V / (EARTH_RADIUS_M + h)


@njit(cache=True, error_model="numpy")
def _flight_condition(est, gw, atm, grid):
    """(qbar Pa, qbar S N, Mach, g m/s^2, speed of sound m/s) from the nominal atmosphere."""
    interp_atmosphere(est[E_H], atm, grid, gw, GW_ATM)
    a_snd = gw[GW_ATM + ATM_SOUND]
    V = max(est[E_V], 1.0)
    qbar = 0.5 * gw[GW_ATM + ATM_RHO] * V * V
    return qbar, max(qbar * S_REF_M2, 1.0), V / a_snd, gw[GW_ATM + ATM_G], a_snd


@njit(cache=True, error_model="numpy")
def guidance_reset(est, gp, mass_kg, xcg_m, gx, thr_now, gw, tab, atm, grid):
    """Engage at the current state without a bump.

    Commands start at the present alpha, mu and gamma (clipped to the envelope's command
    limits: an engagement in an upset is not held in it); the speed reference at V. The
    flight-path integral starts where the lift demand (with gamma_dot = 0) equals the nominal
    trimmed lift at the present alpha, and the speed integral (if ``thr_now`` >= 0, the
    throttle in use, 0..1) where the throttle demand equals ``thr_now``: the integrators take
    up the nominal model's error at once (both within their clamps). ``thr_now`` < 0: the
    speed integral starts at 0 and the first step's throttle is taken without rate limit.
    """
    # the commands start at the present state, within the envelope's command limits: engaged
    # in an upset (a recovery after the fc lost its data, issue 22: mu 175 deg) they would
    # otherwise hold the upset and leave it only at the rate limits, tens of seconds
    a_lo, a_hi = _inside(gp[P_GE_ALPHA_MIN], gp[P_GE_ALPHA_MAX], gp[P_GE_ALPHA_MARGIN])
    _nz_lo, nz_hi = _inside(gp[P_GE_NZ_MIN], gp[P_GE_NZ_MAX], gp[P_GE_NZ_MARGIN])
    mu_max = max(gp[P_GE_MU_MAX] - gp[P_GE_MU_MARGIN], 0.0)
    mu_max = min(mu_max, math.acos(1.0 / nz_hi)) if nz_hi > 1.0 else 0.0
    gmax = gp[P_GE_GAM_MAX]
    gx[GX_GAM_C] = min(max(est[E_GAMMA], -gmax), gmax)
    gx[GX_ALPHA_C] = min(max(est[E_ALPHA], a_lo), a_hi)
    gx[GX_ALPHA_FF] = gx[GX_ALPHA_C]
    gx[GX_MU_C] = min(max(est[E_MU], -mu_max), mu_max)
    gx[GX_THR_C] = thr_now if thr_now >= 0.0 else math.nan
    gx[GX_H_INT] = 0.0
    gx[GX_V_INT] = 0.0
    gx[GX_G_INT] = 0.0
    gx[GX_GDOT_F] = 0.0
    gx[GX_GAM_PREV] = est[E_GAMMA]
    gx[GX_GI_SHORT_F] = 0.0
    gx[GX_V_REF] = est[E_V]
    gx[GX_CHI_ERR_F] = math.nan       # the first step starts the filter at the error
    gx[GX_READY] = 1.0
    ok = True
    for i in range(E_N):
        if not math.isfinite(est[i]):
            ok = False
    if not ok:
        return
    V = max(est[E_V], 1.0)
    alpha = est[E_ALPHA]
    gam = est[E_GAMMA]
    qbar, qS, mach, g, _a = _flight_condition(est, gw, atm, grid)
    cl, cd = trimmed_coefficients(mach, alpha, xcg_m, tab, grid, gw)
    # the thrust in the lift: the throttle in use, or (unknown) the one the first step takes,
    # its feed-forward with the speed integral at 0; else the step's thrust term would move
    # alpha_c off the bumpless value at the second step (0.05 deg at the cruise point)
    thr_lift = thr_now
    if not thr_now >= 0.0:
        t_full = gp[P_GM_CT_MAX] * qS
        proj0 = max(math.cos(alpha) * math.cos(est[E_BETA]), 0.1)
        thr_lift = min(max((cd * qS + mass_kg * g * math.sin(gam)) / (proj0 * t_full), 0.0),
                       min(1.0, gp[P_GM_T_MAX] / t_full))
    if gp[P_GA_K_GAMI] > 0.0:
        normal = cl * qS + _thrust_model(thr_lift, qS, gp) * math.sin(alpha)
        n0 = (_g_relieved(g, V, est[E_H]) * math.cos(gam)
              / (g * max(math.cos(est[E_MU]), _COS_MU_MIN)))
        gdot = (normal / (n0 * mass_kg * g) - 1.0) * g / V
        lim = gp[P_GA_GI_MAX]
        gx[GX_G_INT] = min(max(gdot, -lim), lim) / gp[P_GA_K_GAMI]
    if thr_now >= 0.0 and gp[P_GS_K_VI] > 0.0:
        proj = max(math.cos(alpha) * math.cos(est[E_BETA]), 0.1)
        acc = (thr_now * proj * gp[P_GM_CT_MAX] * qS - cd * qS
               - mass_kg * g * math.sin(gam)) / mass_kg
        lim = gp[P_GS_VI_MAX]
        gx[GX_V_INT] = min(max(acc, -lim), lim) / gp[P_GS_K_VI]


@njit(cache=True, error_model="numpy")
def guidance_step(est, chi_rad, tgt, dt_s, gp, mass_kg, xcg_m, gx, out, gs, gw, tab, atm, grid):
    """One guidance step: targets ``tgt`` (TG_*) and state -> ``out`` (GO_*), status ``gs``.

    est : float64[E_N] the law's estimated state (alpha, beta, mu, p, q, r, V, h, gamma).
    chi_rad : course (rad). dt_s : step (s), in (0, 1]. gp : float64[P_N] SI parameters.
    mass_kg, xcg_m : the nominal model's mass and c.g. offset (the law's MDL_MASS, MDL_XCG).
    gx : state (GX_*); call guidance_reset first. gw : work (GW_N). tab, atm, grid: the
    nominal tables (fc.control.nominal.load_tables). Returns the limit bitfield.
    A non-finite input or dt outside (0, 1] changes nothing but the status (LIM_INPUT_BAD).
    """
    ok = dt_s > 0.0 and dt_s <= 1.0 and math.isfinite(chi_rad) and gx[GX_READY] == 1.0
    for i in range(E_N):
        if not math.isfinite(est[i]):
            ok = False
    if not (math.isfinite(tgt[TG_H]) and math.isfinite(tgt[TG_CHI]) and math.isfinite(tgt[TG_V])
            and math.isfinite(tgt[TG_MACH])):
        ok = False
    if not ok:
        gs[GS_LIMITS] = float(LIM_INPUT_BAD)
        return LIM_INPUT_BAD
    lim = 0
    alpha = est[E_ALPHA]
    beta = est[E_BETA]
    mu = est[E_MU]
    V = max(est[E_V], 1.0)
    h = est[E_H]
    gam = est[E_GAMMA]
    m = mass_kg

    qbar, qS, mach, g, a_snd = _flight_condition(est, gw, atm, grid)

    # --- speed reference -----------------------------------------------------------------
    v_t = tgt[TG_MACH] * a_snd if tgt[TG_MACH] > 0.0 else tgt[TG_V]
    v_prev = gx[GX_V_REF]
    v_ref, lim_acc = _rate_limit(v_prev, v_t, gp[P_GS_ACC_MAX] * dt_s)
    if lim_acc:
        lim |= LIM_ACC
    vref_dot = (v_ref - v_prev) / dt_s
    gx[GX_V_REF] = v_ref

    # --- altitude -> flight-path angle ---------------------------------------------------
    e_h = tgt[TG_H] - h
    hi = gp[P_GA_K_HI] * gx[GX_H_INT]
    hi = min(max(hi, -gp[P_GA_HI_MAX]), gp[P_GA_HI_MAX])
    hmax = gp[P_GA_HDOT_MAX]
    hdot_c, b = _clip_flag(gp[P_GA_K_H] * e_h + hi, -hmax, hmax, LIM_HDOT, LIM_HDOT)
    lim |= b
    gam_raw = math.asin(min(max(hdot_c / V, -1.0), 1.0))
    gmax = gp[P_GE_GAM_MAX]
    g_hi = gmax
    g_lo = -gmax
    band = gp[P_GE_QBAR_BAND]
    q_lo = gp[P_GE_QBAR_MIN]
    q_hi = gp[P_GE_QBAR_MAX]
    if qbar < q_lo + band:
        g_hi = gmax * max((qbar - q_lo) / band, -1.0)
        lim |= LIM_QBAR_LOW
    if qbar > q_hi - band:
        g_lo = -gmax * max((q_hi - qbar) / band, -1.0)
        lim |= LIM_QBAR_HIGH
    if g_lo > g_hi:                   # both ramps at once (a band wider than the corridor)
        g_lo = g_hi = 0.5 * (g_lo + g_hi)
    gam_lim, b = _clip_flag(gam_raw, g_lo, g_hi, LIM_GAM_MIN, LIM_GAM_MAX)
    lim |= b
    gc_prev = gx[GX_GAM_C]
    gam_c, rl = _rate_limit(gc_prev, gam_lim, gp[P_GE_GAM_RATE] * dt_s)
    if rl:
        lim |= LIM_GAM_RATE
    gx[GX_GAM_C] = gam_c
    tau = gp[P_GA_GDOT_TAU]
    gamc_dot = (gam_c - gc_prev) / dt_s
    if tau > 0.0:
        gamc_dot = gx[GX_GDOT_F] + (1.0 - math.exp(-dt_s / tau)) * (gamc_dot - gx[GX_GDOT_F])
    gx[GX_GDOT_F] = gamc_dot

    # --- flight path -> lift -> alpha (feed-forward from the nominal model) ---------------
    # the load factor the flight path asks for is limited; the model-error correction (the
    # flight-path integral) is added after the limit, so the vehicle's load factor, not the
    # nominal model's, is the one bounded
    e_g = gam_c - gam
    gi = gp[P_GA_K_GAMI] * gx[GX_G_INT]
    gi = min(max(gi, -gp[P_GA_GI_MAX]), gp[P_GA_GI_MAX])
    cmu = max(math.cos(mu), _COS_MU_MIN)
    gdot_kin = gamc_dot + gp[P_GA_K_GAM] * e_g
    nz_lo, nz_hi = _inside(gp[P_GE_NZ_MIN], gp[P_GE_NZ_MAX], gp[P_GE_NZ_MARGIN])
    g_cos = _g_relieved(g, V, h) * math.cos(gam)      # the weight less the centrifugal relief
    nz, b = _clip_flag((g_cos + V * gdot_kin) / (g * cmu), nz_lo, nz_hi,
                       LIM_NZ_MIN, LIM_NZ_MAX)
    lim |= b
    gdot_des = (nz * g * cmu - g_cos) / V + gi
    t_est = _thrust_model(gx[GX_THR_C], qS, gp)
    cl_req = (nz * m * g * (1.0 + V * gi / g) - t_est * math.sin(alpha)) / qS
    a_ff = alpha_for_lift(cl_req, mach, gx[GX_ALPHA_FF], xcg_m, tab, grid, gw)
    gx[GX_ALPHA_FF] = a_ff
    a_lo, a_hi = _inside(gp[P_GE_ALPHA_MIN], gp[P_GE_ALPHA_MAX], gp[P_GE_ALPHA_MARGIN])
    a_lim, b = _clip_flag(a_ff, a_lo, a_hi, LIM_ALPHA_MIN, LIM_ALPHA_MAX)
    lim |= b
    alpha_c, rl = _rate_limit(gx[GX_ALPHA_C], a_lim, gp[P_GE_ALPHA_RATE] * dt_s)
    if rl:
        lim |= LIM_ALPHA_RATE
    gx[GX_ALPHA_C] = alpha_c
    # the model-error check: the gamma rate the corrected model predicts at the measured alpha
    # (normal force (C_L,trim qS + T_est sin alpha) / (1 + V gi / g), the inverse of cl_req)
    # against the measured one, low-passed; and what the correction is worth in gamma rate
    cl_m, cd = trimmed_coefficients(mach, alpha, xcg_m, tab, grid, gw)
    f_nom = (cl_m * qS + t_est * math.sin(alpha)) * cmu / (m * V)     # rad/s
    corr = max(1.0 + V * gi / g, 0.1)
    gdot_meas = (gam - gx[GX_GAM_PREV]) / dt_s
    gx[GX_GAM_PREV] = gam
    short = f_nom / corr - g_cos / V - gdot_meas
    gx[GX_GI_SHORT_F] += (1.0 - math.exp(-dt_s / _GI_CHECK_TAU_S)) * (short - gx[GX_GI_SHORT_F])
    gi_worth = f_nom / corr - f_nom

    # --- course -> bank (coordinated turn) ------------------------------------------------
    e_raw = _wrap_pi(tgt[TG_CHI] - chi_rad)
    e_prev = gx[GX_CHI_ERR_F]
    if math.isnan(e_prev) or gp[P_GH_CHI_TAU] <= 0.0:
        e_chi = e_raw
    else:   # filter the change of the error (wrapped), so a target step across +-pi is fine
        e_chi = _wrap_pi(e_prev + (1.0 - math.exp(-dt_s / gp[P_GH_CHI_TAU]))
                         * _wrap_pi(e_raw - e_prev))
    gx[GX_CHI_ERR_F] = e_chi
    cdm = gp[P_GH_CHIDOT_MAX]
    chid, b = _clip_flag(gp[P_GH_K_CHI] * e_chi, -cdm, cdm, LIM_CHIDOT, LIM_CHIDOT)
    lim |= b
    # the bank of a level turn at the load-factor demand's bound, and GE_MU_MAX less its margin
    mu_max = max(gp[P_GE_MU_MAX] - gp[P_GE_MU_MARGIN], 0.0)
    if nz_hi > 1.0:
        mu_max = min(mu_max, math.acos(1.0 / nz_hi))
    else:
        mu_max = 0.0
    mu_raw, b = _clip_flag(math.atan(V * chid * math.cos(gam) / g), -mu_max, mu_max,
                           LIM_MU_MAX, LIM_MU_MAX)
    lim |= b
    mu_c, rl = _rate_limit(gx[GX_MU_C], mu_raw, gp[P_GE_MU_RATE] * dt_s)
    if rl:
        lim |= LIM_MU_RATE
    gx[GX_MU_C] = mu_c

    # --- speed -> throttle (feed-forward from the nominal drag) -------------------------
    drag = cd * qS
    e_v = v_ref - V
    vi = gp[P_GS_K_VI] * gx[GX_V_INT]
    vi = min(max(vi, -gp[P_GS_VI_MAX]), gp[P_GS_VI_MAX])
    acc_c = vref_dot + gp[P_GS_K_V] * e_v + vi
    t_full = gp[P_GM_CT_MAX] * qS
    proj = max(math.cos(alpha) * math.cos(beta), 0.1)
    thr_ff = (drag + m * g * math.sin(gam) + m * vref_dot) / (proj * t_full)
    thr_raw = (drag + m * g * math.sin(gam) + m * acc_c) / (proj * t_full)
    thr_raw, b = _clip_flag(thr_raw, 0.0, min(1.0, gp[P_GM_T_MAX] / t_full), LIM_THR_MIN,
                            LIM_THR_MAX)
    lim |= b
    if math.isnan(gx[GX_THR_C]):
        thr_c = thr_raw
    else:
        thr_c, rl = _rate_limit(gx[GX_THR_C], thr_raw, gp[P_GE_THR_RATE] * dt_s)
        if rl:
            lim |= LIM_THR_RATE
    gx[GX_THR_C] = thr_c

    # --- integrators with anti-windup (conditional integration) ---------------------------
    # an integral grows only inside its zone and while no limit blocks its loop in the
    # error's direction; one that opposes the error always unwinds toward zero (never past
    # it), so a value taken up in a transient (an engagement during an upset) cannot latch the
    # loop at a limit (issue 22: the flight-path integral held at -GA_GI_MAX with the
    # load-factor demand at its bound, the vehicle sinking, for ever)
    up_blocked = (lim & (LIM_HDOT | LIM_GAM_MAX | LIM_NZ_MAX | LIM_ALPHA_MAX)) != 0
    down_blocked = (lim & (LIM_HDOT | LIM_GAM_MIN | LIM_NZ_MIN | LIM_ALPHA_MIN)) != 0
    gx[GX_H_INT] = _integrate(gx[GX_H_INT], e_h, dt_s, abs(e_h) < gp[P_GA_HI_ZONE]
                              and not ((e_h > 0.0 and up_blocked)
                                       or (e_h < 0.0 and down_blocked)))
    lift_up = (lim & (LIM_NZ_MAX | LIM_ALPHA_MAX)) != 0
    lift_down = (lim & (LIM_NZ_MIN | LIM_ALPHA_MIN)) != 0
    # the flight-path integral is the model's lift error: while blocked it unwinds only if the
    # measured gamma rate contradicts it (closer to the uncorrected model's than to the
    # corrected one's): an engagement's wrong estimate goes, a right one held at the load-factor
    # limit in a climb stays (unwound there, the lift went 24 % over: n 1.87 against 1.6)
    g_free = abs(e_g) < gp[P_GA_GI_ZONE] and not ((e_g > 0.0 and lift_up)
                                                   or (e_g < 0.0 and lift_down))
    if g_free or gx[GX_GI_SHORT_F] * gi_worth > 0.5 * gi_worth * gi_worth:
        gx[GX_G_INT] = _integrate(gx[GX_G_INT], e_g, dt_s, g_free)
    gx[GX_V_INT] = _integrate(gx[GX_V_INT], e_v, dt_s,
                              not ((e_v > 0.0 and (lim & LIM_THR_MAX) != 0)
                                   or (e_v < 0.0 and (lim & LIM_THR_MIN) != 0)))

    out[GO_ALPHA] = alpha_c
    out[GO_BETA] = 0.0
    out[GO_MU] = mu_c
    out[GO_THR] = thr_c

    gs[GS_LIMITS] = float(lim)
    gs[GS_H_ERR] = e_h
    gs[GS_CHI_ERR] = e_chi
    gs[GS_V_ERR] = e_v
    gs[GS_V_REF] = v_ref
    gs[GS_HDOT_C] = hdot_c
    gs[GS_GAM_C] = gam_c
    gs[GS_GAMDOT_DES] = gdot_des
    gs[GS_CL_REQ] = cl_req
    gs[GS_NZ_C] = nz
    gs[GS_ALPHA_FF] = a_ff
    gs[GS_ALPHA_C] = alpha_c
    gs[GS_CHIDOT_C] = chid
    gs[GS_MU_C] = mu_c
    gs[GS_ACC_C] = acc_c
    gs[GS_THR_FF] = thr_ff
    gs[GS_THR_C] = thr_c
    gs[GS_QBAR] = qbar
    gs[GS_MACH] = mach
    gs[GS_DRAG] = drag
    gs[GS_H_INT] = gx[GX_H_INT]
    gs[GS_V_INT] = gx[GX_V_INT]
    gs[GS_G_INT] = gx[GX_G_INT]
    return lim


@njit(cache=True, error_model="numpy")
def guidance_step_p(est, chi_rad, tgt, dt_s, gp, mass_kg, xcg_m, gx, out, gs, gw, tab, atm,
                    grid, sizes):
    """:func:`guidance_step` with every array given by address (fc/control/carrays.py: no
    numba record per call). ``sizes``: (E_N, TG_N, P_N, GX_N, GO_N, GS_N, GW_N, tab rows,
    tab columns, tab depth, atm rows, atm columns, grid length), the arrays' shapes."""
    return guidance_step(
        carray(f8p(est), (sizes[0],)), chi_rad, carray(f8p(tgt), (sizes[1],)), dt_s,
        carray(f8p(gp), (sizes[2],)), mass_kg, xcg_m, carray(f8p(gx), (sizes[3],)),
        carray(f8p(out), (sizes[4],)), carray(f8p(gs), (sizes[5],)),
        carray(f8p(gw), (sizes[6],)), carray(f8p(tab), (sizes[7], sizes[8], sizes[9])),
        carray(f8p(atm), (sizes[10], sizes[11])), carray(f8p(grid), (sizes[12],)))


@njit(cache=True)
def guidance_step_pf(est, chi_rad, tgt, dt_s, gp, mass_kg, xcg_m, gx, out, gs, gw, tab, atm,
                     grid, sizes):
    """:func:`guidance_step_p` returning the limit bitfield as a float (exact: the bits are
    below 2^53). The returned Python float comes from CPython's free list; an int past 256
    (LIM_* bits from 512 up, e.g. 16,384) is a new block per step (issue 24)."""
    return float(guidance_step_p(est, chi_rad, tgt, dt_s, gp, mass_kg, xcg_m, gx, out, gs,
                                gw, tab, atm, grid, sizes))
