"""fc/param_service.py - the fc process's parameter service: load, save, set, apply.

One part of the flight controller (docs/architecture.md, the fc's parts). It owns the
parameter file (load at start-up, atomic saves from the I/O thread, a corrupt file set aside)
and every accepted change: the table (fc/params.py) validates with the one rule, then the
value goes to its owner in the owner's unit: the law and the guidance convert to SI
themselves (``to_si``); the process's own parameters are converted here, into
:class:`ProcessSettings` (the one SI conversion point of the process parameters).
"""
from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, field

import numpy as np

from fc.estimator import Estimator
from fc.guided import GUIDANCE_NAMES, GuidanceRunner
from fc.link import mavlink as ML
from fc.params import PROCESS_DRIVEN, ParamFileError, ParamTable, set_aside
from fc.storage import DiskHealth

__all__ = ["ProcessSettings", "ParamService", "load_param_file"]

DEG = math.pi / 180.0


@dataclass
class ProcessSettings:
    """The fc process's own parameters in SI (from CMD_*, TRIM_*, FS_* of the table)."""

    cmd_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))    # alpha_c, beta_c, mu_c
    trim_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))   # elevons L, R, rudder
    fs_timeout_s: float = 0.5
    fs_recover: bool = True
    fs_recover_s: float = 0.2

    def apply(self, p: ParamTable) -> None:
        """Convert the table's values (degrees, seconds, switches) in place."""
        self.cmd_rad[0] = p.get("CMD_ALPHA_DEG") * DEG
        self.cmd_rad[1] = p.get("CMD_BETA_DEG") * DEG
        self.cmd_rad[2] = p.get("CMD_MU_DEG") * DEG
        self.trim_rad[0] = p.get("TRIM_ELEVL_DEG") * DEG
        self.trim_rad[1] = p.get("TRIM_ELEVR_DEG") * DEG
        self.trim_rad[2] = p.get("TRIM_RUD_DEG") * DEG
        self.fs_timeout_s = p.get("FS_TIMEOUT_S")
        self.fs_recover = p.get("FS_RECOVER") > 0.5
        self.fs_recover_s = p.get("FS_RECOVER_S")


def load_param_file(table: ParamTable, path: str, log: logging.Logger) -> list[tuple[int, str]]:
    """Apply the parameter file at ``path`` to ``table`` (before the law is built from it);
    write the defaults when there is none. A corrupt file is set aside and the defaults used.
    Returns the STATUSTEXTs (severity, text) for the ground station once it is up."""
    if os.path.exists(path):
        try:
            applied, warnings = table.load(path)
        except (ParamFileError, OSError) as exc:
            aside = set_aside(path)
            log.error(f"parameter file unreadable ({exc}); kept aside as {aside}; "
                      "running on defaults")
            table.save(path)
            return [(ML.MAV_SEVERITY_CRITICAL, "param file corrupt: kept aside, defaults used")]
        for w in warnings:
            log.warning(w)
        log.info("loaded %d parameters from %s", len(applied), path)
        return []
    table.save(path)
    return []


@dataclass
class ParamService:
    """Sets and saves parameters for the running controller (ground station, timeline)."""

    table: ParamTable
    law_names: set
    law: object                 # the injected law (fc/control AttitudeLaw or a stand-in)
    guid: GuidanceRunner
    est: Estimator
    path: str                   # the parameter file
    log: logging.Logger
    dirty: bool = False         # a setting changed since the last save
    disk: DiskHealth | None = None   # a save that fails is reported there (fc/storage.py)
    settings: ProcessSettings = field(default_factory=ProcessSettings)

    def __post_init__(self) -> None:
        self.apply_process()

    def apply_process(self) -> None:
        self.settings.apply(self.table)
        self.est.stale_s = self.table.get("EST_STALE_S")

    def set(self, name: str, value: float) -> str | None:
        """Validate and apply one parameter. None on success, else the reason."""
        p = self.table
        if name in PROCESS_DRIVEN:
            return PROCESS_DRIVEN[name]
        old = p.get(name) if name in p else None
        reason = p.set(name, value)
        if reason is not None:
            return reason      # the caller says why (STATUSTEXT, mirrored to fc.log, rate-limited)
        new = p.get(name)
        if name in self.law_names:
            try:
                self.law.set_param(name, new)
            except (KeyError, ValueError) as exc:
                p.force(name, old)
                return str(exc.args[0])          # the law's reasons name the parameter
            self.guid.set_param(name, new)       # the nominal model's MDL_MASS / MDL_XCG
        elif name in GUIDANCE_NAMES:
            self.guid.set_param(name, new)
        else:
            self.apply_process()
        if p.defn(name).group != "command":
            self.dirty = True
        self.log.info("param %s = %g (was %g)", name, new, old)
        return None

    def snapshot(self, force: bool = False) -> np.ndarray | None:
        """The values to save when a setting changed since the last call (or ``force``),
        else None."""
        if not (self.dirty or force):
            return None
        self.dirty = False
        return self.table.values.copy()

    def save(self, values: np.ndarray | None = None) -> str | None:
        """Write the parameter file (runs on the I/O thread; ``values`` is a snapshot).
        Commands are not settings: their defaults go on file. None when written, else the
        error (also given to the disk health; the next save tries again)."""
        try:
            saved = ParamTable(self.table.defs)
            saved.values[:] = self.table.values if values is None else values
            for i, d in enumerate(saved.defs):
                if d.group == "command":
                    saved.values[i] = d.default
            saved.save(self.path)
        except OSError as exc:
            self.dirty = True               # tried again at the next save
            if self.disk is None or self.disk.failed("parameters", exc):
                self.log.error("cannot save parameters to %s: %s", self.path, exc)
            return exc.strerror or repr(exc)
        if self.disk is not None:
            self.disk.ok("parameters")
        return None
