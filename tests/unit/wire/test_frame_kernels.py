"""hyfc_wire.frame_kernels: the compiled sensor decoder, PWM map and SERVO_OUTPUT_RAW framing
give exactly what pymavlink's codec and the Python functions give, and never raise."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fc.link import PlantLink, UdpEndpoint, new_codec
from hyfc_wire import frame_kernels as K
from hyfc_wire import layout
from hyfc_wire.pwm import DEFLECTION_LIMIT_RAD, deflection_to_pwm, throttle_to_pwm

F32 = st.floats(width=32, allow_nan=False)
#: float32 values, zeros likely (a zero last field makes the codec truncate the payload)
F32Z = st.one_of(st.just(0.0), F32)


def _datagram(vals, order, sysid=2, seq=0, gps=None) -> bytes:
    """ATTITUDE, AOA_SSA, VFR_HUD (and GPS_INPUT) from the codec, in ``order``."""
    c = new_codec(sysid)
    c.seq = seq
    a, q, h = vals
    frames = [c.attitude_encode(*a).pack(c), c.aoa_ssa_encode(*q).pack(c),
              c.vfr_hud_encode(*h).pack(c)]
    if gps is not None:
        frames.append(c.gps_input_encode(*gps).pack(c))
    return b"".join(frames[i] for i in order if i < len(frames))


ATT = st.tuples(st.integers(0, 2**32 - 1), F32Z, F32Z, F32Z, F32Z, F32Z, F32Z)
AOA = st.tuples(st.integers(0, 2**64 - 1), F32Z, F32Z)
# VFR_HUD encode order: airspeed, groundspeed, heading (int16), throttle (uint16), alt, climb
HUD = st.tuples(F32Z, F32Z, st.integers(-32768, 32767), st.one_of(st.just(0),
                                                                     st.integers(0, 65535)),
                F32Z, F32Z)
# GPS_INPUT encode order: time_usec, gps_id, ignore_flags, time_week_ms, time_week, fix_type,
# lat, lon, alt, hdop, vdop, vn, ve, vd, speed_acc, horiz_acc, vert_acc, sats, yaw
GPS = st.tuples(st.integers(0, 2**64 - 1), st.integers(0, 255), st.integers(0, 65535),
                st.integers(0, 2**32 - 1), st.integers(0, 65535), st.integers(0, 255),
                st.integers(-2**31, 2**31 - 1), st.integers(-2**31, 2**31 - 1), F32Z, F32Z,
                F32Z, F32Z, F32Z, F32Z, F32Z, F32Z, F32Z, st.integers(0, 255),
                st.one_of(st.just(0), st.integers(0, 65535)))


@pytest.fixture(scope="module")
def link():
    ep = UdpEndpoint("127.0.0.1", 0)
    lk = PlantLink(ep, plant_sysid=2)
    assert lk._fast                 # the compiled path passed its start-up self-check
    yield lk
    ep.close()


def _both_paths(lk: PlantLink, data: bytes):
    """(stamp, meas, gps, counters) of the compiled path and of the codec's general parser."""
    out = []
    for fast in (True, False):
        lk._fast = fast
        lk.gps[:] = 0.0
        lk.gps_samples = 0
        names = [f for f in lk.counters.__slots__ if f != "hot"]
        for f in names:
            setattr(lk.counters, f, 0)
        lk.counters.hot[:] = 0
        meas = np.full(layout.M_N, -7.0)
        stamp = lk._decode(data, meas)
        out.append((stamp, meas.tobytes(), lk.gps.tobytes(),
                    [getattr(lk.counters, f) for f in names] + lk.counters.hot.tolist()))
    lk._fast = True
    return out


@settings(max_examples=300, deadline=None)
@given(ATT, AOA, HUD, st.one_of(st.none(), GPS), st.permutations(range(4)),
       st.integers(0, 255))
def test_decoder_matches_the_codec_on_random_frames(link, att, aoa, hud, gps, order, seq):
    # GIVEN a sensor datagram built by the codec: any field values, any message order, with
    # or without GPS_INPUT
    data = _datagram((att, aoa, hud), order, seq=seq, gps=gps)
    # WHEN the compiled kernel decodes it
    meas = np.full(layout.M_N, -7.0)
    g = np.zeros(K.GR_N)
    stamp = K.decode_sensor(np.frombuffer(data, np.uint8), len(data), 2, meas, g)
    # THEN it is accepted (a stamp beyond int64 excepted) with the codec's values
    if aoa[0] >= 2**63:
        assert stamp == K.REJ_STAMP
    else:
        assert stamp == aoa[0]
        assert (g[K.GR_PRESENT] == 1.0) == (gps is not None)
    # AND the link's two paths (compiled / general parser) give the same bytes and counts
    fast, general = _both_paths(link, data)
    assert fast == general


def _mutate(data: bytes, ops) -> bytes:
    b = bytearray(data)
    for kind, pos, val in ops:
        if not b:
            break
        i = pos % len(b)
        if kind == 0:
            b[i] ^= 1 << (val % 8)                  # bit flip
        elif kind == 1:
            b[i] = val                              # byte overwritten
        elif kind == 2:
            del b[i:]                               # truncated
        elif kind == 3:
            b.insert(i, val)                        # byte inserted
        else:
            del b[i]                                # byte deleted
    return bytes(b)


@settings(max_examples=400, deadline=None)
@given(ATT, AOA, HUD, st.one_of(st.none(), GPS),
       st.lists(st.tuples(st.integers(0, 4), st.integers(0, 400), st.integers(0, 255)),
                min_size=1, max_size=4),
       st.sampled_from([2, 3]))
def test_decoder_on_mutated_frames_never_raises_and_agrees(link, att, aoa, hud, gps, ops, sysid):
    # GIVEN a good datagram damaged at random (bit flips, overwrites, truncation, inserts,
    # deletions), possibly from another system
    data = _mutate(_datagram((att, aoa, hud), (0, 1, 2, 3), sysid=sysid, gps=gps), ops)
    # WHEN both paths decode it, THEN neither raises and both give the same result and counts
    fast, general = _both_paths(link, data)
    assert fast == general
    # AND what the kernel accepts the codec parses into the three messages without damage
    meas = np.zeros(layout.M_N)
    stamp = K.decode_sensor(np.frombuffer(data, np.uint8), len(data), 2, meas,
                            np.zeros(K.GR_N))
    if stamp >= 0:
        assert general[0] == stamp


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400))
def test_decoder_never_raises_on_garbage(data):
    buf = np.frombuffer(data + b"\0", np.uint8)     # (frombuffer needs one byte)
    meas = np.full(layout.M_N, 3.0)
    got = K.decode_sensor(buf, len(data), 2, meas, np.zeros(K.GR_N))
    assert got in K.REJ_NAMES or got >= 0
    if got < 0:
        assert (meas == 3.0).all()                  # nothing written on a rejection


def test_each_rejection_has_its_code():
    att = (1, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    aoa = (1_000_000, 2.0, 1.0)
    hud = (2200.0, 2190.0, 45, 0, 25000.0, -1.5)
    good = _datagram((att, aoa, hud), (0, 1, 2))

    def code(data, sysid=2):
        return K.decode_sensor(np.frombuffer(data + b"\0", np.uint8), len(data), sysid,
                               np.zeros(layout.M_N), np.zeros(K.GR_N))

    assert code(good) == 1_000_000
    assert code(good, sysid=3) == K.REJ_SYSID
    assert code(good[:-1]) == K.REJ_LENGTH
    assert code(good + b"\xfd") == K.REJ_FORMAT
    assert code(b"\xfe" + good[1:]) == K.REJ_FORMAT            # MAVLink 1 start byte
    bad = bytearray(good)
    bad[-1] ^= 0x01
    assert code(bytes(bad)) == K.REJ_CRC
    assert code(_datagram((att, aoa, hud), (0, 2))) == K.REJ_INCOMPLETE
    assert code(good + _datagram((att, aoa, hud), (0,))) == K.REJ_REPEAT
    c = new_codec(2)
    assert code(good + c.heartbeat_encode(1, 0, 0, 0, 4).pack(c)) == K.REJ_MSGID
    assert code(_datagram((att, (2**63, 0.0, 0.0), hud), (0, 1, 2))) == K.REJ_STAMP


def test_crc_is_the_codecs():
    from hyfc_wire.framing import crc16
    rng = np.random.default_rng(1)
    for n in (0, 1, 7, 64, 255):
        b = rng.integers(0, 256, n).astype(np.uint8)
        assert K.crc16_range(b, 0, n, 0xFFFF) == crc16(bytes(b))


# ---- PWM ------------------------------------------------------------------------------------
def _around_half_steps() -> np.ndarray:
    """Deflections whose PWM lands on or within a few ulps of every k + 0.5 us (the rounding
    boundaries), on both spans, plus the clip edges and non-finite values."""
    lim = DEFLECTION_LIMIT_RAD
    xs = []
    for k2 in range(1990, 4021):                    # us = k2 / 2: 995 .. 2010 in half steps
        us = k2 / 2.0
        span = 500.0
        x = (us - 1500.0) / span * lim
        for _ in range(6):                          # 6 ulps either side
            xs.append(x)
            x = np.nextafter(x, np.inf)
        x = (us - 1500.0) / span * lim
        for _ in range(6):
            x = np.nextafter(x, -np.inf)
            xs.append(x)
    xs += [0.0, -0.0, 5e-324, -5e-324, 1e300, -1e300, math.inf, -math.inf, math.nan, lim, -lim,
           2 * lim, -2 * lim]
    return np.array(xs)


def test_pwm_map_is_deflection_to_pwm_exactly_around_every_half_step():
    xs = _around_half_steps()
    pwm = np.zeros(4, np.int64)
    n_half = 0
    for i in range(0, len(xs) - 2, 3):
        d = xs[i:i + 3].copy()
        K.pwm_map(d, 1234, pwm)
        want = [deflection_to_pwm(float(x)) for x in d]
        assert pwm.tolist() == want + [1234], d
        n_half += sum(1 for x in d if math.isfinite(x)
                      and (1500 + x / DEFLECTION_LIMIT_RAD * 500) % 1 == 0.5)
    assert n_half > 500            # the exact .5 cases (half to even) were among them


def _python_pwm(x: float) -> int:
    """deflection_to_pwm, except that a finite deflection so large that its PWM overflows to
    infinity (|x| > ~1e305 rad) raises there; the compiled map clips it like any other."""
    try:
        return deflection_to_pwm(x)
    except OverflowError:
        return 2000 if x > 0 else 1000


@settings(max_examples=500, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=3, max_size=3))
def test_pwm_map_is_deflection_to_pwm_on_any_float(d):
    pwm = np.zeros(4, np.int64)
    K.pwm_map(np.array(d), 0, pwm)
    assert pwm.tolist() == [_python_pwm(x) for x in d] + [0]


def test_surfaces_pwm_copies_the_command_then_maps_it():
    # GIVEN the fast tick's output arrays holding an older command
    delta = np.array([0.3, 0.3, 0.3])
    pwm = np.zeros(4, np.int64)
    src = np.array([0.01, -0.2, math.nan])
    # WHEN a new command goes out
    K.surfaces_pwm(src, delta, 1420, pwm)
    # THEN delta is the command, bit for bit, and the PWM its pwm_map
    assert np.array_equal(delta, src, equal_nan=True)
    assert pwm.tolist() == [deflection_to_pwm(x) for x in src] + [1420]
    # AND a held command (the source is delta itself) maps the same, unchanged
    K.surfaces_pwm(delta, delta, 0, pwm)
    assert np.array_equal(delta, src, equal_nan=True)
    assert pwm.tolist() == [deflection_to_pwm(x) for x in src] + [0]


def test_throttle_pwm_is_throttle_to_pwm_around_every_half_step_and_on_any_float():
    # GIVEN throttles next to every k + 0.5 us boundary of 1000..2000 us, beyond 0..1 and not
    # finite, and random floats
    xs = [0.0, -0.0, 1.0, -1.0, 2.0, 5e-324, 1e300, -1e300, math.inf, -math.inf, math.nan]
    for k in range(-5, 1006):
        x = (k + 0.5) / 1000.0
        for _ in range(4):
            xs += [x]
            x = np.nextafter(x, np.inf)
        x = (k + 0.5) / 1000.0
        for _ in range(4):
            x = np.nextafter(x, -np.inf)
            xs += [x]
    xs += list(np.random.default_rng(0).uniform(-0.5, 1.5, 2000))
    # THEN the compiled map gives throttle_to_pwm's value (on the float and on the numpy
    # scalar the guidance's output array holds)
    for x in xs:
        want = throttle_to_pwm(float(x))
        assert K.throttle_pwm(float(x)) == want == throttle_to_pwm(np.float64(x)), x


# ---- SERVO_OUTPUT_RAW -----------------------------------------------------------------------
@settings(max_examples=300, deadline=None)
@given(st.integers(0, 255), st.integers(0, 255), st.integers(0, 255),
       st.integers(0, 2**32 - 1),
       st.lists(st.one_of(st.just(0), st.integers(0, 65535)), min_size=4, max_size=4))
def test_servo_frame_is_the_codecs_bytes(seq, sysid, compid, t_us, pwm):
    c = new_codec(sysid, compid)
    c.seq = seq
    ref = c.servo_output_raw_encode(t_us, 0, *pwm, 0, 0, 0, 0).pack(c)
    out = np.zeros(K.SERVO_FRAME_MAX_B, np.uint8)
    n = K.servo_frame(out, seq, sysid, compid, t_us, np.array(pwm, np.int64))
    assert bytes(out[:n]) == ref
