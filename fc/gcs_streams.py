"""fc/gcs_streams.py - the field values of the streamed state messages that need a rule.

Pure functions (numbers in, field values out) used by fc/gcs.py ``_build``:

- EXTENDED_SYS_STATE (245): ``landed_state`` (``landed_state``) and MAV_VTOL_STATE_UNDEFINED
  (a fixed wing). MAVSDK's ``telemetry.in_air`` and QGroundControl's "flying" read it.
- Speeds where an integer field cannot hold them (issue 21 item 8). The vehicle flies at
  ~2200 m/s; GLOBAL_POSITION_INT's ``vx/vy/vz`` are int16 cm/s (end at 327.67 m/s) and
  GPS_RAW_INT's ``vel`` uint16 cm/s (655.35 m/s). A value the field cannot hold is sent as the
  field's "unknown", never saturated: ``vel`` UINT16_MAX (the spec's "If unknown, set to:
  UINT16_MAX"); ``vx/vy/vz`` INT16_MAX whatever the sign (common.xml gives these three no
  invalid value; INT16_MAX is MAVLink's usual "not provided" for int16 fields, e.g.
  BATTERY_STATUS.temperature). The true velocity travels in LOCAL_POSITION_NED (32, float m/s:
  MAVSDK ``position_velocity_ned``, QGroundControl's local position), built by ``local_ned``.
"""
from __future__ import annotations

import math

from fc.link import mavlink as ML
# the sphere both processes agree on (m): LOCAL_POSITION_NED's x/y about home (``local_ned``)
from hyfc_wire.earth import EARTH_RADIUS_M

__all__ = ["IN_AIR_SPEED_M_S", "EARTH_RADIUS_M", "landed_state", "cm_s_i16", "cm_s_u16",
           "local_ned"]

#: Above this measured airspeed (m/s), with plant data current, the vehicle is IN_AIR. The
#: plant has no ground model: below it (or without data) the state is UNDEFINED, never a
#: guess of ON_GROUND. The winged cone's slowest trimmed point is Mach ~5 (1500 m/s).
IN_AIR_SPEED_M_S = 50.0
INT16_UNKNOWN = 32767
UINT16_UNKNOWN = 65535


def landed_state(has_data: bool, airspeed_m_s: float) -> int:
    """MAV_LANDED_STATE: IN_AIR while plant data is current (``has_data``: frames received,
    no data-loss failsafe) and the measured airspeed exceeds IN_AIR_SPEED_M_S, else UNDEFINED."""
    if has_data and math.isfinite(airspeed_m_s) and airspeed_m_s > IN_AIR_SPEED_M_S:
        return ML.MAV_LANDED_STATE_IN_AIR
    return ML.MAV_LANDED_STATE_UNDEFINED


def cm_s_i16(v_m_s: float) -> int:
    """A velocity component (m/s) as GLOBAL_POSITION_INT's int16 cm/s; INT16_UNKNOWN (32767)
    when it does not fit in [-32768, 32766] cm/s or is not finite."""
    if not math.isfinite(v_m_s):
        return INT16_UNKNOWN
    cm = int(round(v_m_s * 100.0))
    return cm if -32768 <= cm < INT16_UNKNOWN else INT16_UNKNOWN


def cm_s_u16(v_m_s: float) -> int:
    """A speed (m/s, >= 0) as GPS_RAW_INT.vel's uint16 cm/s; UINT16_UNKNOWN (65535) when it
    does not fit below 65535 cm/s or is not finite."""
    if not math.isfinite(v_m_s) or v_m_s < 0.0:
        return UINT16_UNKNOWN
    cm = int(round(v_m_s * 100.0))
    return cm if cm < UINT16_UNKNOWN else UINT16_UNKNOWN


def local_ned(home: tuple[float, float, float], lat_deg: float, lon_deg: float,
              alt_m: float) -> tuple[float, float, float]:
    """LOCAL_POSITION_NED's x, y, z (m) of a GNSS position about ``home`` (lat deg, lon deg,
    alt m MSL): north and east along the sphere of EARTH_RADIUS_M (x = R dlat, y = R cos(lat_home)
    dlon, dlon wrapped to +-180 deg), z = -(alt - alt_home). A plotting aid near home (an
    equirectangular projection: its error grows with the distance); the velocity beside it is
    exact."""
    lat0, lon0, alt0 = home
    dlon = (lon_deg - lon0 + 180.0) % 360.0 - 180.0
    x = EARTH_RADIUS_M * math.radians(lat_deg - lat0)
    y = EARTH_RADIUS_M * math.cos(math.radians(lat0)) * math.radians(dlon)
    return x, y, -(alt_m - alt0)
