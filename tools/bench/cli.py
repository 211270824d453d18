"""``python -m tools.bench [--quick] [--json FILE] [--only PARTS] [--keep DIR]``

and ``python -m tools.bench {law,plant,pingpong,fc-timing,campaign,profile} ...`` (``SUBCOMMANDS``: the
focused benchmarks, each with its own options; ``python -m tools.bench law --help``).

Measures, in one run, every figure of docs/performance.md and prints a table with the target
and the ratio to each peer or floor measured in the same run (JSBSim X-15 step, the loopback
UDP ping-pong between two processes); with ``--json`` it also writes the same figures:

    {"meta": {...}, "figures": {name: number}, "rows": [...], "details": {...}, "skipped": {...}}

``figures`` holds only finite numbers; a figure that could not be measured (e.g. jsbsim not
installed, or the cold start-up, which compiles for tens of seconds and is left out of
``--quick``) is listed in ``skipped`` with the reason instead. ``--quick`` shortens every
measurement to a smoke level (well under a minute). Nothing is asserted: this prints figures.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time

PARTS = ("law", "plant", "pingpong", "fcpath", "allocs", "lockstep", "realtime", "startup",
         "inproc")

# Targets (issue 7) and the reference figures taken on this machine before the code existed
# (../shared/docs/perf_anchors.md): printed next to the measurement, never used to compute it.
ANCHOR = {
    "law": "pure Python 6.5, numpy 3x3 30, numba scalar 0.77 us (anchors s.1)",
    "rk4": "numba per call 1.5 us, in numba loop 0.96 us (anchors s.3)",
    "lockstep": "ArduPilot SITL ~25x typical (anchors s.6)",
    "rt": "plain sleep p99 180 us, 0.8 % late; SCHED_FIFO p99 111 us (anchors s.2)",
    "inproc": "numba RK4 loop ~1000x (anchors s.3)",
}


def _load():
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


class Report:
    def __init__(self) -> None:
        self.figures: dict[str, float] = {}
        self.rows: list[dict] = []
        self.details: dict = {}
        self.skipped: dict[str, str] = {}
        self.load: dict[str, float] = {}

    def fig(self, name: str, value) -> float:
        v = float(value)
        if math.isfinite(v):
            self.figures[name] = v
        else:
            self.skipped[name] = "not measured (non-finite result)"
        return v

    def row(self, figure: str, measured: str, target: str = "", peer: str = "",
            ratio: str = "", part: str = "") -> None:
        self.rows.append({"part": part, "figure": figure, "measured": measured,
                          "target": target, "peer": peer, "ratio": ratio})


def _f(v, fmt=".2f", unit="") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{format(v, fmt)}{unit}"


def _ok(cond: bool) -> str:
    return "met" if cond else "MISSED"


# ---------------------------------------------------------------------------------------------
def part_law(rep: Report, quick: bool) -> None:
    from tools.bench.inproc import law_figures
    r = law_figures(quick)
    rep.details["law"] = r
    med = rep.fig("law_cycle_fc_median_us", r["cycle_fc_path"]["median_us"])
    p99 = rep.fig("law_cycle_fc_p99_us", r["cycle_fc_path"]["p99_us"])
    rep.row("1 law cycle, fc path (Estimator.update + law.slow_step/5 + law.fast_step)",
            f"median {_f(med)} us, p99 {_f(p99)} us", f"<= 2 us median: {_ok(med <= 2.0)}",
            ANCHOR["law"], f"{6.5 / med:.1f}x faster than pure Python (anchor)", "law")
    km = rep.fig("law_cycle_kernels_median_us", r["cycle_kernels"]["median_us"])
    kp = rep.fig("law_cycle_kernels_p99_us", r["cycle_kernels"]["p99_us"])
    rep.row("1 law cycle, kernels called directly", f"median {_f(km)} us, p99 {_f(kp)} us",
            f"<= 2 us median: {_ok(km <= 2.0)}", "", "", "law")
    for key, label in (("estimator", "estimator"), ("slow_step", "slow loop"),
                       ("fast_step", "fast loop"), ("nominal_model", "  fast: nominal model"),
                       ("factors", "  fast: coordination factors"),
                       ("coord_matrix", "  fast: coordinated matrix"),
                       ("allocate", "  fast: allocation"),
                       ("actuator_model", "  fast: actuator model")):
            m = rep.fig(f"law_{key}_median_us", r[key]["median_us"])
            p = rep.fig(f"law_{key}_p99_us", r[key]["p99_us"])
            rep.row(f"1 {label}", f"median {_f(m)} us, p99 {_f(p)} us", "", "", "", "law")
    rep.fig("timer_overhead_ns", r["timer_overhead_ns"])
    from tools.bench.law import bench_parts    # the in-numba per-part benchmark (tools/bench/law.py)
    parts = bench_parts(200 if quick else 2000, 50)
    rep.details["law_parts_in_numba"] = parts
    for name, vals in parts.items():
        key = "law_numba_" + "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_")
        m = rep.fig(key + "_median_us", vals[0])
        p = rep.fig(key + "_p99_us", vals[1])
        rep.row(f"1 inside numba (tools.bench law): {name}", f"median {_f(m, '.3f')} us, "
                f"p99 {_f(p, '.3f')} us", "", "", "", "law")


def part_plant(rep: Report, quick: bool) -> None:
    from tools.bench.inproc import jsbsim_figures, plant_figures
    r = plant_figures(quick)
    rep.details["plant"] = r
    med = rep.fig("plant_rk4_step_median_us", r["rk4_step_per_call"]["median_us"])
    rep.fig("plant_rk4_step_p99_us", r["rk4_step_per_call"]["p99_us"])
    loop = rep.fig("plant_rk4_step_in_loop_us", r["rk4_step_in_loop_us"])
    j = jsbsim_figures(r["dt_s"], quick)
    rep.details["jsbsim"] = j
    if j.get("available"):
        js = rep.fig("jsbsim_x15_step_us", j["x15_run_step_us"])
        rep.fig("plant_rk4_over_jsbsim", med / js)
        peer = f"JSBSim {j.get('version')} X-15 run() at dt {r['dt_s']:g} s: {_f(js)} us"
        ratio = f"{js / med:.1f}x faster than JSBSim"
        tgt = f"<= 5 us and <= JSBSim: {_ok(med <= 5.0 and med <= js)}"
    else:
        rep.skipped["jsbsim_x15_step_us"] = j["note"]
        peer = j["note"]
        ratio = ""
        tgt = f"<= 5 us: {_ok(med <= 5.0)} (JSBSim row skipped)"
    rep.row(f"2 plant RK4 step (dt {r['dt_s']:g} s), per call from Python",
            f"median {_f(med)} us, p99 {_f(r['rk4_step_per_call']['p99_us'])} us", tgt, peer,
            ratio, "plant")
    rep.row("2 plant RK4 step, whole batch inside numba", f"{_f(loop)} us", "",
            ANCHOR["rk4"], "", "plant")
    # the per-frame path (tools/bench/plant.py)
    from tools.bench.plant import bench_frame_path, bench_frame_physics
    med, lo, hi = bench_frame_path("paper", 1000 if quick else 5000, 3 if quick else 5)
    fp = rep.fig("plant_frame_path_us", med)
    rep.row("2 plant per-frame path, no network (tools.bench plant: one compiled call: decode "
            "servo, PWM, truth row, advance 2 RK4 steps, measure, encode sensors)",
            f"{_f(fp, '.1f')} us (batches {_f(lo, '.1f')}-{_f(hi, '.1f')})",
            f"<= 5 us: {_ok(fp <= 5.0)}", "", "", "plant")
    med, lo, hi = bench_frame_physics("paper", 1000 if quick else 5000, 3 if quick else 5)
    ph = rep.fig("plant_frame_physics_us", med)
    rep.row("2 plant frame's physics alone (the same call without the wire, in a numba loop: "
            "truth row, 2 RK4 steps, sensors): the floor under the row above",
            f"{_f(ph, '.2f')} us (batches {_f(lo, '.2f')}-{_f(hi, '.2f')})", "", "", "", "plant")


def part_pingpong(rep: Report, quick: bool, qos_held: bool = False) -> None:
    """The floor under the same conditions as the fc's runs: the fc holds the 0 us wake-up
    latency request in both modes, so the ping-pong holds it too (without it an idle vCPU
    halts and every wake-up waits for the hypervisor); one more pass of the links payload
    without the request shows what the machine costs when nothing holds it."""
    from tools.bench.pingpong import run_pingpong
    n = 2000 if quick else 20000
    rounds = 1 if quick else 4      # payloads interleaved, so a load change hits all three
    runs: dict = {"mavlink": [], "links": [], "raw": []}
    fd = None if qos_held else hold_pm_qos()
    try:
        for _ in range(rounds):
            for payload in runs:
                runs[payload].append(run_pingpong(n // rounds, payload))
    finally:
        if fd is not None:
            os.close(fd)
    held = qos_held or fd is not None
    rep.details["pingpong_pm_qos_held"] = held
    if fd is not None:          # only when this part held it can it compare without
        idle = run_pingpong(n // rounds, "links")
        rep.details["pingpong_links_no_pm_qos"] = idle
        rep.fig("pingpong_links_no_pm_qos_median_us", idle["median_us"])

    def pool(rs):      # medians / p99 of the rounds (each round has n/rounds exchanges)
        out = dict(rs[0])
        for k in ("median_us", "p99_us", "p999_us", "max_us", "mean_us"):
            out[k] = float(sorted(r[k] for r in rs)[len(rs) // 2]) if k != "max_us" \
                else max(r[k] for r in rs)
        out["n"] = sum(r["n"] for r in rs)
        out["rounds"] = [{"median_us": r["median_us"], "p99_us": r["p99_us"]} for r in rs]
        return out

    m, lk, raw = pool(runs["mavlink"]), pool(runs["links"]), pool(runs["raw"])
    rep.details["pingpong"] = {"mavlink": m, "links": lk, "raw": raw}
    rep.fig("pingpong_links_median_us", lk["median_us"])
    rep.fig("pingpong_links_p99_us", lk["p99_us"])
    rep.fig("pingpong_mavlink_median_us", m["median_us"])
    rep.fig("pingpong_mavlink_p99_us", m["p99_us"])
    rep.fig("pingpong_raw_median_us", raw["median_us"])
    rep.fig("pingpong_raw_p99_us", raw["p99_us"])
    rep.row("3 floor: UDP ping-pong, wire frame + SERVO echo, both decoded",
            f"median {_f(m['median_us'], '.1f')} us, p99 {_f(m['p99_us'], '.1f')} us", "",
            "anchors s.5: 106-115 / p99 205-263 us", "", "pingpong")
    rep.row("3 floor: UDP ping-pong through the processes' own links (plant_sim.link -> "
            "fc.link read_frame/send_servo -> plant_sim.link poll_for)",
            f"median {_f(lk['median_us'], '.1f')} us, p99 {_f(lk['p99_us'], '.1f')} us", "",
            "", "", "pingpong")
    rep.row("3 floor: UDP ping-pong, 64 raw bytes",
            f"median {_f(raw['median_us'], '.1f')} us, p99 {_f(raw['p99_us'], '.1f')} us",
            "", "", "", "pingpong")
    if not held:
        rep.row("3 floor: (the rows above without the 0 us wake-up latency request the fc "
                "holds: not root or no /dev/cpu_dma_latency)", "", "", "", "", "pingpong")
    idle = rep.details.get("pingpong_links_no_pm_qos")
    if idle:
        rep.row("3 floor: UDP ping-pong through the links, idle vCPUs allowed to halt (no "
                "wake-up latency request; the rows above hold it, as the fc does)",
                f"median {_f(idle['median_us'], '.1f')} us, p99 {_f(idle['p99_us'], '.1f')} us",
                "", "", "", "pingpong")


def part_fcpath(rep: Report, quick: bool) -> None:
    from tools.bench.fcpath import fc_frame_path
    try:
        r = fc_frame_path(quick)
    except (AttributeError, TypeError) as exc:   # the fc's loop methods changed
        rep.skipped["fc_frame_path_us"] = f"fc loop methods changed: {exc}"
        return
    rep.details["fc_frame_path"] = r
    tot = rep.fig("fc_frame_cpu_median_us", r["total"]["median_us"])
    rd = rep.fig("fc_frame_read_median_us", r["read_frame"]["median_us"])
    fr = rep.fig("fc_frame_work_median_us", r["frame"]["median_us"])
    hk = rep.fig("fc_frame_housekeeping_median_us", r["housekeeping"]["median_us"])
    law = rep.figures.get("law_cycle_fc_median_us")
    if "loop_total" in r:
        lt = rep.fig("fc_frame_loop_cpu_median_us", r["loop_total"]["median_us"])
        lf = rep.fig("fc_frame_loop_recv_frame_median_us", r["loop_recv_and_frame"]["median_us"])
        lh = rep.fig("fc_frame_loop_housekeeping_median_us",
                     r["loop_housekeeping"]["median_us"])
        rep.row("3 fc per-frame CPU as the lockstep loop reads (recv and frame in one compiled "
                "call / GCS housekeeping)", f"median {_f(lt, '.1f')} us = {_f(lf, '.1f')} + "
                f"{_f(lh, '.1f')} us", "", "", "", "fcpath")
    rep.row("3 fc per-frame CPU, in process (recv+decode / frame / GCS housekeeping)",
            f"median {_f(tot, '.1f')} us = {_f(rd, '.1f')} + {_f(fr, '.1f')} + "
            f"{_f(hk, '.1f')} us", "", f"law cycle {_f(law)} us" if law else "",
            f"law = {law / tot * 100:.0f} % of the fc's frame" if law else "", "fcpath")
    if "link_only" in r:
        lk = rep.fig("fc_frame_link_floor_median_us", r["link_only"]["median_us"])
        rep.row("3 floor: the fc's link alone per frame, in process (compiled receive + decode, "
                "framing + send: two system calls, no estimator, law, row or housekeeping)",
                f"median {_f(lk, '.1f')} us", "", "",
                f"{lk / tot * 100:.0f} % of the fc's frame" if tot else "", "fcpath")


def part_allocs(rep: Report, quick: bool) -> None:
    """Allocations per plant frame in the fc's steady state (tools/bench/allocs.py): a count,
    valid under load. The headline figures are the worse of COORDINATED and CRUISE."""
    from tools.bench.allocs import fc_allocations
    r = fc_allocations(quick)
    rep.details["fc_allocations"] = r
    for mode, m in r.items():
        py = rep.fig(f"fc_py_allocs_per_frame_{mode.lower()}", m["py_allocs_per_frame"])
        nrt = rep.fig(f"fc_nrt_allocs_per_frame_{mode.lower()}", m["nrt_allocs_per_frame"])
        rep.row(f"3 fc allocations per plant frame, {mode} (Python object-allocator blocks / "
                f"numba NRT records; {m['frames']} frames in process)",
                f"{_f(py, '.3f')} / {_f(nrt, '.3f')}", "0 / 0: " + _ok(py <= 0 and nrt <= 0),
                "", "", "allocs")
    rep.fig("fc_py_allocs_per_frame", max(m["py_allocs_per_frame"] for m in r.values()))
    rep.fig("fc_nrt_allocs_per_frame", max(m["nrt_allocs_per_frame"] for m in r.values()))


def part_lockstep(rep: Report, quick: bool, keep) -> None:
    from tools.bench.procs import lockstep
    floor = rep.figures.get("pingpong_links_median_us")
    raw = rep.figures.get("pingpong_raw_median_us")
    # the 500 Hz stand-in run is also the long run whose fc RSS gives the heap-growth figure
    for hz, sim_s, long_s in ((500, 2.0 if quick else 60.0, 10.0 if quick else 1200.0),
                              (1000, 1.0 if quick else 20.0, 1.0 if quick else 20.0)):
        r = lockstep(hz, sim_s, keep, real_plant=not quick, standin_sim_s=long_s)
        rep.details[f"lockstep_{hz}"] = r
        rtf = rep.fig(f"lockstep_{hz}_rtf", r["real_time_factor"])
        sd = r["standin"]
        rtf_s = rep.fig(f"lockstep_{hz}_rtf_standin", sd["real_time_factor"])
        ex = rep.fig(f"lockstep_{hz}_exchange_median_us", sd["exchange"]["median_us"])
        rep.fig(f"lockstep_{hz}_exchange_p99_us", sd["exchange"]["p99_us"])
        rep.fig(f"fc_peak_rss_mb_lockstep_{hz}", r["fc_peak_rss_mb"])
        if "plant" in r:
            rep.fig("plant_peak_rss_mb", r["plant"]["peak_rss_mb"])
        rep.fig("standin_peak_rss_mb", sd["peak_rss_mb"])
        g = r["fc_rss_standin"]
        if hz == 500:
            g = dict(g, sim_s=long_s)
            rep.details["heap_growth_run"] = g
            rep.fig("fc_rss_growth_mb_per_min", g["rss_growth_mb_per_min"])
            rep.fig("fc_rss_growth_mb", g["rss_growth_mb"])
        tgt = f">= 20x: {_ok(rtf >= 20.0)}" if hz == 500 else ""
        if floor:
            limit = 1e6 / (floor * hz)
            peer = (f"floor: ping-pong through the links {floor:.0f} us/exchange -> at most "
                    f"{limit:.1f}x at {hz} Hz")
            ratio = f"{rtf / limit * 100:.0f} % of the floor's limit"
            rep.fig(f"lockstep_{hz}_floor_rtf", limit)
        else:
            peer = ratio = ""
        rep.row(f"3 lockstep RTF at {hz} Hz ({r['rtf_source']})", f"{_f(rtf, '.1f')}x", tgt,
                "; ".join(x for x in (peer, ANCHOR["lockstep"]) if x), ratio, "lockstep")
        fcc = rep.figures.get("fc_frame_cpu_median_us")
        plc = rep.figures.get("plant_frame_path_us")
        if raw and fcc and plc and hz == 500:
            budget = raw + fcc + plc
            rep.fig("lockstep_500_budget_us", budget)
            rep.row("3 lockstep 500 Hz budget: raw UDP round trip + fc CPU + plant CPU per "
                    "frame (each CPU figure includes its codec and socket calls)",
                    f"{raw:.0f} + {fcc:.0f} + {plc:.0f} = {budget:.0f} us -> at most "
                    f"{1e6 / (budget * hz):.1f}x", "20x needs <= 100 us per exchange", "",
                    "", "lockstep")
        rep.row(f"3 lockstep at {hz} Hz, measuring stand-in plant",
                f"{_f(rtf_s, '.1f')}x; exchange median {_f(ex, '.0f')} us, p99 "
                f"{_f(sd['exchange']['p99_us'], '.0f')} us", "",
                f"links ping-pong median {_f(floor, '.0f')} us" if floor else "",
                f"{ex / floor:.1f}x the ping-pong" if floor else "", "lockstep")


def part_lockstep_pinned(rep: Report, quick: bool, keep) -> None:
    """Both processes on one CPU: a lockstep exchange is sequential, and on this VM a wake-up
    across CPUs costs more than the work (measured: 5.6x pinned apart, 12-14x together)."""
    from tools.bench.procs import lockstep
    r = lockstep(500, 2.0 if quick else 30.0, keep, real_plant=not quick, pin_cpu=0,
                 standin=quick)
    rep.details["lockstep_500_pinned"] = r
    rtf = rep.fig("lockstep_500_pinned_rtf", r["real_time_factor"])
    free = rep.figures.get("lockstep_500_rtf")
    rep.row(f"3 lockstep RTF at 500 Hz, fc and plant pinned to one CPU (`taskset -c 0`, "
            f"{r['rtf_source']})", f"{_f(rtf, '.1f')}x", f">= 20x: {_ok(rtf >= 20.0)}",
            f"unpinned (above): {_f(free, '.1f')}x" if free else "",
            f"{rtf / free:.2f}x the unpinned" if free else "", "lockstep")


def part_realtime(rep: Report, quick: bool, keep) -> None:
    from tools.bench.procs import realtime
    pp99 = rep.figures.get("pingpong_mavlink_p99_us")
    for hz in (1000, 500):
        r = realtime(hz, 1.5 if quick else 15.0, keep, skip_s=0.3 if quick else 1.0)
        rep.details[f"realtime_{hz}"] = r
        lm = rep.fig(f"rt_{hz}_lateness_median_us", r["lateness_median_us"])
        lp = rep.fig(f"rt_{hz}_lateness_p99_us", r["lateness_p99_us"])
        lx = rep.fig(f"rt_{hz}_lateness_max_us", r["lateness_max_us"])
        ls = rep.fig(f"rt_{hz}_late_20pct_pct", r["late_20pct_share_pct"])
        sm = rep.fig(f"rt_{hz}_latency_median_us", r["latency_median_us"])
        sp = rep.fig(f"rt_{hz}_latency_p99_us", r["latency_p99_us"])
        rep.fig(f"rt_{hz}_tick_exec_median_us", r["tick_exec_median_us"])
        rep.fig(f"rt_{hz}_tick_exec_p99_us", r["tick_exec_p99_us"])
        rep.fig(f"fc_peak_rss_mb_rt_{hz}", r["fc_peak_rss_mb"])
        rep.fig(f"rt_{hz}_gcs_msgs_per_s", r["gcs"]["msgs_per_s"])
        tgt = (f"p99 <= 50 us (issue 24): {_ok(lp <= 50)}; late < 0.1 %: {_ok(ls < 0.1)}"
               if hz == 1000 else "")
        rep.row(f"4 real time {hz} Hz: wake-up lateness ({r['ticks']} ticks, plant + GCS "
                f"streaming {r['gcs']['msgs_per_s']:.0f} msg/s)",
                f"median {_f(lm, '.0f')}, p99 {_f(lp, '.0f')}, max {_f(lx, '.0f')} us; "
                f"{_f(ls, '.2f')} % > 20 % late", tgt, ANCHOR["rt"], "", "realtime")
        tgt = f"p99 <= 300 us: {_ok(sp <= 300)}" if hz == 1000 else ""
        rep.row(f"4 real time {hz} Hz: sensor-to-servo latency at the plant",
                f"median {_f(sm, '.0f')} us, p99 {_f(sp, '.0f')} us "
                f"({r['answered_share'] * 100:.0f} % of frames echoed)", tgt,
                f"ping-pong p99 {_f(pp99, '.0f')} us" if pp99 else "",
                f"{sp / pp99:.1f}x the ping-pong p99" if pp99 else "", "realtime")
        rep.row(f"4 real time {hz} Hz: fc tick work (wake to send)",
                f"median {_f(r['tick_exec_median_us'], '.0f')} us, p99 "
                f"{_f(r['tick_exec_p99_us'], '.0f')} us", "", "", "", "realtime")
    # the host's floor under those figures: the same wait and stand-in, no fc work
    from tools.bench.procs import realtime_floor
    r = realtime_floor(1000, 1.5 if quick else 15.0, keep)
    rep.details["realtime_floor_1000"] = r
    fp = rep.fig("rt_1000_floor_lateness_p99_us", r["lateness_p99_us"])
    fs = rep.fig("rt_1000_floor_late_20pct_pct", r["late_20pct_share_pct"])
    rep.fig("rt_1000_floor_lateness_median_us", r["lateness_median_us"])
    rep.fig("rt_1000_floor_lateness_max_us", r["lateness_max_us"])
    fcp = rep.figures.get("rt_1000_lateness_p99_us")
    rep.row("4 floor: real time 1000 Hz wake-up lateness of a bare receiver (tools.bench.rtfloor: "
            "the fc's link, SCHED_FIFO request and select wait, no law, no GCS; "
            f"{r['frames']} frames)",
            f"median {_f(r['lateness_median_us'], '.0f')}, p99 {_f(fp, '.0f')}, max "
            f"{_f(r['lateness_max_us'], '.0f')} us; {_f(fs, '.2f')} % > 20 % late", "", "",
            f"the fc's p99 is {fcp / fp:.2f}x the floor's" if fcp and fp else "", "realtime")
    # the same at 1 kHz with the fc's free-running clock (--sync clock), for comparison
    r = realtime(1000, 1.5 if quick else 15.0, keep, fc_extra=("--sync", "clock"),
                 skip_s=0.3 if quick else 1.0)
    rep.details["realtime_1000_clock"] = r
    lp = rep.fig("rt_1000_clock_lateness_p99_us", r["lateness_p99_us"])
    ls = rep.fig("rt_1000_clock_late_20pct_pct", r["late_20pct_share_pct"])
    rep.fig("rt_1000_clock_lateness_max_us", r["lateness_max_us"])
    sm = rep.fig("rt_1000_clock_latency_median_us", r["latency_median_us"])
    sp = rep.fig("rt_1000_clock_latency_p99_us", r["latency_p99_us"])
    rep.row("4 real time 1000 Hz, `python -m fc --sync clock` (ticks on the fc's own clock, "
            "answering the newest frame): wake-up lateness",
            f"median {_f(r['lateness_median_us'], '.0f')}, p99 {_f(lp, '.0f')}, max "
            f"{_f(r['lateness_max_us'], '.0f')} us; {_f(ls, '.2f')} % > 20 % late",
            f"p99 <= 100 us: {_ok(lp <= 100)}; late < 0.1 %: {_ok(ls < 0.1)}",
            ANCHOR["rt"], "", "realtime")
    rep.row("4 real time 1000 Hz, `--sync clock`: sensor-to-servo latency at the plant",
            f"median {_f(sm, '.0f')} us, p99 {_f(sp, '.0f')} us "
            f"({r['answered_share'] * 100:.0f} % of frames echoed)",
            f"p99 <= 300 us: {_ok(sp <= 300)} (the phase between two clocks)",
            f"ping-pong p99 {_f(pp99, '.0f')} us" if pp99 else "",
            f"{sp / pp99:.1f}x the ping-pong p99" if pp99 else "", "realtime")


def part_startup(rep: Report, quick: bool, keep) -> None:
    from tools.bench.procs import startup
    startup(False, keep)                     # make sure the cache matches the current code
    warm = [startup(False, keep) for _ in range(1 if quick else 3)]
    w = sorted(x["first_servo_s"] for x in warm)[len(warm) // 2]
    wc = sorted(x["cpu_s_at_first_servo"] for x in warm)[len(warm) // 2]
    rep.details["startup_warm"] = warm
    fl = import_floor(1 if quick else 3)
    rep.details["startup_import_floor"] = fl
    for k, v in fl.items():
        rep.fig(f"startup_import_{k}_s", v)
    rep.fig("startup_warm_first_servo_s", w)
    rep.fig("startup_warm_cpu_s", wc)
    rep.row("5 start-up, warm: process start -> first SERVO_OUTPUT_RAW",
            f"{_f(w)} s wall ({_f(wc)} s CPU)",
            f"<= 1 s: {_ok(w <= 1.0)}",
            f"floor: a bare python importing numpy, numba, pymavlink and calling one cached "
            f"kernel {_f(fl['total'])} s wall, {_f(fl['cpu'])} s CPU (numba import "
            f"{_f(fl['numba'])}, first kernel call {_f(fl['first_kernel'])}, pymavlink "
            f"{_f(fl['pymavlink'])})",
            f"{w / fl['total']:.1f}x the floor (CPU {wc / fl['cpu']:.1f}x)", "startup")
    if quick:
        rep.skipped["startup_cold_first_servo_s"] = ("left out of --quick (compiles every "
                                                      "kernel: tens of seconds)")
        return
    c = startup(True, keep)
    rep.details["startup_cold"] = c
    rep.fig("startup_cold_first_servo_s", c["first_servo_s"])
    rep.row("5 start-up, cold (empty NUMBA_CACHE_DIR)", f"{_f(c['first_servo_s'])} s",
            "", "", "", "startup")
    # the install-time answer to the cold start: ``python -m tools.precompile`` into a fresh
    # cache, then the fc's start
    p = startup(True, keep, precompiled=True)
    rep.details["startup_precompiled"] = p
    ps = rep.fig("startup_precompiled_first_servo_s", p["first_servo_s"])
    pc = rep.fig("startup_precompile_s", p["precompile_s"])
    rep.row("5 start-up after `python -m tools.precompile` (fresh NUMBA_CACHE_DIR)",
            f"{_f(ps)} s; the precompile itself {_f(pc)} s (fc and plant kernels, 2 processes)",
            f"<= 3 s: {_ok(ps <= 3.0)}", f"cold {_f(c['first_servo_s'])} s",
            f"{c['first_servo_s'] / ps:.0f}x faster than cold" if ps else "", "startup")


IMPORT_FLOOR_CODE = """
import time
t0 = time.perf_counter()
import numpy
t1 = time.perf_counter()
import numba
t2 = time.perf_counter()
from tools.bench.floor_kernel import add1
add1(1.0)
t3 = time.perf_counter()
import os
os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega
t4 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, t4 - t3)
"""


def import_floor(n: int = 3) -> dict:
    """Wall time of a bare interpreter that only does what any njit process must (s): import
    numpy and numba, call one trivial cached kernel (numba's CPU-target initialisation, which
    imports scipy.linalg to find BLAS, and one cache load), import pymavlink's dialect.
    Median of ``n`` processes."""
    import subprocess
    import resource
    runs = []
    for _ in range(n):
        c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", IMPORT_FLOOR_CODE], capture_output=True,
                             text=True, timeout=120, check=True,
                             cwd=os.path.dirname(os.path.dirname(os.path.dirname(
                                 os.path.abspath(__file__))))).stdout.split()
        wall = time.perf_counter() - t0
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
        runs.append([wall] + [float(x) for x in out] + [cpu])
    med = [sorted(r[i] for r in runs)[len(runs) // 2] for i in range(6)]
    return {"total": med[0], "numpy": med[1], "numba": med[2], "first_kernel": med[3],
            "pymavlink": med[4], "cpu": med[5]}


def part_inproc(rep: Report, quick: bool) -> None:
    from tools.bench.inproc import closed_loop_figures
    r = closed_loop_figures(quick)
    rep.details["closed_loop"] = r
    x = rep.fig("closed_loop_sim_s_per_wall_s", r["sim_s_per_wall_s"])
    xc = rep.fig("closed_loop_sim_s_per_cpu_s", r.get("sim_s_per_cpu_s", float("nan")))
    loop_us = rep.figures.get("plant_rk4_step_in_loop_us")
    peer = ANCHOR["inproc"]
    ratio = ""
    if loop_us:
        plant_only = 1e6 / (loop_us * 1000.0)
        peer = f"plant alone in numba (this run): {plant_only:.0f}x; " + peer
        ratio = f"{x / plant_only * 100:.0f} % of the plant alone"
    rep.row(f"7 in-process closed loop, one thread ({r.get('source', '')})",
            f"{_f(x, '.0f')}x real time per wall second ({_f(xc, '.0f')}x per CPU second)",
            f">= 500x per core: {_ok(xc >= 500)} (CPU time; wall {_ok(x >= 500)})", peer, ratio,
            "inproc")
    from tools.bench.inproc_parts import closed_loop_parts
    q = closed_loop_parts(quick)
    rep.details["closed_loop_parts"] = q
    for key in ("plant_us", "truth_row_us", "law_us", "record_us", "sum_us"):
        rep.fig(f"closed_loop_part_{key}", q[key])
    whole_us = q["frame_dt_s"] / x * 1e6 if x and x > 0 else float("nan")
    rep.row("7 in-process loop per frame, each part alone in numba (plant advance = 2 RK4 "
            "steps / truth row the law reads / law slow+fast / recording)",
            f"{q['plant_us']:.2f} + {q['truth_row_us']:.2f} + {q['law_us']:.2f} + "
            f"{q['record_us']:.2f} = {q['sum_us']:.2f} us (whole loop {whole_us:.2f} us)",
            "", "", f"ceiling of 'share of the plant alone': {q['plant_share_ceiling'] * 100:.0f} %"
            f" ({q['ceiling_without_truth_row'] * 100:.0f} % with a free truth row)", "inproc")


def memory_rows(rep: Report) -> None:
    f = rep.figures
    fc = [v for k, v in f.items() if k.startswith("fc_peak_rss_mb")]
    if fc:
        rep.fig("fc_peak_rss_mb", max(fc))
    parts = []
    if fc:
        parts.append(f"fc {max(fc):.0f} MB")
    if "plant_peak_rss_mb" in f:
        parts.append(f"plant {f['plant_peak_rss_mb']:.0f} MB")
    if "standin_peak_rss_mb" in f:
        parts.append(f"stand-in plant {f['standin_peak_rss_mb']:.0f} MB")
    if parts:
        rep.row("6 peak RSS per process", ", ".join(parts), "", "", "", "memory")
    g = rep.details.get("heap_growth_run")
    if g:
        rep.row(f"6 fc RSS growth, 2nd half of the 500 Hz lockstep stand-in run "
                f"({g.get('sim_s', float('nan')):.0f} s sim)",
                f"{_f(g['rss_growth_mb'], '.2f')} MB over {g['window_s']:.0f} s "
                f"({_f(g['rss_growth_mb_per_min'], '.2f')} MB/min)", "none expected", "", "",
                "memory")


def hold_pm_qos() -> int | None:
    """Open /dev/cpu_dma_latency and request 0 us (kept while the fd is open); None if not
    allowed. With the request held, cpuidle picks only the polling state: an idle vCPU
    polls instead of halting, so a wake-up does not wait for the hypervisor."""
    import struct
    try:
        fd = os.open("/dev/cpu_dma_latency", os.O_WRONLY)
    except OSError:
        return None
    try:
        os.write(fd, struct.pack("i", 0))
    except OSError:
        os.close(fd)
        return None
    return fd


def print_table(rep: Report, out=sys.stdout) -> None:
    cols = ("figure", "measured", "target", "peer", "ratio")
    print("| " + " | ".join(cols) + " |", file=out)
    print("|" + "---|" * len(cols), file=out)
    for r in rep.rows:
        print("| " + " | ".join(str(r[c]) for c in cols) + " |", file=out)
    for k, v in rep.skipped.items():
        print(f"| {k} | skipped: {v} | | | |", file=out)


#: ``python -m tools.bench NAME ...``: the focused benchmarks, each its own command line
SUBCOMMANDS = {
    "law": "tools.bench.law",            # the law's cost per cycle and per part, inside numba
    "plant": "tools.bench.plant",        # the plant's per-frame path and lockstep throughput
    "pingpong": "tools.bench.pingpong",  # the loopback UDP floor between two processes
    "fc-timing": "tools.bench.fc_timing",  # the fc's real-time tick lateness per fast rate
    "campaign": "tools.bench.campaign",  # Monte Carlo campaign wall time per worker count
    "profile": "tools.bench.profile",    # where the fc's CPU per plant frame goes (issue 16)
    "treerss": "tools.bench.treerss",    # a command's process tree's memory, sampled (issue 24)
    "hour": "tools.bench.hour",          # the 1-hour lockstep cruise: wall, logs, memory (issue 24)
}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in SUBCOMMANDS:
        import importlib
        return importlib.import_module(SUBCOMMANDS[argv[0]]).main(argv[1:])
    ap = argparse.ArgumentParser(prog="python -m tools.bench",
                                 epilog="focused benchmarks: python -m tools.bench {"
                                        + ",".join(SUBCOMMANDS) + "} --help",
                                 description="hyfc benchmarks: prints a table of figures with "
                                             "targets and peers (docs/performance.md).")
    ap.add_argument("--quick", action="store_true",
                    help="smoke level: every measurement shortened (well under a minute)")
    ap.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    ap.add_argument("--only", default=",".join(PARTS),
                    help=f"comma-separated parts (default all: {','.join(PARTS)})")
    ap.add_argument("--keep", metavar="DIR", help="keep the process runs' directories under DIR")
    ap.add_argument("--pm-qos", action="store_true",
                    help="hold /dev/cpu_dma_latency at 0 during the run (idle CPUs poll instead "
                         "of halting: fast wake-ups on a VM; needs root), as cyclictest does")
    args = ap.parse_args(argv)
    parts = [p.strip() for p in args.only.split(",") if p.strip()]
    bad = [p for p in parts if p not in PARTS]
    if bad:
        ap.error(f"unknown part(s) {bad}; choose from {PARTS}")
    if args.keep:
        os.makedirs(args.keep, exist_ok=True)
    qos_fd = None
    if args.pm_qos:
        qos_fd = hold_pm_qos()
        if qos_fd is None:
            print("tools.bench: --pm-qos: cannot write /dev/cpu_dma_latency (not root?); "
                  "measuring without it", file=sys.stderr)
    rep = Report()
    utc0 = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    t0 = time.perf_counter()
    print(f"tools.bench{' --quick' if args.quick else ''}: {os.cpu_count()} cores, "
          f"load {_load():.2f}, python {platform.python_version()}", file=sys.stderr)
    runners = {"law": lambda: part_law(rep, args.quick),
               "plant": lambda: part_plant(rep, args.quick),
               "pingpong": lambda: part_pingpong(rep, args.quick, qos_fd is not None),
               "fcpath": lambda: part_fcpath(rep, args.quick),
               "allocs": lambda: part_allocs(rep, args.quick),
               "lockstep": lambda: (part_lockstep(rep, args.quick, args.keep),
                                    part_lockstep_pinned(rep, args.quick, args.keep)),
               "realtime": lambda: part_realtime(rep, args.quick, args.keep),
               "startup": lambda: part_startup(rep, args.quick, args.keep),
               "inproc": lambda: part_inproc(rep, args.quick)}
    failed = {}
    for p in PARTS:
        if p not in parts:
            continue
        tp = time.perf_counter()
        rep.load[p] = _load()
        print(f"  {p} ...", file=sys.stderr, flush=True)
        try:
            runners[p]()
        except Exception as exc:  # noqa: BLE001 - one broken part must not hide the others
            failed[p] = f"{type(exc).__name__}: {exc}"
            print(f"  {p} FAILED: {failed[p]}", file=sys.stderr)
        print(f"  {p} done in {time.perf_counter() - tp:.1f} s (load {_load():.2f})",
              file=sys.stderr)
    if qos_fd is not None:
        os.close(qos_fd)
    memory_rows(rep)
    print_table(rep)
    meta = {"command": "python -m tools.bench" + (" --quick" if args.quick else "")
            + (" --pm-qos" if args.pm_qos else ""), "pm_qos_held": qos_fd is not None,
            "quick": args.quick, "utc": utc0,
            "cores": os.cpu_count(), "python": platform.python_version(),
            "load_avg_1min_at_part_start": rep.load, "wall_s": time.perf_counter() - t0,
            "failed": failed}
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({"meta": meta, "figures": rep.figures, "rows": rep.rows,
                       "skipped": rep.skipped, "details": rep.details}, f, indent=2,
                      default=float)
    print(f"tools.bench: {time.perf_counter() - t0:.0f} s, {len(rep.figures)} figures"
          + (f", FAILED parts: {', '.join(failed)}" if failed else ""), file=sys.stderr)
    return 1 if failed else 0
