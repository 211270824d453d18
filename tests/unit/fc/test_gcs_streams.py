"""Unit tier: the rules of the streamed state fields (fc/gcs_streams.py)."""
from __future__ import annotations

import math

import pytest

from fc.gcs_streams import (EARTH_RADIUS_M, cm_s_i16, cm_s_u16, landed_state,  # noqa: F401
                            local_ned)
from fc.link import mavlink as ML


@pytest.mark.parametrize("has_data, v, want", [
    (True, 2200.0, ML.MAV_LANDED_STATE_IN_AIR),         # Mach 7 with current plant data
    (False, 2200.0, ML.MAV_LANDED_STATE_UNDEFINED),     # data lost: we do not know
    (True, 0.0, ML.MAV_LANDED_STATE_UNDEFINED),         # before any frame: no ground model
    (True, math.nan, ML.MAV_LANDED_STATE_UNDEFINED),
])
def test_landed_state(has_data, v, want):
    assert landed_state(has_data, v) == want


@pytest.mark.parametrize("v, want", [
    (0.0, 0), (327.66, 32766), (-327.68, -32768), (-2200.0, 32767), (2200.0, 32767),
    (327.67, 32767), (math.inf, 32767), (math.nan, 32767),
])
def test_int16_cm_s_is_the_value_or_unknown_never_saturated(v, want):
    assert cm_s_i16(v) == want


@pytest.mark.parametrize("v, want", [
    (0.0, 0), (655.34, 65534), (655.35, 65535), (2200.0, 65535), (-1.0, 65535),
    (math.nan, 65535),
])
def test_uint16_cm_s_is_the_value_or_unknown(v, want):
    assert cm_s_u16(v) == want


def test_local_ned_about_home():
    home = (34.9, -117.9, 21000.0)
    x, y, z = local_ned(home, 34.9 + 1.0, -117.9 - 1.0, 21500.0)
    assert x == pytest.approx(EARTH_RADIUS_M * math.radians(1.0))
    assert y == pytest.approx(-EARTH_RADIUS_M * math.cos(math.radians(34.9)) * math.radians(1.0))
    assert z == pytest.approx(-500.0)
    # across the antimeridian the east offset stays small
    _, y, _ = local_ned((0.0, 179.5, 0.0), 0.0, -179.5, 0.0)
    assert y == pytest.approx(EARTH_RADIUS_M * math.radians(1.0))
