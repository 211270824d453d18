"""The gain schedule's committed table (fc/control/data/schedule.npz) and what it holds.

Written by ``python -m tools.schedule_design`` (the design procedure, docs/control_law.md
"Scheduling"); read here once, at import, to give the ``SCH_*`` parameters of
fc/control/params.py their defaults. The law itself reads the schedule from its parameter
array (fc/control/schedule.py), so a ground station sees and may change every value.

The table: ``qbar_kpa`` (float64[SCHED_N], increasing: the dynamic-pressure nodes, kPa) and
one float64[SCHED_N] per entry of ``SCHED_QUANTITIES`` (the value at each node, in the unit
given), plus the design's own figures (``design_*``) for the record; and the Mach axis of
the rate-command limit: ``mach_nodes`` (float64[SCHED_N], increasing) and ``omc_mach_factor``
(the factor on SLW_OMC_MAX at each Mach node, in (0, 1]: the rudder authority the airframe's
directional instability leaves, docs/control_law.md s. 13); and ``authority_factor``
(float64[SCHED_N] on the same Mach nodes, >= 1: the least effective channel's effectiveness at
that Mach number over the least over Mach 6-15, for which the dynamic-pressure nodes were
designed; the law looks the gains up at qbar x factor, docs/control_law.md s. 13 "The
authority axis").
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

SCHEDULE_PATH = Path(__file__).with_name("data") / "schedule.npz"

#: Number of dynamic-pressure nodes.
SCHED_N = 6

#: (name in the npz, unit, what it schedules): the order of the SCH_* parameter families.
SCHED_QUANTITIES: tuple[tuple[str, str, str], ...] = (
    ("kappa1", "1/s", "kappa1 of Eq. 29 (SLW_KAPPA)"),
    ("K", "1/s", "K1 = K2 = K3 of Eq. 27 (SLW_K1..3)"),
    ("kappa2", "1/s", "kappa2 of Eq. 35 (FST_KAPPA)"),
    ("dob_c", "1/s", "the observer's bandwidth c of Eq. 37 (DOB_C)"),
    ("cf_wn", "rad/s", "the omega_c command filter's natural frequency (FST_CF_WN)"),
    ("flt_rate_hz", "Hz", "the rate input filter's corner (FLT_RATE_HZ)"),
    ("flt_ang_hz", "Hz", "the angle input filter's corner (FLT_ANG_HZ)"),
    ("omc_max_deg_s", "deg/s", "the rate-command limit (SLW_OMC_MAX)"),
)


#: The Mach axis: (npz name of the nodes, npz name of the values) of the rate-command limit's
#: Mach factor (SCH_M_n, SCH_OMCF_n).
SCHED_MACH = ("mach_nodes", "omc_mach_factor")
#: npz name of the authority factor on the Mach nodes (SCH_AUTH_n).
SCHED_AUTH = "authority_factor"


def load_schedule(path: Path | str = SCHEDULE_PATH) -> dict[str, np.ndarray]:
    """The committed table as name -> float64 array (qbar_kpa, SCHED_QUANTITIES, SCHED_MACH,
    SCHED_AUTH).

    Raises ValueError if the nodes are not SCHED_N increasing values or an entry is missing.
    """
    with np.load(path) as z:
        out = {k: np.asarray(z[k], dtype=np.float64)
               for k in ("qbar_kpa", *(q[0] for q in SCHED_QUANTITIES), *SCHED_MACH, SCHED_AUTH)}
    for nodes in ("qbar_kpa", SCHED_MACH[0]):
        q = out[nodes]
        if q.shape != (SCHED_N,) or not np.all(np.diff(q) > 0):
            raise ValueError(f"{path}: {nodes} must be {SCHED_N} increasing nodes, got {q}")
    f = out[SCHED_MACH[1]]
    if f.shape != (SCHED_N,) or not np.all((f > 0.0) & (f <= 1.0)):
        raise ValueError(f"{path}: {SCHED_MACH[1]} must be {SCHED_N} values in (0, 1]")
    a = out[SCHED_AUTH]
    if a.shape != (SCHED_N,) or not np.all((a >= 1.0) & (a <= 10.0)):
        raise ValueError(f"{path}: {SCHED_AUTH} must be {SCHED_N} values in [1, 10]")
    for name, _u, _t in SCHED_QUANTITIES:
        if out[name].shape != (SCHED_N,) or not np.all(np.isfinite(out[name])):
            raise ValueError(f"{path}: {name} must be {SCHED_N} finite values")
    return out
