"""Where the fc's CPU per plant frame goes (tools.bench; issue 16, "profile first").

    python -m tools.bench profile [--frames N] [--flight-mode COORDINATED|CRUISE|...]
                                  [--top K] [--sort tottime|cumtime] [--no-cprofile]
                                  [--record-only] [--json FILE]

Two passes over the same frames, in process and without a peer to wait for (the fc's share
of a lockstep exchange; the two UDP hops and the plant's work are the rest):

1. record: the stand-in plant physics (``tools.bench.standin.make_sim``, paper scenario at
   500 Hz) flies closed loop against a real ``fc.app.FlightController`` (lockstep, armed, the
   given flight mode, one ground-station output); the sensor datagrams it sends are kept.
2. replay: a fresh controller gets the recorded datagrams one at a time through its plant
   socket; its outputs are the same as in pass 1 (the fc is deterministic in its inputs), so
   it flies the same flight. Each step of its lockstep loop (``plant.read_frame_at``,
   ``loops.lockstep_exchange``, ``loops.housekeeping``) is what is measured:

   - parts: the controller's own callables (decode, estimator, guidance, law, PWM, framing,
     send, internals row, GCS poll, GCS streams, the .tlog's sim-paced streams, the 1 Hz
     chores) are wrapped on the instance with ``perf_counter_ns`` timers; the table gives,
     per part, its mean cost per frame (calls amortised over all frames), its median per
     call, calls per frame and its share of the instrumented total. "glue" rows are the
     parent's time outside the wrapped children (the Python between them). The wrappers cost
     about 0.1-0.2 us each; the uninstrumented replay's total is printed next to it.
   - cProfile (unless ``--no-cprofile``): the same replay again under ``cProfile``, enabled
     only around the controller's calls; the top ``--top`` functions by self time.

Shares (%) do not depend on the machine's load; microseconds do (the load average is
printed). Under valgrind (``valgrind --tool=callgrind python -m tools.bench profile
--record-only --frames N``, once as is and once with ``--baseline``) the difference of the
two instruction counts divided by N + 200 is the controller's user-space cost per frame in
instructions, independent of the load (slow: numba's start-up under valgrind takes many
minutes). Prints figures, asserts nothing.
"""
from __future__ import annotations

import argparse
import cProfile
import io
import json
import logging
import os
import pstats
import shutil
import socket
import sys
import tempfile
import time

import numpy as np

__all__ = ["record", "replay", "profile_parts", "profile_functions", "main"]

WARM_FRAMES = 200       # replayed before the measured frames (caches, first-call paths)


def _drain(*socks) -> None:
    for s in socks:
        while True:
            try:
                s.recv(65536)
            except (BlockingIOError, InterruptedError):
                break


class _Rig:
    """A lockstep controller with a plant socket and a ground-station sink on 127.0.0.1."""

    def __init__(self, flight_mode: str) -> None:
        from fc.app import FcConfig, FlightController
        self.dir = tempfile.mkdtemp(prefix="hyfc-profile-")
        self.sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.plant = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.fc = None
        for s in (self.sink, self.plant):
            s.bind(("127.0.0.1", 0))
            s.setblocking(False)
        log = logging.getLogger("tools.bench.profile")
        log.addHandler(logging.NullHandler())
        log.propagate = False
        cfg = FcConfig(mode="lockstep", plant_bind=("127.0.0.1", 0),
                       gcs=[self.sink.getsockname()], gcs_bind=("127.0.0.1", 0), out=self.dir,
                       arm=True, flight_mode=flight_mode)
        self.fc = FlightController(cfg, log)
        self.hk = self.fc.loops.housekeeping     # the Housekeeping part (1 Hz chores)
        self.hk.next_1hz = 0.0
        self.addr = self.fc.plant.endpoint.address
        from fc.scheduler import freeze_heap
        freeze_heap()           # as ``python -m fc`` before READY: no automatic collections

    def step(self, data: bytes) -> None:
        """Send one datagram and run the fc's lockstep loop body on it (as ``_run_lockstep``)."""
        self.plant.sendto(data, self.addr)
        self.fc_step()
        _drain(self.plant, self.sink)

    def fc_step(self) -> None:
        fc = self.fc
        mono = time.monotonic
        code = fc.plant.read_frame_at(fc.meas_scratch)
        if code >= 0:
            fc.loops.lockstep_exchange(code, mono())
        # no GCS traffic here: the lockstep loop's select finds its socket not readable
        fc.loops.housekeeping(mono(), False)

    def close(self) -> None:
        from fc.scheduler import release_heap
        release_heap()
        try:
            if self.fc is not None:
                self.fc.close()
        finally:
            self.sink.close()
            self.plant.close()
            shutil.rmtree(self.dir, ignore_errors=True)


def record(frames: int, flight_mode: str = "COORDINATED", frame_hz: float = 500.0) -> list:
    """The sensor datagrams (bytes) of a closed-loop flight of ``frames`` frames: the stand-in
    physics against a real controller, the plant's wire encoder (pymavlink codec)."""
    from tools.bench.standin import FrameCodec, make_sim
    rig = _Rig(flight_mode)
    try:
        sim = make_sim("paper", frame_hz)
        codec = FrameCodec()
        meas = np.zeros(14)
        cmd = np.zeros(3)
        out = []
        for _ in range(frames):
            sim.measure(meas)
            data = codec.encode(meas, int(round(sim.t_s * 1e6)))
            out.append(data)
            rig.step(data)
            cmd[:] = rig.fc.out.delta_rad
            sim.step_frame(cmd)
        return out
    finally:
        rig.close()


def replay(datagrams: list, flight_mode: str = "COORDINATED", baseline: bool = False) -> dict:
    """Plain replay (no instrumentation): wall and process CPU time per frame of the fc's
    calls only (feeding and draining the sockets excluded), us. ``baseline``: the fc's calls
    replaced by one bare ``recv`` of the datagram (the feeding loop's own cost, for a
    callgrind difference)."""
    rig = _Rig(flight_mode)
    if baseline:
        sock = rig.fc.plant.endpoint.sock
        rig.fc_step = lambda: sock.recv(65536)
    try:
        pc = time.perf_counter_ns
        cpu = time.process_time_ns
        send, addr, drain = rig.plant.sendto, rig.addr, _drain
        per = np.zeros(max(0, len(datagrams) - WARM_FRAMES), dtype=np.int64)
        cpu_ns = 0
        for k, data in enumerate(datagrams):
            send(data, addr)
            c0 = cpu()
            t0 = pc()
            rig.fc_step()
            t1 = pc()
            c1 = cpu()
            if k >= WARM_FRAMES:
                per[k - WARM_FRAMES] = t1 - t0
                cpu_ns += c1 - c0
            drain(rig.plant, rig.sink)
        n = max(1, per.size)
        return {"frames": int(per.size), "wall_median_us": float(np.median(per)) * 1e-3,
                "wall_mean_us": float(per.mean()) * 1e-3,
                "cpu_mean_us": cpu_ns / n * 1e-3,
                "note": "cpu_mean includes two process_time calls per frame (~0.5-1 us)"}
    finally:
        rig.close()


# (name, parent, label): the parts wrapped on the controller; parent None = top level.
# Each is found by ``_target`` below; a part the controller does not have is left out.
PARTS = (
    ("read_frame", None, "recv + decode (plant.read_frame_at)"),
    ("recv", "read_frame", "socket recv + source check + decode ATTITUDE+AOA_SSA+VFR_HUD "
                           "(recv_sensor_p, compiled, libc recvfrom)"),
    ("frame", None, "frame (loops.lockstep_exchange)"),
    ("fused_ready", "frame", "whether the frame takes the fused step (fused.ready, Python)"),
    ("fused", "frame", "fused frame (fused.step): the compiled step + its Python bookkeeping"),
    ("fused_kernel", "fused", "intake + estimator + planner + law + hold + PWM + framing + "
                              "libc sendto + row (frame_step_p, one compiled call)"),
    ("new_frame", "frame", "frame intake (intake.take)"),
    ("estimator", "new_frame", "frame copy + estimator (est.accept)"),
    ("sync_mode", "frame", "mode sync (mode_ctl.sync)"),
    ("fast_tick", "frame", "fast tick (loops.tick)"),
    ("guidance", "fast_tick", "guidance (guid.tick)"),
    ("slow_step", "fast_tick", "law slow loop (law.slow_step)"),
    ("fast_step", "fast_tick", "law fast loop (law.fast_step)"),
    ("pwm", "fast_tick", "surface copy + PWM x3 + throttle (surfaces_pwm_p, compiled)"),
    ("send_servo", "frame", "SERVO_OUTPUT_RAW (plant.send_servo)"),
    ("framing", "send_servo", "framing + CRC + socket send (send_servo_p, compiled, libc sendto)"),
    ("log_row", "frame", "internals log row (telemetry.log_row)"),
    ("housekeeping", None, "housekeeping (loops.housekeeping)"),
    ("gcs_poll", "housekeeping", "GCS receive (gcs.poll)"),
    ("gcs_service", "housekeeping", "GCS send + .tlog (gcs.service)"),
    ("tlog_streams", "gcs_service", ".tlog sim-paced streams (gcs._service_log)"),
    ("gcs_streams", "gcs_service", "GCS streams (gcs._streams)"),
    ("stats_roll", "housekeeping", "1 Hz: lateness statistics (stats.roll)"),
    ("gc_due", "housekeeping", "1 Hz: whether a collection is due (garbage_due)"),
    ("gc", "housekeeping", "1 Hz, when due: garbage collection (collect_garbage)"),
    ("telemetry", "housekeeping", "1 Hz: telemetry snapshot (telemetry.refresh)"),
    ("gcs_flush", "housekeeping", "1 Hz: .tlog flush (gcs.flush)"),
)


def _target(fc, name: str):
    """(object, attribute) to wrap for a part; attributes of modules are patched on the
    module (``fc.app``'s global), the rest on the instance (shadowing the class method)."""
    import fc.app as app
    import fc.fused as fused_mod
    import fc.link as link_mod
    import fc.loops as loops_mod
    plant = fc.plant
    return {
        "read_frame": (plant, "read_frame_at"), "recv": (link_mod, "recv_sensor_p"),
        "frame": (fc.loops, "lockstep_exchange"),
        "fused_ready": (fc.loops.fused, "ready"), "fused": (fc.loops.fused, "step"),
        "fused_kernel": (fused_mod, "frame_step_p"),
        "new_frame": (fc.intake, "take_at"), "estimator": (fc.est, "accept"),
        "sync_mode": (fc.mode_ctl, "sync"), "fast_tick": (fc.loops, "tick"),
        "guidance": (fc.guid, "tick"), "slow_step": (fc.law, "slow_step"),
        "fast_step": (fc.law, "fast_step"), "pwm": (app, "surfaces_pwm_p"),
        "send_servo": (plant, "send_servo_at"),
        "framing": (link_mod, "send_servo_at_p"), "log_row": (fc.telemetry, "log_row_at"),
        "housekeeping": (fc.loops, "housekeeping"), "gcs_poll": (fc.gcs, "poll"),
        "gcs_service": (fc.gcs, "service"), "tlog_streams": (fc.gcs, "_service_log"),
        "gcs_streams": (fc.gcs, "_streams"), "stats_roll": (fc.stats, "roll"),
        "gc_due": (loops_mod, "garbage_due"), "gc": (loops_mod, "collect_garbage"),
        "telemetry": (fc.telemetry, "refresh"),
        "gcs_flush": (fc.gcs, "flush"),
    }[name]


def _wrap(obj, attr: str, acc: np.ndarray, cnt: np.ndarray, i: int) -> tuple:
    """Time ``obj.attr`` into ``acc[i]`` / ``cnt[i]``; returns what ``_unwrap`` needs. On an
    object with ``__slots__`` (no instance attribute) its class is swapped for a subclass
    that overrides the method."""
    orig = getattr(obj, attr)
    pc = time.perf_counter_ns

    def timed(*a, **kw):
        t0 = pc()
        try:
            return orig(*a, **kw)
        finally:
            acc[i] += pc() - t0
            cnt[i] += 1
    try:
        setattr(obj, attr, timed)
        return obj, attr, orig, None
    except AttributeError:
        cls = obj.__class__
        obj.__class__ = type(cls.__name__, (cls,),
                             {"__slots__": (), attr: lambda _self, *a, **kw: timed(*a, **kw)})
        return obj, attr, orig, cls


def wrapper_overhead_ns(n: int = 20000) -> float:
    """What one ``_wrap`` timer adds to its caller's time (ns, median of ``n`` calls of a
    wrapped no-op against the bare no-op, each timed from outside)."""
    class Probe:
        def noop(self):
            return None
    probe = Probe()
    acc = np.zeros(1, dtype=np.int64)
    cnt = np.zeros(1, dtype=np.int64)
    pc = time.perf_counter_ns
    bare = np.zeros(n, dtype=np.int64)
    wrapped = np.zeros(n, dtype=np.int64)
    f = probe.noop
    for k in range(n):
        t0 = pc()
        f()
        bare[k] = pc() - t0
    _wrap(probe, "noop", acc, cnt, 0)
    f = probe.noop
    for k in range(n):
        t0 = pc()
        f()
        wrapped[k] = pc() - t0
    return float(np.median(wrapped) - np.median(bare))


def _unwrap(obj, attr: str, orig, cls) -> None:
    import types
    if cls is not None:
        obj.__class__ = cls
    elif isinstance(obj, types.ModuleType) or attr in getattr(type(obj), "__dataclass_fields__", ()):
        setattr(obj, attr, orig)    # a module global or a dataclass field (fc.loops' parts)
    else:
        delattr(obj, attr)          # the class method shows through again


def profile_parts(datagrams: list, flight_mode: str = "COORDINATED",
                  chore_every: int = 0) -> dict:
    """Replay with every part of ``PARTS`` timed; per-frame arrays of each part's time.
    ``chore_every`` > 0: the 1 Hz chores are made due every that many frames (a replay runs
    faster than any lockstep run, so on the wall clock they would hardly ever come)."""
    rig = _Rig(flight_mode)
    patched = []
    try:
        names = [p[0] for p in PARTS]
        acc = np.zeros(len(names), dtype=np.int64)
        cnt = np.zeros(len(names), dtype=np.int64)
        live = []
        for i, name in enumerate(names):
            obj, attr = _target(rig.fc, name)
            if obj is None or not hasattr(obj, attr):
                continue
            try:
                patched.append(_wrap(obj, attr, acc, cnt, i))
            except (AttributeError, TypeError):     # __slots__ or a builtin: not wrapped
                continue
            live.append(i)
        n = max(0, len(datagrams) - WARM_FRAMES)
        per = np.zeros((n, len(names)), dtype=np.int64)
        ncall = np.zeros((n, len(names)), dtype=np.int64)
        send, addr = rig.plant.sendto, rig.addr
        for k, data in enumerate(datagrams):
            send(data, addr)
            acc[:] = 0
            cnt[:] = 0
            if chore_every > 0 and k >= WARM_FRAMES and (k - WARM_FRAMES) % chore_every == 0:
                rig.hk.next_1hz = 0.0
            rig.fc_step()
            if k >= WARM_FRAMES:
                per[k - WARM_FRAMES] = acc
                ncall[k - WARM_FRAMES] = cnt
            _drain(rig.plant, rig.sink)
        return {"names": names, "live": live, "per_frame_ns": per, "calls_per_frame": ncall,
                "frames": n, "wrapper_overhead_ns": wrapper_overhead_ns()}
    finally:
        for w in reversed(patched):
            _unwrap(*w)
        rig.close()


def parts_table(r: dict, correct: bool = True) -> list[dict]:
    """Rows (label, depth, mean and median us per frame, median us per call, calls per
    frame, share % of the mean total) of a ``profile_parts`` result, with a glue row per
    parent (its time outside its wrapped children). ``correct``: the timers' own cost
    (``wrapper_overhead_ns`` per wrapped call) is taken out of the parents and glue rows."""
    names, n = r["names"], max(1, r["frames"])
    live = [i for i in r["live"]]
    parent = {p[0]: p[1] for p in PARTS}
    label = {p[0]: p[2] for p in PARTS}
    idx = {nm: i for i, nm in enumerate(names)}
    kids = {nm: [k for k in names if parent[k] == nm and idx[k] in live] for nm in names}
    c = float(r["wrapper_overhead_ns"]) if correct else 0.0
    raw = r["per_frame_ns"].astype(np.float64)
    calls = r["calls_per_frame"].astype(np.float64)

    def desc_calls(nm):             # wrapped calls strictly inside nm, per frame
        tot = np.zeros(raw.shape[0])
        for k in kids[nm]:
            tot += calls[:, idx[k]] + desc_calls(k)
        return tot

    incl = {nm: raw[:, idx[nm]] - c * desc_calls(nm) for nm in names if idx[nm] in live}
    top = [nm for nm in names if parent[nm] is None and idx[nm] in live]
    total = sum(incl[t] for t in top)
    total_mean = float(total.mean())
    rows = []

    def depth(nm):
        d = 0
        while parent[nm] is not None:
            nm = parent[nm]
            d += 1
        return d

    def row(part, text, d, col, cpf, per_call):
        m = float(col.mean())
        rows.append({"part": part, "label": text, "depth": d, "mean_us_per_frame": m * 1e-3,
                     "median_us_per_frame": float(np.median(col)) * 1e-3,
                     "median_us_per_call": per_call, "calls_per_frame": cpf,
                     "share_pct": 100.0 * m / total_mean if total_mean else float("nan")})

    def add(nm):
        col = incl[nm]
        i = idx[nm]
        ncalls = calls[:, i]
        called = col[ncalls > 0] / ncalls[ncalls > 0]
        row(nm, label[nm], depth(nm), col, float(ncalls.sum()) / n,
            float(np.median(called)) * 1e-3 if called.size else float("nan"))
        for k in kids[nm]:
            add(k)
        if kids[nm]:
            glue = col - sum(incl[k] for k in kids[nm])
            row(nm + "_glue", f"(rest of {nm}: Python around the parts above)", depth(nm) + 1,
                glue, 1.0, float(np.median(glue)) * 1e-3)
    for t in top:
        add(t)
    row("total", "total", 0, total, 1.0, float(np.median(total)) * 1e-3)
    return rows


def profile_functions(datagrams: list, flight_mode: str = "COORDINATED", top: int = 25,
                      sort: str = "tottime") -> str:
    """cProfile of the replay, enabled only around the controller's calls: the ``top``
    functions by ``sort`` (pstats text)."""
    rig = _Rig(flight_mode)
    prof = cProfile.Profile()
    try:
        send, addr = rig.plant.sendto, rig.addr
        for k, data in enumerate(datagrams):
            send(data, addr)
            if k >= WARM_FRAMES:
                prof.enable()
                rig.fc_step()
                prof.disable()
            else:
                rig.fc_step()
            _drain(rig.plant, rig.sink)
    finally:
        rig.close()
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats(sort).print_stats(top)
    return buf.getvalue()


def format_parts(rows: list[dict]) -> str:
    out = ["| part | mean us / frame | median us / frame | median us / call | calls / frame "
           "| share % of mean |", "|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {'. ' * r['depth']}{r['label']} | {r['mean_us_per_frame']:.2f} "
                   f"| {r['median_us_per_frame']:.2f} "
                   f"| {r['median_us_per_call']:.2f} | {r['calls_per_frame']:.3g} "
                   f"| {r['share_pct']:.1f} |")
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.bench profile",
                                description="Where the fc's CPU per plant frame goes: the "
                                            "lockstep loop body replayed in process, per part "
                                            "(timers) and per function (cProfile).")
    p.add_argument("--frames", type=int, default=5000,
                   help="frames measured (after %d warm-up frames; default 5000)" % WARM_FRAMES)
    p.add_argument("--flight-mode", default="COORDINATED",
                   help="the fc's flight mode (fc/modes.py name): COORDINATED (default, the "
                        "paper's attitude mode), UNCOORDINATED, CRUISE (guidance on), ...")
    p.add_argument("--chore-every", type=int, default=10000, metavar="N",
                   help="make the 1 Hz chores due every N measured frames (default 10000: one "
                        "wall second of a 500 Hz lockstep run at 20x real time); 0 = on the "
                        "replay's wall clock")
    p.add_argument("--top", type=int, default=25, help="cProfile functions listed (default 25)")
    p.add_argument("--sort", default="tottime", choices=("tottime", "cumtime"),
                   help="cProfile order: tottime = self time (default), cumtime = inclusive")
    p.add_argument("--no-cprofile", action="store_true",
                   help="leave out the cProfile pass (e.g. under valgrind)")
    p.add_argument("--record-only", action="store_true",
                   help="only record and replay once without instrumentation (for a callgrind "
                        "run; its difference with the same run plus --baseline is the fc's "
                        "cost)")
    p.add_argument("--baseline", action="store_true",
                   help="with --record-only: replay with the controller's calls replaced by "
                        "a bare recv of each datagram (what the feeding loop costs)")
    p.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    a = p.parse_args(argv)
    if a.frames < 1:
        p.error("--frames must be >= 1")
    t0 = time.perf_counter()
    load0 = os.getloadavg()[0]
    print(f"tools.bench profile: {a.frames} frames, flight mode {a.flight_mode}, load "
          f"{load0:.2f}", file=sys.stderr)
    data = record(a.frames + WARM_FRAMES, a.flight_mode)
    plain = replay(data, a.flight_mode, baseline=a.baseline)
    print(f"plain replay: wall median {plain['wall_median_us']:.1f} us, mean "
          f"{plain['wall_mean_us']:.1f} us, CPU mean {plain['cpu_mean_us']:.1f} us per frame "
          f"({plain['frames']} frames)")
    out = {"meta": {"frames": a.frames, "flight_mode": a.flight_mode, "load_start": load0,
                    "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())},
           "plain": plain}
    if not a.record_only:
        parts = profile_parts(data, a.flight_mode, a.chore_every)
        rows = parts_table(parts)
        out["parts"] = rows
        out["wrapper_overhead_ns"] = parts["wrapper_overhead_ns"]
        print(f"parts (timers' own cost, {parts['wrapper_overhead_ns']:.0f} ns per wrapped "
              f"call, taken out; 1 Hz chores due every {a.chore_every} frames):")
        print(format_parts(rows))
        if not a.no_cprofile:
            text = profile_functions(data, a.flight_mode, a.top, a.sort)
            out["cprofile"] = text
            print(text)
    out["meta"]["load_end"] = os.getloadavg()[0]
    out["meta"]["wall_s"] = time.perf_counter() - t0
    print(f"tools.bench profile: {out['meta']['wall_s']:.0f} s, load {load0:.2f} -> "
          f"{out['meta']['load_end']:.2f}", file=sys.stderr)
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(out, f, indent=2, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
