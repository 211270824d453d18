"""The plant says goodbye (issue 12 point 7, docs/wire.md section 5): a run that is simply over
ends at INFO in the controller, while plant data lost mid-run still warns and fails safe.

- tier 1: the plant's ``PlantLink.send_goodbye`` over loopback UDP is recognised by the fc's
  ``PlantLink`` (from the locked plant address only), and a frame clears it;
- tier 2 (HIL, the fc as a process): after the goodbye, no FAILSAFE and no WARNING, the
  STATUSTEXT says the plant ended its run; when frames come back and then stop without a
  goodbye, FAILSAFE and the warning follow as before; a "goodbye" from another system id is
  not one.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from fc.link import PlantLink as FcPlantLink
from fc.link import UdpEndpoint
from plant_sim.link import PlantLink, PwmMap
from tests.fc_harness import level_meas
from tests.fc_harness import mavlink as ML


def _goodbye_bytes(sysid: int = 2) -> bytes:
    mav = ML.MAVLink(None, srcSystem=sysid, srcComponent=1)
    return mav.heartbeat_encode(ML.MAV_TYPE_GENERIC, ML.MAV_AUTOPILOT_INVALID, 0, 0,
                                ML.MAV_STATE_POWEROFF).pack(mav)


def _read(fc_link: FcPlantLink, meas: np.ndarray, tries: int = 200) -> int:
    """read_frame until something was accepted or the datagrams are used up (bounded)."""
    import select
    for _ in range(tries):
        select.select([fc_link.endpoint.fileno()], [], [], 0.05)
        stamp = fc_link.read_frame(meas)
        if stamp >= 0 or fc_link.ended:
            return stamp
    return -1


def test_fc_plant_link_recognises_the_plants_goodbye_only_from_the_plant():
    fc_end = UdpEndpoint("127.0.0.1", 0)
    fc_link = FcPlantLink(fc_end, plant_sysid=2)
    plant = PlantLink(fc_end.address, ("127.0.0.1", 0),
                      PwmMap(1000, 1500, 2000, np.radians(20.0)), sysid=2)
    meas = np.zeros(14)
    try:
        # before any frame: no peer yet, a goodbye means nothing
        plant.send_goodbye(copies=1)
        assert _read(fc_link, meas, tries=3) == -1 and not fc_link.ended
        assert fc_link.counters.rejected_incomplete == 1
        plant.build_sensors(1000, level_meas(0.001), 0.0)
        plant.send_sensors()
        assert _read(fc_link, meas) == 1000
        assert plant.send_goodbye() == 3
        _read(fc_link, meas)
        while fc_link.read_frame(meas) >= 0:   # the other copies
            pass
        assert fc_link.ended and fc_link.counters.goodbyes == 1   # once per run, not per copy
        assert fc_link.counters.rejected == 1        # the copies were not counted as junk
        plant.build_sensors(3000, level_meas(0.003), 0.0)
        plant.send_sensors()
        assert _read(fc_link, meas) == 3000 and not fc_link.ended
    finally:
        plant.close()
        fc_end.close()


def _texts_over_heartbeats(gcs, n_heartbeats: int, timeout_s: float = 10.0) -> tuple[list, list]:
    """STATUSTEXT (severity, text) and HEARTBEATs received until ``n_heartbeats`` (1 Hz)."""
    texts, hbs = [], []
    while len(hbs) < n_heartbeats:
        m = gcs.wait(["HEARTBEAT", "STATUSTEXT"], timeout_s)
        assert m is not None, f"telemetry stopped; so far {texts}"
        if m.get_type() == "HEARTBEAT":
            hbs.append(m)
        else:
            texts.append((m.severity, m.text))
    return texts, hbs


@pytest.mark.hil
def test_goodbye_ends_at_info_but_a_silent_loss_still_fails_safe(flying):
    fc, gcs, loop = flying
    loop.run(200)
    assert loop.outputs[-1] != (1500, 1500, 1500), "the law should be flying"
    loop.plant.send_raw(_goodbye_bytes())
    m = gcs.wait("STATUSTEXT", 5, cond=lambda m: "plant ended its run" in m.text)
    assert m is not None and m.severity == ML.MAV_SEVERITY_INFO
    # two heartbeats later (>= 1 s, FS_TIMEOUT_S is 0.3 s): no failsafe, still COORDINATED
    texts, hbs = _texts_over_heartbeats(gcs, 2)
    assert not any("FAILSAFE" in t or "lost" in t for _, t in texts), texts
    assert all((hb.custom_mode & 0xFFFF) == 1 and hb.system_status != ML.MAV_STATE_CRITICAL for hb in hbs)

    # the plant is back (later stamps), then stops without a goodbye: a real loss
    loop.run(50)
    m = gcs.wait("STATUSTEXT", 5, cond=lambda m: "FAILSAFE" in m.text)
    assert m is not None and "plant data lost" in m.text
    assert m.severity == ML.MAV_SEVERITY_CRITICAL
    assert gcs.wait("HEARTBEAT", 3, cond=lambda m: (m.custom_mode & 0xFFFF) == 3) is not None
    assert fc.stop() == 0
    log = open(os.path.join(fc.out, "fc.log")).read().splitlines()
    ended = [ln for ln in log if "plant ended its run" in ln and "STATUSTEXT" not in ln]
    assert len(ended) == 1 and " INFO " in ended[0]
    warnings = [ln for ln in log if " WARNING " in ln]
    assert len(warnings) == 1 and "plant data lost" in warnings[0], warnings


@pytest.mark.hil
def test_a_goodbye_from_another_system_is_not_one(flying):
    fc, gcs, loop = flying
    loop.run(100)
    loop.plant.send_raw(_goodbye_bytes(sysid=3))
    m = gcs.wait("STATUSTEXT", 5, cond=lambda m: "FAILSAFE" in m.text or "ended" in m.text)
    assert m is not None and "plant data lost" in m.text
