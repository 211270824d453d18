"""hyfc_wire, the contract package both processes import: layouts, PWM map, lean framing
(byte-identical to pymavlink's codec), host:port parsing, the timeline reader, the numba
cache helper. Tier 1: no sockets, no processes."""
from __future__ import annotations

import math
import os
import time

import numpy as np
import pytest

from hyfc_wire import layout, numba_cache, pwm, timeline
from hyfc_wire.codec import mavlink, new_codec
from hyfc_wire.framing import (LeanFramer, SensorDecoder, SensorFramer, ServoDecoder,
                               ServoPacker, crc16)
from hyfc_wire.udp import parse_hostport

DEG = math.pi / 180.0


# ---- layouts -----------------------------------------------------------------------------
def _indices(prefix: str, n_name: str) -> dict:
    return {k: getattr(layout, k) for k in layout.__all__
            if k.startswith(prefix) and k != n_name and k != "MEAS_NAMES"}


def test_layouts_are_dense_and_named():
    m = _indices("M_", "M_N")
    assert sorted(m.values()) == list(range(layout.M_N))
    assert len(layout.MEAS_NAMES) == layout.M_N and layout.MEAS_NAMES[layout.M_AOA] == "aoa_rad"
    g = _indices("G_", "G_N")
    assert sorted(g.values()) == list(range(layout.G_N))


def test_both_processes_use_the_one_layout():
    import fc.estimator as fe
    import fc.link as fl
    import plant_sim.gnss as pg
    import plant_sim.sensors as ps
    for name in _indices("M_", "") | {"M_N": 0}:
        assert getattr(fl, name) == getattr(ps, name) == getattr(fe, name) == getattr(layout, name)
    for name in _indices("G_", "") | {"G_N": 0}:
        assert getattr(fl, name) == getattr(pg, name) == getattr(layout, name)


# ---- PWM ---------------------------------------------------------------------------------
def test_pwm_mapping_matches_wire_md():
    d2p = pwm.deflection_to_pwm
    assert d2p(0.0) == 1500
    assert d2p(math.radians(20)) == 2000 and d2p(math.radians(-20)) == 1000
    assert d2p(math.radians(0.04)) == 1501                       # 1 us = 0.04 deg
    assert d2p(math.radians(45)) == pwm.PWM_MAX_US                # clipped
    assert d2p(math.radians(-45)) == pwm.PWM_MIN_US
    assert d2p(math.nan) == 1500                                  # never a garbage PWM
    for us in (1000, 1234, 1500, 1777, 2000):
        assert d2p(pwm.pwm_to_deflection(us)) == us


def test_pwm_map_round_trips_and_asymmetric_spans():
    m = pwm.PwmMap(1000, 1500, 2000, 20.0 * DEG)
    assert m.to_rad(1500) == 0.0
    assert m.to_rad(2000) == pytest.approx(20.0 * DEG) and m.to_rad(1000) == pytest.approx(-20.0 * DEG)
    assert m.to_rad(1501) == pytest.approx(0.04 * DEG)
    assert m.to_rad(900) == pytest.approx(-20.0 * DEG) and m.to_rad(2600) == pytest.approx(20.0 * DEG)
    asym = pwm.PwmMap(1100, 1400, 1900, 20.0 * DEG)       # different spans above and below trim
    assert asym.to_rad(1250) == pytest.approx(-10.0 * DEG)
    assert asym.to_rad(1650) == pytest.approx(10.0 * DEG)
    for us in range(1000, 2001, 7):
        assert m.to_pwm(m.to_rad(us)) == us
    for us in range(1100, 1901, 13):
        assert asym.to_pwm(asym.to_rad(us)) == us
    with pytest.raises(ValueError, match="MIN < TRIM < MAX"):
        pwm.PwmMap(1500, 1500, 2000, 0.3)


def test_throttle_pwm_map_is_1000_to_2000_and_inverts():
    t2p, p2t = pwm.throttle_to_pwm, pwm.throttle_from_pwm
    assert t2p(0.0) == 1000 and t2p(1.0) == 2000
    assert t2p(0.4224) == 1422
    assert t2p(-0.3) == 1000 and t2p(7.0) == 2000     # clipped
    assert t2p(math.nan) == 0                         # no output
    assert p2t(1000) == 0.0 and p2t(2000) == 1.0
    assert p2t(900) == 0.0 and p2t(2100) == 1.0
    for us in range(1000, 2001, 37):
        assert t2p(p2t(us)) == us


# ---- lean framing == the codec's bytes ---------------------------------------------------
MEAS = np.array([1.234567, 0.1, -0.2, 3.0, 0.01, -0.02, 0.0, 0.05, -0.01, 2200.0, 21000.0,
                 -1.5, 2199.0, 6.1])
GNSS = np.array([1.234567, 34.9054321, -117.8839876, 21000.5, 2199.5, -3.25, 1.5, 3.0, 12.0,
                 1.5, 3.0, 0.1])


def _codec_sensor_frames(c, stamp_us, meas, thr_pct, gnss):
    out = c.attitude_encode((stamp_us // 1000) % (1 << 32), *meas[1:7]).pack(c)
    c.seq = (c.seq + 1) & 0xFF
    out += c.aoa_ssa_encode(stamp_us, meas[7] / DEG, meas[8] / DEG).pack(c)
    c.seq = (c.seq + 1) & 0xFF
    out += c.vfr_hud_encode(meas[9], meas[12], int(meas[13] / DEG + 0.5) % 360,
                            int(thr_pct + 0.5), meas[10], meas[11]).pack(c)
    c.seq = (c.seq + 1) & 0xFF
    if gnss is not None:
        out += c.gps_input_encode(stamp_us, 0, 0, 0, 0, int(gnss[7]), round(gnss[1] * 1e7),
                                  round(gnss[2] * 1e7), gnss[3], 1.0, 1.0, gnss[4], gnss[5],
                                  gnss[6], gnss[11], gnss[9], gnss[10], int(gnss[8]), 0).pack(c)
    return out


@pytest.mark.parametrize("gnss", [None, GNSS])
@pytest.mark.parametrize("seq", [0, 200, 254])
def test_sensor_framer_is_byte_identical_to_the_codec(gnss, seq):
    # GIVEN the same measurement, stamp, sequence and identity
    c = new_codec(2)
    c.seq = seq
    ref = _codec_sensor_frames(c, 123_456_789, MEAS, 42.0, gnss)
    buf = bytearray(512)
    # WHEN the lean framer packs the datagram
    n, frames = SensorFramer().pack_into(buf, memoryview(buf), seq, 2, 1, 123_456_789, MEAS,
                                         42.0, gnss)
    # THEN the bytes are the codec's, frame count included
    assert bytes(buf[:n]) == ref and frames == (3 if gnss is None else 4)


@pytest.mark.parametrize("args", [(0, 1500, 1500, 1500, 0), (123456, 1000, 2000, 1500, 1420),
                                  (0xFFFFFFFF, 0, 0, 0, 0), (256, 0, 0, 0, 2000)])
@pytest.mark.parametrize("seq", [0, 7, 255])
def test_servo_packer_is_byte_identical_and_decodes_back(args, seq):
    c = new_codec(1)
    c.seq = seq
    ref = c.servo_output_raw_encode(args[0], 0, *args[1:5], 0, 0, 0, 0).pack(c)
    got = ServoPacker(1).pack(seq, *args)
    assert got == ref
    assert ServoDecoder().decode(got, len(got)) == (1,) + args


def test_servo_decoder_rejects_damage():
    frame = ServoPacker(1).pack(3, 987654, 1234, 1766, 0, 1500)
    dec = ServoDecoder()
    bad = bytearray(frame)
    bad[-1] ^= 0x01                                        # CRC
    assert dec.decode(bad, len(bad)) is None
    assert dec.decode(frame + b"\0", len(frame) + 1) is None   # not exactly one frame
    c = new_codec(1)
    other = c.attitude_encode(1, 0, 0, 0, 0, 0, 0).pack(c)
    assert dec.decode(other, len(other)) is None


def test_sensor_decoder_gives_the_layout_and_rejects_damage():
    buf = bytearray(512)
    n, _ = SensorFramer().pack_into(buf, memoryview(buf), 0, 2, 1, 1_234_567, MEAS, 42.0, GNSS)
    data = bytes(buf[:n])
    dec = SensorDecoder()
    out = np.full(layout.M_N, np.nan)
    assert dec.decode(data, 2, out) == 1_234_567
    assert out[layout.M_T_S] == pytest.approx(1.234567)
    np.testing.assert_allclose(out[1:], MEAS[1:], rtol=1e-6, atol=0.6 * DEG)  # f32, integer heading
    assert dec.gps is not None and dec.gps[2] == round(GNSS[1] * 1e7)
    assert dec.decode(data, 9, out) == -1                   # another system id
    bad = bytearray(data)
    bad[15] ^= 0x40
    assert dec.decode(bytes(bad), 2, out) == -1             # CRC


def test_lean_framer_is_byte_identical_for_every_message_it_frames():
    c = new_codec(1, 1)
    lf = LeanFramer(1, 1)
    assert lf.ok
    msgs = (c.attitude_encode(123, 0.1, -0.2, 0.3, 0.0, 1e-3, -2.5),
            c.heartbeat_encode(1, 0, 129, 2, 4),
            c.statustext_encode(6, b"x" * 50),
            c.param_value_encode(b"CMD_ALPHA_DEG", 5.0, 9, 40, 3),
            c.sys_status_encode(1, 1, 1, 500, 0, -1, -1, 0, 0, 0, 0, 0, 0),
            c.global_position_int_encode(1, 349054000, -1178839000, 21_000_000, 0, 2200, 0, 0, 9000),
            c.gps_raw_int_encode(10, 3, 1, -1, 0, 65535, 65535, 65535, 0, 12, 0, 1500, 3000, 100,
                                 0, 0),
            c.system_time_encode(0, 0))
    for seq, msg in enumerate(msgs):
        c.seq = seq * 37 % 256
        assert lf.frame(msg, c.seq) == msg.pack(c), msg.get_type()


def test_crc16_is_the_codecs():
    data = bytes(range(200))
    ref = mavlink.x25crc()
    ref.accumulate(data)
    assert crc16(data) == ref.crc
    assert crc16(data[100:], crc16(data[:100])) == ref.crc    # chained


# ---- host:port ---------------------------------------------------------------------------
def test_parse_hostport():
    assert parse_hostport("127.0.0.1:14550") == ("127.0.0.1", 14550)
    assert parse_hostport("localhost:0") == ("localhost", 0)
    for bad in ("14550", ":9", "host:", "host:x", "host:70000", "h:-1"):
        with pytest.raises(ValueError, match="HOST:PORT|port"):
            parse_hostport(bad)
        with pytest.raises(ValueError, match="^--fc: "):
            parse_hostport(bad, "--fc")


# ---- the timeline reader -----------------------------------------------------------------
def test_timeline_is_sorted_stably_and_keeps_what_each_entry_gives():
    raw = [{"t_s": 3.0, "mu_deg": -2}, {"t_s": 0.0, "alpha_deg": 5, "beta_deg": 0.0, "mu_deg": 4},
           {"t_s": 3.0, "alpha_deg": 1.0}]
    e = timeline.read_entries(raw, src="x.toml")
    assert e == [{"t_s": 0.0, "alpha_deg": 5.0, "beta_deg": 0.0, "mu_deg": 4.0},
                 {"t_s": 3.0, "mu_deg": -2.0}, {"t_s": 3.0, "alpha_deg": 1.0}]
    # a left-out angle holds its previous value; before the first it is the default 0 deg
    assert timeline.rows(e) == [(0.0, 5.0, 0.0, 4.0), (3.0, 5.0, 0.0, -2.0), (3.0, 1.0, 0.0, -2.0)]
    assert timeline.rows([{"t_s": 1.0, "mu_deg": 3.0}]) == [(1.0, 0.0, 0.0, 3.0)]


def test_empty_timeline_is_valid_and_means_the_defaults():
    assert timeline.read_entries(None) == [] and timeline.read_entries([]) == []
    t, cmd = timeline.command_arrays([])
    assert t.tolist() == [0.0] and cmd.tolist() == [[0.0, 0.0, 0.0]]
    with pytest.raises(timeline.TimelineError, match="no \\[\\[target\\]\\]"):
        timeline.target_arrays([])           # a target has no default


def test_arrays_are_si():
    t, cmd = timeline.command_arrays([(0.0, 5.0, 0.0, 4.0), (3.0, 5.0, -1.0, -2.0)])
    assert t.tolist() == [0.0, 3.0] and cmd.shape == (2, 3) and cmd.flags.c_contiguous
    np.testing.assert_allclose(cmd, np.radians([[5.0, 0.0, 4.0], [5.0, -1.0, -2.0]]))
    t, tg = timeline.target_arrays(timeline.rows(timeline.read_entries(
        [{"t_s": 0.0, "alt_m": 28000.0, "course_deg": 90.0, "speed_m_s": 2250.0}],
        timeline.TARGET), timeline.TARGET))
    assert t.tolist() == [0.0] and tg[0, 0] == 28000.0 and tg[0, 1] == pytest.approx(math.pi / 2)


@pytest.mark.parametrize("raw, match", [
    ({"t_s": 0}, "must be an array of tables"),
    ([1.0], r"command\[0\] must be a table"),
    ([{"alpha_deg": 1.0}], r"'command\[0\].t_s' is missing"),
    ([{"t_s": 0.0, "foo": 1}], r"unknown key 'command\[0\].foo'"),
    ([{"t_s": 0.0}, {"t_s": 1.0, "alpha_deg": math.nan}], r"'command\[1\].alpha_deg': must be finite"),
    ([{"t_s": 0.0, "mu_deg": 400.0}], r"'command\[0\].mu_deg': 400.0 is outside"),
    ([{"t_s": -1.0}], r"'command\[0\].t_s'"),
    ([{"t_s": True}], "expected a number"),
])
def test_timeline_errors_name_the_file_and_entry(raw, match):
    with pytest.raises(timeline.TimelineError, match=match) as exc:
        timeline.read_entries(raw, src="tl.toml")
    assert str(exc.value).startswith("tl.toml")
    assert isinstance(exc.value, ValueError)


def test_first_target_must_give_every_key(tmp_path):
    path = tmp_path / "tg.toml"
    path.write_text("[[target]]\nt_s = 0.0\nalt_m = 1000.0\ncourse_deg = 0.0\n")
    entries = timeline.read_file(path, timeline.TARGET)
    with pytest.raises(timeline.TimelineError, match=r"target\[0\].speed_m_s"):
        timeline.rows(entries, timeline.TARGET, str(path))


def test_read_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[[command]\n")
    with pytest.raises(timeline.TimelineError, match="bad.toml: not valid TOML"):
        timeline.read_file(bad)
    with pytest.raises(timeline.TimelineError, match="cannot read"):
        timeline.read_file(tmp_path / "missing.toml")


# ---- numba cache helper ------------------------------------------------------------------
def test_stale_numba_cache_is_dropped(tmp_path):
    mod = tmp_path / "kern.py"
    dep = tmp_path / "dep.py"
    mod.write_text("#\n")
    dep.write_text("#\n")
    pyc = tmp_path / "__pycache__"
    pyc.mkdir()
    files = [pyc / "kern.f-1.py311.nbi", pyc / "kern.f-1.py311.1.nbc"]
    other = pyc / "other.g-1.py311.nbi"
    for f in files + [other]:
        f.write_bytes(b"x")
    now = time.time()
    os.utime(dep, (now - 100, now - 100))
    for f in files:
        os.utime(f, (now, now))
    # GIVEN a cache newer than its dependency: kept
    assert numba_cache.drop_stale(mod, [dep]) == 0 and all(f.exists() for f in files)
    # WHEN the dependency changes after the cache was written: the module's cache goes
    os.utime(dep, (now + 100, now + 100))
    assert numba_cache.drop_stale(mod, [dep]) == 2
    assert not any(f.exists() for f in files) and other.exists()
    # no cache, or a missing dependency: nothing to do, no error
    assert numba_cache.drop_stale(tmp_path / "none.py", [dep]) == 0
    assert numba_cache.drop_stale(mod, [tmp_path / "gone.py"]) == 0


def test_contract_imports_nothing_of_ours():
    import ast
    import pathlib
    root = pathlib.Path(timeline.__file__).parent
    for f in root.glob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            for n in names:
                assert n.split(".")[0] not in ("fc", "plant_sim", "tools", "tests"), (f.name, n)
