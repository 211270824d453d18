"""fc/gcs_frames.py - the ground station's high-rate streams framed without Python objects (issue 24).

The ground-station link (fc/gcs.py) streams ATTITUDE, AOA_SSA, VFR_HUD, SERVO_OUTPUT_RAW and
the DEBUG_VECTs at 4-10 Hz each, to its outputs and into the .tlog. Built as pymavlink
message objects and packed by the codec, each cost about 30 Python object allocations (the
message, its field values, numpy scalars of the state read, the packed bytes): most of the fc's
allocations per frame in steady state (``python -m tools.bench --only allocs``). Here each is
one compiled call that reads the vehicle's preallocated state arrays by address
(fc/control/carrays.py) and frames the message into a preallocated buffer, the bytes the codec
gives for the same values (field values computed as ``GcsLink._build`` computes them; payload,
trailing-zero truncation, header and CRC as ``hyfc_wire.frame_kernels`` frames the fc's
answer); :func:`send_frame_p` sends it to each output with libc ``sendto``.

Every framing kernel returns the bytes written, or 0 when a value is one the codec's struct
would refuse (a finite float beyond float32, a heading or throttle that does not fit): the
caller then takes the codec's path, which refuses it as before (counted, not sent).
tests/unit/fc/test_gcs_frames.py compares the bytes with the codec's.

The time base (the messages' time fields) is read from the int64 cell at ``time_at`` (the
newest frame's stamp in lockstep: no Python int for it). ``log_epoch_us`` >= 0 prefixes the
frame with the .tlog's big-endian u64 stamp: ``log_epoch_us`` + the time base at the int64 cell
``log_t_at`` (8 bytes), as ``GcsLink._tlog_write`` writes it (the sum made here: no Python int
for it); -1 writes the bare frame (a datagram). The buffer at ``tx`` holds FRAME_MAX_B bytes.
"""
from __future__ import annotations

import math
import socket
import sys

import numpy as np
from numba import carray, njit, types

import fc.control.carrays as _carrays
import fc.control.layout as _control_layout
import fc.gcs_streams as _gcs_streams
import fc.guidance.layout as _guid_layout
import hyfc_wire.codec as _codec
import hyfc_wire.earth as _earth
import hyfc_wire.frame_kernels as _frame_kernels
import hyfc_wire.layout as _wire_layout
from fc.control.carrays import f8p, i8p, u8p
from fc.control.layout import E_H, E_N
from fc.gcs_streams import IN_AIR_SPEED_M_S
from fc.guidance.layout import GS_ALPHA_C, GS_GAM_C, GS_MU_C, GS_N, GS_V_ERR, TG_CHI, TG_H, TG_N
from hyfc_wire.codec import development_dialect, mavlink
from hyfc_wire.earth import EARTH_RADIUS_M
from hyfc_wire.frame_kernels import _frame_at, _put_f32, _put_u
from hyfc_wire.layout import (G_ALT_M, G_FIX, G_HACC_M, G_LAT_DEG, G_LON_DEG, G_N, G_SACC_M_S,
                              G_SATS, G_T_S, G_VACC_M, G_VD, G_VE, G_VN, M_AIRSPEED, M_ALT, M_AOA,
                              M_CLIMB, M_GROUNDSPEED, M_HEADING, M_N, M_P, M_PITCH, M_Q, M_R,
                              M_ROLL, M_SSA, M_YAW)
from hyfc_wire.numba_cache import drop_stale

drop_stale(__file__, [_carrays.__file__, _frame_kernels.__file__, _wire_layout.__file__,
                      _codec.__file__, _earth.__file__, _control_layout.__file__,
                      _guid_layout.__file__, _gcs_streams.__file__])

__all__ = ["FRAME_MAX_B", "DV_CMD", "DV_EST", "DV_DELTA", "DV_GUID", "DV_SIM_T", "DV_NAMES",
           "NV_NAME_B", "attitude_p", "aoa_ssa_p", "vfr_hud_p", "servo_raw_p", "debug_vect_p",
           "sim_t_p", "named_value_p", "gps_raw_int_p", "global_position_int_p",
           "local_position_ned_p", "nav_output_p", "heartbeat_p", "system_time_p",
           "extended_sys_state_p", "mission_current_p", "sys_status_p", "current_mode_p",
           "home_position_p",
           "SYS_PRESENT", "HOME_LAT_DEG", "HOME_LON_DEG", "HOME_ALT_M", "HOME_COS_LAT",
           "HOME_N", "LOG_LAST", "LOG_NEXT", "LOG_DUE", "LOG_SAFE_US", "log_walk_p", "send_frame_p",
           "sockaddr_in", "SOCKADDR_IN_B"]

_HDR = 10


def _spec(cls) -> tuple[int, int, int]:
    """(message id, CRC_EXTRA, payload size) of a codec message class."""
    return cls.id, cls.crc_extra, cls.unpacker.size


ID_ATT, X_ATT, N_ATT = _spec(mavlink.MAVLink_attitude_message)
ID_AOA, X_AOA, N_AOA = _spec(mavlink.MAVLink_aoa_ssa_message)
ID_HUD, X_HUD, N_HUD = _spec(mavlink.MAVLink_vfr_hud_message)
ID_SERVO, X_SERVO, N_SERVO = _spec(mavlink.MAVLink_servo_output_raw_message)
ID_DV, X_DV, N_DV = _spec(mavlink.MAVLink_debug_vect_message)
ID_NV, X_NV, N_NV = _spec(mavlink.MAVLink_named_value_float_message)
ID_GPS, X_GPS, N_GPS = _spec(mavlink.MAVLink_gps_raw_int_message)
ID_GPI, X_GPI, N_GPI = _spec(mavlink.MAVLink_global_position_int_message)
ID_LPN, X_LPN, N_LPN = _spec(mavlink.MAVLink_local_position_ned_message)
ID_NAV, X_NAV, N_NAV = _spec(mavlink.MAVLink_nav_controller_output_message)
ID_HB, X_HB, N_HB = _spec(mavlink.MAVLink_heartbeat_message)
ID_TIME, X_TIME, N_TIME = _spec(mavlink.MAVLink_system_time_message)
ID_EXT, X_EXT, N_EXT = _spec(mavlink.MAVLink_extended_sys_state_message)
ID_MC, X_MC, N_MC = _spec(mavlink.MAVLink_mission_current_message)
ID_SYS, X_SYS, N_SYS = _spec(mavlink.MAVLink_sys_status_message)
ID_CM, X_CM, N_CM = _spec(development_dialect().MAVLink_current_mode_message)
ID_HOME, X_HOME, N_HOME = _spec(mavlink.MAVLink_home_position_message)
#: the longest frame written here, with the .tlog stamp (bytes)
FRAME_MAX_B = 8 + _HDR + max(N_ATT, N_AOA, N_HUD, N_SERVO, N_DV, N_NV, N_GPS, N_GPI, N_LPN,
                             N_NAV, N_HB, N_TIME, N_EXT, N_MC, N_SYS, N_CM, N_HOME) + 2
#: HEARTBEAT.mavlink_version as the codec's ``heartbeat_encode`` sets it
_MAVLINK_VERSION = 3
#: fc/gcs_streams.py ``landed_state``: IN_AIR above this airspeed with data current
_IN_AIR_SPEED_M_S = IN_AIR_SPEED_M_S
_IN_AIR = mavlink.MAV_LANDED_STATE_IN_AIR
_LANDED_UNDEF = mavlink.MAV_LANDED_STATE_UNDEFINED
_VTOL_UNDEF = mavlink.MAV_VTOL_STATE_UNDEFINED
#: SYS_STATUS's sensors present (``GcsLink._build``); the two the law drives are enabled only
#: while it is active; GPS is healthy only with a 3D fix
SYS_PRESENT = (mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO
               | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
               | mavlink.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
               | mavlink.MAV_SYS_STATUS_SENSOR_GPS
               | mavlink.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
               | mavlink.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
               | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | mavlink.MAV_SYS_STATUS_AHRS
               | mavlink.MAV_SYS_STATUS_LOGGING)
_SYS_LAW = (mavlink.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
            | mavlink.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION)
_SYS_GPS = mavlink.MAV_SYS_STATUS_SENSOR_GPS
#: home (``GcsLink.home``) as the GNSS kernels read it: float64[HOME_N]
HOME_LAT_DEG, HOME_LON_DEG, HOME_ALT_M = 0, 1, 2
HOME_COS_LAT = 3               # math.cos(math.radians(lat)): LOCAL_POSITION_NED's east scale
HOME_N = 4
#: GNSS_STALE_S of fc/gcs.py (a sample older than this, plant time, reports NO_FIX)
GNSS_STALE_S = 1.0
_FIX_NONE = mavlink.GPS_FIX_TYPE_NO_FIX
_FIX_3D = mavlink.GPS_FIX_TYPE_3D_FIX
_I32_MIN, _I32_MAX = -(1 << 31), (1 << 31) - 1
#: a value this close to a rounding boundary (x.5) after an operation whose last bit may differ
#: from CPython's (``math.hypot``: its own algorithm, here a square root) is declined
_ROUND_MARGIN = 1e-6
#: NAMED_VALUE_FLOAT.name is char[10]: a name table is uint8[n, NV_NAME_B]
NV_NAME_B = 10
_RAD = 180.0 / np.pi           # CPython's math.degrees multiplies by 180 / pi
_RADIAN = np.pi / 180.0        # and math.radians by pi / 180
_EARTH_R = EARTH_RADIUS_M
_U32 = 1 << 32
_DV_NAME_B = 10                # DEBUG_VECT.name is char[10]

#: the DEBUG_VECTs (fc/telemetry.py ``debug_vectors`` and GcsLink's SIM_T), by index
DV_CMD, DV_EST, DV_DELTA, DV_GUID, DV_SIM_T = 0, 1, 2, 3, 4
DV_NAMES = (b"CMD_DEG", b"EST_DEG", b"DELTA_DEG", b"GUID", b"SIM_T")
_DV_NAME_TABLE = np.zeros((len(DV_NAMES), _DV_NAME_B), np.int64)
for _i, _name in enumerate(DV_NAMES):
    _DV_NAME_TABLE[_i, :len(_name)] = np.frombuffer(_name, np.uint8)
SOCKADDR_IN_B = 16             # sizeof(struct sockaddr_in)
_sendto = types.ExternalFunction("sendto", types.intp(
    types.intc, types.CPointer(types.uint8), types.uintp, types.intc, types.CPointer(types.uint8),
    types.uint32))


@njit(cache=True)
def _stamp_at(out, log_epoch_us, log_t_at):
    """The .tlog's big-endian u64 stamp (``log_epoch_us`` + the int64 at ``log_t_at``, mod
    2^64) at ``out[0:8]`` when ``log_epoch_us`` >= 0; the frame's position (8, or 0 without a
    stamp)."""
    if log_epoch_us < 0:
        return 0
    stamp = log_epoch_us + carray(i8p(log_t_at), (1,))[0]
    for k in range(8):
        out[k] = (stamp >> (8 * (7 - k))) & 0xFF
    return 8


@njit(cache=True)
def _put_ms_six_f32(out, p, time_us, a, b, c, d, e, f):
    """The payload of ATTITUDE and LOCAL_POSITION_NED at ``out[p:]``: time_boot_ms (the time
    base / 1000 mod 2^32) and six float32; False if the struct would refuse one."""
    _put_u(out, p, (time_us // 1000) % _U32, 4)
    ok = _put_f32(out, p + 4, a)
    ok &= _put_f32(out, p + 8, b)
    ok &= _put_f32(out, p + 12, c)
    ok &= _put_f32(out, p + 16, d)
    ok &= _put_f32(out, p + 20, e)
    ok &= _put_f32(out, p + 24, f)
    return ok


@njit(cache=True)
def attitude_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, meas):
    """ATTITUDE (``GcsLink._build``: time_boot_ms = time base / 1000 mod 2^32, roll .. yawspeed
    = meas[M_ROLL .. M_R]) into the uint8 buffer at ``tx`` from the float64 ``meas`` at
    ``meas`` (M_*); bytes written or 0."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    m = carray(f8p(meas), (M_R + 1,))
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    if not _put_ms_six_f32(out, pos + _HDR, time_us, m[M_ROLL], m[M_PITCH], m[M_YAW], m[M_P],
                           m[M_Q], m[M_R]):
        return 0
    return _frame_at(out, pos, N_ATT, seq, sysid, compid, ID_ATT, X_ATT)


@njit(cache=True)
def aoa_ssa_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, meas):
    """AOA_SSA (time_usec = the time base, AOA and SSA in deg of meas[M_AOA], meas[M_SSA]);
    bytes written or 0."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    m = carray(f8p(meas), (M_SSA + 1,))
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, time_us, 8)
    ok = _put_f32(out, p + 8, m[M_AOA] * _RAD)
    ok &= _put_f32(out, p + 12, m[M_SSA] * _RAD)
    if not ok:
        return 0
    return _frame_at(out, pos, N_AOA, seq, sysid, compid, ID_AOA, X_AOA)


@njit(cache=True)
def vfr_hud_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, meas, throttle_pct):
    """VFR_HUD (airspeed, groundspeed, alt, climb of meas; heading = round(deg of
    meas[M_HEADING]) mod 360, half to even, 0 when not finite; throttle ``throttle_pct``);
    bytes written or 0."""
    out = carray(u8p(tx), (FRAME_MAX_B,))
    m = carray(f8p(meas), (max(M_AIRSPEED, M_ALT, M_CLIMB, M_GROUNDSPEED, M_HEADING) + 1,))
    if throttle_pct < 0 or throttle_pct > 0xFFFF:
        return 0
    h = m[M_HEADING]
    hdg = 0
    if np.isfinite(h):
        d = np.rint(h * _RAD)           # Python's round: to nearest, half to even
        if abs(d) > 2.0 ** 62:
            return 0                    # (an int64 would not hold it: the codec's path)
        hdg = np.int64(d) % 360
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    ok = _put_f32(out, p, m[M_AIRSPEED])
    ok &= _put_f32(out, p + 4, m[M_GROUNDSPEED])
    ok &= _put_f32(out, p + 8, m[M_ALT])
    ok &= _put_f32(out, p + 12, m[M_CLIMB])
    if not ok:
        return 0
    _put_u(out, p + 16, hdg, 2)
    _put_u(out, p + 18, throttle_pct, 2)
    return _frame_at(out, pos, N_HUD, seq, sysid, compid, ID_HUD, X_HUD)


@njit(cache=True)
def servo_raw_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, pwm):
    """SERVO_OUTPUT_RAW (time_usec = the time base mod 2^32, port 0, servo1..4 = the int64[4]
    at ``pwm``, the others 0); bytes written or 0 (a PWM value beyond u16)."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    w = carray(i8p(pwm), (4,))
    for c in range(4):
        if w[c] < 0 or w[c] > 0xFFFF:
            return 0
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, time_us % _U32, 4)
    for c in range(4):
        _put_u(out, p + 4 + 2 * c, w[c], 2)
    for i in range(p + 12, p + N_SERVO):            # servo5..8, port, servo9..16
        out[i] = 0
    return _frame_at(out, pos, N_SERVO, seq, sysid, compid, ID_SERVO, X_SERVO)


@njit(cache=True)
def debug_vect_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, which, src, deg, x, y, z):
    """DEBUG_VECT ``DV_NAMES[which]``: x, y, z = the float64[3] at ``src`` (in deg of rad when
    ``deg``) when ``src`` is not 0, else ``x``, ``y``, ``z``; bytes written or 0."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    if src != 0:
        v = carray(f8p(src), (3,))
        if deg:
            x, y, z = v[0] * _RAD, v[1] * _RAD, v[2] * _RAD
        else:
            x, y, z = v[0], v[1], v[2]
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, time_us, 8)
    ok = _put_f32(out, p + 8, x)
    ok &= _put_f32(out, p + 12, y)
    ok &= _put_f32(out, p + 16, z)
    if not ok:
        return 0
    for i in range(_DV_NAME_B):
        out[p + 20 + i] = _DV_NAME_TABLE[which, i]
    return _frame_at(out, pos, N_DV, seq, sysid, compid, ID_DV, X_DV)


@njit(cache=True)
def sim_t_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, stamp, frames):
    """DEBUG_VECT SIM_T (``GcsLink._debug_vectors``): x = the newest plant frame's stamp in the
    int64 cell at ``stamp`` (us) x 1e-6 (its sim time, s) when the int64 count at ``frames``
    (the plant link's frames, ``LinkCounters.hot``) is not 0, else NaN; y = z = 0. Bytes
    written or 0."""
    x = carray(i8p(stamp), (1,))[0] * 1e-6 if carray(i8p(frames), (1,))[0] else np.nan
    return debug_vect_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, DV_SIM_T, 0,
                        False, x, 0.0, 0.0)


@njit(cache=True)
def named_value_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, names, values, k):
    """NAMED_VALUE_FLOAT ``k`` (``GcsLink._build``: time_boot_ms = time base / 1000 mod 2^32)
    of the name table at ``names`` (uint8[n, NV_NAME_B], zero-padded) and the float64[n] at
    ``values``; bytes written or 0."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    name = carray(u8p(names + k * NV_NAME_B), (NV_NAME_B,))
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, (time_us // 1000) % _U32, 4)
    if not _put_f32(out, p + 4, carray(f8p(values + 8 * k), (1,))[0]):
        return 0
    for i in range(NV_NAME_B):
        out[p + 8 + i] = name[i]
    return _frame_at(out, pos, N_NV, seq, sysid, compid, ID_NV, X_NV)


@njit(cache=True)
def _round_i(x):
    """``int(round(x))`` (Python's round: half to even) of a finite ``x``; (ok, value), not ok
    when it would not fit an int64 (the caller declines)."""
    d = np.rint(x)
    if not abs(d) < 2.0 ** 62:
        return False, np.int64(0)
    return True, np.int64(d)


@njit(cache=True)
def _u32_field(x):
    """fc/gcs.py ``_u32``: a non-negative finite value rounded and saturated to u32, else 0."""
    if not (np.isfinite(x) and x > 0.0):
        return np.int64(0)
    if x >= 4294967295.0:
        return np.int64(0xFFFFFFFF)
    return min(np.int64(np.rint(x)), np.int64(0xFFFFFFFF))


@njit(cache=True)
def _cm_s_i16(v):
    """fc/gcs_streams.py ``cm_s_i16``: m/s as int16 cm/s, 32767 when not finite or beyond."""
    if not np.isfinite(v) or abs(v) > 1e6:
        return np.int64(32767)
    cm = np.int64(np.rint(v * 100.0))
    return cm if -32768 <= cm < 32767 else np.int64(32767)


@njit(cache=True)
def _gnss_fix(g, stamp_us):
    """``GcsLink._gnss``'s fix: the sample's own, NO_FIX once older than GNSS_STALE_S of
    plant time (the newest frame's stamp ``stamp_us``, us)."""
    fix = np.int64(g[G_FIX])
    if fix and stamp_us * 1e-6 - g[G_T_S] > GNSS_STALE_S:
        fix = np.int64(_FIX_NONE)
    return fix


@njit(cache=True)
def _put_lat_lon_alt(out, p, g):
    """lat, lon (degE7) and alt (mm) of the GNSS sample as three i32 at ``out[p:]``; False
    when one does not fit (the codec's struct would refuse it)."""
    ok1, lat = _round_i(g[G_LAT_DEG] * 1e7)
    ok2, lon = _round_i(g[G_LON_DEG] * 1e7)
    ok3, alt = _round_i(g[G_ALT_M] * 1000.0)
    if not (ok1 and ok2 and ok3):
        return False
    for v in (lat, lon, alt):
        if v < _I32_MIN or v > _I32_MAX:
            return False
    _put_u(out, p, lat, 4)
    _put_u(out, p + 4, lon, 4)
    _put_u(out, p + 8, alt, 4)
    return True


@njit(cache=True)
def gps_raw_int_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, gps, stamp,
                  home_set):
    """GPS_RAW_INT (``GcsLink._build``) of the GNSS sample float64[G_N] at ``gps`` (layout
    G_*), the newest frame's stamp (us) in the int64 cell at ``stamp``: fix as ``_gnss``, vel = ``cm_s_u16`` of the
    horizontal speed, cog = round(deg of atan2(ve, vn) x 100) mod 36000 when fixed and moving
    (else 65535), accuracies as ``_u32`` of mm. Bytes written, or 0: a value the codec would
    refuse, a speed within _ROUND_MARGIN of a cm/s rounding boundary (``math.hypot`` is
    CPython's own algorithm, here a square root, and may differ in the last bit), or a 3D fix
    while home is not set (not ``home_set``: the codec's path sets it, ``GcsLink._gnss``)."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    g = carray(f8p(gps), (G_N,))
    fix = _gnss_fix(g, carray(i8p(stamp), (1,))[0])
    if not home_set and fix >= _FIX_3D:
        return 0
    sats = np.int64(g[G_SATS])
    if fix < 0 or fix > 0xFF or sats < 0 or sats > 0xFF:
        return 0
    vn, ve = g[G_VN], g[G_VE]
    if not (np.isfinite(vn) and np.isfinite(ve)):
        return 0
    moving = vn != 0.0 or ve != 0.0             # hypot(vn, ve) > 0
    vel = np.int64(65535)
    if abs(vn) < 1e6 and abs(ve) < 1e6:         # else above 655.35 m/s anyway: unknown
        x = np.sqrt(vn * vn + ve * ve) * 100.0
        if abs(x - np.floor(x) - 0.5) < _ROUND_MARGIN:
            return 0
        cm = np.int64(np.rint(x))
        if cm < 65535:
            vel = cm
    cog = np.int64(65535)
    if fix and moving:
        x = math.atan2(ve, vn) * _RAD * 100.0
        if abs(x - np.floor(x) - 0.5) < _ROUND_MARGIN:
            return 0                            # (atan2: libm's in both, declined all the same)
        cog = np.int64(np.rint(x)) % 36000
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, time_us, 8)
    if not _put_lat_lon_alt(out, p + 8, g):
        return 0
    _put_u(out, p + 20, 65535, 2)               # eph
    _put_u(out, p + 22, 65535, 2)               # epv
    _put_u(out, p + 24, vel, 2)
    _put_u(out, p + 26, cog, 2)
    out[p + 28] = fix
    out[p + 29] = sats
    _put_u(out, p + 30, 0, 4)                   # alt_ellipsoid
    _put_u(out, p + 34, _u32_field(g[G_HACC_M] * 1000.0), 4)
    _put_u(out, p + 38, _u32_field(g[G_VACC_M] * 1000.0), 4)
    _put_u(out, p + 42, _u32_field(g[G_SACC_M_S] * 1000.0), 4)
    _put_u(out, p + 46, 0, 6)                   # hdg_acc, yaw
    return _frame_at(out, pos, N_GPS, seq, sysid, compid, ID_GPS, X_GPS)


@njit(cache=True)
def global_position_int_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, gps, meas,
                          home):
    """GLOBAL_POSITION_INT (``GcsLink._build``) of the GNSS sample at ``gps``, the heading of
    float64[M_N] ``meas`` and the float64[HOME_N] ``home``: relative_alt = round((alt -
    home alt) x 1000), velocities as ``cm_s_i16``, hdg = round(deg x 100) mod 36000 (65535
    when not finite). Bytes written or 0."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    g = carray(f8p(gps), (G_N,))
    m = carray(f8p(meas), (M_N,))
    h = carray(f8p(home), (HOME_N,))
    hdg = np.int64(65535)
    if np.isfinite(m[M_HEADING]):
        ok, d = _round_i(m[M_HEADING] * _RAD * 100.0)
        if not ok:
            return 0
        hdg = d % 36000
    ok, rel = _round_i((g[G_ALT_M] - h[HOME_ALT_M]) * 1000.0)
    if not ok or rel < _I32_MIN or rel > _I32_MAX:
        return 0
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, (time_us // 1000) % _U32, 4)
    if not _put_lat_lon_alt(out, p + 4, g):
        return 0
    _put_u(out, p + 16, rel, 4)
    _put_u(out, p + 20, _cm_s_i16(g[G_VN]), 2)
    _put_u(out, p + 22, _cm_s_i16(g[G_VE]), 2)
    _put_u(out, p + 24, _cm_s_i16(g[G_VD]), 2)
    _put_u(out, p + 26, hdg, 2)
    return _frame_at(out, pos, N_GPI, seq, sysid, compid, ID_GPI, X_GPI)


@njit(cache=True)
def local_position_ned_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, gps, home):
    """LOCAL_POSITION_NED (``GcsLink._build``, fc/gcs_streams.py ``local_ned``) of the GNSS
    sample at ``gps`` about the float64[HOME_N] ``home`` (its cosine of latitude computed by
    the caller with ``math.cos``); vx, vy, vz the sample's. Bytes written or 0."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    g = carray(f8p(gps), (G_N,))
    h = carray(f8p(home), (HOME_N,))
    a = g[G_LON_DEG] - h[HOME_LON_DEG] + 180.0
    r = np.fmod(a, 360.0)                       # Python's float %: the sign of the divisor
    if r != 0.0:
        if r < 0.0:
            r += 360.0
    else:
        r = 0.0
    dlon = r - 180.0
    x = _EARTH_R * ((g[G_LAT_DEG] - h[HOME_LAT_DEG]) * _RADIAN)
    y = _EARTH_R * h[HOME_COS_LAT] * (dlon * _RADIAN)
    z = -(g[G_ALT_M] - h[HOME_ALT_M])
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    if not _put_ms_six_f32(out, pos + _HDR, time_us, x, y, z, g[G_VN], g[G_VE], g[G_VD]):
        return 0
    return _frame_at(out, pos, N_LPN, seq, sysid, compid, ID_LPN, X_LPN)


@njit(cache=True)
def _bearing_i16(rad):
    """fc/guided.py ``nav_output``'s bearing field: round(deg of ``rad``) mod 360 (half to even),
    as -180..179; (ok, value), not ok when not finite or beyond an int64."""
    if not np.isfinite(rad):
        return False, np.int64(0)
    ok, d = _round_i(rad * _RAD)
    b = d % 360
    return ok, (b if b < 180 else b - 360)


@njit(cache=True)
def nav_output_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, status, tgt, est, has_wp,
                 wp_bearing, wp_dist, wp_xtrack):
    """NAV_CONTROLLER_OUTPUT (fc/guided.py ``nav_output``) from the guidance's status
    float64[GS_N] at ``status``, targets float64[TG_N] at ``tgt`` and the estimate float64[E_N]
    at ``est``: nav_roll = deg of mu_c, nav_pitch = deg of gamma_c + alpha_c, nav_bearing =
    the course target, target_bearing = ``wp_bearing`` (rad) when ``has_wp`` else the course
    target, wp_dist = round(``wp_dist``) clamped to 0..65535 (0 without a waypoint), alt_error
    = altitude target - altitude, aspd_error = the status' V_ref - V, xtrack_error =
    ``wp_xtrack`` (0 without a waypoint). Bytes written or 0 (also when gamma_c and alpha_c
    are both NaN: which NaN their sum gives, its sign, depends on the order the compiler put
    the operands in, CPython's and LLVM's alike)."""
    out = carray(u8p(tx), (FRAME_MAX_B,))
    st = carray(f8p(status), (GS_N,))
    tg = carray(f8p(tgt), (TG_N,))
    e = carray(f8p(est), (E_N,))
    ok, nav_bearing = _bearing_i16(tg[TG_CHI])
    if not ok or (np.isnan(st[GS_GAM_C]) and np.isnan(st[GS_ALPHA_C])):
        return 0            # (two NaNs added: which one comes out is the compiler's choice)
    tb, dist = nav_bearing, np.int64(0)
    xtrack = 0.0
    if has_wp:
        ok, tb = _bearing_i16(wp_bearing)
        if not ok or not np.isfinite(wp_dist):
            return 0
        ok, d = _round_i(wp_dist)
        if not ok:
            return 0
        dist = d if d > 0 else np.int64(0)
        dist = dist if dist < 65535 else np.int64(65535)
        xtrack = wp_xtrack
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    ok = _put_f32(out, p, st[GS_MU_C] * _RAD)
    ok &= _put_f32(out, p + 4, (st[GS_GAM_C] + st[GS_ALPHA_C]) * _RAD)
    ok &= _put_f32(out, p + 8, tg[TG_H] - e[E_H])
    ok &= _put_f32(out, p + 12, st[GS_V_ERR])
    ok &= _put_f32(out, p + 16, xtrack)
    if not ok:
        return 0
    _put_u(out, p + 20, nav_bearing, 2)
    _put_u(out, p + 22, tb, 2)
    _put_u(out, p + 24, dist, 2)
    return _frame_at(out, pos, N_NAV, seq, sysid, compid, ID_NAV, X_NAV)


@njit(cache=True)
def heartbeat_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, custom_mode, mav_type,
                autopilot, base_mode, system_status):
    """HEARTBEAT (``GcsLink._heartbeat``'s fields, mavlink_version 3 as the codec sets it);
    bytes written or 0 (a field beyond its type)."""
    out = carray(u8p(tx), (FRAME_MAX_B,))
    if not (0 <= custom_mode <= 0xFFFFFFFF and 0 <= mav_type <= 0xFF and 0 <= autopilot <= 0xFF
            and 0 <= base_mode <= 0xFF and 0 <= system_status <= 0xFF):
        return 0
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, custom_mode, 4)
    out[p + 4] = mav_type
    out[p + 5] = autopilot
    out[p + 6] = base_mode
    out[p + 7] = system_status
    out[p + 8] = _MAVLINK_VERSION
    return _frame_at(out, pos, N_HB, seq, sysid, compid, ID_HB, X_HB)


@njit(cache=True)
def system_time_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, epoch_us):
    """SYSTEM_TIME (``GcsLink._build``: time_unix_usec = ``epoch_us`` + the time base at
    ``time_at``, time_boot_ms = time base / 1000 mod 2^32); bytes written or 0 (a sum beyond
    u64)."""
    out = carray(u8p(tx), (FRAME_MAX_B,))
    t = carray(i8p(time_at), (1,))[0]
    if t < 0 or epoch_us < 0 or t > 0x7FFFFFFFFFFFFFFF - epoch_us:
        return 0
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, epoch_us + t, 8)
    _put_u(out, p + 8, (t // 1000) % _U32, 4)
    return _frame_at(out, pos, N_TIME, seq, sysid, compid, ID_TIME, X_TIME)


@njit(cache=True)
def extended_sys_state_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, frames, data_lost,
                         meas):
    """EXTENDED_SYS_STATE (``GcsLink._build``, fc/gcs_streams.py ``landed_state``): vtol_state
    UNDEFINED, landed_state IN_AIR when the int64 count at ``frames`` (the plant link's frames)
    is not 0, not ``data_lost`` and the measured airspeed of float64[M_N] ``meas`` is finite and
    above IN_AIR_SPEED_M_S, else UNDEFINED; bytes written."""
    out = carray(u8p(tx), (FRAME_MAX_B,))
    v = carray(f8p(meas), (M_N,))[M_AIRSPEED]
    has_data = carray(i8p(frames), (1,))[0] > 0 and not data_lost
    landed = _IN_AIR if has_data and np.isfinite(v) and v > _IN_AIR_SPEED_M_S else _LANDED_UNDEF
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    out[p] = _VTOL_UNDEF
    out[p + 1] = landed
    return _frame_at(out, pos, N_EXT, seq, sysid, compid, ID_EXT, X_EXT)


@njit(cache=True)
def _payload_u4(out, log_epoch_us, log_t_at, a, na, b, nb, c, nc, d, nd):
    """A payload of up to four unsigned fields (``na`` .. ``nd`` bytes each, 0: none) after the
    .tlog stamp if any (``_stamp_at``); the frame's position, or -1 when a field does not fit
    its bytes (the codec's struct would refuse it)."""
    for v, nb_ in ((a, na), (b, nb), (c, nc), (d, nd)):
        if v < 0 or (nb_ < 8 and v >= (1 << (8 * nb_))):
            return -1
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    for v, nb_ in ((a, na), (b, nb), (c, nc), (d, nd)):
        _put_u(out, p, v, nb_)
        p += nb_
    return pos


@njit(cache=True)
def mission_current_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, item, total, state,
                      mode):
    """MISSION_CURRENT of fc/mission.py ``current_fields`` (seq, total, mission_state,
    mission_mode); bytes written or 0 (a field beyond its type)."""
    out = carray(u8p(tx), (FRAME_MAX_B,))
    pos = _payload_u4(out, log_epoch_us, log_t_at, item, 2, total, 2, state, 1, mode, 1)
    if pos < 0:
        return 0
    return _frame_at(out, pos, N_MC, seq, sysid, compid, ID_MC, X_MC)


@njit(cache=True)
def sys_status_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, law_active, failed_bits, gps,
                 stamp, home_set, load, c0, c1, c2, c3, c4):
    """SYS_STATUS (``GcsLink._build``): sensors SYS_PRESENT, enabled less the law's two when
    not ``law_active``, health = all but ``failed_bits`` and GPS without a 3D fix (the fix of
    the GNSS sample at ``gps`` as ``_gnss`` gives it, the newest frame's stamp in the int64
    cell at ``stamp``), ``load`` (permille), no battery, the error counts ``c0`` .. ``c4``
    saturated at 65535. Bytes written, or 0 (a field beyond its type, or a 3D fix while home
    is not set: the codec's path sets it)."""
    out = carray(u8p(tx), (FRAME_MAX_B,))
    fix = _gnss_fix(carray(f8p(gps), (G_N,)), carray(i8p(stamp), (1,))[0])
    if not home_set and fix >= _FIX_3D:
        return 0
    if not (0 <= load <= 0xFFFF and c0 >= 0 and c1 >= 0 and c2 >= 0 and c3 >= 0 and c4 >= 0
            and 0 <= failed_bits <= 0xFFFFFFFF):
        return 0
    enabled = SYS_PRESENT if law_active else SYS_PRESENT & ~_SYS_LAW
    health = 0xFFFFFFFF & ~failed_bits
    if fix < _FIX_3D:
        health &= ~_SYS_GPS
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, SYS_PRESENT, 4)
    _put_u(out, p + 4, enabled, 4)
    _put_u(out, p + 8, health, 4)
    _put_u(out, p + 12, load, 2)
    _put_u(out, p + 14, 65535, 2)                # voltage_battery: unknown
    _put_u(out, p + 16, -1, 2)                   # current_battery: unknown
    _put_u(out, p + 18, 0, 2)                    # drop_rate_comm
    k = p + 20
    for c in (c0, c1, c2, c3, c4):
        _put_u(out, k, c if c < 65535 else 65535, 2)
        k += 2
    out[k] = 0xFF                                # battery_remaining: -1
    for i in range(k + 1, p + N_SYS):            # the extensions: 0
        out[i] = 0
    return _frame_at(out, pos, N_SYS, seq, sysid, compid, ID_SYS, X_SYS)


@njit(cache=True)
def current_mode_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, standard_mode, custom_mode):
    """CURRENT_MODE (development dialect; ``GcsLink._current_mode``): custom = intended =
    ``custom_mode``; bytes written or 0 (a field beyond its type)."""
    out = carray(u8p(tx), (FRAME_MAX_B,))
    pos = _payload_u4(out, log_epoch_us, log_t_at, custom_mode, 4, custom_mode, 4,
                      standard_mode, 1, 0, 0)
    if pos < 0:
        return 0
    return _frame_at(out, pos, N_CM, seq, sysid, compid, ID_CM, X_CM)


@njit(cache=True)
def home_position_p(tx, log_epoch_us, log_t_at, seq, sysid, compid, time_at, home):
    """HOME_POSITION (``GcsLink._build``) of the float64[HOME_N] ``home``: latitude and
    longitude (degE7) and altitude (mm) rounded as Python's ``round``, position and approach 0,
    q = (1, 0, 0, 0), time_usec the time base in the int64 cell at ``time_at``. Bytes written,
    or 0 (a value the codec's struct would refuse: beyond int32, not finite, a negative time)."""
    time_us = carray(i8p(time_at), (1,))[0]
    out = carray(u8p(tx), (FRAME_MAX_B,))
    h = carray(f8p(home), (HOME_N,))
    ok1, lat = _round_i(h[HOME_LAT_DEG] * 1e7)
    ok2, lon = _round_i(h[HOME_LON_DEG] * 1e7)
    ok3, alt = _round_i(h[HOME_ALT_M] * 1000.0)
    if not (ok1 and ok2 and ok3) or time_us < 0:
        return 0
    for v in (lat, lon, alt):
        if v < _I32_MIN or v > _I32_MAX:
            return 0
    pos = _stamp_at(out, log_epoch_us, log_t_at)
    p = pos + _HDR
    _put_u(out, p, lat & 0xFFFFFFFF, 4)
    _put_u(out, p + 4, lon & 0xFFFFFFFF, 4)
    _put_u(out, p + 8, alt & 0xFFFFFFFF, 4)
    for k in range(10):                 # x, y, z, q[4], approach_x, _y, _z
        _put_f32(out, p + 12 + 4 * k, 1.0 if k == 3 else 0.0)
    _put_u(out, p + 52, time_us, 8)
    return _frame_at(out, pos, N_HOME, seq, sysid, compid, ID_HOME, X_HOME)


#: the .tlog schedule's state (``GcsLink._log_st``, int64[LOG_DUE + n streams]): the last time
#: base seen, the next due time of any stream, each stream's next due time (us); values within
#: +-LOG_SAFE_US only (else Python ints, ``GcsLink._log_big``)
LOG_LAST, LOG_NEXT, LOG_DUE = 0, 1, 2
LOG_SAFE_US = 1 << 62


@njit(cache=True)
def log_walk_p(time_at, st, iv, n, due_flags):
    """``GcsLink._service_log``'s schedule at the time base in the int64 cell at ``time_at``:
    plant time gone back restarts it (every stream due now); the streams due (int64
    ``due_flags[i]`` = 1, stream ``i`` of the n intervals int64[n] at ``iv``, us) are stepped
    to their next due time (the next multiple of the interval, or a whole interval from now
    when behind). Returns how many are due (0 on most frames: nothing to write)."""
    t = carray(i8p(time_at), (1,))[0]
    s = carray(i8p(st), (LOG_DUE + n,))
    step = carray(i8p(iv), (n,))
    flags = carray(i8p(due_flags), (n,))
    if t < s[LOG_LAST]:                     # the plant restarted: the schedule starts over
        for i in range(n):
            s[LOG_DUE + i] = t
        s[LOG_NEXT] = t
    s[LOG_LAST] = t
    if t < s[LOG_NEXT]:
        return 0
    count = 0
    nxt = s[LOG_DUE]
    for i in range(n):
        d = s[LOG_DUE + i]
        flags[i] = 0
        if t >= d:
            flags[i] = 1
            count += 1
            d = d + step[i] if d + step[i] > t else t + step[i]
            s[LOG_DUE + i] = d
        if i == 0 or d < nxt:
            nxt = d
    s[LOG_NEXT] = nxt
    return count


@njit(cache=True)
def send_frame_p(fd, tx, n, dests, n_dests):
    """``n`` bytes at ``tx`` sent on the UDP socket ``fd`` to each of the ``n_dests``
    sockaddr_in at ``dests`` (uint8[n_dests, 16]) with libc ``sendto``; the number of sends
    that failed."""
    failed = 0
    for k in range(n_dests):
        if _sendto(fd, u8p(tx), n, 0, u8p(dests + k * SOCKADDR_IN_B), SOCKADDR_IN_B) < 0:
            failed += 1
    return failed


def sockaddr_in(host: str, port: int) -> np.ndarray | None:
    """``(host, port)`` as sockaddr_in bytes (uint8[16]), or None when ``host`` is not an IPv4
    address (the caller keeps ``socket``'s send for it)."""
    try:
        addr = socket.inet_aton(host)
    except (OSError, TypeError):
        return None
    if socket.inet_ntoa(addr) != host or not 0 <= int(port) <= 0xFFFF:
        return None                     # a name or a short form: socket resolves it
    sa = np.zeros(SOCKADDR_IN_B, np.uint8)
    sa[0:2] = np.frombuffer(socket.AF_INET.to_bytes(2, sys.byteorder), np.uint8)
    sa[2:4] = np.frombuffer(int(port).to_bytes(2, "big"), np.uint8)
    sa[4:8] = np.frombuffer(addr, np.uint8)
    return sa
