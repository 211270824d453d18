"""In-process figures of tools.bench: control law, plant step, JSBSim X-15, closed loop.

Timing method (docs/performance.md, "Method"):
- per-call figures call the function from Python and time each call with
  ``time.perf_counter_ns`` (the timer pair costs ``timer_overhead_ns``, included, as in the
  shared perf anchors); they are what the fc process pays per call;
- batch figures (``*_in_loop``) time a whole batch inside numba and divide;
- JSBSim: ``load_model``, ``disable_output``, the stock airborne reset file, engine running,
  reset to initial conditions before each of the batches of ``fdm.run()``; median of batches.
Nothing is asserted here: the functions return figures.
"""
from __future__ import annotations

import math
import time

import numpy as np

__all__ = ["law_figures", "plant_figures", "jsbsim_figures", "closed_loop_figures",
           "timer_overhead_ns", "stats_us", "trajectory"]


def stats_us(ns) -> dict:
    us = np.asarray(ns, dtype=np.float64) * 1e-3
    return {"median_us": float(np.median(us)), "p99_us": float(np.percentile(us, 99)),
            "n": int(us.size)}


def timer_overhead_ns(n: int = 20000) -> float:
    pc = time.perf_counter_ns
    d = np.empty(n, dtype=np.int64)
    for i in range(n):
        t0 = pc()
        d[i] = pc() - t0
    return float(np.median(d))


# ---------------------------------------------------------------------------------------------
# A realistic input sequence: the measurements of a short in-process closed loop
# ---------------------------------------------------------------------------------------------
def _closed_loop_setup(scenario: str = "paper"):
    from fc.control.law import AttitudeLaw
    from fc.estimator import Estimator
    from plant_sim.scenario import load
    from plant_sim.sim import PlantSim
    sc = load(scenario)
    sim = PlantSim(sc)
    est = Estimator()
    law = AttitudeLaw({"CO_ENABLE": 1})
    meas = np.zeros(14)
    sim.measure(meas)
    est.update(meas)
    law.reset(est.est, sim.cmd_rad)
    return sc, sim, est, law, meas


def trajectory(n_frames: int, scenario: str = "paper") -> np.ndarray:
    """Measurement vectors (n_frames x 14) of an in-process closed loop from the scenario start."""
    from fc.control.kernels import fast_kernel, slow_kernel
    from fc.estimator import LIMITS_HI, LIMITS_LO, estimate_kernel
    from plant_sim.dynamics import advance_frame
    from plant_sim.sensors import measure
    sc, sim, est, law, meas = _closed_loop_setup(scenario)
    x, p, w, n_sub, ring, rc, rng, mw = sim.kernel_args()
    ka = law.kernel_args()
    ratio = 5
    dt_f = sim.frame_dt_s
    out = np.zeros((n_frames, 14))
    cmd = np.zeros(3)
    for k in range(n_frames):
        measure(x, p, ring, rc, rng, mw, meas)
        out[k] = meas
        estimate_kernel(meas, est.good, est.good_t, LIMITS_LO, LIMITS_HI, est.stale_s, est.est,
                        est.masks)
        if k % ratio == 0:
            a, b, m = sc.command_at(meas[0])
            cmd[0], cmd[1], cmd[2] = a, b, m
            slow_kernel(est.est, cmd, dt_f * ratio, ka["par"], ka["x"], ka["nm"], ka["st"],
                        ka["tab"], ka["atm"], ka["grid"])
        fast_kernel(est.est, dt_f, ka["par"], ka["x"], ka["nm"], ka["st"], ka["tab"], ka["atm"],
                    ka["grid"], ka["delta"])
        advance_frame(x, ka["delta"], p, w, n_sub)
    return out


# ---------------------------------------------------------------------------------------------
# 1. Control law
# ---------------------------------------------------------------------------------------------
def law_figures(quick: bool = False) -> dict:
    """Per-call cost of the law's cycle and parts (median, p99 in us)."""
    from fc.control import kernels as K
    from fc.control.law import AttitudeLaw
    from fc.control.nominal import eval_model
    from fc.estimator import LIMITS_HI, LIMITS_LO, Estimator, estimate_kernel

    n = 4000 if quick else 40000
    rounds = 2 if quick else 5
    seq = trajectory(2000)
    n_seq = seq.shape[0]
    law = AttitudeLaw({"CO_ENABLE": 1})
    est = Estimator()
    ka = law.kernel_args()
    par, x, nm, st, tab, atm, grid, delta = (ka[k] for k in ("par", "x", "nm", "st", "tab",
                                                             "atm", "grid", "delta"))
    meas = np.zeros(14)
    t_base = 0.0
    ratio = 5
    dt_f = 0.002
    dt_s = dt_f * ratio
    cmd = np.array([math.radians(2.0), 0.0, math.radians(5.0)])
    pc = time.perf_counter_ns
    lam = st  # coordinated_factors writes into st at S_LAMBDA
    from fc.control.layout import S_LAMBDA

    def feed(i):
        nonlocal t_base
        meas[:] = seq[i % n_seq]
        if i % n_seq == 0 and i:
            t_base += seq[-1, 0] + dt_f
        meas[0] += t_base

    # warm-up (loads caches / compiles) and the starting state
    feed(0)
    est.update(meas)
    law.reset(est.est)
    res: dict = {"timer_overhead_ns": timer_overhead_ns()}
    samples = {k: [] for k in ("cycle_fc_path", "cycle_kernels", "estimator", "slow_step",
                               "fast_step", "nominal_model", "factors", "coord_matrix",
                               "allocate", "actuator_model")}
    i_glob = 1
    for _r in range(rounds):
        law.reset(est.est)
        # (a) what the fc does per fast tick: Estimator.update + [slow_step] + fast_step
        d = np.empty(n, dtype=np.int64)
        for i in range(n):
            feed(i_glob)
            i_glob += 1
            slow = i % ratio == 0
            t0 = pc()
            est.update(meas)
            if slow:
                law.slow_step(est.est, cmd, dt_s)
            law.fast_step(est.est, dt_f)
            d[i] = pc() - t0
        samples["cycle_fc_path"].append(d)
        # (b) the same cycle through the kernels directly (tools, closed loop)
        d = np.empty(n, dtype=np.int64)
        ds = np.empty(n // ratio, dtype=np.int64)
        df = np.empty(n, dtype=np.int64)
        de = np.empty(n, dtype=np.int64)
        good, good_t, masks, stale_s, e = est.good, est.good_t, est.masks, est.stale_s, est.est
        for i in range(n):
            feed(i_glob)
            i_glob += 1
            t0 = pc()
            estimate_kernel(meas, good, good_t, LIMITS_LO, LIMITS_HI, stale_s, e, masks)
            t1 = pc()
            if i % ratio == 0:
                slow_kernel = K.slow_kernel
                slow_kernel(e, cmd, dt_s, par, x, nm, st, tab, atm, grid)
            t2 = pc()
            K.fast_kernel(e, dt_f, par, x, nm, st, tab, atm, grid, delta)
            t3 = pc()
            d[i] = t3 - t0
            de[i] = t1 - t0
            if i % ratio == 0:
                ds[i // ratio] = t2 - t1
            df[i] = t3 - t2
        samples["cycle_kernels"].append(d)
        samples["estimator"].append(de)
        samples["slow_step"].append(ds)
        samples["fast_step"].append(df)
        # (c) parts of the fast step, each called alone
        m = n // 4
        for name, fn in (
                ("nominal_model", lambda: eval_model(e, par, tab, atm, grid, nm)),
                ("factors", lambda: K.coordinated_factors(e, par, lam, S_LAMBDA)),
                ("coord_matrix", lambda: K.coordinated_matrix(par, nm, lam, S_LAMBDA)),
                ("allocate", lambda: K.allocate(par, nm, 1e5, 2e5, -1e5, 0.0, delta, st)),
                ("actuator_model", lambda: K.actuator_model_step(par, x, delta, dt_f))):
            fn()
            d = np.empty(m, dtype=np.int64)
            for i in range(m):
                t0 = pc()
                fn()
                d[i] = pc() - t0
            samples[name].append(d)
    for k, v in samples.items():
        res[k] = stats_us(np.concatenate(v))
    res["note"] = ("per call from Python, timer pair included; cycle = estimator + fast step, "
                   f"+ slow step every {ratio}th tick (500/100 Hz); parts of the fast step "
                   "include one Python->numba dispatch each (a lambda adds ~0.05 us)")
    return res


# ---------------------------------------------------------------------------------------------
# 2. Plant
# ---------------------------------------------------------------------------------------------
def plant_figures(quick: bool = False) -> dict:
    from plant_sim import dynamics as dy
    from plant_sim.scenario import load
    from plant_sim.sim import PlantSim
    sim = PlantSim(load("paper"))
    x0 = sim.x.copy()
    x, p, w = sim.x, sim.p, sim.w
    n = 2000
    batches = 5 if quick else 9
    pc = time.perf_counter_ns
    dy.rk4_step(x, p, w)
    per_call = []
    batch_med = []
    in_loop = []
    for _b in range(batches):
        x[:] = x0
        d = np.empty(n, dtype=np.int64)
        tb = pc()
        for i in range(n):
            t0 = pc()
            dy.rk4_step(x, p, w)
            d[i] = pc() - t0
        batch_med.append((pc() - tb) / n)
        per_call.append(d)
        x[:] = x0
        t0 = pc()
        dy.advance_frame_latched(x, p, w, n)
        in_loop.append((pc() - t0) / n)
    allc = np.concatenate(per_call)
    return {"dt_s": float(p[dy.P_DT]),
            "rk4_step_per_call": stats_us(allc),
            "rk4_step_batch_us": float(np.median(batch_med)) * 1e-3,
            "rk4_step_in_loop_us": float(np.median(in_loop)) * 1e-3,
            "note": f"paper scenario, {batches} batches of {n} steps from the initial state; "
                    "per call from Python (timer pair included) and whole batch inside numba"}


def jsbsim_figures(dt_s: float = 0.001, quick: bool = False) -> dict:
    """JSBSim X-15 ``run()`` cost at ``dt_s``; ``{"available": False, ...}`` without jsbsim."""
    try:
        import jsbsim
    except ImportError:
        return {"available": False,
                "note": "jsbsim not installed: pip install 'hyfc[bench]' (optional bench extra)"}
    fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
    fdm.set_debug_level(0)
    if not fdm.load_model("X15"):
        return {"available": False, "note": "jsbsim has no X15 model"}
    fdm.disable_output()
    fdm.load_ic("reset01", True)          # stock reset file: airborne at 40000 ft
    fdm.set_dt(dt_s)
    fdm["ic/h-sl-ft"] = 60000.0            # airborne override, well clear of the ground
    fdm["ic/u-fps"] = 3000.0
    fdm.run_ic()
    try:
        fdm["propulsion/set-running"] = -1
    except Exception:  # noqa: BLE001 - older bindings: engines start with the throttle
        pass
    fdm["fcs/throttle-cmd-norm"] = 1.0
    n = 2000
    batches = 5 if quick else 9
    pc = time.perf_counter_ns
    med = []
    for _b in range(batches):
        fdm.reset_to_initial_conditions(0)
        fdm["fcs/throttle-cmd-norm"] = 1.0
        run = fdm.run
        t0 = pc()
        for _ in range(n):
            run()
        med.append((pc() - t0) / n)
    return {"available": True, "version": getattr(jsbsim, "__version__", "?"), "dt_s": dt_s,
            "x15_run_step_us": float(np.median(med)) * 1e-3,
            "altitude_ft_end": float(fdm["position/h-sl-ft"]),
            "note": f"X15 reset01 + 60 kft/3000 ft/s override, engine on, {batches} batches of "
                    f"{n} run(), median"}


# ---------------------------------------------------------------------------------------------
# 7. In-process closed loop
# ---------------------------------------------------------------------------------------------
def closed_loop_figures(quick: bool = False) -> dict:
    """Simulated seconds per wall second of the closed loop without UDP, one thread."""
    sim_s = 5.0 if quick else 30.0
    try:
        from tools.sitl.closed_loop import simulate
    except ImportError:
        simulate = None
    if simulate is not None:
        simulate("paper", duration_s=0.2)          # compile / load the cache
        walls = []
        cpus = []
        for _ in range(1 if quick else 5):
            c0 = time.thread_time()
            simulate("paper", duration_s=0.01)           # set-up cost alone
            c1 = time.thread_time()
            res = simulate("paper", duration_s=sim_s)
            c2 = time.thread_time()
            cpus.append((c2 - c1) - (c1 - c0))
            walls.append(res.wall_s)
        wall = float(np.median(walls))
        cpu = float(np.median(cpus))
        t_sim = float(res.t_s[-1] - res.t_s[0]) if res.t_s.size > 1 else sim_s
        return {"source": "tools.sitl.closed_loop.simulate (whole loop in numba, every frame "
                          "recorded)", "sim_time_s": t_sim, "wall_time_s": wall,
                "sim_s_per_wall_s": t_sim / wall, "cpu_time_s": cpu,
                "sim_s_per_cpu_s": t_sim / cpu if cpu > 0 else float("nan"),
                "diverged": bool(res.diverged)}
    n_frames_warm = 200
    trajectory(n_frames_warm)          # compiles / loads every kernel
    from fc.control.kernels import fast_kernel, slow_kernel
    from fc.estimator import LIMITS_HI, LIMITS_LO, estimate_kernel
    from plant_sim.dynamics import advance_frame
    from plant_sim.sensors import measure
    sc, sim, est, law, meas = _closed_loop_setup("paper")
    x, p, w, n_sub, ring, rc, rng, mw = sim.kernel_args()
    ka = law.kernel_args()
    par, xl, nm, st, tab, atm, grid, delta = (ka[k] for k in ("par", "x", "nm", "st", "tab",
                                                              "atm", "grid", "delta"))
    ratio = 5
    dt_f = sim.frame_dt_s
    n = int(round(sim_s / dt_f))
    cmd = np.zeros(3)
    good, good_t, masks, stale_s, e = est.good, est.good_t, est.masks, est.stale_s, est.est
    t0 = time.perf_counter()
    c0 = time.thread_time()
    for k in range(n):
        measure(x, p, ring, rc, rng, mw, meas)
        estimate_kernel(meas, good, good_t, LIMITS_LO, LIMITS_HI, stale_s, e, masks)
        if k % ratio == 0:
            a, b, m = sc.command_at(meas[0])
            cmd[0], cmd[1], cmd[2] = a, b, m
            slow_kernel(e, cmd, dt_f * ratio, par, xl, nm, st, tab, atm, grid)
        fast_kernel(e, dt_f, par, xl, nm, st, tab, atm, grid, delta)
        advance_frame(x, delta, p, w, n_sub)
    wall = time.perf_counter() - t0
    cpu = time.thread_time() - c0
    return {"source": "tools.bench (kernels called from a Python loop; tools.sitl.closed_loop "
                      "not available)",
            "sim_time_s": n * dt_f, "wall_time_s": wall, "sim_s_per_wall_s": n * dt_f / wall,
            "cpu_time_s": cpu, "sim_s_per_cpu_s": n * dt_f / cpu,
            "frame_hz": 1.0 / dt_f, "physics_hz": 1.0 / sim.physics_dt_s,
            "us_per_frame": wall / n * 1e6}
