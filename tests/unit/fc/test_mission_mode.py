"""fc/mission_mode.py: MISSION mode against a stub vehicle that has only the members of the
:class:`fc.mission_mode.MissionVehicle` Protocol (no FlightController, no sockets).

GIVEN a stored mission and a GNSS fix WHEN MissionFlight ticks THEN it sets the guidance's
targets toward the first item and NAV_CONTROLLER_OUTPUT's waypoint; without a mission or a fix
MISSION is refused. A member MissionFlight used beyond the Protocol would fail here.
"""
from types import SimpleNamespace

import numpy as np

from fc.control.layout import E_H, E_N, E_V
from fc.link import G_FIX, G_LAT_DEG, G_LON_DEG, G_N, G_T_S
from fc.link import mavlink as ML
from fc.mission import Mission
from fc.mission_mode import MissionFlight, MissionVehicle
from fc.params import build_table
from tests.unit.fc.test_mission_protocol import _upload, _wp


class StubVehicle:
    """Exactly MissionVehicle's members (checked below against the Protocol's annotations)."""

    def __init__(self) -> None:
        self.plant = SimpleNamespace(gps=np.zeros(G_N))
        self.meas_stamp_us = 0
        self.params = build_table()
        self.gcs = SimpleNamespace(home=None)
        self.est = SimpleNamespace(est=np.zeros(E_N))
        self.modes = SimpleNamespace(changes=1)
        self.guid = SimpleNamespace(nav_wp=None)
        self.targets = (21000.0, 0.0, 2100.0)
        self.asked: list = []

    def guidance_targets(self):
        return self.targets

    def set_guidance_targets(self, h_m=None, chi_rad=None, V_m_s=None):
        self.asked.append((h_m, chi_rad, V_m_s))
        self.targets = (h_m, chi_rad, V_m_s)
        return None


def _fix(v: StubVehicle, t_s: float, lat: float = 35.0, lon: float = -117.0) -> None:
    g = v.plant.gps
    g[G_FIX] = ML.GPS_FIX_TYPE_3D_FIX
    g[G_LAT_DEG], g[G_LON_DEG], g[G_T_S] = lat, lon, t_s
    v.meas_stamp_us = int(t_s * 1e6)
    v.gcs.home = v.gcs.home or (lat, lon, 21000.0)


def test_stub_has_exactly_the_protocols_members():
    members = set(MissionVehicle.__annotations__) | {"guidance_targets", "set_guidance_targets"}
    stub = {n for n in vars(StubVehicle()) if n not in ("targets", "asked")}
    stub |= {"guidance_targets", "set_guidance_targets"}
    assert members == stub


def test_mission_is_refused_without_a_mission_or_a_fix():
    from fc.link import new_codec
    gcs = new_codec(255, 190)
    v = StubVehicle()
    mf = MissionFlight(Mission())
    assert "no mission" in mf.entry_refusal(v)
    _upload(gcs, mf.mission, [_wp(gcs, 0, 35.5, -117.0, 25000.0)])
    assert mf.mission.count == 1
    assert "no GNSS fix" in mf.entry_refusal(v)
    _fix(v, 1.0)
    assert mf.entry_refusal(v) is None
    v.meas_stamp_us = int(3.0e6)                   # the fix is 2 s old: stale
    assert "no GNSS fix" in mf.entry_refusal(v)


def test_tick_sets_targets_toward_the_first_item_and_the_waypoint():
    from fc.link import new_codec
    gcs = new_codec(255, 190)
    v = StubVehicle()
    v.est.est[E_H], v.est.est[E_V] = 21000.0, 2100.0
    mf = MissionFlight(Mission())
    _upload(gcs, mf.mission, [_wp(gcs, 0, 35.5, -117.0, 25000.0)])
    _fix(v, 1.0)
    mf.tick(v)
    assert v.asked, "the navigator set no target"
    h_t, chi_t, v_t = v.asked[-1]
    assert h_t == 25000.0                          # the item's altitude
    assert abs(chi_t) < 0.05                       # due north, rad
    bearing, dist, _xt = v.guid.nav_wp
    assert abs(bearing) < 0.05 and 50_000.0 < dist < 60_000.0   # 0.5 deg of latitude, m
