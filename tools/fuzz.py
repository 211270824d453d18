"""tools/fuzz.py - malformed input for every port of the fc and the plant (promise 4).

Three targets, each a UDP port a peer may write to:

- ``fc-plant``: the fc's plant link (``--plant-bind``), normally fed sensor frames by the plant;
- ``fc-gcs``: the fc's ground-station socket (``--gcs-bind``);
- ``plant``: the plant's socket (``--bind``), normally fed SERVO_OUTPUT_RAW by the fc.

``datagram(target, rng)`` draws one hostile datagram: random bytes, a valid frame mutated
(tools.sitl.linkimpair.mutate: bit flips, truncation, garbage), a valid frame with a bad CRC, a
frame of the wrong message type, a valid frame whose fields are NaN/Inf/huge, a MAVLink 1
frame, a burst of frames glued together. ``corpus()`` is the recorded, deterministic set
(tests/fuzz_corpus/, replayed by tests/hil/test_reliability_fuzz.py).

The long run (by hand; not CI)::

    python -m tools.fuzz run --duration 600 --seed 1 [--rate 2000] [--out DIR]
                             [--targets fc-plant,fc-gcs,plant] [--corrupt 0.1]

flies the cruise scenario in CRUISE in real time (tools.sitl.rig.Rig, its default) with the
plant link corrupting 10 % of datagrams in flight both ways (so each process decodes mutated
frames from its legitimate peer) and a fuzzer writing ``--rate`` datagrams/s to the fc's
ground-station port and, from foreign addresses, to the fc's plant port and the plant's port.
Every second it checks that both processes are alive; at the end both must exit 0. Any death
is reported with the last inputs sent (written to ``OUT/last_inputs/``, ready to be added to
the corpus). Prints the rejected-input counters of both processes.

    python -m tools.fuzz corpus --write tests/fuzz_corpus    # regenerate the recorded corpus
"""
from __future__ import annotations

import argparse
import json
import math
import os
import random
import socket
import struct
import sys
import tempfile
import time
from collections import deque
from pathlib import Path

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as ml  # noqa: E402

from tools.sitl.linkimpair import Impairment, mutate  # noqa: E402

TARGETS = ("fc-plant", "fc-gcs", "plant")
#: Commands that arm, change the mode or steer the vehicle (COMMAND_LONG and COMMAND_INT share
#: one handler): a random command number that hits one is sent as an unknown one instead, so
#: the fuzzer never flies the vehicle (the real ARM/DO_SET_MODE go only with hostile values).
FLYING_COMMANDS = frozenset({ml.MAV_CMD_COMPONENT_ARM_DISARM, ml.MAV_CMD_DO_SET_MODE,
                             ml.MAV_CMD_NAV_RETURN_TO_LAUNCH, ml.MAV_CMD_DO_REPOSITION,
                             ml.MAV_CMD_DO_ORBIT, ml.MAV_CMD_DO_SET_STANDARD_MODE,
                             ml.MAV_CMD_DO_CHANGE_SPEED, ml.MAV_CMD_DO_CHANGE_ALTITUDE,
                             ml.MAV_CMD_GUIDED_CHANGE_SPEED, ml.MAV_CMD_GUIDED_CHANGE_ALTITUDE,
                             ml.MAV_CMD_GUIDED_CHANGE_HEADING, ml.MAV_CMD_USER_1,
                             ml.MAV_CMD_DO_SET_MISSION_CURRENT})
UNKNOWN_COMMAND = 31999
HOSTILE_FLOATS = (float("nan"), float("inf"), float("-inf"), 1e38, -1e38, 3.4e38, 0.0, -0.0,
                  1e-45, 65535.0, -1.0)


class _Null:
    def write(self, _b):
        return None


def codec(sysid: int, compid: int = 1) -> ml.MAVLink:
    return ml.MAVLink(_Null(), srcSystem=sysid, srcComponent=compid)


def pack(mav: ml.MAVLink, msg) -> bytes:
    b = msg.pack(mav)
    mav.seq = (mav.seq + 1) % 256
    return b


def sensor_frame(mav, stamp_us: int, vals: tuple | None = None) -> bytes:
    """ATTITUDE + AOA_SSA + VFR_HUD in one datagram (docs/wire.md 2). ``vals``: 12 floats
    roll, pitch, yaw, p, q, r, aoa_deg, ssa_deg, airspeed, groundspeed, alt, climb."""
    v = vals or (0.0, 0.05, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 2200.0, 2200.0, 21000.0, 0.0)
    return (pack(mav, mav.attitude_encode((stamp_us // 1000) & 0xFFFFFFFF, *v[0:6]))
            + pack(mav, mav.aoa_ssa_encode(stamp_us & 0xFFFFFFFFFFFFFFFF, v[6], v[7]))
            + pack(mav, mav.vfr_hud_encode(v[8], v[9], 0, 0, v[10], v[11])))


def servo_frame(mav, stamp_u32: int, pwm=(1500, 1500, 1500)) -> bytes:
    return pack(mav, mav.servo_output_raw_encode(stamp_u32 & 0xFFFFFFFF, 0, *pwm, 0, 0, 0, 0, 0))


def _f(rng: random.Random) -> float:
    return rng.choice(HOSTILE_FLOATS) if rng.random() < 0.6 else rng.uniform(-1e6, 1e6)


def _random_command(rng) -> int:
    """A random MAV_CMD number that is none of FLYING_COMMANDS."""
    cmd = rng.randrange(65536)
    return UNKNOWN_COMMAND if cmd in FLYING_COMMANDS else cmd


def gcs_message(mav, rng: random.Random) -> bytes:
    """A well-formed ground-station message with hostile field values."""
    k = rng.randrange(10)
    tgt = rng.choice((0, 1, 1, 1, 255))
    if k == 0:
        name = rng.choice((b"FS_TIMEOUT_S", b"CO_ENABLE", b"CMD_ALPHA_DEG", b"TRIM_RUD_DEG",
                           b"NO_SUCH", b"", b"\xff\xfe" * 8, bytes(rng.getrandbits(8)
                                                               for _ in range(16))))
        return pack(mav, mav.param_set_encode(tgt, 1, name, _f(rng), rng.randrange(256)))
    if k == 1:
        cmd = rng.choice((ml.MAV_CMD_COMPONENT_ARM_DISARM, ml.MAV_CMD_DO_SET_MODE, ml.MAV_CMD_USER_1,
                          ml.MAV_CMD_SET_MESSAGE_INTERVAL, ml.MAV_CMD_REQUEST_MESSAGE,
                          ml.MAV_CMD_GET_MESSAGE_INTERVAL, ml.MAV_CMD_PREFLIGHT_STORAGE,
                          _random_command(rng)))
        # the real arm/mode commands only with hostile values: the fuzzer must not fly it
        p = [_f(rng) for _ in range(7)]
        if cmd in (ml.MAV_CMD_COMPONENT_ARM_DISARM, ml.MAV_CMD_DO_SET_MODE) and all(
                math.isfinite(x) for x in p[:2]):
            p[0] = p[1] = float("nan")
        return pack(mav, mav.command_long_encode(tgt, 1, cmd, rng.randrange(256), *p))
    if k == 2:
        return pack(mav, mav.command_int_encode(tgt, 1, rng.randrange(256), _random_command(rng),
                                                0, 0, *[_f(rng) for _ in range(4)],
                                                rng.randrange(-2**31, 2**31),
                                                rng.randrange(-2**31, 2**31), _f(rng)))
    if k == 3:
        return pack(mav, mav.param_request_read_encode(tgt, 1, bytes(rng.getrandbits(8)
                                                                     for _ in range(16)),
                                                       rng.randrange(-32768, 32768)))
    if k == 4:
        return pack(mav, mav.request_data_stream_encode(tgt, 1, rng.randrange(256),
                                                        rng.randrange(65536), rng.randrange(256)))
    if k == 5:
        return pack(mav, mav.set_mode_encode(tgt, rng.randrange(256), rng.choice(
            (rng.randrange(2**32), 4, 99, 2**32 - 1))))
    if k == 6:
        return pack(mav, mav.mission_count_encode(tgt, 1, rng.randrange(65536), rng.randrange(256)))
    if k == 7:
        return pack(mav, mav.param_request_list_encode(tgt, 1))
    if k == 8:
        return pack(mav, mav.statustext_encode(rng.randrange(256),
                                               bytes(rng.getrandbits(8) for _ in range(50))))
    return pack(mav, mav.servo_output_raw_encode(0, 0, *[rng.randrange(65536) for _ in range(8)]))


def datagram(target: str, rng: random.Random, stamp_us: int = 1_000_000) -> bytes:
    """One hostile datagram for ``target`` (see the module docstring)."""
    k = rng.randrange(8)
    if target == "plant":
        good = servo_frame(codec(1), stamp_us // 1 & 0xFFFFFFFF,
                           tuple(rng.randrange(900, 2100) for _ in range(3)))
    elif target == "fc-plant":
        good = sensor_frame(codec(2), stamp_us)
    else:
        good = gcs_message(codec(rng.choice((255, 250, 2, 1))), rng)
    if k == 0:
        return bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 300)))
    if k == 1:
        return mutate(good, rng)
    if k == 2:                                   # bad CRC only
        b = bytearray(good)
        b[-1] ^= 0xFF
        return bytes(b)
    if k == 3:                                   # wrong message type for this port
        mav = codec(rng.choice((1, 2, 7)))
        return gcs_message(mav, rng) if target != "fc-gcs" else sensor_frame(mav, stamp_us)
    if k == 4:                                   # valid frame, hostile values
        if target == "fc-plant":
            return sensor_frame(codec(2), rng.randrange(2**64), tuple(_f(rng) for _ in range(12)))
        if target == "plant":
            return servo_frame(codec(1), rng.randrange(2**32),
                               tuple(rng.choice((0, 1, 999, 2001, 65535)) for _ in range(3)))
        return gcs_message(codec(255), rng)
    if k == 5:                                   # MAVLink 1 frame
        m1 = ml.MAVLink(_Null(), srcSystem=2, srcComponent=1)
        m1.WIRE_PROTOCOL_VERSION = "1.0"
        try:
            return m1.heartbeat_encode(1, 0, 0, 0, 0).pack(m1, force_mavlink1=True)
        except TypeError:
            return good[:6]
    if k == 6:                                   # many frames glued, some cut
        return b"".join(mutate(good, rng) if rng.random() < 0.3 else good
                        for _ in range(rng.randint(2, 12)))[:2000]
    return good[:rng.randrange(len(good))]       # truncated


def corpus() -> dict[str, bytes]:
    """The recorded corpus: named, deterministic hostile datagrams (all targets)."""
    out: dict[str, bytes] = {}
    m2 = codec(2)
    good_sensor = sensor_frame(m2, 1_000_000)
    good_servo = servo_frame(codec(1), 1_000_000 & 0xFFFFFFFF)
    good_gcs = pack(codec(255), codec(255).param_request_list_encode(1, 1))
    out["empty"] = b""
    out["one_stx_v2"] = b"\xfd"
    out["one_stx_v1"] = b"\xfe"
    out["stx_only_run"] = b"\xfd" * 300
    out["zeros_300"] = bytes(300)
    out["ff_300"] = b"\xff" * 300
    out["v2_header_len255_no_payload"] = bytes([0xFD, 255, 0, 0, 0, 2, 1, 30, 0, 0])
    out["v2_unknown_msgid"] = bytes([0xFD, 4, 0, 0, 0, 2, 1, 0xAB, 0xCD, 0xEF, 1, 2, 3, 4, 0, 0])
    out["v2_signed_flag_no_signature"] = bytes([0xFD, 0, 1, 0, 0, 2, 1, 0, 0, 0, 0, 0])
    out["v2_incompat_unknown_flag"] = bytes([0xFD, 0, 0x80, 0, 0, 2, 1, 0, 0, 0, 0, 0])
    for n in (1, 5, 9, 10, 11, 20, 40, len(good_sensor) - 1):
        out[f"sensor_truncated_{n}"] = good_sensor[:n]
    b = bytearray(good_sensor)
    b[12] ^= 0x01
    out["sensor_bad_crc_first"] = bytes(b)
    b = bytearray(good_sensor)
    b[-1] ^= 0xFF
    out["sensor_bad_crc_last"] = bytes(b)
    out["sensor_doubled"] = good_sensor + good_sensor
    out["sensor_plus_garbage"] = good_sensor + b"\x00\xfd\x09garbage"
    out["sensor_wrong_sysid_7"] = sensor_frame(codec(7), 1_000_000)
    out["sensor_attitude_only"] = good_sensor[:40]
    for name, v in (("nan", float("nan")), ("inf", float("inf")), ("ninf", float("-inf")),
                    ("huge", 3.4e38)):
        out[f"sensor_all_{name}"] = sensor_frame(codec(2), 1_002_000, (v,) * 12)
        out[f"sensor_aoa_{name}"] = sensor_frame(
            codec(2), 1_004_000, (0.0, 0.05, 0.0, 0.0, 0.0, 0.0, v, 0.0, 2200.0, 2200.0, 21000.0,
                                  0.0))
    out["sensor_stamp_max_u64"] = sensor_frame(codec(2), 2**64 - 1)
    out["sensor_stamp_zero"] = sensor_frame(codec(2), 0)
    out["servo_pwm_0"] = servo_frame(codec(1), 1000, (0, 0, 0))
    out["servo_pwm_65535"] = servo_frame(codec(1), 1000, (65535, 65535, 65535))
    out["servo_wrong_sysid_9"] = servo_frame(codec(9), 1000, (2000, 2000, 2000))
    out["servo_truncated"] = good_servo[:15]
    b = bytearray(good_servo)
    b[-2] ^= 0x55
    out["servo_bad_crc"] = bytes(b)
    out["heartbeat_to_plant"] = pack(codec(1), codec(1).heartbeat_encode(1, 0, 0, 0, 0))
    mav = codec(255)
    out["gcs_param_set_nan"] = pack(mav, mav.param_set_encode(1, 1, b"FS_TIMEOUT_S", float("nan"), 9))
    out["gcs_param_set_inf"] = pack(mav, mav.param_set_encode(1, 1, b"FS_TIMEOUT_S", float("inf"), 9))
    out["gcs_param_set_unknown"] = pack(mav, mav.param_set_encode(1, 1, b"NOPE", 1.0, 9))
    out["gcs_param_set_binary_name"] = pack(mav, mav.param_set_encode(1, 1, b"\xff" * 16, 1.0, 9))
    out["gcs_param_read_index_neg"] = pack(mav, mav.param_request_read_encode(1, 1, b"", -2))
    out["gcs_param_read_index_big"] = pack(mav, mav.param_request_read_encode(1, 1, b"", 32767))
    out["gcs_cmd_mode_nan"] = pack(mav, mav.command_long_encode(
        1, 1, ml.MAV_CMD_DO_SET_MODE, 0, float("nan"), float("nan"), 0, 0, 0, 0, 0))
    out["gcs_cmd_mode_huge"] = pack(mav, mav.command_long_encode(
        1, 1, ml.MAV_CMD_DO_SET_MODE, 0, 1, 3.4e38, 0, 0, 0, 0, 0))
    out["gcs_cmd_interval_nan"] = pack(mav, mav.command_long_encode(
        1, 1, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 0, float("nan"), float("nan"), 0, 0, 0, 0, 0))
    out["gcs_cmd_interval_tiny"] = pack(mav, mav.command_long_encode(
        1, 1, ml.MAV_CMD_SET_MESSAGE_INTERVAL, 0, 30, 1e-30, 0, 0, 0, 0, 0))
    # found by `python -m tools.fuzz run` (seed 2): a message id outside u16 made the
    # MESSAGE_INTERVAL answer unpackable and killed the fc from its send path
    for name, v in (("huge", 1e6), ("neg", -5.0), ("u16max_plus1", 65536.0)):
        out[f"gcs_cmd_get_interval_{name}"] = pack(mav, mav.command_long_encode(
            1, 1, ml.MAV_CMD_GET_MESSAGE_INTERVAL, 0, v, 0, 0, 0, 0, 0, 0))
    out["gcs_cmd_request_msg_inf"] = pack(mav, mav.command_long_encode(
        1, 1, ml.MAV_CMD_REQUEST_MESSAGE, 0, float("inf"), 0, 0, 0, 0, 0, 0))
    out["gcs_cmd_user1_nan_all"] = pack(mav, mav.command_long_encode(
        1, 1, ml.MAV_CMD_USER_1, 0, *([float("nan")] * 7)))
    out["gcs_cmd_unknown"] = pack(mav, mav.command_long_encode(1, 1, 65535, 255, *([0.0] * 7)))
    out["gcs_set_mode_u32max"] = pack(mav, mav.set_mode_encode(1, 255, 2**32 - 1))
    out["gcs_data_stream_rate_max"] = pack(mav, mav.request_data_stream_encode(1, 1, 0, 65535, 1))
    out["gcs_mission_count_max"] = pack(mav, mav.mission_count_encode(1, 1, 65535, 255))
    out["gcs_from_sysid_1"] = pack(codec(1), codec(1).param_request_list_encode(1, 1))
    b = bytearray(good_gcs)
    b[2] |= 0x01                                 # claims to be signed, no signature
    out["gcs_fake_signed_flag"] = bytes(b)
    out["gcs_signed_garbage_signature"] = good_gcs[:-2] + bytes(2) + bytes(13)
    # the protocol services of docs/fc.md section 7a (issue 21)
    out["gcs_ftp_all_ff"] = pack(mav, mav.file_transfer_protocol_encode(0, 1, 1, [255] * 251))
    path = b"../../../../etc/passwd"
    ftp_open = [0, 0, 0, 4, len(path), 0, 0, 0, 0, 0, 0, 0] + list(path)
    out["gcs_ftp_open_outside"] = pack(mav, mav.file_transfer_protocol_encode(
        0, 1, 1, ftp_open + [0] * (251 - len(ftp_open))))
    burst = [0, 0, 7, 15, 255, 0, 0, 0, 255, 255, 255, 255]       # no session, offset u32 max
    out["gcs_ftp_burst_no_session"] = pack(mav, mav.file_transfer_protocol_encode(
        0, 1, 1, burst + [0] * (251 - len(burst))))
    out["gcs_log_data_u32max"] = pack(mav, mav.log_request_data_encode(
        1, 1, 1, 2**32 - 1, 2**32 - 1))
    out["gcs_log_list_reversed"] = pack(mav, mav.log_request_list_encode(1, 1, 65535, 0))
    out["gcs_timesync_extremes"] = pack(mav, mav.timesync_encode(0, -2**63))
    rng = random.Random(20261122)
    for i in range(24):
        t = TARGETS[i % 3]
        out[f"random_{t}_{i:02d}"] = datagram(t, rng)
    return out


def write_corpus(directory: str) -> int:
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    items = corpus()
    for name, data in items.items():
        (d / f"{name}.bin").write_bytes(data)
    (d / "README.md").write_text(
        "# Recorded fuzz corpus (promise 4, docs/reliability.md)\n\n"
        "One hostile UDP datagram per `.bin` file, replayed by tests/hil/test_reliability_fuzz.py\n"
        "to every port of the fc (plant link, ground-station link) and to the plant. Regenerate\n"
        "with `python -m tools.fuzz corpus --write tests/fuzz_corpus`; add any input that ever\n"
        "crashed a process here (tools.fuzz run writes them to OUT/last_inputs/).\n")
    return len(items)


def load_corpus(directory: str) -> dict[str, bytes]:
    return {p.stem: p.read_bytes() for p in sorted(Path(directory).glob("*.bin"))}


# ---------------------------------------------------------------------- long run
def run(args) -> int:
    from tools.sitl.rig import Rig, RigConfig, tracking_error_deg  # noqa: F401
    out = Path(args.out or tempfile.mkdtemp(prefix="hyfc-fuzz-"))
    imp = Impairment(corrupt=args.corrupt)
    cfg = RigConfig(out=out, duration_s=args.duration, seed=args.seed, impair_up=imp,
                    impair_down=imp)
    rng = random.Random(args.seed)
    targets = tuple(args.targets.split(","))
    bad = set(targets) - set(TARGETS)
    if bad:
        raise SystemExit(f"unknown --targets {sorted(bad)}; choose from {','.join(TARGETS)}")
    last: deque = deque(maxlen=64)
    sent = {t: 0 for t in TARGETS}
    report: dict = {"duration_s": args.duration, "seed": args.seed, "rate_hz": args.rate,
                    "corrupt": args.corrupt, "out": str(out)}
    dead = None
    with Rig(cfg) as rig:
        rig.start()
        ports = {"fc-plant": rig.plant_port, "fc-gcs": rig.gcs_bind_port,
                 "plant": rig.plant_bind_port}
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        t0 = time.monotonic()
        n = 0
        next_check = t0 + 1.0
        while time.monotonic() - t0 < args.duration - 1.0:
            due = t0 + n / args.rate
            now = time.monotonic()
            if due > now:
                time.sleep(due - now)   # pacing of a load generator
            t = targets[rng.randrange(len(targets))]
            d = datagram(t, rng, stamp_us=int((now - t0) * 1e6))
            last.append((t, d))
            try:
                s.sendto(d, ("127.0.0.1", ports[t]))
            except OSError:
                pass
            sent[t] += 1
            n += 1
            if now >= next_check:
                next_check = now + 1.0
                for p in (rig.fc, rig.plant):
                    if p.proc.poll() is not None:
                        dead = (p.name, p.proc.returncode)
                if dead:
                    break
        s.close()
        rcs = rig.finish()
        report["exit_codes"] = rcs
        report["sent"] = sent
        report["relay"] = rig.relay.counters
        try:
            ps = rig.plant_summary()
            report["plant_rejected"] = {k: ps.get(k) for k in (
                "rejected_malformed", "rejected_source", "rejected_sysid", "ignored_messages")}
        except OSError as exc:
            report["plant_rejected"] = f"no summary: {exc}"
        report["fc_named_values"] = {k: v for k, v in rig.gcs.named.items()
                                     if k in ("REJ_PLANT", "REJ_GCS", "REJ_SIGN", "EST_INVAL")}
        ok = dead is None and rcs == {"plant": 0, "fc": 0}
        if not ok:
            d = out / "last_inputs"
            d.mkdir(exist_ok=True)
            for i, (t, data) in enumerate(last):
                (d / f"{i:02d}_{t}.bin").write_bytes(data)
            report["died"] = dead
            report["last_inputs"] = str(d)
    print(json.dumps(report, indent=2))
    return 0 if ok else 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.fuzz",
                                 description="Malformed-input fuzzing of the fc and plant ports.")
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="long fuzz run against the real processes (by hand)")
    r.add_argument("--duration", type=float, default=600.0, help="seconds (600)")
    r.add_argument("--seed", type=int, default=1, help="random seed of the fuzzer (1)")
    r.add_argument("--rate", type=float, default=2000.0, help="fuzz datagrams per second (2000)")
    r.add_argument("--corrupt", type=float, default=0.1,
                   help="fraction of plant-link datagrams mutated in flight (0.1)")
    r.add_argument("--out", help="run directory (default: a new temp directory)")
    r.add_argument("--targets", default=",".join(TARGETS),
                   help="comma-separated ports to fuzz (default: all: fc-plant,fc-gcs,plant)")
    c = sub.add_parser("corpus", help="write the recorded corpus")
    c.add_argument("--write", required=True, metavar="DIR",
                   help="directory to write the corpus files into")
    args = ap.parse_args(argv)
    if args.cmd == "corpus":
        print(f"{write_corpus(args.write)} datagrams written to {args.write}")
        return 0
    if not (args.duration >= 5 and 0 < args.rate <= 50000 and 0 <= args.corrupt <= 1):
        ap.error("--duration >= 5, 0 < --rate <= 50000, 0 <= --corrupt <= 1")
    return run(args)


if __name__ == "__main__":
    raise SystemExit(main())
