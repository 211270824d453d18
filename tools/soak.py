"""``python -m tools.soak``: the real-time soak, and ``python -m tools.soak flood`` (the
ground-station flood process the rig's ``Flood`` starts).

Soak: flies the cruise scenario in CRUISE (the guidance holds altitude, course and speed;
``--scenario paper --flight-mode COORDINATED`` for the paper's step) in real time for
``--duration`` wall seconds with the plant link impaired (default: 5 % loss, 0-5 ms jitter,
1 % duplicates, 1 % reordering, both directions) and, optionally, a ground-station flood, then
prints the figures of docs/reliability.md: tracking error after settling (in CRUISE the hold
figures of tools/guided_hil.py: altitude, course, speed against the targets, the inner loop),
late ticks per 1000, rejected input counters, relay counters, failsafe entries, process exit
codes. The rig it stands on is ``tools.sitl.rig``.

    python -m tools.soak --duration 60 --flood-rate 2000 --seed 1 [--out DIR]
                         [--stall-max 1.0 --stall-every 60]

With ``--stall-max S`` the plant process is stopped at random (seeded) for 0.1..S s about every
``--stall-every`` s (plant freezes, tools.sitl.rig.PlantStaller). The figures include the
fc's and the plant's RSS and open file descriptors (sampled with each progress line), the
60 s windows that left the steady bounds, the FAILSAFE, recovery and stall texts.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import socket
import sys
import tempfile
import time
from pathlib import Path

from tools.sitl.linkimpair import Impairment
from tools.sitl.rig import (Flood, PlantStaller, Rig, RigConfig, late_ticks, proc_usage,
                            steady_figures, steady_violations, tracking_error_deg)


def flood_main(target: tuple[str, int], rate_hz: float, duration_s: float, seed: int,
               sysid: int) -> int:
    """Send the flood mix; prints ``FLOOD sent=N seconds=S``. Never more than rate*duration."""
    os.environ["MAVLINK20"] = "1"
    from pymavlink.dialects.v20 import ardupilotmega as ml

    class _Null:
        def write(self, _b):
            return None

    mav = ml.MAVLink(_Null(), srcSystem=sysid, srcComponent=190)
    rng = random.Random(seed)

    def pk(msg):
        b = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        return b

    templates = [
        lambda: pk(mav.param_request_list_encode(1, 1)),
        lambda: pk(mav.command_long_encode(1, 1, ml.MAV_CMD_REQUEST_MESSAGE, 0,
                                           ml.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)),
        lambda: pk(mav.command_long_encode(1, 1, 31337, 0, 0, 0, 0, 0, 0, 0, 0)),
        lambda: pk(mav.param_set_encode(1, 1, b"NO_SUCH_PARAM", 1.0, 9)),
        lambda: bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 120))),
        lambda: pk(mav.param_request_list_encode(1, 1))[:rng.randint(1, 8)],
    ]
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    n_total = int(rate_hz * duration_s)
    t0 = time.monotonic()
    sent = 0
    batch = max(1, int(rate_hz / 200))     # bursts every 5 ms
    while sent < n_total:
        due = t0 + sent / rate_hz
        now = time.monotonic()
        if due > now:
            time.sleep(due - now)   # pacing of a load generator, not a wait for an event
        for _ in range(min(batch, n_total - sent)):
            try:
                s.sendto(templates[rng.randrange(len(templates))](), target)
            except OSError:
                pass
            sent += 1
    print(f"FLOOD sent={sent} seconds={time.monotonic() - t0:.3f}", flush=True)
    return 0


# ---------------------------------------------------------------------- soak CLI
class _Say:
    """Progress lines on stderr (the figures go to stdout as JSON); silent if every_s <= 0."""

    def __init__(self, every_s: float):
        self.every_s = every_s

    def __call__(self, text: str) -> None:
        if self.every_s > 0:
            print(text, file=sys.stderr, flush=True)


def progress_line(rig: Rig, duration_s: float) -> str:
    """One line of a running soak: sim time, the fc's late ticks and rejected input (its
    NAMED_VALUE_FLOAT counters), FAILSAFE entries so far, what the relay dropped."""
    nv = rig.gcs.named
    with rig.gcs.cv:
        failsafes = sum(1 for _, _, t in rig.gcs.texts if "FAILSAFE" in t)
    dropped = sum(d.get("dropped", 0) for d in rig.relay.counters.values()) if rig.relay else 0
    return (f"soak: t = {rig.plant_time_now():7.1f} / {duration_s:g} s   late ticks "
            f"{nv.get('LATE_CNT', 0):.0f}   rejected gcs {nv.get('REJ_GCS', 0):.0f} plant "
            f"{nv.get('REJ_PLANT', 0):.0f}   failsafes {failsafes}   relay dropped {dropped}")


def watch_progress(rig: Rig, duration_s: float, say, usage: dict | None = None) -> None:
    """Until the plant has finished (bounded): a progress line every ``say.every_s`` s; each
    time, when ``usage`` is given, the fc's and the plant's RSS (kB) and open descriptors
    sampled into it (``usage[name]``: list of (wall s, rss kB, fds))."""
    deadline = time.monotonic() + duration_s * 3 + 60
    every = say.every_s if say.every_s > 0 else 1.0
    t0 = time.monotonic()
    while time.monotonic() < deadline:
        if rig.plant.wait_exit(min(every, max(0.0, deadline - time.monotonic()))) is not None:
            return
        if usage is not None:
            for name, p in (("fc", rig.fc), ("plant", rig.plant)):
                u = proc_usage(p.pid)
                if u is not None:
                    usage.setdefault(name, []).append((time.monotonic() - t0, *u))
        say(progress_line(rig, duration_s))


def usage_summary(samples: list) -> dict:
    """RSS (kB) and descriptors: first sample after 30 s (start-up done), last, max."""
    late = [s for s in samples if s[0] >= 30.0] or samples
    if not late:
        return {}
    return {"rss_kb_first": late[0][1], "rss_kb_last": late[-1][1],
            "rss_kb_max": max(s[1] for s in late), "fds_first": late[0][2],
            "fds_last": late[-1][2], "fds_max": max(s[2] for s in late),
            "samples": len(late)}


def soak(args) -> int:
    out = Path(args.out or tempfile.mkdtemp(prefix="hyfc-soak-"))
    imp = Impairment(loss=args.loss, jitter_s=args.jitter_ms * 1e-3, dup=args.dup,
                     reorder=args.reorder)
    guided = args.flight_mode != "COORDINATED"
    cfg = RigConfig(out=out, duration_s=args.duration, seed=args.seed, impair_up=imp,
                    impair_down=imp, scenario=args.scenario, flight_mode=args.flight_mode,
                    params={"REF_PF_EN": 1.0} if guided else {})
    fig: dict = {"duration_s": args.duration, "seed": args.seed, "impairment": imp.__dict__,
                 "scenario": args.scenario, "flight_mode": args.flight_mode,
                 "flood_rate_hz": args.flood_rate, "out": str(out)}
    say = _Say(args.progress_every)
    say(f"soak: {args.duration:g} s in real time, seed {args.seed}, run directory {out}")
    with Rig(cfg) as rig:
        rig.start()
        say(f"soak: fc (pid {rig.fc.pid}) and plant (pid {rig.plant.pid}) flying, armed")
        flood = None
        if args.flood_rate > 0:
            rig.wait_plant_time(1.0, 60)
            flood = Flood(("127.0.0.1", rig.gcs_bind_port), args.flood_rate,
                          max(0.0, args.duration - 2.0), seed=args.seed).start()
            say(f"soak: ground-station flood started ({args.flood_rate:g} datagrams/s)")
        staller = None
        if args.stall_max > 0:
            staller = PlantStaller(rig.plant.pid, args.stall_max, args.stall_every,
                                   seed=args.seed).start()
            say(f"soak: plant stalls up to {args.stall_max:g} s about every "
                f"{args.stall_every:g} s")
        usage: dict = {}
        try:
            watch_progress(rig, args.duration, say, usage)
        finally:
            if staller is not None:
                staller.stop()
        rcs = rig.finish()
        fig["usage"] = {k: usage_summary(v) for k, v in usage.items()}
        if staller is not None:
            fig["plant_stalls"] = {"count": len(staller.stalls),
                                   "max_s": max((d for _, d in staller.stalls), default=0.0),
                                   "total_s": sum(d for _, d in staller.stalls)}
        say(f"soak: done (exit codes plant {rcs['plant']}, fc {rcs['fc']}); figures follow")
        if flood is not None:
            fig["flood_sent"] = flood.wait(30)
        truth, internals = rig.truth(), rig.internals()
        fig["exit_codes"] = rcs
        if guided:
            from tools.sitl.metrics import hold_figures
            # after the engagement transient (10 s, or half of a shorter run)
            fig["hold_figures"] = hold_figures(truth, internals, min(10.0, 0.5 * args.duration))
        else:
            fig["tracking_error_deg_after_3s"] = tracking_error_deg(truth, 3.0)
        late, ticks = late_ticks(internals, t_from_s=1.0)
        fig["late_ticks"] = late
        fig["ticks"] = ticks
        fig["late_per_1000"] = 1000.0 * late / max(ticks, 1)
        fig["relay"] = rig.relay.counters
        ps = rig.plant_summary()
        fig["plant"] = {k: ps.get(k) for k in ("frames", "late_frames", "no_command_frames",
                                               "rejected_malformed", "rejected_source",
                                               "rejected_sysid", "real_time_factor")}
        fig["fc_named_values"] = {k: v for k, v in rig.gcs.named.items()
                                  if k in ("REJ_PLANT", "REJ_GCS", "REJ_SIGN", "LATE_CNT",
                                           "DUP_FRAMES", "FS_CAUSE", "SKIPPED", "OVERRUN")}
        fig["failsafe_texts"] = [t for _, _, t in rig.gcs.texts if "FAILSAFE" in t]
        fig["recovery_texts"] = [t for _, _, t in rig.gcs.texts if "data back" in t]
        fig["stall_texts"] = [t for _, _, t in rig.gcs.texts if "stalled" in t]
        if guided:
            # the steady bounds over the whole flight after the engagement, in 60 s windows
            t_end = float(truth["t_s"][-1])
            bad = []
            t = min(10.0, 0.5 * args.duration)
            while t < t_end - 1.0:
                w = steady_figures(truth, internals, t, min(t + 60.0, t_end + 1.0))
                v = steady_violations(w)
                if v:
                    bad.append({"from_s": t, "violations": v})
                t += 60.0
            fig["steady_windows_violated"] = bad
    print(json.dumps(fig, indent=2))
    ok = rcs["plant"] == 0 and rcs["fc"] == 0
    return 0 if ok else 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.soak",
                                 description="Real-time soak: cruise scenario with an impaired "
                                             "plant link and a ground-station flood; prints the "
                                             "figures of docs/reliability.md as JSON.")
    sub = ap.add_subparsers(dest="cmd")
    f = sub.add_parser("flood", help="send a bounded ground-station flood (used by the soak)")
    f.add_argument("--target", required=True, metavar="HOST:PORT",
                   help="the fc's ground-station socket")
    f.add_argument("--rate", type=float, default=2000.0,
                   help="datagrams per second, up to 100000 (2000)")
    f.add_argument("--duration", type=float, default=5.0, help="seconds, up to 3600 (5)")
    f.add_argument("--seed", type=int, default=0, help="seed of the message mix (0)")
    f.add_argument("--sysid", type=int, default=251,
                   help="MAVLink system id the flood sends as (251)")
    for p in (ap,):
        p.add_argument("--duration", type=float, default=60.0, help="wall/sim seconds (60)")
        p.add_argument("--scenario", default="cruise", help="plant scenario (cruise)")
        p.add_argument("--flight-mode", choices=("CRUISE", "COORDINATED"), default="CRUISE",
                       help="CRUISE: the guidance holds the state at arming (default); "
                            "COORDINATED: the paper's attitude step (with --scenario paper)")
        p.add_argument("--seed", type=int, default=1,
                       help="seed of the plant and of the link impairment (1)")
        p.add_argument("--loss", type=float, default=0.05,
                       help="plant link: fraction of datagrams dropped, each way (0.05)")
        p.add_argument("--jitter-ms", type=float, default=5.0,
                       help="plant link: extra delay, uniform 0..J ms, each way (5)")
        p.add_argument("--dup", type=float, default=0.01,
                       help="plant link: fraction of datagrams duplicated (0.01)")
        p.add_argument("--reorder", type=float, default=0.01,
                       help="plant link: fraction of datagrams reordered (0.01)")
        p.add_argument("--flood-rate", type=float, default=2000.0,
                       help="ground-station datagrams per second, 0 = no flood (2000)")
        p.add_argument("--stall-max", type=float, default=0.0, metavar="S",
                       help="random plant stalls (SIGSTOP) of 0.1..S s, 0 = none (0)")
        p.add_argument("--stall-every", type=float, default=60.0, metavar="S",
                       help="mean wall seconds between plant stalls (60)")
        p.add_argument("--out", help="run directory (default: a new temp directory)")
        p.add_argument("--progress-every", type=float, default=5.0, metavar="S",
                       help="a progress line on stderr every S wall seconds, 0 = none (5)")
    args = ap.parse_args(argv)
    if args.cmd == "flood":
        from tools.sitl.linkimpair import parse_hostport
        if args.rate <= 0 or args.rate > 100000 or args.duration < 0 or args.duration > 3600:
            ap.error("--rate must be in (0, 100000] and --duration in [0, 3600]")
        return flood_main(parse_hostport(args.target), args.rate, args.duration, args.seed,
                          args.sysid)
    return soak(args)


if __name__ == "__main__":
    raise SystemExit(main())
