"""Fly one variant: start the controller and the plant as two processes on loopback UDP,
drive them (lockstep: command line; realtime: the scripted ground station), watch them,
stop them. See docs/hil.md.
"""
from __future__ import annotations

import math
import queue
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from tools.sitl import rundata
from tools.sitl.procs import Child, free_udp_port

FLIGHT_MODE = {"coordinated": "COORDINATED", "uncoordinated": "UNCOORDINATED"}
CUSTOM_MODE = {"coordinated": 1, "uncoordinated": 2}   # fc/modes.py FlightMode
#: --flight-mode choices beyond the variant's attitude mode: the guidance modes (fc/modes.py),
#: whose inner loop (GUID_INNER_CO) follows the variant
GUIDANCE_FLIGHT_MODES = {"CRUISE": 4, "GUIDED": 5, "MISSION": 6}
#: MISSION needs a mission and a GNSS fix, so the lockstep controller starts in CRUISE and the
#: scripted ground station uploads the mission and selects MISSION (``_drive_mission``)
START_MODE = {"MISSION": "CRUISE"}
#: the ground station's record of the mission's progress (sim times as it heard them)
MISSION_PROGRESS_FILE = "mission_progress.json"
#: first start of numba-compiled processes on a loaded 2-core machine can be slow
READY_TIMEOUT_S = 180.0
#: the controller's data-loss failsafe timeout in lockstep runs (s; see write_params)
LOCKSTEP_FS_TIMEOUT_S = 30.0
#: messages the main job's ground station keeps in its log (tools/sitl/gcs.py ``log_keep``):
#: it only waits on the log for the mission upload (MISSION) and the realtime script's
#: answers, never on old messages. The default keeps 10,000 to 20,000 messages of about
#: 0.8 KB each after a few minutes: the runner was 63 MB of the 1-hour cruise's 422 MB
GCS_LOG_KEEP = 1000


@dataclass
class RunConfig:
    scenario: str
    mode: str = "lockstep"
    variants: tuple = ("coordinated", "uncoordinated")
    out_dir: Path = Path("runs")
    duration_s: float | None = None      # None: the scenario's; 0: until Ctrl-C (realtime)
    seed: int = 0
    command_shaping: str = "steps"
    gains: str = "scheduled"             # "scheduled" (CTL_SCHED 1, the default) or "paper"
    flight_mode: str = ""                # "" the variant's attitude mode, or CRUISE / GUIDED / MISSION
    mission_file: Path | None = None     # QGC WPL 110 file uploaded in MISSION
    params_file: Path | None = None      # extra controller parameters (MAVProxy format)
    gcs_out: tuple = ()                  # extra ground-station addresses (realtime)
    progress_every_s: float = 1.0
    python: str = sys.executable
    quiet: bool = False
    #: command prefixes of the two processes (tests and relays may substitute their own)
    plant_cmd: tuple = ()
    fc_cmd: tuple = ()

    def plant_argv0(self) -> list[str]:
        return list(self.plant_cmd) or [self.python, "-m", "plant_sim"]

    def fc_argv0(self) -> list[str]:
        return list(self.fc_cmd) or [self.python, "-m", "fc"]


@dataclass
class VariantResult:
    variant: str
    ok: bool
    error: str | None = None
    interrupted: bool = False
    plant_rc: int | None = None
    fc_rc: int | None = None
    wall_time_total_s: float = math.nan
    last_progress: dict = field(default_factory=dict)


def shaping_params(shaping: str) -> dict[str, float]:
    """Controller parameters that select the command shaping (fc/control/params.py)."""
    if shaping == "steps":
        return {"REF_PF_EN": 0.0}
    if shaping == "prefilter":
        return {"REF_PF_EN": 1.0}
    raise ValueError(f"unknown command shaping {shaping!r} (steps or prefilter)")


def gains_params(gains: str) -> dict[str, float]:
    """Controller parameters that select the gains: the schedule (the default) or the paper's
    fixed gains (CTL_SCHED 0, docs/control_law.md "Scheduling")."""
    if gains == "scheduled":
        return {"CTL_SCHED": 1.0}
    if gains == "paper":
        return {"CTL_SCHED": 0.0}
    raise ValueError(f"unknown gains {gains!r} (scheduled or paper)")


def controller_params(cfg: RunConfig) -> dict[str, float]:
    """The parameters tools.hil gives the controller: the user's file, then the shaping and
    the gains, then (lockstep) the failsafe timeout unless the user set it."""
    values: dict[str, float] = {}
    if cfg.params_file is not None:
        from fc.params import ParamTable
        values.update(ParamTable.read_file(str(cfg.params_file)))
    values.update(shaping_params(cfg.command_shaping))
    values.update(gains_params(cfg.gains))
    if cfg.mode == "lockstep":
        # In lockstep the plant waits for the controller and may itself pause (JIT compile,
        # a loaded CPU); a pause of the sim is not a loss of plant data. The controller's
        # wall-clock data-loss failsafe would otherwise fire mid-run and make the run depend
        # on the machine's load (docs/hil.md). 30 s is the parameter's maximum.
        values.setdefault("FS_TIMEOUT_S", LOCKSTEP_FS_TIMEOUT_S)
    return values


def flight_mode_of(cfg: RunConfig, variant: str) -> tuple[str, int]:
    """(name, number) of the flight mode a variant flies: the variant's attitude mode, or the
    guidance mode ``cfg.flight_mode`` (its inner loop set by GUID_INNER_CO)."""
    if cfg.flight_mode:
        return cfg.flight_mode, GUIDANCE_FLIGHT_MODES[cfg.flight_mode]
    return FLIGHT_MODE[variant], CUSTOM_MODE[variant]


def write_params(path: Path, cfg: RunConfig, variant: str | None = None) -> dict[str, float]:
    """The controller's parameter file of a variant (MAVProxy format)."""
    values = controller_params(cfg)
    if cfg.flight_mode and variant is not None:
        values["GUID_INNER_CO"] = 1.0 if variant == "coordinated" else 0.0
    lines = ["# hyfc controller parameters written by tools.hil"]
    if cfg.params_file is not None:
        lines.append(f"# includes {cfg.params_file}")
    lines += [f"{k:<16s} {v:.9g}" for k, v in values.items()]
    Path(path).write_text("\n".join(lines) + "\n")
    return values


def parse_progress(line: str) -> dict | None:
    """``PROGRESS t_s=1.234 rtf=21.5`` -> {"t_s": 1.234, "rtf": 21.5}; None otherwise."""
    if not line.startswith("PROGRESS"):
        return None
    out = {}
    for tok in line.split()[1:]:
        k, sep, v = tok.partition("=")
        if sep:
            try:
                out[k] = float(v)
            except ValueError:
                pass
    return out


class Progress:
    """One status line per variant: sim time and real-time factor from PROGRESS lines."""

    def __init__(self, variant: str, total_s: float | None, quiet: bool):
        self.variant = variant
        self.total_s = total_s
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.last: dict = {}

    def update(self, p: dict) -> None:
        self.last = p
        if self.quiet:
            return
        t = p.get("t_s", math.nan)
        rtf = p.get("rtf", math.nan)
        of = f" / {self.total_s:.1f}" if self.total_s else ""
        msg = f"[{self.variant}] sim t = {t:7.2f}{of} s   real-time factor {rtf:6.2f}"
        if self.tty:
            print("\r" + msg, end="", file=sys.stderr, flush=True)
        else:
            print(msg, file=sys.stderr, flush=True)

    def done(self) -> None:
        if self.tty and not self.quiet and self.last:
            print(file=sys.stderr)


def _upload_when_home(gcs, items: list[dict]) -> None:
    """Wait for the vehicle's home (its first GNSS fix), then upload the mission."""
    gcs.wait_for(lambda tel: tel.heartbeats > 0 and tel.home is not None, 60.0,
                 "the controller's HEARTBEAT and HOME_POSITION (a GNSS fix)")
    gcs.upload_mission(items)


def _drive_mission(gcs, items: list[dict], stop: threading.Event, errors: queue.Queue) -> None:
    """Lockstep MISSION: the controller flies CRUISE from the start; the ground station
    uploads the mission once the vehicle has a fix, then selects MISSION (fc/modes.py 6)."""
    try:
        _upload_when_home(gcs, items)
        gcs.set_mode(GUIDANCE_FLIGHT_MODES["MISSION"])
    except Exception as exc:  # reported by the runner, which stops the run
        if not stop.is_set():
            errors.put(f"ground station: {exc}")


def _drive_realtime(gcs, commands: list[dict], mode_number: int, stop: threading.Event,
                    errors: queue.Queue, mission: list[dict] | None = None) -> None:
    """The scripted operator: commands as parameters, the mission (MISSION), mode, arm, then
    the timeline by sim time."""
    from tools.sitl.gcs import GcsError
    try:
        # AOA_SSA stamp 0: the controller has no plant frame yet
        gcs.wait_for(lambda tel: tel.heartbeats > 0 and bool(tel.sim_t_s), 60.0,
                     "the controller's HEARTBEAT and AOA_SSA with plant data")
        first = {"alpha_deg": 0.0, "beta_deg": 0.0, "mu_deg": 0.0}
        pending = list(commands)
        # entries due at start are merged and set before the law is engaged
        while pending and pending[0]["t_s"] <= 0.0:
            first.update({k: v for k, v in pending.pop(0).items() if k != "t_s"})
        gcs.set_command_deg(first["alpha_deg"], first["beta_deg"], first["mu_deg"])
        if mission:
            _upload_when_home(gcs, mission)
        gcs.set_mode(mode_number)
        gcs.arm()
        while pending and not stop.is_set():
            c = pending[0]
            try:
                gcs.wait_for(lambda tel: (tel.sim_time_s() or 0.0) >= c["t_s"], 0.5, "sim time")
            except GcsError:
                continue
            pending.pop(0)
            gcs.set_command_deg(c.get("alpha_deg", math.nan), c.get("beta_deg", math.nan),
                                c.get("mu_deg", math.nan))
    except Exception as exc:  # reported by the runner, which stops the run
        if not stop.is_set():
            errors.put(f"ground station: {exc}")


def sent_timeline(gcs, commands: list[dict]) -> list[dict]:
    """The timeline as the ground station actually applied it (vehicle sim time when the
    COMMAND_ACK arrived), for the metrics of a realtime run."""
    out = []
    for t_s, key, value in gcs.sent:
        if key not in ("alpha_deg", "beta_deg", "mu_deg") or not math.isfinite(t_s):
            continue
        if out and abs(out[-1]["t_s"] - t_s) < 1e-9:
            out[-1][key] = value
        else:
            out.append({"t_s": t_s, key: value})
    return out or commands


def run_variant(cfg: RunConfig, variant: str, vdir: Path, commands: list[dict],
                scenario_ref: str, stop: threading.Event) -> VariantResult:
    """Fly one variant into ``vdir``; never leaves a child process behind."""
    vdir.mkdir(parents=True, exist_ok=True)
    res = VariantResult(variant=variant, ok=False)
    rundata.write_timeline(vdir / rundata.TIMELINE_FILE, commands,
                           header=f"attitude-command timeline of scenario {scenario_ref}")
    params_path = vdir / "params_in.parm"
    write_params(params_path, cfg, variant)
    plant_port = free_udp_port()
    gcs_bind_port = free_udp_port()
    gcs = None
    errors: queue.Queue[str] = queue.Queue()
    fc = plant = None
    realtime = cfg.mode == "realtime"
    forever = realtime and cfg.duration_s == 0
    total_s = cfg.duration_s if cfg.duration_s else None
    progress = Progress(variant, None if forever else total_s, cfg.quiet)
    t0 = time.monotonic()
    driver_stop = threading.Event()   # ends the realtime ground-station script
    driver = None
    try:
        from tools.sitl.gcs import ScriptedGcs
        gcs = ScriptedGcs(heartbeat=True, record=False, log_keep=GCS_LOG_KEEP)
        fc_argv = cfg.fc_argv0() + ["--mode", cfg.mode,
                   "--plant-bind", f"127.0.0.1:{plant_port}",
                   "--gcs-bind", f"127.0.0.1:{gcs_bind_port}",
                   "--gcs", f"127.0.0.1:{gcs.port}",
                   "--params", str(params_path), "--out", str(vdir)]
        for addr in cfg.gcs_out:
            fc_argv += ["--gcs", addr]
        mode_name, mode_number = flight_mode_of(cfg, variant)
        mission = None
        if mode_name == "MISSION":
            from tools.sitl.gcs import read_wpl
            mission = read_wpl(cfg.mission_file)
        if not realtime:
            fc_argv += ["--timeline", str(vdir / rundata.TIMELINE_FILE), "--arm",
                        "--flight-mode", START_MODE.get(mode_name, mode_name)]
        fc = Child("fc", fc_argv, vdir / "fc.console.log")
        _say(cfg, f"tools.hil: [{variant}] fc pid {fc.pid}")
        fc.wait_for_line("READY", READY_TIMEOUT_S, stop=stop)
        plant_argv = cfg.plant_argv0() + ["run", "--scenario", scenario_ref,
                      "--mode", cfg.mode, "--fc", f"127.0.0.1:{plant_port}",
                      "--bind", "127.0.0.1:0", "--out", str(vdir), "--seed", str(cfg.seed),
                      "--progress-every", str(cfg.progress_every_s)]
        if forever:
            plant_argv += ["--duration", "0"]       # the plant's open-ended run
        elif cfg.duration_s is not None:
            plant_argv += ["--duration", repr(float(cfg.duration_s))]
        plant = Child("plant", plant_argv, vdir / "plant.console.log")
        _say(cfg, f"tools.hil: [{variant}] plant pid {plant.pid}")
        if realtime:
            driver = threading.Thread(target=_drive_realtime, name="gcs-driver", daemon=True,
                                      args=(gcs, commands, mode_number, driver_stop, errors,
                                            mission))
            driver.start()
        elif mission is not None:
            driver = threading.Thread(target=_drive_mission, name="gcs-mission", daemon=True,
                                      args=(gcs, mission, driver_stop, errors))
            driver.start()
        # ---- watch ----
        while True:
            try:
                line = plant.lines.get(timeout=0.2)
                p = parse_progress(line)
                if p is not None:
                    progress.update(p)
                    res.last_progress = p
            except queue.Empty:
                pass
            if stop.is_set():
                res.interrupted = True
                driver_stop.set()
                break
            if not errors.empty():
                res.error = errors.get()
                break
            if plant.poll() is not None:
                while True:  # drain the last lines
                    try:
                        p = parse_progress(plant.lines.get_nowait())
                    except queue.Empty:
                        break
                    if p is not None:
                        progress.update(p)
                        res.last_progress = p
                if plant.poll() != 0:
                    res.error = plant.death_message()
                break
            if fc.poll() is not None:
                res.error = (fc.death_message() + " before the plant finished")
                break
        progress.done()
    except InterruptedError:
        res.interrupted = True
    except Exception as exc:
        res.error = str(exc)
    finally:
        driver_stop.set()
        if gcs is not None:
            gcs.abort.set()
        if driver is not None:
            driver.join(timeout=10.0)
        # the plant first (it writes truth.npz on SIGINT), then the controller
        for child in (plant, fc):
            if child is not None:
                rc = child.stop()
                if child is plant:
                    res.plant_rc = rc
                else:
                    res.fc_rc = rc
        if gcs is not None:
            if realtime:
                _write_applied_timeline(vdir, gcs, commands)
            _save_gcs(gcs, vdir)
            gcs.close()
    _write_params_used(vdir, params_path, variant)
    res.wall_time_total_s = time.monotonic() - t0
    if res.error is None and not res.interrupted:
        if res.fc_rc not in (0, None):
            res.error = f"fc exited with code {res.fc_rc} when stopped (see {vdir / 'fc.console.log'})"
    res.ok = res.error is None and not res.interrupted
    return res


def _write_applied_timeline(vdir: Path, gcs, commands: list[dict]) -> None:
    """Realtime: the timeline the metrics use is the one the controller actually applied
    (its internals log), else the ground station's acknowledged commands."""
    applied = None
    try:
        applied = rundata.timeline_from_internals(rundata.load_internals(vdir))
    except Exception:  # a missing or truncated log: fall back to what the GCS saw
        applied = None
    if applied:
        header = "timeline as applied by the controller (its cmd_* internals, sensor time)"
    else:
        applied = sent_timeline(gcs, commands)
        header = ("timeline as applied by the ground station "
                  "(vehicle sim time of each acknowledged command)")
    rundata.write_timeline(vdir / rundata.TIMELINE_FILE, applied, header=header)


def _write_params_used(vdir: Path, params_path: Path, variant: str) -> None:
    """``params_used.parm``: every controller parameter as flown (the table's defaults with
    the parameter file applied; the fc saves ground-station changes into that file)."""
    try:
        from fc.params import build_table
        table = build_table()
        _, warnings = table.load(str(params_path))
        table.force("CO_ENABLE", 1.0 if variant == "coordinated" else 0.0)
        table.save(str(vdir / "params_used.parm"))
        for w in warnings:
            print(f"tools.hil: {w}", file=sys.stderr)
    except Exception as exc:  # the run itself is fine; say what is missing
        print(f"tools.hil: could not write params_used.parm: {exc}", file=sys.stderr)


def _say(cfg: RunConfig, text: str) -> None:
    if not cfg.quiet:
        print(text, file=sys.stderr, flush=True)


def _save_gcs(gcs, vdir: Path) -> None:
    import numpy as np
    tel = gcs.telemetry_arrays()
    np.savez(vdir / "gcs_telemetry.npz", **tel)
    if gcs.tel.mission_acks or gcs.tel.mission_current:
        import json
        t = gcs.tel
        with open(vdir / MISSION_PROGRESS_FILE, "w") as f:
            json.dump({"acks": t.mission_acks, "requests": t.mission_requests,
                       "current": [list(r) for r in t.mission_current],
                       "reached": [list(r) for r in t.mission_reached],
                       "sent": [list(r) for r in gcs.sent]}, f, indent=1)
