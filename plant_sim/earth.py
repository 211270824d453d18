"""The plant's round Earth at the edges: geodetic <-> Earth-centred conversions with pymap3d.

The dynamics (plant_sim/dynamics.py ``deriv_sphere``) integrate the position as a vector r_E
(m) in the Earth-centred frame E (x through latitude 0 / longitude 0, z through the north
pole; non-rotating, docs/plant.md section 5a) on the sphere ``EARTH`` (the WGS-84 mean
radius, hyfc_wire.earth). The conversions to and from latitude/longitude happen here, with a
maintained geodesy library (pymap3d) rather than hand-written formulas: the start point and
its local axes (``origin_vectors``) and the GNSS receiver's samples (``geodetic``,
``offset_geodetic``). None of it runs in a numba kernel: at reset and at the receiver's rate.
"""
from __future__ import annotations

import numpy as np
import pymap3d
from pymap3d import Ellipsoid

from hyfc_wire.earth import EARTH_RADIUS_M

__all__ = ["EARTH", "EARTH_RADIUS_M", "origin_vectors", "geodetic", "offset_geodetic"]

#: The sphere (pymap3d's WGS-84 mean-radius model; its radius is hyfc_wire.earth's)
EARTH = Ellipsoid(EARTH_RADIUS_M, EARTH_RADIUS_M, "wgs84_mean sphere", "wgs84_mean")


def origin_vectors(lat_deg: float, lon_deg: float) -> np.ndarray:
    """float64[9]: the unit up, north and east vectors (E axes) at (lat, lon) on the sphere."""
    r0 = np.array(pymap3d.geodetic2ecef(lat_deg, lon_deg, 0.0, EARTH), dtype=float)
    north = np.array(pymap3d.ned2ecef(1.0, 0.0, 0.0, lat_deg, lon_deg, 0.0, EARTH)) - r0
    east = np.array(pymap3d.ned2ecef(0.0, 1.0, 0.0, lat_deg, lon_deg, 0.0, EARTH)) - r0
    return np.concatenate((r0 / np.linalg.norm(r0), north / np.linalg.norm(north),
                           east / np.linalg.norm(east)))


def geodetic(r_e_m) -> tuple[float, float, float]:
    """(lat deg, lon deg in [-180, 180), height m above the sphere) of the point r_E (m)."""
    lat, lon, h = pymap3d.ecef2geodetic(float(r_e_m[0]), float(r_e_m[1]), float(r_e_m[2]),
                                        EARTH)
    return float(lat), (float(lon) + 180.0) % 360.0 - 180.0, float(h)


def offset_geodetic(r_e_m, north_m: float, east_m: float, down_m: float) -> tuple[float, float, float]:
    """(lat deg, lon deg, height m) of the point ``north_m, east_m, down_m`` away from r_E
    along its local axes (the receiver's position error). Exact at the poles too: the offset
    is taken in E, not in latitude/longitude."""
    lat, lon, h = pymap3d.ecef2geodetic(float(r_e_m[0]), float(r_e_m[1]), float(r_e_m[2]),
                                        EARTH)
    x, y, z = pymap3d.ned2ecef(north_m, east_m, down_m, lat, lon, h, EARTH)
    return geodetic((x, y, z))
