"""The Earth both processes agree on: a sphere of the WGS-84 mean radius.

The plant integrates a round Earth on this sphere (``[earth] model = "sphere"``,
docs/plant.md section 5a) and reports GNSS latitude/longitude on it; the fc's navigation
(fc/guidance/waypoints.py, fc/mission_mode.py) measures distances and courses on the same
sphere, so the vehicle and its waypoints agree. Why a sphere and not the ellipsoid: see
docs/plant.md section 5a. The value is pymap3d's ``Ellipsoid.from_name("wgs84_mean")``
(R1 = (2a + b) / 3 of WGS-84), checked in tests/unit/plant/test_earth.py; it is written out
here because the contract imports no geodesy library.
"""
from __future__ import annotations

__all__ = ["EARTH_RADIUS_M"]

#: Radius of the spherical Earth (m): the WGS-84 mean radius R1.
EARTH_RADIUS_M = 6371008.7714
