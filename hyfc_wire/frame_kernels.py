"""Compiled kernels of the fc's frame path: sensor datagram in, PWM and SERVO_OUTPUT_RAW out.

The per-frame wire work of the controller (docs/performance.md, issue 16) as ``@njit`` kernels
over preallocated buffers, the same bytes and values as the pure-Python lean framing
(``hyfc_wire.framing``) and pymavlink's generated codec:

- :func:`decode_sensor`: the plant's sensor datagram (docs/wire.md section 2, ATTITUDE +
  AOA_SSA + VFR_HUD and at most one GPS_INPUT) as a ``uint8`` array, straight into the
  measurement vector ``M_*``; validates every frame (MAVLink 2 unsigned, length, system id,
  message id, CRC with CRC_EXTRA, each message once) before writing anything, and returns the
  frame stamp or a negative ``REJ_*`` code. It never raises on any input: the caller takes the
  codec's general parser for anything rejected, which does the counting (fc/link.py).
- :func:`pwm_map`: three surface deflections to PWM through docs/wire.md's default map, with
  Python's ``round`` (half to even) exactly as ``hyfc_wire.pwm.deflection_to_pwm``.
- :func:`servo_frame`: SERVO_OUTPUT_RAW (channels 1-4, port 0) framed as the codec does
  (trailing-zero truncation, CRC-16/MCRF4XX with CRC_EXTRA) into a preallocated buffer.

And of the plant's (issue 24: its frame path without the Python framer):

- :func:`sensor_frame`: the plant's sensor datagram framed into a preallocated buffer, the
  bytes of ``hyfc_wire.framing.SensorFramer`` (and so of the codec); returns -1, writing
  nothing the caller uses, for a value the codec's struct would refuse (a non-finite heading,
  throttle or GNSS integer, a finite float beyond float32), so that the caller takes the
  Python framer, which raises as before.
- :func:`decode_servo`: a datagram that is exactly one good unsigned SERVO_OUTPUT_RAW into
  (sysid, time_usec, servo1..4), as ``hyfc_wire.framing.ServoDecoder``; 0 for anything else
  (the caller takes the codec's general parser, which counts).

Message ids, CRC_EXTRA and payload sizes come from the codec's own classes at import; numba
freezes them (and ``layout``'s ``M_*``, ``pwm``'s constants) into the machine code, so this
module's numba cache is dropped at import when any of those modules is newer than it.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

import hyfc_wire.codec as _codec_mod
import hyfc_wire.layout as _layout_mod
import hyfc_wire.pwm as _pwm_mod
from hyfc_wire.codec import mavlink
from hyfc_wire.layout import (M_AIRSPEED, M_ALT, M_AOA, M_CLIMB, M_GROUNDSPEED, M_HEADING, M_P,
                              M_PITCH, M_Q, M_R, M_ROLL, M_SSA, M_T_S, M_YAW)
from hyfc_wire.numba_cache import drop_stale
from hyfc_wire.pwm import (DEFLECTION_LIMIT_RAD, PWM_MAX_US, PWM_MIN_US, PWM_TRIM_US,
                           THROTTLE_PWM_MAX_US, THROTTLE_PWM_MIN_US)

drop_stale(__file__, [_codec_mod.__file__, _layout_mod.__file__, _pwm_mod.__file__])

__all__ = ["decode_sensor", "pwm_map", "surfaces_pwm", "throttle_pwm", "servo_frame", "crc16_range", "REJ_FORMAT",
           "REJ_LENGTH", "REJ_SYSID", "REJ_MSGID", "REJ_REPEAT", "REJ_CRC", "REJ_INCOMPLETE",
           "REJ_STAMP", "REJ_NAMES", "GR_PRESENT", "GR_LAT_E7", "GR_LON_E7", "GR_ALT_M",
           "GR_VN", "GR_VE", "GR_VD", "GR_FIX", "GR_SATS", "GR_HACC_M", "GR_VACC_M",
           "GR_SACC_M_S", "GR_N", "SERVO_FRAME_MAX_B", "sensor_frame", "decode_servo",
           "SENSOR_FRAME_MAX_B", "SV_SYSID", "SV_TIME_USEC", "SV_SERVO1", "SV_N"]

# ---- rejection codes of decode_sensor (negative; a stamp is >= 0)
REJ_FORMAT = -1        # not MAVLink 2, signed or incompatible flags, or shorter than a frame
REJ_LENGTH = -2        # a frame runs past the datagram, or its payload is longer than defined
REJ_SYSID = -3         # a frame from another system than the plant
REJ_MSGID = -4         # a message that is not one of the sensor datagram's four
REJ_REPEAT = -5        # a message twice in one datagram
REJ_CRC = -6           # CRC (with CRC_EXTRA) does not match
REJ_INCOMPLETE = -7    # ATTITUDE, AOA_SSA or VFR_HUD missing
REJ_STAMP = -8         # AOA_SSA.time_usec beyond 2^63 - 1 (not representable as a stamp)
REJ_NAMES = {REJ_FORMAT: "format", REJ_LENGTH: "length", REJ_SYSID: "sysid",
             REJ_MSGID: "msgid", REJ_REPEAT: "repeat", REJ_CRC: "crc",
             REJ_INCOMPLETE: "incomplete", REJ_STAMP: "stamp"}

# ---- the raw GPS_INPUT fields decode_sensor writes (float64[GR_N]; GR_PRESENT 0 = none)
GR_PRESENT = 0
GR_LAT_E7 = 1          # degE7 (an int32, exact in float64)
GR_LON_E7 = 2          # degE7
GR_ALT_M = 3           # m MSL
GR_VN = 4              # m/s NED
GR_VE = 5
GR_VD = 6
GR_FIX = 7             # fix_type
GR_SATS = 8            # satellites_visible
GR_HACC_M = 9
GR_VACC_M = 10
GR_SACC_M_S = 11
GR_N = 12

_MAGIC2 = mavlink.PROTOCOL_MARKER_V2
_HDR = 10
_ATT = mavlink.MAVLink_attitude_message
_AOA = mavlink.MAVLink_aoa_ssa_message
_HUD = mavlink.MAVLink_vfr_hud_message
_GPS = mavlink.MAVLink_gps_input_message
_SERVO = mavlink.MAVLink_servo_output_raw_message
ID_ATT, ID_AOA, ID_HUD, ID_GPS, ID_SERVO = _ATT.id, _AOA.id, _HUD.id, _GPS.id, _SERVO.id
X_ATT, X_AOA, X_HUD, X_GPS, X_SERVO = (_ATT.crc_extra, _AOA.crc_extra, _HUD.crc_extra,
                                       _GPS.crc_extra, _SERVO.crc_extra)
N_ATT, N_AOA, N_HUD, N_GPS, N_SERVO = (_ATT.unpacker.size, _AOA.unpacker.size,
                                       _HUD.unpacker.size, _GPS.unpacker.size,
                                       _SERVO.unpacker.size)
#: the longest SERVO_OUTPUT_RAW frame (header, full payload, CRC), bytes
SERVO_FRAME_MAX_B = _HDR + N_SERVO + 2
_DEG2RAD = math.pi / 180.0     # what CPython's math.radians multiplies by
_RAD = 180.0 / math.pi         # hyfc_wire.framing.RAD: rad -> deg as the Python framer does
#: the longest sensor datagram (the four frames untruncated), bytes
SENSOR_FRAME_MAX_B = 4 * (_HDR + 2) + N_ATT + N_AOA + N_HUD + N_GPS
_GPS_HDOP = 1.0                # hyfc_wire.framing.GPS_HDOP
_F32_MAX = 3.4028234663852886e38
_U32 = 1 << 32
# decode_servo's output record (int64[SV_N])
SV_SYSID = 0
SV_TIME_USEC = 1
SV_SERVO1 = 2          # servo1..4 at SV_SERVO1 .. SV_SERVO1 + 3
SV_N = 6

# Payload offsets (wire order, little endian), checked against the codec's structs in
# tests/unit/wire/test_frame_kernels.py: ATTITUDE <Iffffff, AOA_SSA <Qff, VFR_HUD <ffffhH,
# GPS_INPUT <QIiifffffffffHHBBBH, SERVO_OUTPUT_RAW <IHHHHHHHHBHHHHHHHH.


def _crc_table() -> np.ndarray:
    """CRC-16/MCRF4XX of each byte value from 0 (the reflected polynomial 0x8408)."""
    t = np.zeros(256, np.int64)
    for b in range(256):
        c = b
        for _ in range(8):
            c = (c >> 1) ^ 0x8408 if c & 1 else c >> 1
        t[b] = c
    return t


_CRC_TABLE = _crc_table()


@njit(cache=True)
def crc16_range(buf, start, end, crc):
    """CRC-16/MCRF4XX (X.25, the codec's) of ``buf[start:end]`` continuing from ``crc``."""
    for i in range(start, end):
        crc = (crc >> 8) ^ _CRC_TABLE[(crc ^ np.int64(buf[i])) & 0xFF]
    return crc


@njit(cache=True)
def _crc_byte(b, crc):
    return (crc >> 8) ^ _CRC_TABLE[(crc ^ b) & 0xFF]


@njit(cache=True)
def _u8(buf, off, mlen, i):
    """Payload byte ``i`` of a frame whose payload starts at ``off``, ``mlen`` bytes long: the
    codec zero-fills a truncated payload."""
    return np.int64(buf[off + i]) if i < mlen else np.int64(0)


@njit(cache=True)
def _uint(buf, off, mlen, i, nb):
    v = np.uint64(0)
    for k in range(nb):
        v |= np.uint64(_u8(buf, off, mlen, i + k)) << np.uint64(8 * k)
    return v


@njit(cache=True)
def _f32(buf, off, mlen, i):
    """float32 field at payload offset ``i``, as float64."""
    return np.float64(np.uint32(_uint(buf, off, mlen, i, 4)).view(np.float32))


@njit(cache=True)
def _i32(buf, off, mlen, i):
    v = np.int64(_uint(buf, off, mlen, i, 4))
    return v - (np.int64(1) << 32) if v >= (np.int64(1) << 31) else v


@njit(cache=True)
def decode_sensor(buf, n, plant_sysid, meas_out, gps_out):
    """Decode the sensor datagram ``buf[:n]`` (uint8) from ``plant_sysid`` into ``meas_out``
    (float64[M_N], SI) and ``gps_out`` (float64[GR_N], raw GPS_INPUT fields, GR_PRESENT 0.0
    when the datagram has none). Returns the frame stamp (AOA_SSA.time_usec, us) or a
    ``REJ_*`` code (< 0), in which case neither output was written."""
    # each message's payload offset and length: scalars, not arrays (an array made here would
    # be a numba runtime record per call, issue 24)
    off0 = off1 = off2 = off3 = np.int64(0)
    ln0 = ln1 = ln2 = ln3 = np.int64(0)
    seen = 0
    pos = 0
    while pos < n:
        if n - pos < _HDR + 2 or buf[pos] != _MAGIC2 or buf[pos + 2] != 0:
            return REJ_FORMAT
        mlen = np.int64(buf[pos + 1])
        end = pos + _HDR + mlen
        if end + 2 > n:
            return REJ_LENGTH
        if buf[pos + 5] != plant_sysid:
            return REJ_SYSID
        mid = (np.int64(buf[pos + 7]) | (np.int64(buf[pos + 8]) << 8)
               | (np.int64(buf[pos + 9]) << 16))
        if mid == ID_ATT:
            slot, size, extra = 0, N_ATT, X_ATT
        elif mid == ID_AOA:
            slot, size, extra = 1, N_AOA, X_AOA
        elif mid == ID_HUD:
            slot, size, extra = 2, N_HUD, X_HUD
        elif mid == ID_GPS:
            slot, size, extra = 3, N_GPS, X_GPS
        else:
            return REJ_MSGID
        if mlen > size:
            return REJ_LENGTH
        if seen & (1 << slot):
            return REJ_REPEAT
        crc = _crc_byte(extra, crc16_range(buf, pos + 1, end, 0xFFFF))
        if crc != (np.int64(buf[end]) | (np.int64(buf[end + 1]) << 8)):
            return REJ_CRC
        if slot == 0:
            off0, ln0 = np.int64(pos + _HDR), mlen
        elif slot == 1:
            off1, ln1 = np.int64(pos + _HDR), mlen
        elif slot == 2:
            off2, ln2 = np.int64(pos + _HDR), mlen
        else:
            off3, ln3 = np.int64(pos + _HDR), mlen
        seen |= 1 << slot
        pos = end + 2
    if seen & 7 != 7:
        return REJ_INCOMPLETE
    o, m = off1, ln1
    stamp_u = _uint(buf, o, m, 0, 8)                 # AOA_SSA.time_usec
    if stamp_u > np.uint64(0x7FFFFFFFFFFFFFFF):
        return REJ_STAMP
    stamp = np.int64(stamp_u)
    aoa_deg = _f32(buf, o, m, 8)
    ssa_deg = _f32(buf, o, m, 12)
    o, m = off0, ln0                                 # ATTITUDE
    meas_out[M_T_S] = stamp * 1e-6
    meas_out[M_ROLL] = _f32(buf, o, m, 4)
    meas_out[M_PITCH] = _f32(buf, o, m, 8)
    meas_out[M_YAW] = _f32(buf, o, m, 12)
    meas_out[M_P] = _f32(buf, o, m, 16)
    meas_out[M_Q] = _f32(buf, o, m, 20)
    meas_out[M_R] = _f32(buf, o, m, 24)
    meas_out[M_AOA] = aoa_deg * _DEG2RAD
    meas_out[M_SSA] = ssa_deg * _DEG2RAD
    o, m = off2, ln2                                 # VFR_HUD
    meas_out[M_AIRSPEED] = _f32(buf, o, m, 0)
    meas_out[M_GROUNDSPEED] = _f32(buf, o, m, 4)
    meas_out[M_ALT] = _f32(buf, o, m, 8)
    meas_out[M_CLIMB] = _f32(buf, o, m, 12)
    hdg = np.int64(_uint(buf, o, m, 16, 2))
    if hdg >= 32768:                                 # int16
        hdg -= 65536
    meas_out[M_HEADING] = np.float64(hdg) * _DEG2RAD
    if seen & 8:
        o, m = off3, ln3                             # GPS_INPUT
        gps_out[GR_PRESENT] = 1.0
        gps_out[GR_LAT_E7] = np.float64(_i32(buf, o, m, 12))
        gps_out[GR_LON_E7] = np.float64(_i32(buf, o, m, 16))
        gps_out[GR_ALT_M] = _f32(buf, o, m, 20)
        gps_out[GR_VN] = _f32(buf, o, m, 32)
        gps_out[GR_VE] = _f32(buf, o, m, 36)
        gps_out[GR_VD] = _f32(buf, o, m, 40)
        gps_out[GR_SACC_M_S] = _f32(buf, o, m, 44)
        gps_out[GR_HACC_M] = _f32(buf, o, m, 48)
        gps_out[GR_VACC_M] = _f32(buf, o, m, 52)
        gps_out[GR_FIX] = np.float64(_u8(buf, o, m, 61))
        gps_out[GR_SATS] = np.float64(_u8(buf, o, m, 62))
    else:
        gps_out[GR_PRESENT] = 0.0
    return stamp


@njit(cache=True)
def _to_pwm(rad):
    """``hyfc_wire.pwm.DEFAULT_PWM.to_pwm``: the same operations in the same order, rounded
    half to even (Python's ``round``), clipped in floating point first (no integer overflow)."""
    if not math.isfinite(rad):
        return PWM_TRIM_US
    if rad >= 0.0:
        us = PWM_TRIM_US + rad / DEFLECTION_LIMIT_RAD * (PWM_MAX_US - PWM_TRIM_US)
    else:
        us = PWM_TRIM_US + rad / DEFLECTION_LIMIT_RAD * (PWM_TRIM_US - PWM_MIN_US)
    r = np.rint(us)
    if r < PWM_MIN_US:
        return PWM_MIN_US
    if r > PWM_MAX_US:
        return PWM_MAX_US
    return np.int64(r)


@njit(cache=True)
def pwm_map(delta_rad, throttle_pwm_us, pwm_out):
    """Surfaces ``delta_rad`` (float64[3], rad: left, right, rudder) to ``pwm_out[0:3]`` (us,
    docs/wire.md's default map) and ``throttle_pwm_us`` (servo4, 0 = no output) to
    ``pwm_out[3]`` (int64[4])."""
    pwm_out[0] = _to_pwm(delta_rad[0])
    pwm_out[1] = _to_pwm(delta_rad[1])
    pwm_out[2] = _to_pwm(delta_rad[2])
    pwm_out[3] = throttle_pwm_us


@njit(cache=True)
def throttle_pwm(throttle):
    """``hyfc_wire.pwm.throttle_to_pwm``: the same operations, rounded half to even (Python's
    ``round``), clipped in floating point first (no integer overflow); 0 if not finite."""
    if not math.isfinite(throttle):
        return 0
    r = np.rint(THROTTLE_PWM_MIN_US + throttle * (THROTTLE_PWM_MAX_US - THROTTLE_PWM_MIN_US))
    if r < THROTTLE_PWM_MIN_US:
        return THROTTLE_PWM_MIN_US
    if r > THROTTLE_PWM_MAX_US:
        return THROTTLE_PWM_MAX_US
    return np.int64(r)


@njit(cache=True)
def surfaces_pwm(src_rad, delta_out, throttle_pwm_us, pwm_out):
    """The fast tick's output in one call: ``delta_out[0:3] = src_rad[0:3]`` (the surface
    command, rad; ``src_rad`` may be ``delta_out`` itself) and :func:`pwm_map` of it."""
    for i in range(3):
        delta_out[i] = src_rad[i]
    pwm_map(delta_out, throttle_pwm_us, pwm_out)


@njit(cache=True)
def _frame_at(out, pos, size, seq, sysid, compid, msg_id, crc_extra):
    """Header, trailing-zero truncation and CRC of the frame whose full ``size``-byte payload is
    at ``out[pos + 10:]``, as the codec frames it; returns the position after the frame (the
    fc's SERVO_OUTPUT_RAW and the plant's sensor datagram)."""
    p = pos + _HDR
    n = size
    while n > 1 and out[p + n - 1] == 0:
        n -= 1
    out[pos] = _MAGIC2
    out[pos + 1] = n
    out[pos + 2] = 0
    out[pos + 3] = 0
    out[pos + 4] = seq & 0xFF
    out[pos + 5] = sysid & 0xFF
    out[pos + 6] = compid & 0xFF
    out[pos + 7] = msg_id & 0xFF
    out[pos + 8] = (msg_id >> 8) & 0xFF
    out[pos + 9] = msg_id >> 16
    end = p + n
    crc = _crc_byte(crc_extra, crc16_range(out, pos + 1, end, 0xFFFF))
    out[end] = crc & 0xFF
    out[end + 1] = crc >> 8
    return end + 2


@njit(cache=True)
def servo_frame(out, seq, sysid, compid, time_usec, pwm_us):
    """SERVO_OUTPUT_RAW (``time_usec`` u32, servo1..4 = ``pwm_us[0:4]``, port 0, the other
    channels 0) framed at the start of ``out`` (uint8, at least SERVO_FRAME_MAX_B) as
    ``sysid``/``compid`` with sequence ``seq``; returns the frame's length in bytes."""
    p = _HDR
    t = np.int64(time_usec) & 0xFFFFFFFF
    for k in range(4):
        out[p + k] = (t >> (8 * k)) & 0xFF
    for c in range(4):
        v = np.int64(pwm_us[c]) & 0xFFFF
        out[p + 4 + 2 * c] = v & 0xFF
        out[p + 5 + 2 * c] = v >> 8
    for i in range(p + 12, p + N_SERVO):            # servo5..8, port, servo9..16
        out[i] = 0
    return _frame_at(out, 0, N_SERVO, seq, sysid, compid, ID_SERVO, X_SERVO)


# ---------------------------------------------------------------- the plant's frame path
@njit(cache=True)
def _put_u(out, i, v, nb):
    """``nb`` little-endian bytes of the non-negative integer ``v`` at ``out[i:]``."""
    for k in range(nb):
        out[i + k] = (v >> (8 * k)) & 0xFF


@njit(cache=True)
def _put_f32(out, i, x):
    """float32 of ``x`` (round to nearest, as struct's 'f') at ``out[i:i + 4]``; False if the
    struct would refuse it (finite and beyond float32)."""
    if math.isfinite(x) and abs(x) > _F32_MAX and not math.isfinite(np.float64(np.float32(x))):
        return False
    _put_u(out, i, np.int64(np.float32(x).view(np.uint32)), 4)
    return True


@njit(cache=True)
def _int_field(x, lo, hi):
    """``int(x)`` (toward zero) if finite and in [lo, hi], else None-like: (False, 0)."""
    if not math.isfinite(x):
        return False, np.int64(0)
    v = np.int64(x)
    if v < lo or v > hi:
        return False, np.int64(0)
    return True, v


@njit(cache=True)
def sensor_frame(out, seq, sysid, compid, stamp_us, meas, throttle_pct, gnss, with_gnss):
    """The plant's sensor datagram (ATTITUDE, AOA_SSA, VFR_HUD and, if ``with_gnss``,
    GPS_INPUT from ``gnss``, float64[G_N]) framed at the start of ``out`` (uint8, at least
    SENSOR_FRAME_MAX_B) with sequence numbers ``seq``, ``seq + 1``, ... (mod 256); ``meas``
    float64[M_N] (SI), ``throttle_pct`` 0..100, ``stamp_us`` >= 0. Returns the length in bytes,
    or -1 for a value the codec's struct would refuse (see the module's docstring)."""
    ok = True
    # ATTITUDE <Iffffff
    p = _HDR
    _put_u(out, p, (np.int64(stamp_us) // 1000) % _U32, 4)
    ok &= _put_f32(out, p + 4, meas[M_ROLL])
    ok &= _put_f32(out, p + 8, meas[M_PITCH])
    ok &= _put_f32(out, p + 12, meas[M_YAW])
    ok &= _put_f32(out, p + 16, meas[M_P])
    ok &= _put_f32(out, p + 20, meas[M_Q])
    ok &= _put_f32(out, p + 24, meas[M_R])
    pos = _frame_at(out, 0, N_ATT, seq, sysid, compid, ID_ATT, X_ATT)
    # AOA_SSA <Qff
    p = pos + _HDR
    _put_u(out, p, np.int64(stamp_us), 8)
    ok &= _put_f32(out, p + 8, meas[M_AOA] * _RAD)
    ok &= _put_f32(out, p + 12, meas[M_SSA] * _RAD)
    pos = _frame_at(out, pos, N_AOA, seq + 1, sysid, compid, ID_AOA, X_AOA)
    # VFR_HUD <ffffhH: airspeed, groundspeed, alt, climb, heading, throttle
    p = pos + _HDR
    ok &= _put_f32(out, p, meas[M_AIRSPEED])
    ok &= _put_f32(out, p + 4, meas[M_GROUNDSPEED])
    ok &= _put_f32(out, p + 8, meas[M_ALT])
    ok &= _put_f32(out, p + 12, meas[M_CLIMB])
    good, hdg = _int_field(meas[M_HEADING] * _RAD + 0.5, -(np.int64(1) << 62), np.int64(1) << 62)
    ok &= good
    hdg = hdg % 360
    thr_x = throttle_pct
    if not math.isfinite(thr_x):
        ok = False
        thr_x = 0.0
    good, thr = _int_field(min(100.0, max(0.0, thr_x)) + 0.5, 0, 0xFFFF)
    ok &= good
    _put_u(out, p + 16, hdg, 2)
    _put_u(out, p + 18, thr, 2)
    pos = _frame_at(out, pos, N_HUD, seq + 2, sysid, compid, ID_HUD, X_HUD)
    if with_gnss:
        # GPS_INPUT <QIiifffffffffHHBBBH: time_usec, time_week_ms, lat, lon, alt, hdop, vdop,
        # vn, ve, vd, speed_accuracy, horiz_accuracy, vert_accuracy, ignore_flags, time_week,
        # gps_id, fix_type, satellites_visible, yaw (gnss: the G_* layout, as SensorFramer)
        p = pos + _HDR
        _put_u(out, p, np.int64(stamp_us), 8)
        _put_u(out, p + 8, 0, 4)
        for j in range(2):
            x = gnss[1 + j] * 1e7
            if not math.isfinite(x):
                ok = False
                x = 0.0
            good, v = _int_field(np.rint(x), -(np.int64(1) << 31), (np.int64(1) << 31) - 1)
            ok &= good
            _put_u(out, p + 12 + 4 * j, v & 0xFFFFFFFF, 4)
        ok &= _put_f32(out, p + 20, gnss[3])
        ok &= _put_f32(out, p + 24, _GPS_HDOP)
        ok &= _put_f32(out, p + 28, _GPS_HDOP)
        ok &= _put_f32(out, p + 32, gnss[4])
        ok &= _put_f32(out, p + 36, gnss[5])
        ok &= _put_f32(out, p + 40, gnss[6])
        ok &= _put_f32(out, p + 44, gnss[11])
        ok &= _put_f32(out, p + 48, gnss[9])
        ok &= _put_f32(out, p + 52, gnss[10])
        _put_u(out, p + 56, 0, 2)          # ignore_flags
        _put_u(out, p + 58, 0, 2)          # time_week
        out[p + 60] = 0                    # gps_id
        good, fix = _int_field(gnss[7], 0, 255)
        ok &= good
        good, sats = _int_field(gnss[8], 0, 255)
        ok &= good
        out[p + 61] = fix
        out[p + 62] = sats
        _put_u(out, p + 63, 0, 2)          # yaw
        pos = _frame_at(out, pos, N_GPS, seq + 3, sysid, compid, ID_GPS, X_GPS)
    return pos if ok else -1


@njit(cache=True)
def decode_servo(buf, n, out):
    """``buf[:n]`` (uint8) as one unsigned MAVLink 2 SERVO_OUTPUT_RAW with a good CRC: writes
    sysid, time_usec, servo1..4 into ``out`` (int64[SV_N]) and returns 1; anything else returns
    0 without writing (``hyfc_wire.framing.ServoDecoder.decode``'s acceptance)."""
    if n < _HDR + 3 or buf[0] != _MAGIC2 or buf[2] != 0:
        return 0
    mlen = np.int64(buf[1])
    if n != _HDR + mlen + 2 or mlen > N_SERVO:
        return 0
    if buf[7] != (ID_SERVO & 0xFF) or buf[8] != 0 or buf[9] != 0:
        return 0
    end = _HDR + mlen
    crc = _crc_byte(X_SERVO, crc16_range(buf, 1, end, 0xFFFF))
    if crc != (np.int64(buf[end]) | (np.int64(buf[end + 1]) << 8)):
        return 0
    out[SV_SYSID] = buf[5]
    out[SV_TIME_USEC] = np.int64(_uint(buf, _HDR, mlen, 0, 4))
    for c in range(4):
        out[SV_SERVO1 + c] = np.int64(_uint(buf, _HDR, mlen, 4 + 2 * c, 2))
    return 1
