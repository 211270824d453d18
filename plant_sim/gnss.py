"""GNSS receiver model: flat-earth NED position and velocity mapped to latitude/longitude about
the scenario origin (or, on the round Earth, the Earth-centred position converted by pymap3d,
plant_sim/earth.py), sampled at the receiver rate, with seeded white noise and a latency.

The sample layout G_* is the contract of docs/wire.md section 2 (defined once, in
hyfc_wire.layout, for the plant and the fc). Per sample (every ``round(frame_hz / rate_hz)``
frames):

    pos_ned = pos_ned_true(t - latency) + [s_h n1, s_h n2, s_v n3]     (m)
    vel_ned = vel_ned_true(t - latency) + s_vel [n4, n5, n6]           (m/s)
    lat, lon = origin + flat-earth mapping of pos_ned (ned_to_geodetic)
    alt = origin_alt_m - pos_down                                      (m MSL)

n ~ N(0, 1) from the GNSS's own generator (numpy PCG64 seeded with (seed, GNSS_STREAM)), so
adding or tuning the receiver never changes the noise of the other sensors (plant_sim/sensors.py).
The latency is a whole number of frames (``sensors.latency_s.gps`` rounded to a frame); the
sample's stamp G_T_S is the frame it is sent with. ``sensors.enabled = false`` turns noise and
latency off, as for the other sensors; ``gnss.enabled = false`` sends no GNSS at all.

Flat earth about the origin (lat0, lon0), WGS-84 radii of curvature at lat0:
    lat = lat0 + north / (R_N + h0),  lon = lon0 + east / ((R_E + h0) cos lat0)
with h0 the origin altitude; its inverse is ``geodetic_to_ned``. Exact for the mapping itself
(a round trip is the identity to rounding); over a few hundred km it departs from the
ellipsoid by the flat-earth approximation the plant's dynamics already make.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from hyfc_wire.layout import (G_ALT_M, G_FIX, G_HACC_M, G_LAT_DEG, G_LON_DEG, G_N, G_SACC_M_S,
                              G_SATS, G_T_S, G_VACC_M, G_VD, G_VE, G_VN)  # the GNSS sample layout
from plant_sim.dynamics import X_PD, X_PE, X_PN, X_Q0, X_Q1, X_Q2, X_Q3, X_S, X_U, X_V, X_W
from plant_sim.earth import offset_geodetic

__all__ = ["GnssSensor", "ned_to_geodetic", "geodetic_to_ned", "G_T_S", "G_LAT_DEG",
           "G_LON_DEG", "G_ALT_M", "G_VN", "G_VE", "G_VD", "G_FIX", "G_SATS", "G_HACC_M",
           "G_VACC_M", "G_SACC_M_S", "G_N", "GNSS_STREAM"]

GNSS_STREAM = 0x474E5353      # "GNSS": second word of the receiver's generator seed
WGS84_A_M = 6378137.0
WGS84_E2 = 6.69437999014e-3
FIX_3D = 3


def _radii(lat0_deg: float) -> tuple[float, float]:
    """Meridian (north) and prime-vertical (east) radii of curvature at ``lat0_deg`` (m)."""
    s = math.sin(math.radians(lat0_deg))
    d = 1.0 - WGS84_E2 * s * s
    return WGS84_A_M * (1.0 - WGS84_E2) / d ** 1.5, WGS84_A_M / math.sqrt(d)


def ned_to_geodetic(north_m: float, east_m: float, down_m: float, lat0_deg: float,
                    lon0_deg: float, alt0_m: float) -> tuple[float, float, float]:
    """Flat-earth NED offset from the origin -> (lat deg, lon deg, alt m MSL)."""
    rn, re = _radii(lat0_deg)
    lat = lat0_deg + math.degrees(north_m / (rn + alt0_m))
    lon = lon0_deg + math.degrees(east_m / ((re + alt0_m) * math.cos(math.radians(lat0_deg))))
    lon = (lon + 180.0) % 360.0 - 180.0
    return lat, lon, alt0_m - down_m


def geodetic_to_ned(lat_deg: float, lon_deg: float, alt_m: float, lat0_deg: float,
                    lon0_deg: float, alt0_m: float) -> tuple[float, float, float]:
    """Inverse of :func:`ned_to_geodetic`: (north m, east m, down m) from the origin."""
    rn, re = _radii(lat0_deg)
    dlon = (lon_deg - lon0_deg + 180.0) % 360.0 - 180.0
    north = math.radians(lat_deg - lat0_deg) * (rn + alt0_m)
    east = math.radians(dlon) * (re + alt0_m) * math.cos(math.radians(lat0_deg))
    return north, east, alt0_m - alt_m


def velocity_ned(x) -> tuple[float, float, float]:
    """NED velocity (m/s) of plant state ``x``: C_nb (body -> NED) times the body velocity."""
    q0, q1, q2, q3 = x[X_Q0], x[X_Q1], x[X_Q2], x[X_Q3]
    u, v, w = x[X_U], x[X_V], x[X_W]
    vn = ((q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3) * u + 2.0 * (q1 * q2 - q0 * q3) * v
          + 2.0 * (q1 * q3 + q0 * q2) * w)
    ve = (2.0 * (q1 * q2 + q0 * q3) * u + (q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3) * v
          + 2.0 * (q2 * q3 - q0 * q1) * w)
    vd = (2.0 * (q1 * q3 - q0 * q2) * u + 2.0 * (q2 * q3 + q0 * q1) * v
          + (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * w)
    return vn, ve, vd


class GnssSensor:
    """The plant's GNSS receiver. ``update(k, x)`` once per frame k (state ``x`` at t_k)
    returns the sample to send with frame k (float64[G_N], reused) or None.

    Cost per frame without a sample: two integer tests; a capture or a sample is a few
    microseconds of Python at the receiver rate (10 Hz by default), off the numba kernels.
    """

    def __init__(self, scenario, seed: int, frame_dt_s: float):
        g = scenario.data["gnss"]
        sn = scenario.data["sensors"]
        self.enabled = bool(g["enabled"])
        self.seed = int(seed)
        self.frame_dt_s = float(frame_dt_s)
        self.every = max(1, int(round(1.0 / (g["rate_hz"] * frame_dt_s))))
        self.rate_hz = 1.0 / (self.every * frame_dt_s)
        on = bool(sn["enabled"])
        self.delay = int(round(sn["latency_s"]["gps"] / frame_dt_s)) if on else 0
        self.sigma_h_m = g["noise"]["horizontal_m"] if on else 0.0
        self.sigma_v_m = g["noise"]["vertical_m"] if on else 0.0
        self.sigma_vel_m_s = g["noise"]["velocity_m_s"] if on else 0.0
        self.origin = (g["origin_lat_deg"], g["origin_lon_deg"], g["origin_alt_m"])
        #: round Earth: the position is the Earth-centred vector x[X_S:X_S+3] (docs/plant.md 5a)
        self.sphere = scenario.data["earth"]["model"] == "sphere"
        self.sats = int(g["satellites"])
        self.out = np.zeros(G_N)
        self._pending: deque = deque()
        self.samples = 0
        self.reset()

    def reset(self) -> None:
        """Back to no history and the start of the noise stream."""
        self.rng = np.random.default_rng((self.seed & 0xFFFFFFFFFFFFFFFF, GNSS_STREAM))
        self._pending.clear()
        self.samples = 0

    def next_event(self, k: int) -> int:
        """The first frame from ``k`` at which ``update`` does something (captures a sample or
        returns one); ``update`` of any frame before it returns None and changes nothing. A
        very large frame index when the receiver is off."""
        if not self.enabled:
            return 1 << 62
        cap = k + (-(k + self.delay)) % self.every
        if self._pending:
            return min(cap, self._pending[0][0])
        return cap

    def update(self, k: int, x) -> np.ndarray | None:
        """Frame ``k`` (state ``x`` at t_k = k frame_dt): capture the clean sample that will be
        sent ``delay`` frames later, and return the sample due with this frame, if any."""
        if not self.enabled:
            return None
        if (k + self.delay) % self.every == 0:
            pos = (x[X_S + X_PN], x[X_S + X_PE], x[X_S + X_PD]) if self.sphere else \
                (x[X_PN], x[X_PE], x[X_PD])
            self._pending.append((k + self.delay,) + pos + velocity_ned(x))
        if not self._pending or self._pending[0][0] != k:
            return None
        _, p0, p1, p2, vn, ve, vd = self._pending.popleft()
        n = self.rng.standard_normal(6)
        o = self.out
        o[G_T_S] = k * self.frame_dt_s
        if self.sphere:          # the error along the local axes, converted by pymap3d
            lat, lon, h = offset_geodetic((p0, p1, p2), self.sigma_h_m * n[0],
                                          self.sigma_h_m * n[1], self.sigma_v_m * n[2])
            o[G_LAT_DEG], o[G_LON_DEG], o[G_ALT_M] = lat, lon, self.origin[2] + h
        else:
            o[G_LAT_DEG], o[G_LON_DEG], o[G_ALT_M] = ned_to_geodetic(
                p0 + self.sigma_h_m * n[0], p1 + self.sigma_h_m * n[1],
                p2 + self.sigma_v_m * n[2], *self.origin)
        o[G_VN] = vn + self.sigma_vel_m_s * n[3]
        o[G_VE] = ve + self.sigma_vel_m_s * n[4]
        o[G_VD] = vd + self.sigma_vel_m_s * n[5]
        o[G_FIX] = FIX_3D
        o[G_SATS] = self.sats
        o[G_HACC_M] = self.sigma_h_m
        o[G_VACC_M] = self.sigma_v_m
        o[G_SACC_M_S] = self.sigma_vel_m_s
        self.samples += 1
        return o
