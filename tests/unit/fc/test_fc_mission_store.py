"""Unit tier: fc/mission_store.py keeps the mission and home across a restart."""
from __future__ import annotations

import json

from fc.mission import Mission
from fc.mission_store import MissionStore


def _three(gcs):  # noqa: F811
    return [_wp(gcs, 0, 35.3), _wp(gcs, 1, 35.6, -116.9), _wp(gcs, 2, 35.9, alt=29000.0)]
from tests.unit.fc.test_mission_protocol import _upload, _wp, gcs  # noqa: F401


def test_mission_current_item_and_home_round_trip(tmp_path, gcs):  # noqa: F811
    path = str(tmp_path / "mission.json")
    home = [None]
    mis = Mission()
    store = MissionStore(mis, path, lambda: home[0])
    assert store.load() is None and store.snapshot() is None      # nothing yet: no file
    _upload(gcs, mis, _three(gcs))
    mis.advance(0)
    home[0] = (34.9054246, -117.8839078, 27998.8)
    store.save(store.snapshot())
    assert store.snapshot() is None                               # saved, nothing changed
    # WHEN a new fc starts on the same file
    mis2 = Mission()
    got = MissionStore(mis2, path, lambda: None).load()
    # THEN the same items, at the same current item, and home
    assert got == home[0]
    assert mis2.count == 3 and mis2.current == 1
    assert (json.dumps([mis2.item(i) for i in range(3)])          # param4 NaN: as text
            == json.dumps([mis.item(i) for i in range(3)]))


def test_a_file_with_an_invalid_item_is_set_aside_and_nothing_restored(tmp_path, gcs):  # noqa: F811
    path = tmp_path / "mission.json"
    mis = Mission()
    store = MissionStore(mis, str(path), lambda: None)
    _upload(gcs, mis, _three(gcs))
    doc = json.loads(store.snapshot())
    doc["items"][0]["x"] = 2_000_000_000                          # latitude 200 deg
    path.write_text(json.dumps(doc))
    mis2 = Mission()
    assert MissionStore(mis2, str(path), lambda: None).load() is None
    assert mis2.count == 0 and (tmp_path / "mission.json.bad").exists()


def test_a_snapshot_per_change_and_no_block_between(tmp_path, gcs):  # noqa: F811
    from tests.unit.fc.test_gcs_links import _blocks
    home = [None]
    mis = Mission()
    store = MissionStore(mis, str(tmp_path / "mission.json"), lambda: home[0])
    assert store.load() is None and store.snapshot() is None      # no file, nothing changed
    # GIVEN nothing changed: no snapshot, and the 1 Hz check takes no Python block (its
    # document's comprehension made a cell object on every call while in the same function)
    assert _blocks(store.snapshot) == 0
    # WHEN home is set, a mission uploaded, its current item advanced: one snapshot each
    home[0] = (34.9054246, -117.8839078, 27998.8)
    assert json.loads(store.snapshot())["home"] == list(home[0])
    assert store.snapshot() is None
    _upload(gcs, mis, _three(gcs))
    assert len(json.loads(store.snapshot())["items"]) == 3
    mis.advance(0)
    assert json.loads(store.snapshot())["current"] == 1
    assert store.snapshot() is None and _blocks(store.snapshot) == 0
    # AND a save that failed is tried again at the next snapshot
    store.path = str(tmp_path / "no such dir" / "mission.json")
    store.save(b"{}")
    assert store.snapshot() is not None
