"""fc/gcs_frames.py: the compiled stream frames are the codec's bytes for the same values.

Each kernel against ``GcsLink._build``'s message for the same state, packed by the codec (as
the ground-station link sends it) and with the .tlog's stamp (as ``_tlog_write`` writes it);
a value the codec refuses makes the kernel return 0.
"""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fc import gcs_frames as F
from fc.control.carrays import address_of
from hyfc_wire.codec import new_codec
from hyfc_wire.layout import (M_AIRSPEED, M_ALT, M_AOA, M_CLIMB, M_GROUNDSPEED, M_HEADING, M_N,
                              M_P, M_PITCH, M_Q, M_R, M_ROLL, M_SSA, M_YAW)

SYSID, COMPID = 1, 1
EPOCH_US = 1_764_000_000_000_000
finite = st.floats(-1e6, 1e6, allow_nan=False)
any_float = st.floats(allow_nan=True, allow_infinity=True)
stamps = st.integers(0, 2**62)


_T = np.zeros(1, np.int64)
_T_P = address_of(_T, np.int64, 1)


def _at(us):
    """The time base ``us`` in an int64 cell (the kernels read it there): its address."""
    _T[0] = us
    return _T_P


_LT = np.zeros(1, np.int64)
_LT_P = address_of(_LT, np.int64, 1)


def _lt(us):
    """The .tlog's time base ``us`` in an int64 cell: its address."""
    _LT[0] = us
    return _LT_P


class Buf:
    def __init__(self):
        self.a = np.zeros(F.FRAME_MAX_B, np.uint8)
        self.p = address_of(self.a, np.uint8, F.FRAME_MAX_B)

    def bytes(self, n):
        return bytes(self.a[:n])


def _codec(seq):
    c = new_codec(SYSID, COMPID)
    c.seq = seq
    return c


def _want(msg, seq, t_us=None):
    """The codec's frame (None if it refuses the values), with the .tlog stamp if ``t_us``."""
    try:
        frame = msg.pack(_codec(seq))
    except (struct.error, ValueError, OverflowError):
        return None
    return frame if t_us is None else struct.pack(">Q", EPOCH_US + t_us) + frame


def _check(got_n, buf, want, may_decline=False):
    """0 where the codec refuses the values; else its bytes (or 0 where ``may_decline``: the
    caller then takes the codec's path, which gives them)."""
    if want is None or (may_decline and got_n == 0):
        assert got_n == 0
    else:
        assert buf.bytes(got_n) == want


@settings(max_examples=200, deadline=None)
@given(vals=st.lists(st.one_of(finite, any_float), min_size=M_N, max_size=M_N),
       us=stamps, seq=st.integers(0, 255), log=st.booleans(),
       thr=st.integers(0, 100))
def test_state_messages_are_the_codecs(vals, us, seq, log, thr):
    # GIVEN a measurement vector (any floats, also non-finite and beyond float32)
    meas = np.array(vals, np.float64)
    mp = address_of(meas, np.float64, M_N)
    b = Buf()
    c = _codec(seq)
    t_us = us if log else None
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    ms = (us // 1000) & 0xFFFFFFFF
    # THEN ATTITUDE, AOA_SSA and VFR_HUD are the codec's frames of _build's values
    m = meas
    _check(F.attitude_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), mp), b,
           _want(c.attitude_encode(ms, m[M_ROLL], m[M_PITCH], m[M_YAW], m[M_P], m[M_Q], m[M_R]),
                 seq, t_us))
    _check(F.aoa_ssa_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), mp), b,
           _want(c.aoa_ssa_encode(us, math.degrees(m[M_AOA]), math.degrees(m[M_SSA])), seq, t_us))
    deg = math.degrees(m[M_HEADING])
    if math.isfinite(m[M_HEADING]) and not math.isfinite(deg):
        # (_build raises here: round() of an infinite float; the kernel declines)
        assert F.vfr_hud_p(b.p, ep, tl, seq, SYSID, COMPID, mp, thr) == 0
        return
    hdg = int(round(deg)) % 360 if math.isfinite(m[M_HEADING]) else 0
    _check(F.vfr_hud_p(b.p, ep, tl, seq, SYSID, COMPID, mp, thr), b,
           _want(c.vfr_hud_encode(m[M_AIRSPEED], m[M_GROUNDSPEED], hdg, thr, m[M_ALT],
                                  m[M_CLIMB]), seq, t_us),
           may_decline=abs(math.degrees(m[M_HEADING])) > 2.0 ** 62)


@pytest.mark.parametrize("heading_deg", [-0.5, 0.5, 1.5, 2.5, -1.5, 359.5, -359.5, 719.5,
                                         -180.0, 1e15])
def test_vfr_hud_heading_rounds_as_python(heading_deg):
    # GIVEN headings on the rounding boundaries and far beyond a turn
    meas = np.zeros(M_N)
    meas[M_HEADING] = math.radians(heading_deg)
    b = Buf()
    n = F.vfr_hud_p(b.p, -1, 0, 3, SYSID, COMPID, address_of(meas, np.float64, M_N), 55)
    hdg = int(round(math.degrees(meas[M_HEADING]))) % 360
    # THEN the heading field is Python's round half to even, mod 360
    assert b.bytes(n) == _want(_codec(3).vfr_hud_encode(0.0, 0.0, hdg, 55, 0.0, 0.0), 3)


@settings(max_examples=100, deadline=None)
@given(pwm=st.lists(st.integers(-5, 70000), min_size=4, max_size=4), us=stamps,
       seq=st.integers(0, 255), log=st.booleans())
def test_servo_output_raw_is_the_codecs(pwm, us, seq, log):
    p = np.array(pwm, np.int64)
    b = Buf()
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    n = F.servo_raw_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), address_of(p, np.int64, 4))
    want = _want(_codec(seq).servo_output_raw_encode(us & 0xFFFFFFFF, 0, *pwm, 0, 0, 0, 0), seq,
                 us if log else None)
    _check(n, b, want)


@settings(max_examples=200, deadline=None)
@given(v=st.lists(st.one_of(finite, any_float), min_size=3, max_size=3), us=stamps,
       seq=st.integers(0, 255), which=st.integers(0, len(F.DV_NAMES) - 1),
       deg=st.booleans(), by_address=st.booleans(), log=st.booleans())
def test_debug_vect_is_the_codecs(v, us, seq, which, deg, by_address, log):
    src = np.array(v, np.float64)
    b = Buf()
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    if by_address:
        n = F.debug_vect_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), which,
                           address_of(src, np.float64, 3), deg, 0.0, 0.0, 0.0)
        xyz = [math.degrees(x) for x in src] if deg else list(src)
    else:
        n = F.debug_vect_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), which, 0, False, *v)
        xyz = v
    want = _want(_codec(seq).debug_vect_encode(F.DV_NAMES[which], us, *xyz), seq,
                 us if log else None)
    _check(n, b, want)


def test_sockaddr_in_only_for_ipv4_literals():
    assert F.sockaddr_in("127.0.0.1", 14550) is not None
    assert F.sockaddr_in("localhost", 14550) is None
    assert F.sockaddr_in("::1", 14550) is None


@pytest.mark.parametrize("frames", [0, 1, 5000])
def test_sim_t_is_nan_before_the_first_frame(frames):
    hot = np.array([frames], np.int64)
    stamp = np.array([2_000_000], np.int64)           # the newest frame's stamp cell (us)
    b = Buf()
    n = F.sim_t_p(b.p, -1, 0, 7, SYSID, COMPID, _at(2_000_000), address_of(stamp, np.int64, 1),
                  address_of(hot, np.int64, 1))
    t = 2.0 if frames else math.nan
    assert b.bytes(n) == _want(_codec(7).debug_vect_encode(b"SIM_T", 2_000_000, t, 0.0, 0.0), 7)


def _vehicle_frames(data: bytes, skip=(1, 251)) -> list[bytes]:
    """The MAVLink 2 frames of a datagram or of .tlog bytes (``stamped``: an 8-byte stamp
    before each), less SYS_STATUS and NAMED_VALUE_FLOAT (their load and timing fields are
    measured on the wall clock)."""
    out, i = [], 0
    while i < len(data):
        n = data[i + 1]
        f = data[i:i + 12 + n + (13 if data[i + 2] & 1 else 0)]
        i += len(f)
        if f[7] | (f[8] << 8) | (f[9] << 16) not in skip:
            out.append(f)
    return out


def _unstamp(tlog: bytes) -> bytes:
    out, i = bytearray(), 0
    while i < len(tlog):
        i += 8
        n = 12 + tlog[i + 1] + (13 if tlog[i + 2] & 1 else 0)
        out += tlog[i:i + n]
        i += n
    return bytes(out)


@pytest.mark.parametrize("mode", ["COORDINATED", "CRUISE"])
def test_a_flight_streams_the_codecs_bytes(mode, monkeypatch):
    # GIVEN a recorded flight replayed twice into a fresh controller (the loop clock the sensor
    # time, tools/bench/allocs.py), once with the compiled stream framing and once with the
    # codec's (``fast`` False), the .tlog kept in memory with the same epoch
    from tools.bench import allocs
    from tools.bench.profile import record
    flight = record(allocs.WARM_FRAMES + 1300, mode)
    runs = []
    for fast in (True, False):
        rep = allocs._Replay(flight, mode)
        try:
            gcs = rep.rig.fc.gcs
            gcs.epoch_us = EPOCH_US
            monkeypatch.setattr(gcs, "flush", lambda: None)
            if not fast:
                gcs.fast = False
            sent = []
            for _ in range(len(flight)):
                rep.step(rep.feed())
                while True:
                    try:
                        sent += _vehicle_frames(rep.rig.sink.recv(65536))
                    except BlockingIOError:
                        break
                rep.rig.plant.setblocking(False)
                while True:
                    try:
                        rep.rig.plant.recv(65536)
                    except BlockingIOError:
                        break
            assert gcs.fast is fast
            runs.append((sent, _vehicle_frames(_unstamp(bytes(gcs._tlog_buf)))))
        finally:
            rep.close()
    # THEN the ground station received the same frames, and the .tlog holds the same ones
    (sent_fast, log_fast), (sent_codec, log_codec) = runs
    assert len(sent_fast) > 200 and len(log_fast) > 200
    assert sent_fast == sent_codec
    assert log_fast == log_codec


@settings(max_examples=150, deadline=None)
@given(values=st.lists(st.one_of(finite, any_float), min_size=1, max_size=6),
       names=st.lists(st.binary(min_size=1, max_size=10).filter(lambda b: b[-1:] != b"\0"),
                      min_size=6, max_size=6),
       us=stamps, seq=st.integers(0, 255), log=st.booleans(), data=st.data())
def test_named_value_float_is_the_codecs(values, names, us, seq, log, data):
    # GIVEN a name table (zero-padded rows) and values, as fc/telemetry.py keeps them
    n = len(values)
    table = np.zeros((n, F.NV_NAME_B), np.uint8)
    for i in range(n):
        table[i, :len(names[i])] = np.frombuffer(names[i], np.uint8)
    vals = np.array(values, np.float64)
    k = data.draw(st.integers(0, n - 1))
    b = Buf()
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    got = F.named_value_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us),
                          address_of(table, np.uint8, table.size), address_of(vals, np.float64, n),
                          k)
    # THEN the frame is the codec's NAMED_VALUE_FLOAT (time_boot_ms of the time base)
    want = _want(_codec(seq).named_value_float_encode((us // 1000) & 0xFFFFFFFF, names[k],
                                                      values[k]), seq, us if log else None)
    _check(got, b, want)


@pytest.mark.parametrize("timing", ["lockstep", "realtime"])
def test_the_compiled_framing_is_taken_in_both_timing_modes(tmp_path, timing):
    # GIVEN a controller built as python -m fc builds it, in each timing mode (real time: the
    # time base moves on between two reads of it)
    import logging

    from fc.app import FcConfig, FlightController
    log = logging.getLogger("test_gcs_frames")
    log.addHandler(logging.NullHandler())
    log.propagate = False
    cfg = FcConfig(mode=timing, plant_bind=("127.0.0.1", 0), gcs=[], gcs_bind=("127.0.0.1", 0),
                   out=str(tmp_path))
    fc = FlightController(cfg, log)
    try:
        # THEN its start-up check found the kernels' frames equal to the codec's
        assert fc.gcs.fast is True
    finally:
        fc.close()


class _GnssState:
    """What ``GcsLink._build`` reads for the GNSS messages: the vehicle's sample, meas, the
    newest frame's stamp, home (set: no side effect in ``_gnss``) and the codec."""

    def __init__(self, gps, meas, stamp_us, home, seq):
        from types import MethodType, SimpleNamespace

        from fc.gcs import GcsLink
        self.v = SimpleNamespace(plant=SimpleNamespace(gps=gps), meas=meas,
                                 meas_stamp_us=stamp_us)
        self.home = home
        self.mav = _codec(seq)
        self._gnss = MethodType(GcsLink._gnss, self)
        self._build = MethodType(GcsLink._build, self)


def _home_array(home):
    h = np.zeros(F.HOME_N)
    h[F.HOME_LAT_DEG], h[F.HOME_LON_DEG], h[F.HOME_ALT_M] = home
    h[F.HOME_COS_LAT] = math.cos(math.radians(home[0]))
    return h


def _near_half(x):
    return math.isfinite(x) and abs(x - math.floor(x) - 0.5) < 1e-6


lat_e7 = st.integers(-900_000_000, 900_000_000)
lon_e7 = st.integers(-1_800_000_000, 1_800_000_000)
alt_m = st.floats(-2e6, 2e6, allow_nan=False)
# speeds on and near the cm/s rounding boundaries, and any finite ones
speed = st.one_of(finite, st.integers(-70000, 70000).map(lambda c: (c + 0.5) / 100.0),
                  st.floats(-1e300, 1e300, allow_nan=False))


@settings(max_examples=300, deadline=None)
@given(lat=lat_e7, lon=lon_e7, alt=alt_m, vel=st.lists(speed, min_size=3, max_size=3),
       fix=st.integers(0, 6), sats=st.integers(0, 255),
       acc=st.lists(st.one_of(finite, st.floats(0, 1e10)), min_size=3, max_size=3),
       age_s=st.floats(0.0, 3.0), home=st.tuples(lat_e7, lon_e7, alt_m),
       heading=st.one_of(finite, any_float), us=stamps, seq=st.integers(0, 255),
       log=st.booleans())
def test_gnss_messages_are_the_codecs(lat, lon, alt, vel, fix, sats, acc, age_s, home, heading,
                                      us, seq, log):
    # GIVEN a GNSS sample as fc/link.py keeps it (degE7 x 1e-7, finite), an age, a home and a
    # heading (any float)
    from fc.gcs import GNSS_STALE_S
    from hyfc_wire.layout import (G_ALT_M, G_FIX, G_HACC_M, G_LAT_DEG, G_LON_DEG, G_N,
                                  G_SACC_M_S, G_SATS, G_T_S, G_VACC_M, G_VD, G_VE, G_VN)
    assert F.GNSS_STALE_S == GNSS_STALE_S
    stamp_us = 50_000_000
    g = np.zeros(G_N)
    g[G_T_S] = stamp_us * 1e-6 - age_s
    g[G_LAT_DEG], g[G_LON_DEG], g[G_ALT_M] = lat * 1e-7, lon * 1e-7, alt
    g[G_VN], g[G_VE], g[G_VD] = vel
    g[G_FIX], g[G_SATS] = fix, sats
    g[G_HACC_M], g[G_VACC_M], g[G_SACC_M_S] = acc
    meas = np.zeros(M_N)
    meas[M_HEADING] = heading
    home_t = (home[0] * 1e-7, home[1] * 1e-7, home[2])
    state = _GnssState(g, meas, stamp_us, home_t, seq)
    b = Buf()
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    gp = address_of(g, np.float64, G_N)
    hp = address_of(_home_array(home_t), np.float64, F.HOME_N)
    from fc.link import mavlink as ML
    # THEN GPS_RAW_INT is the codec's frame of _build's message; the kernel may decline only
    # a horizontal speed or course on a rounding boundary (math.hypot is CPython's own)
    spd = math.hypot(g[G_VN], g[G_VE])
    cog_x = math.degrees(math.atan2(g[G_VE], g[G_VN])) * 100.0
    stamp_cell = np.array([stamp_us], np.int64)     # the newest frame's stamp (kept alive)
    cell = address_of(stamp_cell, np.int64, 1)
    _check(F.gps_raw_int_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), gp, cell, True), b,
           _want(state._build(ML.MAVLINK_MSG_ID_GPS_RAW_INT, 0, us), seq, us if log else None),
           may_decline=_near_half(spd * 100.0) or _near_half(cog_x))
    # AND GLOBAL_POSITION_INT and LOCAL_POSITION_NED are the codec's frames (a heading beyond
    # an int64 of centidegrees declined)
    big = math.isfinite(heading) and not abs(heading * F._RAD * 100.0) < 2.0 ** 62
    try:
        want = _want(state._build(ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 0, us), seq,
                     us if log else None)
    except (OverflowError, ValueError):
        want = None                 # (round() of an infinite float: _build raises)
    _check(F.global_position_int_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), gp,
                                   address_of(meas, np.float64, M_N), hp), b, want,
           may_decline=big)
    _check(F.local_position_ned_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), gp, hp), b,
           _want(state._build(ML.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 0, us), seq,
                 us if log else None))


@pytest.mark.parametrize("vn,ve", [(0.0, 0.0), (3.0, 4.0), (-1.0, 0.0), (-1.0, -0.0),
                                   (0.0, -2.0), (1e-300, 0.0), (700.0, 0.0), (0.005, 0.0),
                                   (-0.015, 0.0), (2200.0, 10.0)])
def test_gps_raw_int_course_and_speed_edges(vn, ve):
    # GIVEN a 3D fix at rest, on the axes (signed zeros), tiny, on a cm/s boundary, too fast
    from fc.link import mavlink as ML
    from hyfc_wire.layout import G_FIX, G_N, G_SATS, G_T_S, G_VE, G_VN
    g = np.zeros(G_N)
    g[G_T_S], g[G_FIX], g[G_SATS], g[G_VN], g[G_VE] = 1.0, 3, 12, vn, ve
    state = _GnssState(g, np.zeros(M_N), 1_500_000, (0.0, 0.0, 0.0), 9)
    b = Buf()
    cells = np.array([1_500_000, 2_500_000], np.int64)       # newest frame's stamps (us)
    now, later = address_of(cells, np.int64, 2), address_of(cells, np.int64, 2) + 8
    n = F.gps_raw_int_p(b.p, -1, 0, 9, SYSID, COMPID, _at(1_500_000),
                        address_of(g, np.float64, G_N), now, True)
    want = _want(state._build(ML.MAVLINK_MSG_ID_GPS_RAW_INT, 0, 1_500_000), 9)
    # THEN the frame is the codec's, or declined exactly on a cm/s rounding boundary
    if _near_half(math.hypot(vn, ve) * 100.0):
        assert n == 0
        return
    assert b.bytes(n) == want
    # AND with home not set, a 3D fix is declined (the codec's path sets home), an older one
    # (stale: NO_FIX) is framed
    gp = address_of(g, np.float64, G_N)
    assert F.gps_raw_int_p(b.p, -1, 0, 9, SYSID, COMPID, _at(1_500_000), gp, now, False) == 0
    assert F.gps_raw_int_p(b.p, -1, 0, 9, SYSID, COMPID, _at(1_500_000), gp, later, False) > 0


@settings(max_examples=300, deadline=None)
@given(st_vals=st.lists(st.one_of(finite, any_float), min_size=4, max_size=4),
       tgt=st.lists(st.one_of(finite, any_float), min_size=2, max_size=2),
       alt=st.one_of(finite, any_float),
       wp=st.one_of(st.none(), st.tuples(st.one_of(finite, any_float),
                                         st.one_of(st.floats(-1e5, 1e6), any_float),
                                         st.one_of(finite, any_float))),
       us=stamps, seq=st.integers(0, 255), log=st.booleans())
def test_nav_controller_output_is_the_codecs(st_vals, tgt, alt, wp, us, seq, log):
    # GIVEN the guidance's status, targets and waypoint and the estimate (any floats)
    from types import MethodType, SimpleNamespace

    from fc.control.layout import E_H, E_N
    from fc.guidance import layout as G
    from fc.guided import GuidanceRunner
    status, targets, est = np.zeros(G.GS_N), np.zeros(G.TG_N), np.zeros(E_N)
    status[G.GS_MU_C], status[G.GS_GAM_C], status[G.GS_ALPHA_C], status[G.GS_V_ERR] = st_vals
    targets[G.TG_H], targets[G.TG_CHI] = tgt
    est[E_H] = alt
    runner = SimpleNamespace(g=SimpleNamespace(status=status, tgt=targets), nav_wp=wp)
    runner.targets = MethodType(GuidanceRunner.targets, runner)
    b = Buf()
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    n = F.nav_output_p(b.p, ep, tl, seq, SYSID, COMPID, address_of(status, np.float64, G.GS_N),
                       address_of(targets, np.float64, G.TG_N), address_of(est, np.float64, E_N),
                       wp is not None, *(wp or (0.0, 0.0, 0.0)))
    try:
        nav = GuidanceRunner.nav_output(runner, est)
        want = _want(_codec(seq).nav_controller_output_encode(*nav), seq, us if log else None)
    except (OverflowError, ValueError):
        want = None         # (round() of a non-finite float: nav_output raises)
    # THEN the frame is the codec's (a bearing or distance beyond an int64 declined)
    big = any(math.isfinite(x) and not abs(x) < 2.0 ** 62
              for x in (math.degrees(tgt[1]) if math.isfinite(tgt[1]) else 0.0,
                        *((math.degrees(wp[0]) if math.isfinite(wp[0]) else 0.0, wp[1])
                          if wp else ())))
    _check(n, b, want, may_decline=big or (math.isnan(st_vals[1]) and math.isnan(st_vals[2])))


@settings(max_examples=150, deadline=None)
@given(custom=st.integers(0, 2**32 - 1), base=st.integers(0, 255),
       status=st.integers(0, 255), item=st.integers(0, 2**16 - 1),
       total=st.integers(0, 2**16 - 1), mstate=st.integers(0, 255), mmode=st.integers(0, 1),
       frames=st.integers(0, 10**9), lost=st.booleans(),
       airspeed=st.one_of(finite, any_float, st.just(50.0)),
       us=st.integers(0, 2**62), epoch=st.integers(0, 2**61), seq=st.integers(0, 255),
       log=st.booleans())
def test_the_status_messages_are_the_codecs(custom, base, status, item, total, mstate, mmode,
                                            frames, lost, airspeed, us, epoch, seq, log):
    # GIVEN the fields of HEARTBEAT, MISSION_CURRENT, EXTENDED_SYS_STATE and SYSTEM_TIME as
    # GcsLink builds them (the landed state from fc/gcs_streams.py)
    from fc.gcs_streams import landed_state
    from fc.link import mavlink as ML
    b = Buf()
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    t_us = us if log else None
    c = _codec(seq)
    # THEN each kernel's frame is the codec's
    _check(F.heartbeat_p(b.p, ep, tl, seq, SYSID, COMPID, custom, ML.MAV_TYPE_FIXED_WING,
                         ML.MAV_AUTOPILOT_GENERIC, base, status), b,
           _want(c.heartbeat_encode(ML.MAV_TYPE_FIXED_WING, ML.MAV_AUTOPILOT_GENERIC, base,
                                    custom, status), seq, t_us))
    _check(F.mission_current_p(b.p, ep, tl, seq, SYSID, COMPID, item, total, mstate, mmode), b,
           _want(c.mission_current_encode(item, total, mstate, mmode), seq, t_us))
    meas = np.zeros(M_N)
    meas[M_AIRSPEED] = airspeed
    hot = np.array([frames], np.int64)
    _check(F.extended_sys_state_p(b.p, ep, tl, seq, SYSID, COMPID,
                                  address_of(hot, np.int64, 1), lost,
                                  address_of(meas, np.float64, M_N)), b,
           _want(c.extended_sys_state_encode(ML.MAV_VTOL_STATE_UNDEFINED,
                                             landed_state(frames > 0 and not lost, airspeed)),
                 seq, t_us))
    _check(F.system_time_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us), epoch), b,
           _want(c.system_time_encode(epoch + us, (us // 1000) & 0xFFFFFFFF), seq, t_us))


def _named_values_as_built(t) -> list:
    """fc/telemetry.py ``Telemetry.refresh``'s list as it was built before its array form."""
    e = t.est.est
    c = t.plant.counters
    nv = [(b"GAMMA_DEG", math.degrees(e[8])),
          (b"LATE_P99", t.stats.window_p99_us), (b"LATE_MAX", t.stats.window_max_us),
          (b"LATE_CNT", float(t.stats.late)), (b"OVERRUN", float(t.stats.overruns)),
          (b"SKIPPED", float(t.skipped_ticks())), (b"TICK_FALLB", float(t.gate.fallback_ticks)),
          (b"GC_US", t.counters.gc_us), (b"REJ_PLANT", float(c.rejected)),
          (b"GNSS_DROP", float(c.gnss_rejected)), (b"REJ_GCS", float(t.gcs.rejected_bad)),
          (b"REJ_SIGN", float(t.gcs.rejected_signing)),
          (b"EST_INVAL", float(t.est.invalid_frames)),
          (b"EST_FLAGS", float(t.est.masks[0] | t.est.masks[1])),
          (b"FS_CAUSE", float(t.modes.fs_cause)),
          (b"DUP_FRAMES", float(t.counters.duplicate_frames)),
          (b"FC_STALLS", float(t.counters.fc_stalls))]
    for i, n in enumerate(t.status_names[:16]):
        nv.append((n.upper()[:10].encode("ascii", "replace"), float(t.law.status[i])))
    return nv


def test_the_named_values_are_the_ones_the_list_held():
    # GIVEN a controller after a short flight, its counters and the law's status not zero
    from tools.bench.profile import _Rig, record
    flight = record(600, "COORDINATED")
    rig = _Rig("COORDINATED")
    try:
        for data in flight:
            rig.step(data)
        t = rig.fc.telemetry
        t.stats.late, t.counters.duplicate_frames, t.counters.fc_stalls = 3, 7, 1
        t.plant.counters.gnss_rejected = 300
        # WHEN the 1 Hz refresh runs
        t.refresh()
        # THEN the named values are the pairs the list held, value for value
        want = _named_values_as_built(t)
        got = t.named_values()
        assert [n for n, _ in got] == [n for n, _ in want]
        assert [struct.pack("<d", v) for _, v in got] == [struct.pack("<d", v) for _, v in want]
        assert t.named_value_count() == len(want) > 17
    finally:
        rig.close()


@settings(max_examples=200, deadline=None)
@given(law_active=st.booleans(), failed=st.sampled_from([0, 1 << 21, (1 << 21) | (1 << 24)]),
       fix=st.integers(0, 6), age_s=st.floats(0.0, 3.0), home_set=st.booleans(),
       load=st.integers(0, 70000),
       counts=st.lists(st.integers(0, 200000), min_size=5, max_size=5),
       standard=st.integers(0, 300), custom=st.integers(0, 2**32),
       us=stamps, seq=st.integers(0, 255), log=st.booleans())
def test_sys_status_and_current_mode_are_the_codecs(law_active, failed, fix, age_s, home_set,
                                                    load, counts, standard, custom, us, seq,
                                                    log):
    # GIVEN the vehicle's state SYS_STATUS is built from (``GcsLink._build``), and a mode
    from types import SimpleNamespace

    from fc.link import mavlink_dev as MD
    from hyfc_wire.layout import G_FIX, G_N, G_T_S
    g = np.zeros(G_N)
    stamp_us = 50_000_000
    g[G_T_S], g[G_FIX] = stamp_us * 1e-6 - age_s, fix
    state = _GnssState(g, np.zeros(M_N), stamp_us, (1.0, 2.0, 3.0) if home_set else None, seq)
    state.v.modes = SimpleNamespace(law_active=law_active)
    state.v.health_failed_bits = lambda: failed
    state.v.load_permille = lambda: load
    state.v.error_counts = lambda: tuple(counts)
    state.statustext = lambda *a: None
    state.oneshot = []
    b = Buf()
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    stamp_cell = np.array([stamp_us], np.int64)
    n = F.sys_status_p(b.p, ep, tl, seq, SYSID, COMPID, law_active, failed,
                       address_of(g, np.float64, G_N), address_of(stamp_cell, np.int64, 1),
                       home_set, load, *counts)
    from fc.link import mavlink as ML
    codec_sets_home = not home_set and fix >= 3 and age_s <= 1.0
    want = None if codec_sets_home else _want(
        state._build(ML.MAVLINK_MSG_ID_SYS_STATUS, 0, us), seq, us if log else None)
    # THEN SYS_STATUS is the codec's frame (declined where the codec's path sets home)
    if codec_sets_home:
        assert n == 0
    else:
        _check(n, b, want)
    # AND CURRENT_MODE is the codec's (development dialect)
    n = F.current_mode_p(b.p, ep, tl, seq, SYSID, COMPID, standard, custom)
    _check(n, b, _want(MD.MAVLink_current_mode_message(standard, custom, custom), seq,
                       us if log else None))


def test_vfr_hud_throttle_percent_rounds_as_round_and_allocates_nothing():
    # GIVEN a controller in CRUISE (the guidance flies the throttle)
    from tests.unit.fc.test_gcs_links import _blocks
    from tools.bench.profile import _Rig, record
    flight = record(300, "CRUISE")
    rig = _Rig("CRUISE")
    try:
        for data in flight:
            rig.step(data)
        t = rig.fc.telemetry
        assert t.modes.guidance_active
        # THEN VFR_HUD's throttle is ``int(round(100 * throttle))``, halves to even included
        # (``__round__`` is what ``round`` calls), and reading it takes no Python block
        real = t.guid.throttle
        for thr in (0.0, 0.005, 0.015, 0.025, 0.125, 0.135, 0.5, 0.625, 0.995, 1.0, 0.3333,
                    real()):
            t.guid.throttle = lambda thr=thr: thr
            assert t.throttle_percent() == int(round(100.0 * thr)), thr
            assert type(t.throttle_percent()) is int
        t.guid.throttle = real
        assert _blocks(t.throttle_percent) == 0
    finally:
        rig.close()


# home values on and near the rounding boundaries of degE7 and mm, beyond int32, non-finite
home_deg = st.one_of(lat_e7.map(lambda e: e * 1e-7), lat_e7.map(lambda e: (e + 0.5) * 1e-7),
                     st.floats(-300.0, 300.0), any_float)
home_alt = st.one_of(alt_m, st.integers(-2_200_000_000, 2_200_000_000).map(lambda c: (c + 0.5)
                                                                              / 1000.0),
                     any_float)


@settings(max_examples=300, deadline=None)
@given(lat=home_deg, lon=home_deg, alt=home_alt, us=stamps, seq=st.integers(0, 255),
       log=st.booleans())
def test_home_position_is_the_codecs(lat, lon, alt, us, seq, log):
    # GIVEN a home (any floats: on rounding boundaries, beyond int32, not finite)
    from fc.link import mavlink as ML
    from hyfc_wire.layout import G_N
    home = (lat, lon, alt)
    state = _GnssState(np.zeros(G_N), np.zeros(M_N), 50_000_000, home, seq)
    h = np.zeros(F.HOME_N)
    h[F.HOME_LAT_DEG], h[F.HOME_LON_DEG], h[F.HOME_ALT_M] = home
    b = Buf()
    ep, tl = (EPOCH_US, _lt(us)) if log else (-1, 0)
    try:
        want = _want(state._build(ML.MAVLINK_MSG_ID_HOME_POSITION, 0, us), seq,
                     us if log else None)
    except (OverflowError, ValueError):
        want = None                 # (round() of a non-finite float: _build raises)
    # THEN the kernel frames the codec's bytes of _build's message, or declines where the
    # codec refuses (the codec's path then refuses it as before)
    _check(F.home_position_p(b.p, ep, tl, seq, SYSID, COMPID, _at(us),
                             address_of(h, np.float64, F.HOME_N)), b, want)
