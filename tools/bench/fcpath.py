"""CPU cost of the fc's per-frame path, in process, without waiting on a peer (tools.bench).

A real ``fc.app.FlightController`` (lockstep, armed, COORDINATED, a ground-station output)
gets sensor datagrams from a local socket, one at a time, and each step of its lockstep loop
is timed with ``perf_counter_ns``: ``plant.read_frame_at`` (recv + MAVLink decode), the frame
(estimator, law, PWM, SERVO_OUTPUT_RAW encode + send, internals-log row) and the
housekeeping (ground-station poll and streams). The datagrams come from the measuring
stand-in's encoder with the plant physics between frames, so the law sees a flight.

This is the fc's share of a lockstep exchange (the rest is the plant's share and the
two UDP hops: the ping-pong floor). It uses the fc's loop parts (``loops.lockstep_exchange``,
``loops.housekeeping``, fc/loops.py) directly; if those change, the part is reported as skipped.
"""
from __future__ import annotations

import logging
import shutil
import socket
import tempfile
import time

import numpy as np

from tools.bench.inproc import stats_us

__all__ = ["fc_frame_path"]


def _drain(*socks) -> None:
    for s in socks:
        while True:
            try:
                s.recv(4096)
            except (BlockingIOError, InterruptedError):
                break


def fc_frame_path(quick: bool = False, frames: int | None = None) -> dict:
    from fc.app import FcConfig, FlightController
    from tools.bench.standin import FrameCodec, make_sim
    n = frames or (1000 if quick else 10000)
    d = tempfile.mkdtemp(prefix="hyfc-fcpath-")
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    plant = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    fc = None
    try:
        sink.bind(("127.0.0.1", 0))
        sink.setblocking(False)
        plant.bind(("127.0.0.1", 0))
        plant.setblocking(False)
        log = logging.getLogger("tools.bench.fcpath")
        log.addHandler(logging.NullHandler())
        log.propagate = False
        cfg = FcConfig(mode="lockstep", plant_bind=("127.0.0.1", 0), gcs=[sink.getsockname()],
                       gcs_bind=("127.0.0.1", 0), out=d, arm=True, flight_mode="COORDINATED")
        fc = FlightController(cfg, log)
        sim = make_sim("paper", 500.0)
        codec = FrameCodec()
        meas = np.zeros(14)
        addr = fc.plant.endpoint.address
        pc = time.perf_counter_ns
        mono = time.monotonic
        t = np.zeros((n, 3), dtype=np.int64)
        cmd = np.zeros(3)
        warm = 200
        fused = getattr(fc.loops, "fused", None)
        rx = np.zeros((n, 2), dtype=np.int64) if fused is not None else None
        for k in range(warm + n):
            sim.measure(meas)
            stamp = int(round(sim.t_s * 1e6))
            plant.sendto(codec.encode(meas, stamp), addr)
            t0 = pc()
            code = fc.plant.read_frame_at(fc.meas_scratch)
            t1 = pc()
            if code >= 0:
                fc.loops.lockstep_exchange(code, mono())
            t2 = pc()
            # no GCS traffic here: the lockstep loop's select finds its socket not readable
            fc.loops.housekeeping(mono(), False)
            t3 = pc()
            if k >= warm:
                t[k - warm] = (t1 - t0, t2 - t1, t3 - t2)
            _drain(plant, sink)
            cmd[:] = fc.out.delta_rad
            sim.step_frame(cmd)
        # a second pass as the lockstep loop reads since the fused step (fc/loops.py
        # ``_run_lockstep``): the receive and the frame in one call where it may
        from fc.fused import EXCHANGE_DONE
        from fc.link import FRAME_NONE
        for k in range(n if rx is not None else 0):
            sim.measure(meas)
            stamp = int(round(sim.t_s * 1e6))
            plant.sendto(codec.encode(meas, stamp), addr)
            t0 = pc()
            if fused.ready_rx():
                code = fused.exchange(t0 * 1e-9, time.perf_counter)
                if code != FRAME_NONE and code != EXCHANGE_DONE:
                    fc.loops.lockstep_rest(code, mono())
            else:
                code = fc.plant.read_frame_at(fc.meas_scratch)
                if code >= 0:
                    fc.loops.lockstep_exchange(code, mono())
            t1 = pc()
            fc.loops.housekeeping(mono(), False)
            rx[k] = (t1 - t0, pc() - t1)
            _drain(plant, sink)
            cmd[:] = fc.out.delta_rad
            sim.step_frame(cmd)
        loop = {} if rx is None else {
            "loop_recv_and_frame": stats_us(rx[:, 0]), "loop_housekeeping": stats_us(rx[:, 1]),
            "loop_total": stats_us(rx.sum(axis=1))}
        # the floor under the frame: the same link's receive + decode and answer (framing +
        # send), compiled, with no intake, estimator, law, row or housekeeping between them;
        # the same datagrams' kind, the same sockets, the fc left as it flew
        link = np.zeros(n, dtype=np.int64)
        pwm = fc.out.pwm_us
        for k in range(warm + n):
            sim.measure(meas)
            stamp = int(round(sim.t_s * 1e6))
            plant.sendto(codec.encode(meas, stamp), addr)
            t0 = pc()
            if fc.plant.read_frame_at(fc.meas_scratch) >= 0:
                fc.plant.send_servo_at(pwm)
            t1 = pc()
            if k >= warm:
                link[k - warm] = t1 - t0
            _drain(plant, sink)
            sim.step_frame(cmd)
        return {"frames": n, "read_frame": stats_us(t[:, 0]), "frame": stats_us(t[:, 1]),
                "housekeeping": stats_us(t[:, 2]), "total": stats_us(t.sum(axis=1)),
                "link_only": stats_us(link), **loop,
                "note": "in process, one thread, no peer wait; read_frame = recv + decode of "
                        "ATTITUDE+AOA_SSA+VFR_HUD; frame = estimator + law + PWM + "
                        "SERVO_OUTPUT_RAW encode/send + internals row; housekeeping = GCS; "
                        "loop_*: a second pass of as many frames read as the lockstep loop "
                        "reads them (fc/fused.py: the receive and the frame in one compiled "
                        "call); link_only = read_frame_at + send_servo_at alone (the sockets' "
                        "floor)"}
    finally:
        if fc is not None:
            try:
                fc.close()
            except Exception:  # noqa: BLE001 - measuring tool: closing is best effort
                pass
        sink.close()
        plant.close()
        shutil.rmtree(d, ignore_errors=True)
