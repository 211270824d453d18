"""The plant's hold on a silent fc (real time, docs/plant.md section 14): what the surfaces do
while no servo command has arrived for ``servo.no_command_s``.

The vehicle side of the link keeps a minimal backup stability augmentation, as actuator
electronics with their own rate gyros (or a direct-mode damper) do on a fly-by-wire vehicle
whose flight computer has gone quiet. Per frame, while silent:

    delta = base + clip(damper, +-backup_authority_deg)
    damper_L = +k_p p - k_q q          (left elevon)
    damper_R = -k_p p - k_q q          (right elevon)
    damper_U = +k_r r - k_beta beta    (rudder)

- ``base``: ``servo.no_command = "hold"``: the commands' recent mean (a running mean over
  their first :data:`HOLD_TAU_S`, a first-order low-pass after; the last command if none has
  come yet), or ``"trim"``: the initial-state trim. Fixed for the whole silence.
- ``p, q, r`` (rad/s) and ``beta`` (rad): the plant's own measurement vector (the one it sends,
  hyfc_wire.layout ``M_P, M_Q, M_R, M_SSA``: the vehicle's gyros and sideslip vane).
- gains ``servo.backup_p_gain_s``, ``backup_q_gain_s``, ``backup_r_gain_s`` (rad of surface
  per rad/s of rate, i.e. s) and ``backup_beta_gain`` (rad per rad), each 0 = off; positive
  gains damp (signs in the aerodynamic database's convention, docs/architecture.md section 2:
  a positive differential left-minus-right rolls left, a positive elevon pitches up, a positive
  rudder yaws left; ``python -m plant_sim modes`` shows the modes with and without them).

Why (``python -m plant_sim modes --scenario cruise``): at Mach 7.5 / 28 km the lateral modes
are barely damped (roll damping L_p about -0.06 1/s, a Dutch roll of 0.84 rad/s at a damping
ratio of 0.07, a slow roll-spiral oscillation near 0.04 rad/s), so a held surface a tenth of
a degree off the true trim rolls the vehicle off: 0.2 deg of rudder held from the exact trim
banks it 33 deg in 10 s. The damper turns that into a small, steady roll rate.

Never on the normal path: the process calls :meth:`SilentHold.command_received` for each
fresh command (the mean) and :meth:`SilentHold.output` only for the frames of a silence.
Nothing allocates after construction.
"""
from __future__ import annotations

import math

import numpy as np

from hyfc_wire.layout import M_P, M_Q, M_R, M_SSA

#: ``servo.no_command = "hold"``: time constant of the commands' mean it holds, s (the fc's
#: FAILSAFE holds its law's commands averaged the same way: fc/mode_control.py)
HOLD_TAU_S = 3.0
DEG = math.pi / 180.0


class SilentHold:
    """The surface commands for the frames of a silent fc (module docstring).

    Parameters
    ----------
    servo : the scenario's validated ``servo`` table (``no_command``, the ``backup_*`` gains).
    trim_rad : float64[3], the initial-state trim (rad; used by ``no_command = "trim"``).
    frame_dt_s : the frame period, s (the mean's step).
    """

    def __init__(self, servo: dict, trim_rad: np.ndarray, frame_dt_s: float):
        self.to_trim = servo["no_command"] == "trim"
        self.trim_rad = np.array(trim_rad, dtype=np.float64)
        self.frame_dt_s = float(frame_dt_s)
        self.k_p_s = float(servo["backup_p_gain_s"])
        self.k_q_s = float(servo["backup_q_gain_s"])
        self.k_r_s = float(servo["backup_r_gain_s"])
        self.k_beta = float(servo["backup_beta_gain"])
        self.authority_rad = float(servo["backup_authority_deg"]) * DEG
        self.mean_rad = np.zeros(3)        # the commands' recent mean
        self.flown_s = 0.0                 # command time behind the mean, s
        self.base_rad = np.zeros(3)        # what this silence holds (set by ``engage``)
        self.damper_rad = np.zeros(3)      # the last frame's damper increment (rad)

    @property
    def damping(self) -> bool:
        """True when any backup gain is set."""
        return bool(self.k_p_s or self.k_q_s or self.k_r_s or self.k_beta)

    def command_received(self, cmd_rad) -> None:
        """A fresh fc command (rad) was applied this frame: fold it into the mean."""
        self.flown_s += self.frame_dt_s
        g = self.frame_dt_s / min(self.flown_s, HOLD_TAU_S)
        m = self.mean_rad
        m[0] += g * (cmd_rad[0] - m[0])
        m[1] += g * (cmd_rad[1] - m[1])
        m[2] += g * (cmd_rad[2] - m[2])

    def engage(self, last_cmd_rad) -> None:
        """A silence begins: fix its base (the trim, the mean, or ``last_cmd_rad`` before any
        command was received)."""
        if self.to_trim:
            self.base_rad[:] = self.trim_rad
        elif self.flown_s > 0.0:
            self.base_rad[:] = self.mean_rad
        else:
            self.base_rad[:] = last_cmd_rad

    def output(self, meas, out_rad) -> None:
        """The command for one silent frame into ``out_rad`` (float64[3], rad): the base plus
        the damper on the measurement ``meas`` (float64[14], hyfc_wire.layout), each increment
        clipped to the backup authority. A non-finite measurement adds nothing."""
        d = self.damper_rad
        p, q, r, beta = meas[M_P], meas[M_Q], meas[M_R], meas[M_SSA]
        if math.isfinite(p + q + r + beta):
            lim = self.authority_rad
            d[0] = min(max(self.k_p_s * p - self.k_q_s * q, -lim), lim)
            d[1] = min(max(-self.k_p_s * p - self.k_q_s * q, -lim), lim)
            d[2] = min(max(self.k_r_s * r - self.k_beta * beta, -lim), lim)
        else:
            d[:] = 0.0
        b = self.base_rad
        out_rad[0] = b[0] + d[0]
        out_rad[1] = b[1] + d[1]
        out_rad[2] = b[2] + d[2]


def damper_increments(servo: dict, p_rad_s, q_rad_s, r_rad_s, beta_rad) -> np.ndarray:
    """The damper's surface increments (rad, shape (n, 3): left, right, rudder) for arrays of
    measured rates (rad/s) and sideslip (rad), as :meth:`SilentHold.output` adds them frame by
    frame (for analysis: a truth log's ``meas_*`` columns give what a silent frame applied)."""
    kp, kq = float(servo["backup_p_gain_s"]), float(servo["backup_q_gain_s"])
    kr, kb = float(servo["backup_r_gain_s"]), float(servo["backup_beta_gain"])
    lim = float(servo["backup_authority_deg"]) * DEG
    p, q, r, b = (np.asarray(v, dtype=np.float64) for v in (p_rad_s, q_rad_s, r_rad_s, beta_rad))
    out = np.stack([kp * p - kq * q, -kp * p - kq * q, kr * r - kb * b], axis=-1)
    return np.clip(out, -lim, lim)
