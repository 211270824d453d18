"""PWM on SERVO_OUTPUT_RAW (docs/wire.md section 3), as ArduPilot's SERVOn_MIN/TRIM/MAX.

Surfaces (servo1..3): ``deflection = (pwm - TRIM) / (MAX - TRIM) * LIMIT`` above trim,
``(pwm - TRIM) / (TRIM - MIN) * LIMIT`` below, PWM clipped to [MIN, MAX]. Throttle (servo4):
1000..2000 us = 0..1, clipped. A channel value 0 means "no output" (the plant keeps its last
command).
"""
from __future__ import annotations

import math

__all__ = ["PwmMap", "PWM_MIN_US", "PWM_TRIM_US", "PWM_MAX_US", "DEFLECTION_LIMIT_RAD",
           "DEFAULT_PWM", "deflection_to_pwm", "pwm_to_deflection", "THROTTLE_PWM_MIN_US",
           "THROTTLE_PWM_MAX_US", "throttle_to_pwm", "throttle_from_pwm"]

# Defaults of docs/wire.md section 3: one microsecond is 0.04 deg.
PWM_MIN_US = 1000
PWM_TRIM_US = 1500
PWM_MAX_US = 2000
DEFLECTION_LIMIT_RAD = math.radians(20.0)

THROTTLE_PWM_MIN_US = 1000
THROTTLE_PWM_MAX_US = 2000


class PwmMap:
    """PWM [us] <-> surface deflection [rad] through MIN/TRIM/MAX [us] and LIMIT [rad]."""

    def __init__(self, pwm_min: int, pwm_trim: int, pwm_max: int, limit_rad: float):
        if not pwm_min < pwm_trim < pwm_max:
            raise ValueError("PWM map needs MIN < TRIM < MAX")
        self.pwm_min = pwm_min
        self.pwm_trim = pwm_trim
        self.pwm_max = pwm_max
        self.limit_rad = limit_rad
        self._up = limit_rad / (pwm_max - pwm_trim)      # rad per us above trim
        self._down = limit_rad / (pwm_trim - pwm_min)    # rad per us below trim

    def to_rad(self, pwm: int) -> float:
        """PWM [us] -> deflection [rad]; PWM clipped to [MIN, MAX] first."""
        if pwm < self.pwm_min:
            pwm = self.pwm_min
        elif pwm > self.pwm_max:
            pwm = self.pwm_max
        d = pwm - self.pwm_trim
        return d * self._up if d >= 0 else d * self._down

    def to_pwm(self, rad: float) -> int:
        """Deflection [rad] -> PWM [us], rounded and clipped to [MIN, MAX]; TRIM if not finite."""
        trim = self.pwm_trim
        if not math.isfinite(rad):
            return trim
        if rad >= 0.0:
            us = trim + rad / self.limit_rad * (self.pwm_max - trim)
        else:
            us = trim + rad / self.limit_rad * (trim - self.pwm_min)
        us = int(round(us))
        return self.pwm_min if us < self.pwm_min else self.pwm_max if us > self.pwm_max else us


#: the map of docs/wire.md's defaults (1000/1500/2000 us, 20 deg)
DEFAULT_PWM = PwmMap(PWM_MIN_US, PWM_TRIM_US, PWM_MAX_US, DEFLECTION_LIMIT_RAD)


def _map(trim_us: int) -> PwmMap:
    if trim_us == PWM_TRIM_US:
        return DEFAULT_PWM
    return PwmMap(PWM_MIN_US, trim_us, PWM_MAX_US, DEFLECTION_LIMIT_RAD)


def deflection_to_pwm(delta_rad: float, trim_us: int = PWM_TRIM_US) -> int:
    """Surface deflection [rad] -> PWM [us] with the default MIN/MAX/LIMIT, clipped."""
    return _map(trim_us).to_pwm(delta_rad)


def pwm_to_deflection(pwm_us: int, trim_us: int = PWM_TRIM_US) -> float:
    """PWM [us] -> deflection [rad], the inverse of :func:`deflection_to_pwm`."""
    return _map(trim_us).to_rad(pwm_us)


def throttle_to_pwm(throttle: float) -> int:
    """Throttle 0..1 -> servo4 PWM [us], clipped to 1000..2000; 0 (no output: the plant keeps
    its last throttle) for a value that is not finite."""
    if not math.isfinite(throttle):
        return 0
    us = int(round(THROTTLE_PWM_MIN_US + throttle * (THROTTLE_PWM_MAX_US - THROTTLE_PWM_MIN_US)))
    return min(max(us, THROTTLE_PWM_MIN_US), THROTTLE_PWM_MAX_US)


def throttle_from_pwm(pwm_us: int) -> float:
    """servo4 PWM [us] -> throttle 0..1, clipped (1000 us = 0, 2000 us = 1)."""
    f = (pwm_us - THROTTLE_PWM_MIN_US) / (THROTTLE_PWM_MAX_US - THROTTLE_PWM_MIN_US)
    return 0.0 if f < 0.0 else 1.0 if f > 1.0 else f
