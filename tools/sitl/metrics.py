"""Step-response metrics of attitude channels (alpha, beta, mu) from a time history.

Pure functions: arrays in, numbers out. No files, no plotting. The definitions are in
``docs/metrics.md``; this module is their one implementation, used by ``tools.hil`` (the
``summary.json`` of a run) and ``tools.evidence.montecarlo``.

Inputs are SI (s, rad); outputs carry their unit in the name (``*_deg``, ``*_s``, ``*_pct``),
degrees being the edge unit of reports.

The command of a channel is a zero-order-hold timeline: ``cmd_t_s[i]`` is the time from which
``cmd_rad[i]`` holds (the ``[[command]]`` tables of a scenario). Every metric is measured from
the channel's *last step*: the last timeline entry at or before the end of the data whose value
differs from the previous entry's (or the first entry if the value never changes).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

#: Settling band as a fraction of the step size |A| (5 % criterion; docs/metrics.md).
SETTLE_BAND_FRAC = 0.05
#: Absolute floor of the settling band, deg (2 sigma of the air-data noise; docs/metrics.md).
SETTLE_BAND_FLOOR_DEG = 0.1
#: A step smaller than this (deg) counts as "command equals initial value": overshoot and
#: rise time are undefined (reported as None / JSON null).
MIN_STEP_DEG = 0.1
#: Length of the window at the end of the data over which final_error_deg is taken, s.
FINAL_WINDOW_S = 1.0
#: Rise-time thresholds, fractions of the step.
RISE_LO, RISE_HI = 0.1, 0.9
#: |alpha|, |beta| or |mu| beyond this (deg) or any non-finite sample marks a run as diverged.
DIVERGED_ANGLE_DEG = 45.0
#: A surface within this much (deg) of its limit counts as saturated (the wire quantises
#: deflection commands to 0.04 deg).
SATURATION_TOL_DEG = 0.05

SURFACE_NAMES = ("left_elevon", "right_elevon", "rudder")
METRIC_KEYS = ("overshoot_pct", "settling_time_s", "rise_time_s", "final_error_deg",
               "rms_error_deg")


@dataclass(frozen=True)
class ChannelMetrics:
    """Metrics of one channel, measured from its last command step.

    Attributes
    ----------
    overshoot_pct : excursion past the command, in the direction of the step, as % of |A|
        (A = command - value at the step time); None when |A| < MIN_STEP_DEG.
    settling_time_s : time from the step until the error last leaves the settling band;
        None if the error is outside the band at the end of the data.
    rise_time_s : time from 10 % to 90 % of the step (first crossings); None when the step is
        undefined or 90 % is never reached.
    final_error_deg : max |error| over the last FINAL_WINDOW_S of the data, deg.
    rms_error_deg : RMS of the error from the step to the end (time-weighted), deg.
    step_deg : A, the signed step (command - value at the step time), deg.
    t_step_s : time of the last step, s.
    peak_error_deg : max |error| after the step, deg (always defined).
    band_deg : half-width of the settling band used, deg.
    undershoot_pct : largest move in the *wrong* direction (away from the command, beyond the
        value at the step) as % of |A|; None when the step is undefined.
    """

    overshoot_pct: float | None
    settling_time_s: float | None
    rise_time_s: float | None
    final_error_deg: float
    rms_error_deg: float
    step_deg: float
    t_step_s: float
    peak_error_deg: float
    band_deg: float
    undershoot_pct: float | None = None

    def as_dict(self) -> dict:
        return asdict(self)


def command_at(cmd_t_s: np.ndarray, cmd_val: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Zero-order-hold command at times ``t_s`` (before the first entry: the first value)."""
    cmd_t_s = np.asarray(cmd_t_s, dtype=float)
    cmd_val = np.asarray(cmd_val, dtype=float)
    idx = np.searchsorted(cmd_t_s, np.asarray(t_s, dtype=float), side="right") - 1
    return cmd_val[np.clip(idx, 0, len(cmd_val) - 1)]


def last_step_index(cmd_t_s: np.ndarray, cmd_val: np.ndarray, t_end_s: float) -> int:
    """Index of the last timeline entry at or before ``t_end_s`` that changes the value."""
    last = 0
    for i in range(1, len(cmd_t_s)):
        if cmd_t_s[i] > t_end_s:
            break
        if cmd_val[i] != cmd_val[i - 1]:
            last = i
    return last


def _validate(t_s, y, cmd_t_s, cmd_val):
    t_s = np.asarray(t_s, dtype=float)
    y = np.asarray(y, dtype=float)
    cmd_t_s = np.asarray(cmd_t_s, dtype=float)
    cmd_val = np.asarray(cmd_val, dtype=float)
    if t_s.ndim != 1 or y.shape != t_s.shape:
        raise ValueError(f"t_s and y must be 1-D of equal length, got {t_s.shape} and {y.shape}")
    if len(t_s) < 2:
        raise ValueError("need at least two samples")
    if np.any(np.diff(t_s) <= 0):
        raise ValueError("t_s must be strictly increasing")
    if cmd_t_s.ndim != 1 or cmd_t_s.shape != cmd_val.shape or len(cmd_t_s) == 0:
        raise ValueError("command timeline must be two non-empty 1-D arrays of equal length")
    if np.any(np.diff(cmd_t_s) < 0):
        raise ValueError("command timeline times must be non-decreasing")
    return t_s, y, cmd_t_s, cmd_val


def _first_crossing(t: np.ndarray, x: np.ndarray, level: float) -> float | None:
    """First time x (normalised progress) reaches ``level``, linearly interpolated."""
    above = np.nonzero(x >= level)[0]
    if len(above) == 0:
        return None
    k = int(above[0])
    if k == 0:
        return float(t[0])
    x0, x1 = x[k - 1], x[k]
    frac = (level - x0) / (x1 - x0) if x1 != x0 else 1.0
    return float(t[k - 1] + frac * (t[k] - t[k - 1]))


def _wrap_pi(x: np.ndarray) -> np.ndarray:
    return (x + math.pi) % (2.0 * math.pi) - math.pi


def channel_metrics(t_s, y_rad, cmd_t_s, cmd_rad, *, wrap: bool = False,
                    band_frac: float = SETTLE_BAND_FRAC,
                    band_floor_deg: float = SETTLE_BAND_FLOOR_DEG,
                    final_window_s: float = FINAL_WINDOW_S,
                    min_step_deg: float = MIN_STEP_DEG) -> ChannelMetrics:
    """Step-response metrics of one channel (docs/metrics.md).

    Parameters
    ----------
    t_s : (n,) sample times, s, strictly increasing.
    y_rad : (n,) the channel's true value, rad.
    cmd_t_s, cmd_rad : the command timeline (zero-order hold), s and rad.
    wrap : take errors modulo 2 pi (angles such as mu that may wrap).
    band_frac, band_floor_deg : settling band = max(band_frac * |A|, band_floor_deg).
    final_window_s : window at the end of the data for final_error_deg, s.
    min_step_deg : below this |A| the step is undefined (overshoot and rise time None).
    """
    t_s, y, cmd_t_s, cmd_val = _validate(t_s, y_rad, cmd_t_s, cmd_rad)
    i_step = last_step_index(cmd_t_s, cmd_val, t_s[-1])
    t_step = max(float(cmd_t_s[i_step]), float(t_s[0]))
    c = float(cmd_val[i_step])
    k0 = int(np.searchsorted(t_s, t_step, side="left"))
    k0 = min(k0, len(t_s) - 2)
    t = t_s[k0:]
    err = y[k0:] - c  # error = value - command (rad)
    if wrap:
        err = _wrap_pi(err)
    step = -float(err[0])  # A = command - value at the step
    step_deg = math.degrees(step)
    abs_err = np.abs(err)
    band_deg = max(band_frac * abs(step_deg), band_floor_deg)
    band = math.radians(band_deg)

    if abs(step_deg) >= min_step_deg:
        direction = math.copysign(1.0, step)
        past = float(np.max(direction * err))  # excursion beyond the command
        overshoot = 100.0 * max(past, 0.0) / abs(step)
        progress = 1.0 + err / step  # 0 at the start, 1 at the command
        undershoot = 100.0 * max(0.0, -float(np.min(progress)))
        t_lo = _first_crossing(t, progress, RISE_LO)
        t_hi = _first_crossing(t, progress, RISE_HI)
        rise = (t_hi - t_lo) if (t_lo is not None and t_hi is not None) else None
    else:
        overshoot = None
        rise = None
        undershoot = None

    outside = np.nonzero(abs_err > band)[0]
    if len(outside) == 0:
        settling = 0.0
    elif outside[-1] == len(t) - 1:
        settling = None
    else:
        k = int(outside[-1])
        e0, e1 = abs_err[k], abs_err[k + 1]
        frac = (e0 - band) / (e0 - e1) if e0 != e1 else 1.0
        settling = float(t[k] + frac * (t[k + 1] - t[k]) - t_step)

    in_final = t >= (t[-1] - final_window_s)
    final_err = math.degrees(float(np.max(abs_err[in_final])))
    # time-weighted RMS (trapezoid), robust to uneven sampling
    e2 = err * err
    dur = float(t[-1] - t[0])
    rms = math.degrees(math.sqrt(float(np.sum(0.5 * (e2[1:] + e2[:-1]) * np.diff(t))) / dur))
    return ChannelMetrics(overshoot_pct=overshoot, settling_time_s=settling, rise_time_s=rise,
                          final_error_deg=final_err, rms_error_deg=rms, step_deg=step_deg,
                          t_step_s=t_step, peak_error_deg=math.degrees(float(abs_err.max())),
                          band_deg=band_deg, undershoot_pct=undershoot)


def surface_metrics(t_s, delta_rad, limit_rad: float | np.ndarray,
                    tol_deg: float = SATURATION_TOL_DEG) -> tuple[dict, float]:
    """Peak |deflection| per surface (deg) and time with any surface saturated (s).

    Parameters
    ----------
    t_s : (n,) sample times, s.
    delta_rad : (n, 3) actual surface deflections, rad (left elevon, right elevon, rudder).
    limit_rad : deflection limit, rad (scalar or (3,)).
    tol_deg : a surface within this of its limit counts as saturated.

    Returns
    -------
    ({"left_elevon": deg, "right_elevon": deg, "rudder": deg}, saturated_s). The saturated
    time counts each sample interval [t_k, t_k+1) whose starting sample is saturated.
    """
    t_s = np.asarray(t_s, dtype=float)
    d = np.asarray(delta_rad, dtype=float)
    if d.ndim != 2 or d.shape[1] != 3 or d.shape[0] != t_s.shape[0]:
        raise ValueError(f"delta_rad must be (n, 3) matching t_s, got {d.shape}")
    peak = {name: math.degrees(float(np.max(np.abs(d[:, i])))) for i, name in
            enumerate(SURFACE_NAMES)}
    lim = np.broadcast_to(np.asarray(limit_rad, dtype=float), (3,))
    sat = np.any(np.abs(d) >= lim - math.radians(tol_deg), axis=1)
    saturated_s = float(np.sum(np.diff(t_s)[sat[:-1]])) if len(t_s) > 1 else 0.0
    return peak, saturated_s


#: cutoff of the first-order high-pass whose output's RMS is a surface command's chatter, Hz:
#: well above the attitude loops' bandwidth (about 1 Hz), so what passes is the command's
#: jitter (sensor noise through the law, limit cycles), not the manoeuvre
CHATTER_HZ = 5.0

#: the keys of ``surface_figures`` (docs/metrics.md), in order
SURFACE_FIGURE_KEYS = tuple(
    [f"peak_{s}_deg" for s in SURFACE_NAMES] + [f"travel_{s}_deg" for s in SURFACE_NAMES]
    + ["travel_total_deg"] + [f"chatter_{s}_deg" for s in SURFACE_NAMES]
    + ["at_limit_s", "cmd_at_limit_s", "rate_cmd_limited_s"])


def _interval_time(t_s: np.ndarray, flag: np.ndarray) -> float:
    """Sum of the sample intervals [t_k, t_k+1) whose starting sample is flagged, s."""
    if len(t_s) < 2:
        return 0.0
    return float(np.sum(np.diff(t_s)[np.asarray(flag, bool)[:-1]]))


def highpass_rms(t_s: np.ndarray, x: np.ndarray, cutoff_hz: float = CHATTER_HZ) -> float:
    """RMS of ``x`` through a first-order high-pass (bilinear, at the median sample interval;
    the filter starts at rest on x[0], so a constant reads 0)."""
    from scipy.signal import lfilter
    x = np.asarray(x, dtype=float)
    if len(x) < 2:
        return 0.0
    dt = float(np.median(np.diff(t_s)))
    k = math.tan(math.pi * cutoff_hz * dt)       # bilinear: y = a (y1 + x - x1)
    a = (1.0 - k) / (1.0 + k)
    g = 1.0 / (1.0 + k)
    y = lfilter([g, -g], [1.0, -a], x - x[0])
    return float(np.sqrt(np.mean(np.square(y))))


def surface_figures(t_s, delta_rad, delta_cmd_rad, limit_rad, rate_limited=None,
                    rate_t_s=None, tol_deg: float = SATURATION_TOL_DEG) -> dict:
    """What the surfaces did over a run (docs/metrics.md, "Surfaces"), flat keys
    ``SURFACE_FIGURE_KEYS``.

    Parameters
    ----------
    t_s : (n,) sample times, s.
    delta_rad : (n, 3) achieved deflections (the plant's, after the actuators), rad.
    delta_cmd_rad : (n, 3) the controller's deflection commands, rad.
    limit_rad : deflection limit, rad (scalar or (3,)).
    rate_limited : (m,) the law's flag "omega_c limited" (1/0), or None if unknown.
    rate_t_s : (m,) its sample times, s (default ``t_s``).

    Returns
    -------
    dict: ``peak_<surface>_deg`` max |achieved|; ``travel_<surface>_deg`` sum of |changes| of
    the achieved deflection and ``travel_total_deg`` their sum; ``chatter_<surface>_deg`` the
    RMS of the command through a CHATTER_HZ high-pass; ``at_limit_s`` time with an achieved
    deflection within ``tol_deg`` of the limit; ``cmd_at_limit_s`` time with a command within
    ``tol_deg`` of it; ``rate_cmd_limited_s`` time with the law's rate-command limit active
    (None when ``rate_limited`` is None).
    """
    t = np.asarray(t_s, dtype=float)
    d = np.asarray(delta_rad, dtype=float)
    c = np.asarray(delta_cmd_rad, dtype=float)
    for name, a in (("delta_rad", d), ("delta_cmd_rad", c)):
        if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] != t.shape[0]:
            raise ValueError(f"{name} must be (n, 3) matching t_s, got {a.shape}")
    lim = np.broadcast_to(np.asarray(limit_rad, dtype=float), (3,)) - math.radians(tol_deg)
    out = {}
    for i, s in enumerate(SURFACE_NAMES):
        out[f"peak_{s}_deg"] = math.degrees(float(np.max(np.abs(d[:, i]))))
    travel = np.degrees(np.sum(np.abs(np.diff(d, axis=0)), axis=0)) if len(t) > 1 else np.zeros(3)
    for i, s in enumerate(SURFACE_NAMES):
        out[f"travel_{s}_deg"] = float(travel[i])
    out["travel_total_deg"] = float(travel.sum())
    for i, s in enumerate(SURFACE_NAMES):
        out[f"chatter_{s}_deg"] = math.degrees(highpass_rms(t, c[:, i]))
    out["at_limit_s"] = _interval_time(t, np.any(np.abs(d) >= lim, axis=1))
    out["cmd_at_limit_s"] = _interval_time(t, np.any(np.abs(c) >= lim, axis=1))
    if rate_limited is None:
        out["rate_cmd_limited_s"] = None
    else:
        rt = t if rate_t_s is None else np.asarray(rate_t_s, dtype=float)
        out["rate_cmd_limited_s"] = _interval_time(rt, np.asarray(rate_limited) > 0.5)
    return out


def is_diverged(*angles_rad: np.ndarray, limit_deg: float = DIVERGED_ANGLE_DEG) -> bool:
    """True if any sample of any angle is non-finite or beyond ``limit_deg`` in magnitude."""
    lim = math.radians(limit_deg)
    for a in angles_rad:
        a = np.asarray(a, dtype=float)
        if not np.all(np.isfinite(a)) or np.any(np.abs(a) > lim):
            return True
    return False


def json_metrics(m: ChannelMetrics) -> dict:
    """The summary.json form of a channel: the five keys first, then the extras."""
    d = m.as_dict()
    out = {k: d.pop(k) for k in METRIC_KEYS}
    out.update(d)
    return out


# ---------------------------------------------------------------------------------------------
# guided flight: hold figures against the fc's targets (tools.guided_hil, the rig, the soak)
# ---------------------------------------------------------------------------------------------
DEG = math.pi / 180.0
SURFACE_LIMIT_DEG = 20.0         # the winged-cone's surface limit (plant_sim actuators)


def targets_at(truth: dict, fc: dict) -> np.ndarray:
    """(n, 3) the fc's targets (h m, chi rad, V m/s) in force at the truth's times."""
    t = fc["t_s"]
    i = np.clip(np.searchsorted(t, truth["t_s"], side="right") - 1, 0, len(t) - 1)
    return np.stack([fc["guid_tgt_h_m"][i], fc["guid_tgt_chi_rad"][i], fc["guid_tgt_V_m_s"][i]], 1)


def wrap_rad(a):
    """Angles wrapped to (-pi, pi], rad."""
    return np.angle(np.exp(1j * a))


def _sphere_axes(u):
    """Unit east and north (n, 3) at the unit positions ``u`` (n, 3), Earth-centred axes (z
    through the north pole; at a pole east is taken along y, as the plant does)."""
    rho = np.hypot(u[:, 0], u[:, 1])
    ok = rho > 1e-12
    east = np.zeros_like(u)
    east[:, 1] = 1.0
    east[ok, 0] = -u[ok, 1] / rho[ok]
    east[ok, 1] = u[ok, 0] / rho[ok]
    return east, np.cross(u, east)


def circle_course_error_rad(truth: dict, fc: dict, origin_deg: tuple[float, float],
                            r_m: float = 6371008.7714, far_m: float = 50e3) -> np.ndarray:
    """Course error (rad, per truth row) to the great circle the fc holds in CRUISE on the round
    Earth, defined without north: the angle, about the local vertical u, from the circle's
    direction n x u to the true velocity's horizontal direction (+ to the right).

    u: the true position, from the truth's azimuthal-equidistant map (pos_n_m, pos_e_m: the
    great-circle distance from the scenario's GNSS origin ``origin_deg`` (lat, lon) along its
    initial azimuth, on the sphere of radius ``r_m``); the velocity's direction from the true
    course chi_rad at u (north and east at u itself, so exact wherever the plant's own course
    is). n: the pole of the circle at the fc's course target, n = u x d(chi_t), taken at the fc's
    rows more than ``far_m`` from a pole (there the target's north and the truth's agree to the
    GNSS position error over R) and carried on through the rows nearer a pole. Unlike
    wrap(chi - chi_t), it does not depend on the target's and the truth's sample times agreeing
    where the circle's course turns at V / d (43 deg/s 3 km from a pole)."""
    la, lo = math.radians(origin_deg[0]), math.radians(origin_deg[1])
    u0 = np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])
    n0 = np.array([-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)])
    e0 = np.array([-math.sin(lo), math.cos(lo), 0.0])
    pn, pe = np.asarray(truth["pos_n_m"]), np.asarray(truth["pos_e_m"])
    c = np.hypot(pn, pe) / r_m
    az = np.arctan2(pe, pn)
    u = (np.cos(c)[:, None] * u0
         + np.sin(c)[:, None] * (np.cos(az)[:, None] * n0 + np.sin(az)[:, None] * e0))
    east, north = _sphere_axes(u)
    chi = np.asarray(truth["chi_rad"])
    d = np.cos(chi)[:, None] * north + np.sin(chi)[:, None] * east
    # the circle's pole at the fc's rows far from a pole, carried forward to every truth row
    ti = np.clip(np.searchsorted(truth["t_s"], fc["t_s"]), 0, len(chi) - 1)
    uf = u[ti]
    far = r_m * np.arctan2(np.hypot(uf[:, 0], uf[:, 1]), np.abs(uf[:, 2])) > far_m
    if not np.any(far):
        raise ValueError(f"no fc row more than {far_m:.0f} m from a pole: no circle to measure")
    fe, fnorth = _sphere_axes(uf)
    ct = np.asarray(fc["guid_tgt_chi_rad"])
    nf = np.cross(uf, np.cos(ct)[:, None] * fnorth + np.sin(ct)[:, None] * fe)
    k = np.nonzero(far)[0]
    j = np.searchsorted(fc["t_s"][k], truth["t_s"], side="right") - 1
    n = nf[k[np.clip(j, 0, len(k) - 1)]]
    t = np.cross(n, u)
    return np.arctan2(np.einsum("ij,ij->i", np.cross(d, t), u), np.einsum("ij,ij->i", t, d))


def hold_figures(truth: dict, fc: dict, t_from_s: float,
                 origin_deg: tuple[float, float] | None = None) -> dict:
    """Max abs errors after ``t_from_s``: altitude (m), course (deg), speed (m/s) to the fc's
    targets; the inner loop (truth alpha/beta/mu to the fc's command, deg) and the law's own
    tracking error e1 (deg); time with a surface within 0.05 deg of its limit (s); the range of
    the adaptive estimates in the first and second half; limits seen. ``origin_deg`` (the GNSS
    origin of a round-Earth run, lat/lon deg) adds ``course_err_circle_max_deg``, the course
    error to the great circle CRUISE holds (:func:`circle_course_error_rad`), for the rows
    flown in CRUISE."""
    sel = truth["t_s"] >= t_from_s
    if np.count_nonzero(sel) < 2 or np.count_nonzero(fc["t_s"] >= t_from_s) < 2:
        raise ValueError(f"no samples after t = {t_from_s} s (the run ends at "
                         f"{truth['t_s'][-1]:.1f} s)")
    tg = targets_at(truth, fc)[sel]
    out = {"t_from_s": t_from_s, "t_to_s": float(truth["t_s"][-1])}
    out["alt_err_max_m"] = float(np.max(np.abs(truth["h_m"][sel] - tg[:, 0])))
    out["course_err_max_deg"] = float(np.degrees(np.max(np.abs(wrap_rad(truth["chi_rad"][sel]
                                                                       - tg[:, 1])))))
    out["speed_err_max_m_s"] = float(np.max(np.abs(truth["V_m_s"][sel] - tg[:, 2])))
    fsel = fc["t_s"] >= t_from_s
    if origin_deg is not None:
        from fc.modes import FlightMode
        cruise = fc["mode"] == int(FlightMode.CRUISE)
        if np.any(cruise & fsel):
            sub = {k: v[cruise] for k, v in fc.items() if getattr(v, "shape", ()) == cruise.shape}
            e = circle_course_error_rad(truth, sub, origin_deg)
            t0 = max(t_from_s, float(sub["t_s"][0]))
            out["course_err_circle_max_deg"] = float(np.degrees(
                np.max(np.abs(e[(truth["t_s"] >= t0) & (truth["t_s"] <= sub["t_s"][-1])]))))
    ti = np.clip(np.searchsorted(truth["t_s"], fc["t_s"][fsel]), 0, len(truth["t_s"]) - 1)
    inner = []
    for name, c in (("alpha_rad", "cmd_alpha_rad"), ("beta_rad", "cmd_beta_rad"),
                    ("mu_rad", "cmd_mu_rad")):
        inner.append(float(np.degrees(np.max(np.abs(wrap_rad(truth[name][ti] - fc[c][fsel]))))))
    out["inner_cmd_err_max_deg"] = inner
    e1 = [k for k in fc if k.startswith("law_e1")]
    if e1:
        out["inner_e1_max_deg"] = [float(np.degrees(np.max(np.abs(fc[k][fsel])))) for k in e1]
    d = np.stack([truth[k][sel] for k in ("delta_left_rad", "delta_right_rad",
                                          "delta_rudder_rad")], 1)
    at_limit = np.any(np.abs(d) >= (SURFACE_LIMIT_DEG - 0.05) * DEG, 1)
    dt = float(np.median(np.diff(truth["t_s"])))
    gaps = np.diff(truth["t_s"][sel])
    if np.all(np.abs(gaps - dt) <= 1e-9):
        out["surface_at_limit_s"] = float(np.sum(at_limit)) * dt
    else:   # a decimated truth log (plant_sim/truthlog.py): each row's own interval
        out["surface_at_limit_s"] = float(np.sum(gaps[at_limit[:-1]]))
    out["surface_peak_deg"] = [float(v) for v in np.degrees(np.max(np.abs(d), 0))]
    rho = [k for k in fc if k.startswith("law_rho")]
    if rho:
        r = np.stack([fc[k][fsel] for k in rho], 1)
        half = len(r) // 2
        out["rho_abs_max_halves"] = [float(np.max(np.abs(r[:half]))),
                                     float(np.max(np.abs(r[half:])))]
    from fc.guidance.guidance import limit_names
    bits = np.bitwise_or.reduce(fc["guid_limits"][fsel].astype(np.int64))
    out["limits_seen"] = limit_names(int(bits))
    return out
