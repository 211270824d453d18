"""fc/estimator.py - measurements (ATTITUDE + AOA_SSA + VFR_HUD) -> estimated state.

Input: the measurement vector ``float64[14]`` of docs/architecture.md section 4 (filled by
fc/link.py). Output: the estimated state ``float64[9]`` of section 5 (E_ALPHA ... E_GAMMA).

Frames: NED earth axes, FRD body axes, ZYX Euler angles (psi, theta, phi) as MAVLink
ATTITUDE. Air-relative velocity in body axes v_b = V [cos a cos b, sin b, sin a cos b].
The wind axes are x_w = v_b / V, y_w = [-cos a sin b, cos b, -sin a sin b],
z_w = [-sin a, 0, cos a] (body components). The "down" component of a body vector
x = [x1, x2, x3] in NED is d(x) = -sin(theta) x1 + sin(phi) cos(theta) x2 + cos(phi) cos(theta) x3.
With the wind-axis Euler angles (chi, gamma, mu) (ZYX, like phi/theta/psi for the body):

    sin(gamma)          = -d(x_w) = cos a cos b sin th - sin b sin ph cos th - sin a cos b cos ph cos th
    cos(gamma) sin(mu)  =  d(y_w) = cos a sin b sin th + cos b sin ph cos th - sin a sin b cos ph cos th
    cos(gamma) cos(mu)  =  d(z_w) = sin a sin th + cos a cos ph cos th

so ``gamma = atan2(-d(x_w), hypot(d(y_w), d(z_w)))`` and ``mu = atan2(d(y_w), d(z_w))``
(Stevens & Lewis, Aircraft Control and Simulation, 3rd ed., section 2.4; wind-over-earth
neglected: the air-relative and inertial velocity directions coincide). alpha and beta are
the vane measurements, p, q, r the body rates, V the airspeed, h the altitude.

Validation: each measured field must be finite and inside the plausible range of
``LIMITS_LO/HI``; an invalid field keeps its last good value and sets its bit in the
``invalid`` mask. A field whose last good value is older (sensor time) than ``stale_s`` sets
its bit in the ``stale`` mask. A frame whose stamp does not advance is flagged FLAG_OLD_STAMP
and changes nothing. The estimate is healthy when every field the law uses has a good,
fresh value.

Per-call cost: the Estimator keeps all its arrays (last good values and times, the ranges,
stale_s, est, the masks and the invalid-frame count) as views of one float64 buffer ``mem``
(layout EM_*; masks and count as int64 bits), so ``update`` calls one compiled entry point
with 2 array arguments (``estimate_entry``) instead of 7 plus Python-side bookkeeping.
"""
from __future__ import annotations

import math

import numpy as np
from numba import carray, njit

from hyfc_wire.layout import (M_AIRSPEED, M_ALT, M_AOA, M_CLIMB, M_GROUNDSPEED, M_HEADING, M_N,
                              M_P, M_PITCH, M_Q, M_R, M_ROLL, M_SSA, M_T_S, M_YAW)

from fc.frame_calls import ArrayAddress, f8p

try:  # the law owns its input layout (architecture.md section 5)
    from fc.control.layout import (E_ALPHA, E_BETA, E_GAMMA, E_H, E_MU, E_N, E_P,  # noqa: F401
                                   E_Q, E_R, E_V)
except ImportError:  # the law is not there yet: same layout, section 5
    E_ALPHA, E_BETA, E_MU, E_P, E_Q, E_R, E_V, E_H, E_GAMMA = range(9)
    E_N = 9

try:  # the kernels below freeze hyfc_wire's M_* and layout's E_* (and the EM_* built on them)
    import hyfc_wire.layout as _wire_layout
    from fc.control import layout as _layout
    from fc.control import carrays as _carrays
    from hyfc_wire.numba_cache import drop_stale
    drop_stale(__file__, [_wire_layout.__file__, _layout.__file__, _carrays.__file__])
except ImportError:
    pass

__all__ = ["Estimator", "estimate_kernel", "estimate_entry", "mu_gamma", "LIMITS_LO",
           "LIMITS_HI", "FLAG_OLD_STAMP", "FLAG_NEVER", "USED_MASK", "E_N", "EM_N"]

_PI = math.pi
#: Plausible range of each measurement field (SI, index = M_*); outside = invalid.
LIMITS_LO = np.full(M_N, -np.inf)
LIMITS_HI = np.full(M_N, np.inf)
for _i, _lo, _hi in (
        (M_ROLL, -_PI - 1e-3, _PI + 1e-3), (M_PITCH, -_PI / 2 - 1e-3, _PI / 2 + 1e-3),
        (M_YAW, -2 * _PI, 2 * _PI), (M_P, -20.0, 20.0), (M_Q, -20.0, 20.0), (M_R, -20.0, 20.0),
        (M_AOA, -_PI / 2, _PI / 2), (M_SSA, -_PI / 2, _PI / 2), (M_AIRSPEED, 1.0, 1.0e4),
        (M_ALT, -1.0e3, 1.5e5), (M_CLIMB, -5.0e3, 5.0e3), (M_GROUNDSPEED, 0.0, 1.0e4),
        (M_HEADING, 0.0, 2 * _PI)):
    LIMITS_LO[_i] = _lo
    LIMITS_HI[_i] = _hi

#: Fields the estimate depends on (bit i = M_i).
USED_MASK = sum(1 << i for i in (M_ROLL, M_PITCH, M_P, M_Q, M_R, M_AOA, M_SSA, M_AIRSPEED, M_ALT))
FLAG_OLD_STAMP = 1 << 30   # in the invalid mask: stamp did not advance, frame ignored
FLAG_NEVER = 1 << 31       # in the stale mask: some used field never had a good value

# Layout of the Estimator's buffer mem (float64[EM_N]); the masks and the invalid-frame count
# are int64 slots of mem.view(np.int64).
EM_GOOD = 0                     # float64[M_N] last good values (SI)
EM_GOOD_T = EM_GOOD + M_N       # float64[M_N] sensor time of the last good value (s), -inf never
EM_LO = EM_GOOD_T + M_N         # float64[M_N] plausible range, low (copy of LIMITS_LO)
EM_HI = EM_LO + M_N             # float64[M_N] plausible range, high (copy of LIMITS_HI)
EM_EST = EM_HI + M_N            # float64[E_N] estimated state
EM_STALE_S = EM_EST + E_N       # staleness threshold (s)
EM_MASKS = EM_STALE_S + 1       # int64[2] invalid, stale bit masks
EM_INVALID_FRAMES = EM_MASKS + 2  # int64 count of frames with a nonzero invalid mask
EM_N = EM_INVALID_FRAMES + 1


@njit(cache=True)
def mu_gamma(phi, theta, alpha, beta):
    """(mu, gamma) [rad] from Euler roll/pitch and alpha/beta [rad] (module docstring)."""
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    sb = math.sin(beta)
    cb = math.cos(beta)
    sp = math.sin(phi)
    cp = math.cos(phi)
    st = math.sin(theta)
    ct = math.cos(theta)
    dx = -st * ca * cb + sp * ct * sb + cp * ct * sa * cb
    dy = st * ca * sb + sp * ct * cb - cp * ct * sa * sb
    dz = st * sa + cp * ct * ca
    return math.atan2(dy, dz), math.atan2(-dx, math.sqrt(dy * dy + dz * dz))


@njit(cache=True)
def estimate_kernel(meas, good, good_t, lo, hi, stale_s, est, masks):
    """One estimator update, no allocation.

    meas: float64[14] measurement (SI). good: float64[14] last good values (in/out).
    good_t: float64[14] sensor time of the last good value, -inf = never (in/out).
    lo, hi: float64[14] plausible ranges. stale_s: staleness threshold [s].
    est: float64[9] estimated state (out). masks: int64[2] -> [invalid, stale] bit masks.
    Returns 1 when the estimate is healthy, 0 otherwise.
    """
    t = meas[M_T_S]
    invalid = 0
    if not (math.isfinite(t) and t > good_t[M_T_S]):
        invalid = FLAG_OLD_STAMP
    else:
        good[M_T_S] = t
        good_t[M_T_S] = t
        for i in range(1, 14):
            x = meas[i]
            if math.isfinite(x) and lo[i] <= x <= hi[i]:
                good[i] = x
                good_t[i] = t
            else:
                invalid |= 1 << i
    stale = 0
    tnow = good_t[M_T_S]
    for i in range(1, 14):
        if good_t[i] == -np.inf:
            stale |= 1 << i
            if (USED_MASK >> i) & 1:
                stale |= FLAG_NEVER
        elif tnow - good_t[i] > stale_s:
            stale |= 1 << i
    masks[0] = invalid
    masks[1] = stale
    alpha = good[M_AOA]
    beta = good[M_SSA]
    mu, gamma = mu_gamma(good[M_ROLL], good[M_PITCH], alpha, beta)
    est[E_ALPHA] = alpha
    est[E_BETA] = beta
    est[E_MU] = mu
    est[E_P] = good[M_P]
    est[E_Q] = good[M_Q]
    est[E_R] = good[M_R]
    est[E_V] = good[M_AIRSPEED]
    est[E_H] = good[M_ALT]
    est[E_GAMMA] = gamma
    return 1 if (stale & (USED_MASK | FLAG_NEVER)) == 0 and good_t[M_T_S] > -np.inf else 0


@njit(cache=True)
def estimate_entry(meas, mem):
    """estimate_kernel on the views of an Estimator's buffer ``mem`` (layout EM_*); counts
    the frames with a nonzero invalid mask. Returns True when the estimate is healthy."""
    iv = mem.view(np.int64)
    masks = iv[EM_MASKS:EM_MASKS + 2]
    ok = estimate_kernel(meas, mem[EM_GOOD:EM_GOOD + M_N], mem[EM_GOOD_T:EM_GOOD_T + M_N],
                         mem[EM_LO:EM_LO + M_N], mem[EM_HI:EM_HI + M_N], mem[EM_STALE_S],
                         mem[EM_EST:EM_EST + E_N], masks)
    if masks[0] != 0:
        iv[EM_INVALID_FRAMES] += 1
    return ok == 1


@njit(cache=True)
def accept_entry(frame, meas, mem):
    """The frame intake's one compiled call: the new frame ``frame`` copied into ``meas``
    (both float64[M_N]), then :func:`estimate_entry` on it. (A loop: ``meas[:] = frame``
    compiles in 2 s, this in 0.1 s.)"""
    for i in range(meas.shape[0]):
        meas[i] = frame[i]
    return estimate_entry(meas, mem)


@njit(cache=True)
def accept_p(frame, meas, meas_n, mem, mem_n):
    """:func:`accept_entry` on the float64[meas_n] ``frame`` and ``meas`` and the estimator's
    float64[mem_n] buffer, all given by address (fc/frame_calls.py: no array record per call).
    True when healthy."""
    return accept_entry(carray(f8p(frame), (meas_n,)), carray(f8p(meas), (meas_n,)),
                        carray(f8p(mem), (mem_n,)))


class Estimator:
    """Allocates the estimator's arrays once; ``update(meas)`` returns True when healthy.

    Attributes (views of the one buffer ``mem``, never rebind them): est float64[E_N],
    good float64[M_N], good_t float64[M_N], masks int64[2] (invalid, stale), lo/hi
    float64[M_N] (copies of LIMITS_LO/HI at construction). ``stale_s`` (s) and
    ``invalid_frames`` are properties over mem; ``healthy`` is the last update's result.
    """

    def __init__(self, stale_s: float = 0.1) -> None:
        m = self.mem = np.zeros(EM_N)
        self.good = m[EM_GOOD:EM_GOOD + M_N]
        self.good_t = m[EM_GOOD_T:EM_GOOD_T + M_N]
        self.lo = m[EM_LO:EM_LO + M_N]
        self.hi = m[EM_HI:EM_HI + M_N]
        self.est = m[EM_EST:EM_EST + E_N]
        self._iv = m.view(np.int64)
        self.masks = self._iv[EM_MASKS:EM_MASKS + 2]
        self.lo[:] = LIMITS_LO
        self.hi[:] = LIMITS_HI
        self.stale_s = stale_s
        self.healthy = False
        # accept()'s arguments by address (fc/frame_calls.py), bound on first use
        self._mem_addr = ArrayAddress(np.float64, EM_N, m).addr
        self._frame_at = ArrayAddress(np.float64, M_N)
        self._meas_at = ArrayAddress(np.float64, M_N)
        self.update(np.full(M_N, np.nan))  # compile / load from cache now, not in the loop
        self.accept(np.full(M_N, np.nan), np.zeros(M_N))
        self.reset()

    @property
    def stale_s(self) -> float:
        """Staleness threshold (s)."""
        return float(self.mem[EM_STALE_S])

    @stale_s.setter
    def stale_s(self, value: float) -> None:
        self.mem[EM_STALE_S] = float(value)

    @property
    def invalid_frames(self) -> int:
        """Frames since reset() with at least one invalid field or an old stamp."""
        return self._iv.item(EM_INVALID_FRAMES)       # (an int; no numpy scalar)

    @invalid_frames.setter
    def invalid_frames(self, value: int) -> None:
        self._iv[EM_INVALID_FRAMES] = int(value)

    def reset(self) -> None:
        self.est[:] = 0.0
        self.good[:] = 0.0
        self.good_t[:] = -np.inf
        self.masks[:] = 0
        self.healthy = False
        self.invalid_frames = 0

    def update(self, meas: np.ndarray) -> bool:
        """One frame: meas float64[M_N] (SI, fc.link M_*) -> est; True when healthy."""
        h = estimate_entry(meas, self.mem)
        self.healthy = h
        return h

    def accept(self, frame: np.ndarray, meas: np.ndarray) -> bool:
        """:meth:`update` on ``frame`` after copying it into ``meas`` (float64[M_N] both), in
        one compiled call (fc/intake.py, a new plant frame)."""
        h = accept_p(self._frame_at.of(frame), self._meas_at.of(meas), M_N, self._mem_addr, EM_N)
        self.healthy = h
        return h

    @property
    def invalid_mask(self) -> int:
        return int(self.masks[0])

    @property
    def stale_mask(self) -> int:
        return int(self.masks[1])
