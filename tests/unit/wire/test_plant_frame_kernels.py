"""hyfc_wire.frame_kernels' plant side (issue 24): the compiled sensor datagram is the bytes of
the Python framer (``SensorFramer``, itself checked against the codec in test_wire_contract),
values the codec's struct refuses fall back to that framer, and the compiled servo decoder
accepts and decodes exactly what ``ServoDecoder`` does, never raising."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hyfc_wire import frame_kernels as K
from hyfc_wire.codec import new_codec
from hyfc_wire.framing import SensorFramer, ServoDecoder
from hyfc_wire.layout import G_N, M_N
from hyfc_wire.pwm import DEFAULT_PWM
from plant_sim.link import PlantLink

#: physical-range doubles (not float32-exact: the float32 rounding is part of what is checked)
PHYS = st.floats(-1e6, 1e6, allow_nan=False)
ANGLE = st.floats(-50.0, 50.0, allow_nan=False)
SEQ = st.integers(0, 255)


def _python_frame(seq, sysid, compid, stamp_us, meas, thr, gnss):
    buf = bytearray(512)
    n, frames = SensorFramer().pack_into(buf, memoryview(buf), seq, sysid, compid, stamp_us, meas,
                                         thr, gnss)
    return bytes(buf[:n]), frames


def _kernel_frame(seq, sysid, compid, stamp_us, meas, thr, gnss):
    out = np.zeros(K.SENSOR_FRAME_MAX_B, dtype=np.uint8)
    n = K.sensor_frame(out, seq, sysid, compid, stamp_us, meas, thr,
                       np.zeros(G_N) if gnss is None else gnss, gnss is not None)
    return n, bytes(out[:max(n, 0)])


@settings(max_examples=300, deadline=None)
@given(seq=SEQ, sysid=st.integers(1, 255), compid=st.integers(0, 255),
       stamp_us=st.integers(0, 2**53), meas=st.lists(PHYS, min_size=M_N, max_size=M_N),
       thr=st.floats(-50.0, 150.0), with_gnss=st.booleans(),
       lat=st.floats(-89.9, 89.9), lon=st.floats(-179.9, 179.9),
       g=st.lists(PHYS, min_size=G_N, max_size=G_N), fix=st.integers(0, 6),
       sats=st.integers(0, 40), zeros=st.lists(st.booleans(), min_size=M_N, max_size=M_N))
def test_sensor_frame_is_the_python_framers_bytes(seq, sysid, compid, stamp_us, meas, thr,
                                                   with_gnss, lat, lon, g, fix, sats, zeros):
    m = np.array([0.0 if z else v for v, z in zip(meas, zeros)])      # zeros: truncation
    m[7] = math.radians(max(-50.0, min(50.0, m[7] * 1e-5)))           # alpha, beta in rad
    m[8] = math.radians(max(-50.0, min(50.0, m[8] * 1e-5)))
    gnss = None
    if with_gnss:
        gnss = np.array(g)
        gnss[1], gnss[2], gnss[7], gnss[8] = lat, lon, float(fix), float(sats)
    ref, frames = _python_frame(seq, sysid, compid, stamp_us, m, thr, gnss)
    n, got = _kernel_frame(seq, sysid, compid, stamp_us, m, thr, gnss)
    assert frames == (4 if with_gnss else 3)
    assert n == len(ref) and got == ref


@pytest.mark.parametrize("slot, value", [(13, math.nan), (13, math.inf), (1, 1e39),
                                         (9, -1e300)])
def test_a_value_the_struct_refuses_gives_minus_one_and_the_link_raises_as_before(slot, value):
    meas = np.zeros(M_N)
    meas[slot] = value
    with pytest.raises((ValueError, OverflowError)):
        _python_frame(0, 2, 1, 0, meas, 50.0, None)
    assert _kernel_frame(0, 2, 1, 0, meas, 50.0, None)[0] == -1
    link = PlantLink(("127.0.0.1", 9), ("127.0.0.1", 0), DEFAULT_PWM)
    try:
        with pytest.raises((ValueError, OverflowError)):
            link.build_sensors(0, meas, 50.0)
    finally:
        link.close()


def test_nan_and_inf_floats_are_framed_as_the_struct_frames_them():
    meas = np.zeros(M_N)
    meas[1], meas[2], meas[9] = math.nan, math.inf, -math.inf
    ref, _ = _python_frame(7, 2, 1, 123, meas, 20.0, None)
    n, got = _kernel_frame(7, 2, 1, 123, meas, 20.0, None)
    assert got == ref and n == len(ref)


def test_the_link_sends_the_kernels_frames_and_counts_sequence_numbers():
    link = PlantLink(("127.0.0.1", 9), ("127.0.0.1", 0), DEFAULT_PWM)
    try:
        assert link.lean
        meas = np.linspace(0.01, 0.14, M_N)
        seq0 = link.mav.seq
        link.build_sensors(2000, meas, 42.0)
        ref, _ = _python_frame(seq0, link.mav.srcSystem, link.mav.srcComponent, 2000, meas, 42.0,
                               None)
        assert bytes(link._out_mv[:link._out_len]) == ref
        assert link.mav.seq == (seq0 + 3) & 0xFF
    finally:
        link.close()


def _servo(seq, sysid, t_us, s):
    c = new_codec(sysid)
    c.seq = seq
    return c.servo_output_raw_encode(t_us, 0, *s, 0, 0, 0, 0).pack(c)


def _kernel_decode(data: bytes):
    buf = np.zeros(2048, dtype=np.uint8)
    buf[:len(data)] = np.frombuffer(data, dtype=np.uint8)
    rec = np.full(K.SV_N, -7, dtype=np.int64)
    ok = K.decode_servo(buf, len(data), rec)
    return (tuple(int(v) for v in rec) if ok else None), rec


@settings(max_examples=300, deadline=None)
@given(seq=SEQ, sysid=st.integers(1, 255), t_us=st.integers(0, 2**32 - 1),
       s=st.tuples(*[st.one_of(st.just(0), st.integers(0, 65535))] * 4))
def test_decode_servo_is_the_python_decoders(seq, sysid, t_us, s):
    data = _servo(seq, sysid, t_us, s)
    got, _ = _kernel_decode(data)
    assert got == ServoDecoder().decode(data, len(data)) == (sysid, t_us) + tuple(s)


@settings(max_examples=400, deadline=None)
@given(data=st.binary(max_size=80), pos=st.integers(0, 40), byte=st.integers(0, 255),
       base=st.booleans())
def test_decode_servo_on_mutated_and_garbage_input_agrees_and_never_raises(data, pos, byte, base):
    """A good frame with one byte changed, cut short or followed by a byte, or garbage."""
    if base:              # a good frame with one byte changed (or the frame cut short)
        good = bytearray(_servo(3, 1, 123456, (1100, 1900, 1500, 0)))
        if pos < len(good):
            good[pos] = byte
        cut = len(good) - (pos % 3 == 0)
        data = bytes(good[:max(1, cut)]) + (bytes([byte]) if pos % 3 == 1 else b"")
    got, rec = _kernel_decode(data)
    assert got == ServoDecoder().decode(data, len(data))
    if got is None:
        assert (rec == -7).all()          # nothing written on a rejection
