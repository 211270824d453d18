"""Rigid-body 6-DOF dynamics of the winged cone, actuators and the fixed-step RK4 integrator.

Flat, non-rotating earth (NED; the paper's case), or a non-rotating spherical Earth
(scenario ``[earth] model = "sphere"``: ``deriv_sphere``, ``sphere_view``); gravity with
altitude (US76 inverse square), body axes FRD, attitude as a unit quaternion (scalar first,
body -> NED), all in SI. See docs/plant.md for every modelling choice and its source.

Equations (per physics step dt, RK4 on the 13 rigid-body states, surfaces held over the step):
    p_dot_NED = C_nb v_b
    v_b_dot   = (F_aero_b + T x_b) / m + C_bn [0, 0, g(h)] - omega x v_b
    q_dot     = 0.5 q (x) [0, omega]
    omega_dot = I^-1 (M_cg - omega x I omega) + d(t)
with F_aero_b = C_bw [-D, Y, -L] (wind axes: D along -V, L in the body x-z plane), the
aerodynamic moment about the MRC plus the transfer r_MRC/cg x F_aero_b with
r_MRC/cg = (x_cg, 0, 0) (x_cg = MRC -> c.g., + aft; winged_cone.md section 3), thrust T along
body x through the c.g. (speed model: an ideal speed hold, or an engine with a throttle
command, its limits and a first-order lag), and d(t) the paper's disturbance as an angular
acceleration (or as a moment divided by the inertia, per scenario).

All kernels work on flat float64 arrays with the index constants below; nothing allocates.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from plant_sim._jitcache import refresh as _refresh_jit_cache
from plant_sim.aero import C_D, C_L, C_N, C_PITCH, C_ROLL, C_Y, C_YAW, coefficients
from plant_sim.atmosphere import A_G_M_S2, A_N, A_P_PA, A_RHO_KG_M3, A_SOUND_M_S, us76
from plant_sim.vehicle import B_REF_M, C_REF_M, S_REF_M2

_refresh_jit_cache(__file__)

DEG = math.pi / 180.0

# ---- state vector x (float64[X_N]) ----
X_PN = 0          # position north (m)
X_PE = 1          # position east (m)
X_PD = 2          # position down (m); h = -x[X_PD]
X_U = 3           # body velocity (m/s), FRD
X_V = 4
X_W = 5
X_Q0 = 6          # attitude quaternion body -> NED, scalar first
X_Q1 = 7
X_Q2 = 8
X_Q3 = 9
X_P = 10          # body rates (rad/s)
X_Q = 11
X_R = 12
X_RB_N = 13       # rigid-body states integrated by RK4: x[0:13]
X_DL = 13         # surface positions (rad): left elevon, right elevon, rudder
X_DR = 14
X_DU = 15
X_CMD_L = 16      # latched surface commands (rad)
X_CMD_R = 17
X_CMD_U = 18
X_STEP = 19       # physics step counter (t = step * dt, exact)
X_THRUST = 20     # thrust at the last derivative evaluation (N)
X_CLIP = 21       # OR of aero clip flags since the last frame began
X_CMD_THR = 22    # latched throttle command (0..1; engine speed model only)
X_THR = 23        # engine throttle position (0..1) after its lag and rate limit
# Round Earth (P_EARTH = EARTH_SPHERE): the 13 rigid-body states integrated in the Earth-centred
# frame E (non-rotating sphere), same order as x[0:13]: position r_E (m, E axes), body velocity
# (m/s), quaternion body -> E (scalar first), body rates. x[0:13] is then the local-NED view of
# this block (refreshed after every physics step by ``sphere_view``): north/east on the
# azimuthal-equidistant map about the origin, down = -h, the quaternion body -> local NED.
X_S = 24
X_N = X_S + X_RB_N

# ---- parameter vector p (float64[P_N]) ----
P_MASS = 0
P_IXX = 1
P_IYY = 2
P_IZZ = 3
P_IXZ = 4
P_XCG = 5          # MRC -> c.g., + aft (m)
P_DT = 6           # physics step (s)
P_UNC = 7          # 7..12: multipliers (1 + u) on CL, CD, CY, Cl, Cm, Cn
P_DIST_ON = 13
P_DIST_AMP = 14    # amplitude x scale, in rad/s^2 (or N m if P_DIST_MOMENT)
P_DIST_MOMENT = 15  # 1: the disturbance is a moment (N m) divided by the inertia
P_SPEED_MODE = 16  # 0 none, 1 thrust speed hold
P_VREF = 17        # m/s
P_KV = 18          # 1/s
P_TMAX = 19        # N
P_ACT_LIMIT = 20   # rad
P_ACT_RATE = 21    # rad/s, 0 = no rate limit
P_ACT_TAU = 22     # s, 0 = no lag
P_IINV = 23        # 23..31: inverse inertia, row major
P_FRAME_DT = 32    # s
P_NOISE = 33       # 33..46: noise standard deviation per measurement channel (SI)
P_BIAS = 47        # 47..60: bias per measurement channel (SI)
P_DELAY = 61       # 61..74: latency per channel in frames (integer valued)
P_SENSORS_ON = 75
P_DIST_PHASE = 76  # 76..78: phase added to the roll, pitch, yaw sine arguments (rad)
P_ENG_CT = 79      # engine: thrust coefficient at full throttle, T = thr C_T qbar S (capped P_TMAX)
P_ENG_TAU = 80     # engine: first-order lag of the throttle position (s), 0 = none
P_ENG_RATE = 81    # engine: throttle rate limit (1/s), 0 = none
P_DIST_QREF = 82   # Pa; > 0: d(t) scaled by qbar / P_DIST_QREF (a moment coefficient), 0 = as given
P_EARTH = 83       # EARTH_FLAT (the paper's flat NED earth) or EARTH_SPHERE
P_EARTH_R = 84     # sphere radius (m)
P_ORIGIN = 85      # 85..93: origin (start) on the sphere, E axes: unit up, north, east vectors
P_DIST_END = 94    # s; > 0: d(t) = 0 from this sim time on (a release test), 0 = never
P_N = 95

EARTH_FLAT = 0
EARTH_SPHERE = 1

SPEED_NONE = 0
SPEED_HOLD = 1
SPEED_ENGINE = 2

# ---- work array w (float64[W_N]) ----
W_ATM = 0          # 0..4 atmosphere output
W_COEF = 5         # 5..10 coefficients
W_K1 = 11          # 11..23, RK4 stages (13 each)
W_K2 = 24
W_K3 = 37
W_K4 = 50
W_XT = 63          # 63..75 trial state
W_AUX = 76         # 76..: aero_eval outputs
# aero_eval outputs (offsets from W_AUX)
AX_ALPHA = 0
AX_BETA = 1
AX_V = 2
AX_MACH = 3
AX_QBAR = 4
AX_FX = 5          # aerodynamic force, body axes (N)
AX_FY = 6
AX_FZ = 7
AX_L = 8           # aerodynamic moment about the c.g., body axes (N m)
AX_M = 9
AX_N = 10
AX_LIFT = 11
AX_DRAG = 12
AX_SIDE = 13
AX_GRAV = 14
AX_SOUND = 15
AX_THRUST = 16     # speed-model thrust (N)
AX_THR_POS = 17    # engine throttle position used by thrust_n over the step (copy of x[X_THR])
AX_N_OUT = 18
W_N = W_AUX + AX_N_OUT


@njit(cache=True)
def quat_to_dcm_nb(q0, q1, q2, q3):
    """Direction cosines C_nb (body -> NED) of the attitude quaternion (q0 scalar), row major."""
    return (q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3,
            2.0 * (q1 * q2 - q0 * q3),
            2.0 * (q1 * q3 + q0 * q2),
            2.0 * (q1 * q2 + q0 * q3),
            q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3,
            2.0 * (q2 * q3 - q0 * q1),
            2.0 * (q1 * q3 - q0 * q2),
            2.0 * (q2 * q3 + q0 * q1),
            q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3)


@njit(cache=True)
def disturbance_components(t_s, p, qbar_pa):
    """The paper's Section 5 disturbance as body angular acceleration (rad/s^2) at ``t_s``.

    d(t) = A [0.5 sin(1.5 t + ph_p), 0.5 cos(2 t + ph_q), 0.5 sin(2 t + ph_r)] with
    A = amplitude x scale (paper: 10, phases 0), converted to rad/s^2 from the scenario unit; a
    disturbance given as a moment (N m) is divided by the inertia (I^-1 d). The phases (rad) let
    campaigns disperse the disturbance. With P_DIST_QREF > 0 (``qbar_ref_Pa``) d is multiplied
    by qbar_pa / P_DIST_QREF: a moment coefficient, equal to d at the reference dynamic pressure
    and proportional to the dynamic pressure ``qbar_pa`` (Pa) elsewhere (docs/plant.md s. 8).
    With P_DIST_END > 0 (``end_s``) d is zero from that sim time on. Returns (d_p, d_q, d_r);
    zeros when off.
    """
    if p[P_DIST_ON] == 0.0 or (p[P_DIST_END] > 0.0 and t_s >= p[P_DIST_END]):
        return 0.0, 0.0, 0.0
    a = p[P_DIST_AMP]
    if p[P_DIST_QREF] > 0.0:
        a *= qbar_pa / p[P_DIST_QREF]
    d0 = a * 0.5 * math.sin(1.5 * t_s + p[P_DIST_PHASE])
    d1 = a * 0.5 * math.cos(2.0 * t_s + p[P_DIST_PHASE + 1])
    d2 = a * 0.5 * math.sin(2.0 * t_s + p[P_DIST_PHASE + 2])
    if p[P_DIST_MOMENT] != 0.0:
        i = P_IINV
        return (p[i] * d0 + p[i + 1] * d1 + p[i + 2] * d2,
                p[i + 3] * d0 + p[i + 4] * d1 + p[i + 5] * d2,
                p[i + 6] * d0 + p[i + 7] * d1 + p[i + 8] * d2)
    return d0, d1, d2


@njit(cache=True)
def aero_eval(x, dl, dr, du, p, w):
    """Air data, aerodynamic forces (body) and moments about the c.g. at state ``x`` (the
    flat-earth layout or the local-NED view: h = -x[X_PD]).

    Writes w[W_AUX + AX_*] and returns the aero clip flags. ``dl, dr, du`` are the surface
    positions (rad).
    """
    return aero_eval_h(x, -x[X_PD], dl, dr, du, p, w)


@njit(cache=True)
def aero_eval_h(x, h, dl, dr, du, p, w):
    """:func:`aero_eval` at altitude ``h`` (m): reads only the body velocity and rates of
    ``x`` (so it serves both the flat state and the round-Earth block)."""
    us76(h, w[W_ATM:W_ATM + A_N])
    rho = w[W_ATM + A_RHO_KG_M3]
    a_snd = w[W_ATM + A_SOUND_M_S]
    u = x[X_U]
    v = x[X_V]
    ww = x[X_W]
    V = math.sqrt(u * u + v * v + ww * ww)
    if V < 1e-6:
        V = 1e-6
    alpha = math.atan2(ww, u)
    sb = v / V
    if sb > 1.0:
        sb = 1.0
    elif sb < -1.0:
        sb = -1.0
    beta = math.asin(sb)
    mach = V / a_snd
    qbar = 0.5 * rho * V * V
    inv2v = 1.0 / (2.0 * V)
    c = w[W_COEF:W_COEF + C_N]
    flags = coefficients(alpha / DEG, mach, beta,
                         x[X_P] * B_REF_M * inv2v, x[X_Q] * C_REF_M * inv2v, x[X_R] * B_REF_M * inv2v,
                         dl / DEG, dr / DEG, du / DEG, c)
    qs = qbar * S_REF_M2
    lift = qs * c[C_L] * p[P_UNC + 0]
    drag = qs * c[C_D] * p[P_UNC + 1]
    side = qs * c[C_Y] * p[P_UNC + 2]
    ca = math.cos(alpha)
    sa = math.sin(alpha)
    cb = math.cos(beta)
    # wind -> body: F_b = C_bw [-D, Y, -L]; columns of C_bw are the wind axes in body axes
    fx = -drag * ca * cb - side * ca * sb + lift * sa
    fy = -drag * sb + side * cb
    fz = -drag * sa * cb - side * sa * sb - lift * ca
    xcg = p[P_XCG]
    # moments about the MRC, then r x F with r = (x_cg, 0, 0) from the c.g. to the MRC
    lm = qs * B_REF_M * c[C_ROLL] * p[P_UNC + 3]
    mm = qs * C_REF_M * c[C_PITCH] * p[P_UNC + 4] - xcg * fz
    nm = qs * B_REF_M * c[C_YAW] * p[P_UNC + 5] + xcg * fy
    o = W_AUX
    w[o + AX_ALPHA] = alpha
    w[o + AX_BETA] = beta
    w[o + AX_V] = V
    w[o + AX_MACH] = mach
    w[o + AX_QBAR] = qbar
    w[o + AX_FX] = fx
    w[o + AX_FY] = fy
    w[o + AX_FZ] = fz
    w[o + AX_L] = lm
    w[o + AX_M] = mm
    w[o + AX_N] = nm
    w[o + AX_LIFT] = lift
    w[o + AX_DRAG] = drag
    w[o + AX_SIDE] = side
    w[o + AX_GRAV] = w[W_ATM + A_G_M_S2]
    w[o + AX_SOUND] = a_snd
    return flags


@njit(cache=True)
def thrust_n(x, p, w):
    """Speed-model thrust (N) along body x, from the last aero_eval in ``w``.

    SPEED_HOLD, an ideal autothrottle: T cos(alpha) cos(beta) = D + m g sin(gamma)
    + m k_V (V_ref - V), clipped to [0, T_max]. SPEED_ENGINE: T = thr C_T,max qbar S with the
    throttle position thr = w[W_AUX + AX_THR_POS] (0..1; the RK4 trial states hold only the
    rigid-body states, so the position is handed over in ``w``), capped at T_max.
    SPEED_NONE gives 0.
    """
    mode = p[P_SPEED_MODE]
    if mode == SPEED_ENGINE:
        t = w[W_AUX + AX_THR_POS] * p[P_ENG_CT] * w[W_AUX + AX_QBAR] * S_REF_M2
        return t if t < p[P_TMAX] else p[P_TMAX]
    if mode != SPEED_HOLD:
        return 0.0
    V = w[W_AUX + AX_V]
    # sin(gamma) = -v_D / V; v_D from the quaternion: third row of C_nb times v_b
    q0 = x[X_Q0]
    q1 = x[X_Q1]
    q2 = x[X_Q2]
    q3 = x[X_Q3]
    vd = (2.0 * (q1 * q3 - q0 * q2) * x[X_U] + 2.0 * (q2 * q3 + q0 * q1) * x[X_V]
          + (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * x[X_W])
    return hold_thrust(-vd / V, p, w)


@njit(cache=True)
def hold_thrust(sgam, p, w):
    """SPEED_HOLD's thrust (N) at sin(gamma) = ``sgam``, from the last aero_eval in ``w``."""
    o = W_AUX
    V = w[o + AX_V]
    m = p[P_MASS]
    need = w[o + AX_DRAG] + m * w[o + AX_GRAV] * sgam + m * p[P_KV] * (p[P_VREF] - V)
    cc = math.cos(w[o + AX_ALPHA]) * math.cos(w[o + AX_BETA])
    t = need / cc if cc > 0.05 else 0.0
    if t < 0.0:
        t = 0.0
    elif t > p[P_TMAX]:
        t = p[P_TMAX]
    return t


@njit(cache=True)
def deriv(x, t_s, dl, dr, du, p, w, xdot):
    """Time derivative of the 13 rigid-body states; returns the aero clip flags."""
    flags = aero_eval(x, dl, dr, du, p, w)
    thrust = thrust_n(x, p, w)
    o = W_AUX
    w[o + AX_THRUST] = thrust
    m = p[P_MASS]
    g = w[o + AX_GRAV]
    u = x[X_U]
    v = x[X_V]
    ww = x[X_W]
    pp = x[X_P]
    qq = x[X_Q]
    rr = x[X_R]
    q0 = x[X_Q0]
    q1 = x[X_Q1]
    q2 = x[X_Q2]
    q3 = x[X_Q3]
    # C_nb (body -> NED)
    c11, c12, c13, c21, c22, c23, c31, c32, c33 = quat_to_dcm_nb(q0, q1, q2, q3)
    xdot[X_PN] = c11 * u + c12 * v + c13 * ww
    xdot[X_PE] = c21 * u + c22 * v + c23 * ww
    xdot[X_PD] = c31 * u + c32 * v + c33 * ww
    # gravity in body axes: C_bn [0, 0, g] = g * (third row of C_nb) transposed
    xdot[X_U] = (w[o + AX_FX] + thrust) / m + g * c31 - (qq * ww - rr * v)
    xdot[X_V] = w[o + AX_FY] / m + g * c32 - (rr * u - pp * ww)
    xdot[X_W] = w[o + AX_FZ] / m + g * c33 - (pp * v - qq * u)
    _attitude_deriv(x, t_s, p, w, xdot)
    return flags


@njit(cache=True, inline="always")
def _attitude_deriv(x, t_s, p, w, xdot):
    """xdot[X_Q0..X_R]: q' = 0.5 q (x) (0, omega) and omega' = I^-1 (M_cg - omega x I omega)
    + d(t), from the moments of the last aero_eval in ``w`` (the same on both earths)."""
    o = W_AUX
    pp = x[X_P]
    qq = x[X_Q]
    rr = x[X_R]
    q0 = x[X_Q0]
    q1 = x[X_Q1]
    q2 = x[X_Q2]
    q3 = x[X_Q3]
    xdot[X_Q0] = 0.5 * (-q1 * pp - q2 * qq - q3 * rr)
    xdot[X_Q1] = 0.5 * (q0 * pp + q2 * rr - q3 * qq)
    xdot[X_Q2] = 0.5 * (q0 * qq + q3 * pp - q1 * rr)
    xdot[X_Q3] = 0.5 * (q0 * rr + q1 * qq - q2 * pp)
    ixx = p[P_IXX]
    iyy = p[P_IYY]
    izz = p[P_IZZ]
    ixz = p[P_IXZ]
    # I omega with I = [[Ixx, 0, -Ixz], [0, Iyy, 0], [-Ixz, 0, Izz]]
    h0 = ixx * pp - ixz * rr
    h1 = iyy * qq
    h2 = izz * rr - ixz * pp
    m0 = w[o + AX_L] - (qq * h2 - rr * h1)
    m1 = w[o + AX_M] - (rr * h0 - pp * h2)
    m2 = w[o + AX_N] - (pp * h1 - qq * h0)
    i = P_IINV
    xdot[X_P] = p[i] * m0 + p[i + 1] * m1 + p[i + 2] * m2
    xdot[X_Q] = p[i + 3] * m0 + p[i + 4] * m1 + p[i + 5] * m2
    xdot[X_R] = p[i + 6] * m0 + p[i + 7] * m1 + p[i + 8] * m2
    if p[P_DIST_ON] != 0.0:
        d0, d1, d2 = disturbance_components(t_s, p, w[o + AX_QBAR])
        xdot[X_P] += d0
        xdot[X_Q] += d1
        xdot[X_R] += d2


@njit(cache=True)
def deriv_sphere(xs, t_s, dl, dr, du, p, w, xdot):
    """Time derivative of the round-Earth block ``xs`` (float64[13]: r_E, v_b, q_eb, omega;
    layout of x[0:13]) on a non-rotating sphere of radius R = p[P_EARTH_R]; returns the aero
    clip flags.

        r_E'   = C_eb v_b
        v_b'   = (F_aero_b + T x_b) / m - g(h) C_be r_E / |r_E| - omega x v_b,  h = |r_E| - R
        q_eb'  = 0.5 q_eb (x) [0, omega]
        omega' = as the flat earth (the attitude dynamics do not see the Earth)

    The frame E is inertial, so these are the flat equations with gravity along the local
    vertical -r_E/|r_E| instead of a fixed axis: the curvature terms of the flight-path
    equations (V cos(gamma) / r in gamma' and in the course) come out of the turning vertical,
    with no singular term anywhere, the poles included.
    """
    rx = xs[X_PN]
    ry = xs[X_PE]
    rz = xs[X_PD]
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    flags = aero_eval_h(xs, r - p[P_EARTH_R], dl, dr, du, p, w)
    o = W_AUX
    m = p[P_MASS]
    g = w[o + AX_GRAV]
    u = xs[X_U]
    v = xs[X_V]
    ww = xs[X_W]
    pp = xs[X_P]
    qq = xs[X_Q]
    rr = xs[X_R]
    c11, c12, c13, c21, c22, c23, c31, c32, c33 = quat_to_dcm_nb(xs[X_Q0], xs[X_Q1], xs[X_Q2],
                                                                  xs[X_Q3])   # here C_eb
    ve0 = c11 * u + c12 * v + c13 * ww
    ve1 = c21 * u + c22 * v + c23 * ww
    ve2 = c31 * u + c32 * v + c33 * ww
    if p[P_SPEED_MODE] == SPEED_HOLD:
        thrust = hold_thrust((rx * ve0 + ry * ve1 + rz * ve2) / (r * w[o + AX_V]), p, w)
    else:
        thrust = thrust_n(xs, p, w)      # engine or none: no use of the attitude
    w[o + AX_THRUST] = thrust
    xdot[X_PN] = ve0
    xdot[X_PE] = ve1
    xdot[X_PD] = ve2
    # gravity in body axes: -g C_be r_hat, C_be = C_eb^T
    gr = -g / r
    xdot[X_U] = (w[o + AX_FX] + thrust) / m + gr * (c11 * rx + c21 * ry + c31 * rz) - (qq * ww - rr * v)
    xdot[X_V] = w[o + AX_FY] / m + gr * (c12 * rx + c22 * ry + c32 * rz) - (rr * u - pp * ww)
    xdot[X_W] = w[o + AX_FZ] / m + gr * (c13 * rx + c23 * ry + c33 * rz) - (pp * v - qq * u)
    _attitude_deriv(xs, t_s, p, w, xdot)
    return flags


@njit(cache=True)
def ned_axes(rx, ry, rz):
    """Local north, east, down unit vectors (E axes) at the point r_E (m) of the sphere, as
    nine numbers (n, e, d). At a pole (no east), east is taken as E's y axis (longitude 0)."""
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    dx = -rx / r
    dy = -ry / r
    dz = -rz / r
    rho = math.sqrt(rx * rx + ry * ry)
    if rho > 1e-9 * r:
        ex = -ry / rho
        ey = rx / rho
    else:
        ex = 0.0
        ey = 1.0
    # north = east x down
    nx = ey * dz
    ny = -ex * dz
    nz = ex * dy - ey * dx
    return nx, ny, nz, ex, ey, 0.0, dx, dy, dz


@njit(cache=True)
def sphere_view(x, p):
    """Write the local-NED view x[0:13] of the round-Earth block x[X_S:X_S+13]: the
    quaternion body -> local NED (C_nb = C_ne C_eb), down = -(|r_E| - R), north/east on the
    azimuthal-equidistant map about the origin (great-circle distance from the origin along
    its initial azimuth, at radius R), body velocity and rates copied."""
    b = X_S
    rx = x[b + X_PN]
    ry = x[b + X_PE]
    rz = x[b + X_PD]
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    nx, ny, nz, ex, ey, ez, dx, dy, dz = ned_axes(rx, ry, rz)
    e11, e12, e13, e21, e22, e23, e31, e32, e33 = quat_to_dcm_nb(x[b + X_Q0], x[b + X_Q1],
                                                                  x[b + X_Q2], x[b + X_Q3])
    # C_nb = C_ne C_eb, rows of C_ne = n, e, d
    c11 = nx * e11 + ny * e21 + nz * e31
    c12 = nx * e12 + ny * e22 + nz * e32
    c13 = nx * e13 + ny * e23 + nz * e33
    c21 = ex * e11 + ey * e21 + ez * e31
    c22 = ex * e12 + ey * e22 + ez * e32
    c23 = ex * e13 + ey * e23 + ez * e33
    c31 = dx * e11 + dy * e21 + dz * e31
    c32 = dx * e12 + dy * e22 + dz * e32
    c33 = dx * e13 + dy * e23 + dz * e33
    quat_from_dcm(c11, c12, c13, c21, c22, c23, c31, c32, c33, x)
    # azimuthal-equidistant map about the origin (up u0, north n0, east e0 in p)
    o = P_ORIGIN
    ux = rx / r
    uy = ry / r
    uz = rz / r
    cosc = ux * p[o] + uy * p[o + 1] + uz * p[o + 2]
    tn = ux * p[o + 3] + uy * p[o + 4] + uz * p[o + 5]
    te = ux * p[o + 6] + uy * p[o + 7] + uz * p[o + 8]
    sinc = math.sqrt(tn * tn + te * te)
    c = math.atan2(sinc, cosc)
    scale = p[P_EARTH_R] * c / sinc if sinc > 1e-15 else p[P_EARTH_R]
    x[X_PN] = tn * scale
    x[X_PE] = te * scale
    x[X_PD] = -(r - p[P_EARTH_R])
    for i in range(X_U, X_W + 1):
        x[i] = x[b + i]
    for i in range(X_P, X_R + 1):
        x[i] = x[b + i]


@njit(cache=True)
def quat_from_dcm(c11, c12, c13, c21, c22, c23, c31, c32, c33, x):
    """x[X_Q0:X_Q3+1] := the unit quaternion (scalar first, >= 0) of the rotation matrix C
    (row major; Shepperd's method)."""
    tr = c11 + c22 + c33
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        q0, q1, q2, q3 = 0.25 * s, (c32 - c23) / s, (c13 - c31) / s, (c21 - c12) / s
    elif c11 > c22 and c11 > c33:
        s = math.sqrt(1.0 + c11 - c22 - c33) * 2.0
        q0, q1, q2, q3 = (c32 - c23) / s, 0.25 * s, (c12 + c21) / s, (c13 + c31) / s
    elif c22 > c33:
        s = math.sqrt(1.0 + c22 - c11 - c33) * 2.0
        q0, q1, q2, q3 = (c13 - c31) / s, (c12 + c21) / s, 0.25 * s, (c23 + c32) / s
    else:
        s = math.sqrt(1.0 + c33 - c11 - c22) * 2.0
        q0, q1, q2, q3 = (c21 - c12) / s, (c13 + c31) / s, (c23 + c32) / s, 0.25 * s
    if q0 < 0.0:
        q0, q1, q2, q3 = -q0, -q1, -q2, -q3
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    x[X_Q0] = q0 / n
    x[X_Q1] = q1 / n
    x[X_Q2] = q2 / n
    x[X_Q3] = q3 / n


@njit(cache=True)
def actuator_step(x, p, dt):
    """Advance the three surfaces one physics step toward their latched commands.

    Per surface: command clipped to +-limit; first-order lag with time constant tau
    (exact discretisation, tau = 0: none); the change per step limited to rate_max*dt
    (rate_max = 0: none); position clipped to +-limit.
    """
    lim = p[P_ACT_LIMIT]
    tau = p[P_ACT_TAU]
    rate = p[P_ACT_RATE]
    frac = 1.0 if tau <= 0.0 else 1.0 - math.exp(-dt / tau)
    for k in range(3):
        cmd = x[X_CMD_L + k]
        if cmd > lim:
            cmd = lim
        elif cmd < -lim:
            cmd = -lim
        pos = _lag_rate_step(x[X_DL + k], cmd, frac, rate * dt)
        if pos > lim:
            pos = lim
        elif pos < -lim:
            pos = -lim
        x[X_DL + k] = pos


@njit(cache=True, inline="always")
def _lag_rate_step(pos, cmd, frac, step_max):
    """pos moved toward cmd by the lag fraction ``frac``, the move limited to +-step_max
    (step_max <= 0: no limit)."""
    step = (cmd - pos) * frac
    if step_max > 0.0:
        if step > step_max:
            step = step_max
        elif step < -step_max:
            step = -step_max
    return pos + step


@njit(cache=True)
def engine_step(x, p, dt):
    """Advance the engine's throttle position one physics step toward the latched command
    (SPEED_ENGINE only): command clipped to [0, 1]; first-order lag with time constant
    P_ENG_TAU (exact discretisation, 0 = none); change per step limited to P_ENG_RATE x dt
    (0 = none); position clipped to [0, 1]."""
    if p[P_SPEED_MODE] != SPEED_ENGINE:
        return
    cmd = min(max(x[X_CMD_THR], 0.0), 1.0)
    if not cmd == cmd:           # NaN command: hold the position
        return
    tau = p[P_ENG_TAU]
    frac = 1.0 if tau <= 0.0 else 1.0 - math.exp(-dt / tau)
    x[X_THR] = min(max(_lag_rate_step(x[X_THR], cmd, frac, p[P_ENG_RATE] * dt), 0.0), 1.0)


@njit(cache=True)
def rk4_step(x, p, w):
    """One physics step: actuators and engine, then classic RK4 of the rigid body with the
    surfaces and throttle held."""
    dt = p[P_DT]
    t = x[X_STEP] * dt
    actuator_step(x, p, dt)
    engine_step(x, p, dt)
    w[W_AUX + AX_THR_POS] = x[X_THR]
    dl = x[X_DL]
    dr = x[X_DR]
    du = x[X_DU]
    sphere = p[P_EARTH] == EARTH_SPHERE
    b = X_S if sphere else 0
    flags, thrust0 = _rk4_rigid(x[b:b + X_RB_N], t, dl, dr, du, p, w, sphere)
    if sphere:
        sphere_view(x, p)
    x[X_THRUST] = thrust0
    x[X_STEP] += 1.0
    x[X_CLIP] = float(int(x[X_CLIP]) | flags)
    return flags


@njit(cache=True, inline="always")
def _deriv_any(xs, t_s, dl, dr, du, p, w, xdot, sphere):
    if sphere:
        return deriv_sphere(xs, t_s, dl, dr, du, p, w, xdot)
    return deriv(xs, t_s, dl, dr, du, p, w, xdot)


@njit(cache=True)
def _rk4_rigid(xs, t, dl, dr, du, p, w, sphere):
    """Classic RK4 of the 13 rigid-body states ``xs`` (x[0:13], or the round-Earth block)
    over one physics step, surfaces held; returns (clip flags, thrust at the step's start)."""
    dt = p[P_DT]
    n = X_RB_N
    k1 = w[W_K1:W_K1 + n]
    k2 = w[W_K2:W_K2 + n]
    k3 = w[W_K3:W_K3 + n]
    k4 = w[W_K4:W_K4 + n]
    xt = w[W_XT:W_XT + X_RB_N]         # trial state (deriv reads only 0..12)
    flags = _deriv_any(xs, t, dl, dr, du, p, w, k1, sphere)
    thrust0 = w[W_AUX + AX_THRUST]
    for i in range(n):
        xt[i] = xs[i] + 0.5 * dt * k1[i]
    flags |= _deriv_any(xt, t + 0.5 * dt, dl, dr, du, p, w, k2, sphere)
    for i in range(n):
        xt[i] = xs[i] + 0.5 * dt * k2[i]
    flags |= _deriv_any(xt, t + 0.5 * dt, dl, dr, du, p, w, k3, sphere)
    for i in range(n):
        xt[i] = xs[i] + dt * k3[i]
    flags |= _deriv_any(xt, t + dt, dl, dr, du, p, w, k4, sphere)
    for i in range(n):
        xs[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    qn = math.sqrt(xs[X_Q0] ** 2 + xs[X_Q1] ** 2 + xs[X_Q2] ** 2 + xs[X_Q3] ** 2)
    for i in range(X_Q0, X_Q3 + 1):
        xs[i] /= qn
    return flags, thrust0


@njit(cache=True)
def advance_frame(x, cmd_rad, p, w, n_sub):
    """Latch ``cmd_rad`` (float64[3], rad: left, right, rudder) and advance ``n_sub`` physics
    steps (one frame). Returns the OR of the aero clip flags over the frame."""
    x[X_CMD_L] = cmd_rad[0]
    x[X_CMD_R] = cmd_rad[1]
    x[X_CMD_U] = cmd_rad[2]
    x[X_CLIP] = 0.0
    flags = 0
    for _ in range(n_sub):
        flags |= rk4_step(x, p, w)
    return flags


@njit(cache=True)
def advance_frame_latched(x, p, w, n_sub):
    """Advance one frame with the commands already latched in x[X_CMD_*]."""
    x[X_CLIP] = 0.0
    flags = 0
    for _ in range(n_sub):
        flags |= rk4_step(x, p, w)
    return flags


@njit(cache=True)
def advance_frames(x, cmd_rad, p, w, n_sub, n_frames):
    """Advance ``n_frames`` frames with a constant command (benchmarks, open-loop runs)."""
    flags = 0
    for _ in range(n_frames):
        flags |= advance_frame(x, cmd_rad, p, w, n_sub)
    return flags


@njit(cache=True)
def euler_from_quat(x, out3):
    """ZYX Euler angles (phi, theta, psi) in rad from the attitude quaternion in x."""
    q0 = x[X_Q0]
    q1 = x[X_Q1]
    q2 = x[X_Q2]
    q3 = x[X_Q3]
    out3[0] = math.atan2(2.0 * (q0 * q1 + q2 * q3), 1.0 - 2.0 * (q1 * q1 + q2 * q2))
    s = 2.0 * (q0 * q2 - q3 * q1)
    if s > 1.0:
        s = 1.0
    elif s < -1.0:
        s = -1.0
    out3[1] = math.asin(s)
    out3[2] = math.atan2(2.0 * (q0 * q3 + q1 * q2), 1.0 - 2.0 * (q2 * q2 + q3 * q3))


@njit(cache=True)
def flight_path(x, out4):
    """Flight-path angles from the state: out4 = gamma, chi, mu (rad) and V (m/s).

    v_NED = C_nb v_b; gamma = atan2(-v_D, sqrt(v_N^2 + v_E^2)); chi = atan2(v_E, v_N).
    mu from the wind-axes DCM: C_wn = C_wb C_bn with C_bw = R2(alpha) R3(-beta) (columns of
    C_bw^T are the wind axes in body axes) and C_wn = R1(mu) R2(gamma) R3(chi), so
    mu = atan2(C_wn[1, 2], C_wn[2, 2]) (the 'roll' of the wind frame about the velocity).
    """
    q0 = x[X_Q0]
    q1 = x[X_Q1]
    q2 = x[X_Q2]
    q3 = x[X_Q3]
    c11, c12, c13, c21, c22, c23, c31, c32, c33 = quat_to_dcm_nb(q0, q1, q2, q3)
    u = x[X_U]
    v = x[X_V]
    ww = x[X_W]
    vn = c11 * u + c12 * v + c13 * ww
    ve = c21 * u + c22 * v + c23 * ww
    vd = c31 * u + c32 * v + c33 * ww
    V = math.sqrt(u * u + v * v + ww * ww)
    out4[0] = math.atan2(-vd, math.sqrt(vn * vn + ve * ve))
    out4[1] = math.atan2(ve, vn)
    alpha = math.atan2(ww, u)
    sb = v / V if V > 0.0 else 0.0
    sb = min(1.0, max(-1.0, sb))
    beta = math.asin(sb)
    ca = math.cos(alpha)
    sa = math.sin(alpha)
    cb = math.cos(beta)
    # wind y and z axes in body components (rows 2 and 3 of C_wb)
    yw0 = -ca * sb
    yw1 = cb
    yw2 = -sa * sb
    zw0 = -sa
    zw1 = 0.0
    zw2 = ca
    # C_wn = C_wb C_bn, C_bn = C_nb^T: element (j, 3) = (wind axis j) . (third column of C_bn)
    # third column of C_bn = third row of C_nb = (c31, c32, c33)
    cwn23 = yw0 * c31 + yw1 * c32 + yw2 * c33
    cwn33 = zw0 * c31 + zw1 * c32 + zw2 * c33
    out4[2] = math.atan2(cwn23, cwn33)
    out4[3] = V


def initial_state(V_m_s, h_m, alpha_rad, beta_rad, mu_rad, gamma_rad, chi_rad,
                  p_rad_s, q_rad_s, r_rad_s, x):
    """Fill x (float64[X_N]) from flight-path quantities (Python; called at reset only).

    C_bn = R2(alpha) R3(-beta) R1(mu) R2(gamma) R3(chi) (frame rotations); v_b = C_bw [V,0,0].
    """
    def r1(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[1, 0, 0], [0, c, s], [0, -s, c]], dtype=np.float64)

    def r2(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]], dtype=np.float64)

    def r3(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]], dtype=np.float64)

    c_bw = r2(alpha_rad) @ r3(-beta_rad)
    c_bn = c_bw @ r1(mu_rad) @ r2(gamma_rad) @ r3(chi_rad)
    c_nb = c_bn.T
    vb = c_bw @ np.array([V_m_s, 0.0, 0.0])
    x[:] = 0.0
    x[X_PD] = -h_m
    x[X_U:X_W + 1] = vb
    # quaternion from C_nb (Shepperd)
    tr = c_nb[0, 0] + c_nb[1, 1] + c_nb[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2.0
        q = [0.25 * s, (c_nb[2, 1] - c_nb[1, 2]) / s, (c_nb[0, 2] - c_nb[2, 0]) / s,
             (c_nb[1, 0] - c_nb[0, 1]) / s]
    elif c_nb[0, 0] > c_nb[1, 1] and c_nb[0, 0] > c_nb[2, 2]:
        s = math.sqrt(1.0 + c_nb[0, 0] - c_nb[1, 1] - c_nb[2, 2]) * 2.0
        q = [(c_nb[2, 1] - c_nb[1, 2]) / s, 0.25 * s, (c_nb[0, 1] + c_nb[1, 0]) / s,
             (c_nb[0, 2] + c_nb[2, 0]) / s]
    elif c_nb[1, 1] > c_nb[2, 2]:
        s = math.sqrt(1.0 + c_nb[1, 1] - c_nb[0, 0] - c_nb[2, 2]) * 2.0
        q = [(c_nb[0, 2] - c_nb[2, 0]) / s, (c_nb[0, 1] + c_nb[1, 0]) / s, 0.25 * s,
             (c_nb[1, 2] + c_nb[2, 1]) / s]
    else:
        s = math.sqrt(1.0 + c_nb[2, 2] - c_nb[0, 0] - c_nb[1, 1]) * 2.0
        q = [(c_nb[1, 0] - c_nb[0, 1]) / s, (c_nb[0, 2] + c_nb[2, 0]) / s,
             (c_nb[1, 2] + c_nb[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    if q[0] < 0:
        q = -q
    x[X_Q0:X_Q3 + 1] = q / np.linalg.norm(q)
    x[X_P] = p_rad_s
    x[X_Q] = q_rad_s
    x[X_R] = r_rad_s


def init_sphere(x, p):
    """Round Earth (p[P_EARTH] = EARTH_SPHERE): build the block x[X_S:X_S+13] from the
    flat initial state ``x`` (as ``initial_state`` fills it: attitude relative to the local
    NED, h = -x[X_PD]) placed at the origin of p[P_ORIGIN:], then refresh the view x[0:13].
    No-op on the flat earth. (Python; called at reset only.)"""
    if p[P_EARTH] != EARTH_SPHERE:
        return
    o = P_ORIGIN
    up, north, east = p[o:o + 3], p[o + 3:o + 6], p[o + 6:o + 9]
    c_en = np.column_stack((north, east, -up))            # NED -> E
    c_nb = np.array(quat_to_dcm_nb(x[X_Q0], x[X_Q1], x[X_Q2], x[X_Q3])).reshape(3, 3)
    c_eb = c_en @ c_nb
    b = X_S
    x[b:b + X_RB_N] = x[0:X_RB_N]
    x[b + X_PN:b + X_PD + 1] = (p[P_EARTH_R] - x[X_PD]) * up
    tmp = np.zeros(X_N)
    quat_from_dcm(*c_eb.ravel(), tmp)
    x[b + X_Q0:b + X_Q3 + 1] = tmp[X_Q0:X_Q3 + 1]
    sphere_view(x, p)
