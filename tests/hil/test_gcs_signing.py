"""HIL tier: MAVLink 2 signing on the ground-station link (--signing-key-file)."""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys

import pytest

from tests.fc_harness import REPO, fc_with_gcs, mavlink as ML

pytestmark = pytest.mark.hil

PASSPHRASE = b"correct horse battery staple"


@pytest.fixture()
def signed_fc(tmp_path):
    key_file = tmp_path / "gcs.key"
    key_file.write_bytes(PASSPHRASE + b"\n")
    os.chmod(key_file, 0o600)
    with fc_with_gcs(str(tmp_path / "run"), "--signing-key-file", str(key_file)) as (fc, gcs):
        yield fc, gcs


def test_unsigned_writes_are_rejected_and_counted_signed_accepted(signed_fc):
    fc, gcs = signed_fc
    # read-only requests work unsigned
    assert gcs.param_get("TRIM_RUD_DEG").param_value == 0.0
    # unsigned PARAM_SET: no effect
    assert gcs.param_set("TRIM_RUD_DEG", 3.0, timeout_s=1.0) is None
    assert gcs.param_get("TRIM_RUD_DEG").param_value == 0.0
    # unsigned commands (arm, mode) get no ACK and change nothing
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_DO_SET_MODE, 0, 1, 1, 0, 0, 0, 0, 0)
    assert gcs.wait("COMMAND_ACK", 1.0) is None
    gcs.mav.set_mode_send(1, 1, 2)
    rej = gcs.wait("NAMED_VALUE_FLOAT", 8, cond=lambda m: m.name == "REJ_SIGN" and m.value >= 3)
    assert rej is not None, "rejected unsigned input must be visible in telemetry"
    assert gcs.wait("HEARTBEAT", 3).custom_mode & 0xFFFF == 0
    # a wrong key is as bad as none
    gcs.setup_signing(hashlib.sha256(b"wrong").digest(), sign_outgoing=True)
    assert gcs.param_set("TRIM_RUD_DEG", 4.0, timeout_s=1.0) is None
    # the right key: accepted
    gcs.setup_signing(hashlib.sha256(PASSPHRASE).digest(), sign_outgoing=True)
    reply = gcs.param_set("TRIM_RUD_DEG", 3.0)
    assert reply is not None and reply.param_value == 3.0
    assert gcs.command(ML.MAV_CMD_DO_SET_MODE, 1, 2).result == ML.MAV_RESULT_ACCEPTED
    # outgoing frames are signed
    hb = gcs.wait("HEARTBEAT", 3)
    assert hb.get_signed()
    assert fc.stop() == 0
    with open(os.path.join(fc.out, "fc.log")) as f:
        log = f.read()
    assert PASSPHRASE.decode() not in log and hashlib.sha256(PASSPHRASE).hexdigest() not in log


def test_key_file_readable_by_others_is_refused(tmp_path):
    key_file = tmp_path / "gcs.key"
    key_file.write_bytes(PASSPHRASE)
    os.chmod(key_file, 0o644)
    res = subprocess.run([sys.executable, "-m", "fc", "--out", str(tmp_path / "run"),
                          "--plant-bind", "127.0.0.1:0", "--gcs-bind", "127.0.0.1:0",
                          "--signing-key-file", str(key_file)],
                         cwd=REPO, capture_output=True, text=True, timeout=60)
    assert res.returncode != 0 and "READY" not in res.stdout
    assert "chmod 600" in res.stderr


def test_signed_mission_upload_unsigned_download(signed_fc):
    """With signing on, an unsigned MISSION_COUNT is rejected (no upload starts); a signed
    upload is stored; an unsigned download (REQUEST_LIST, REQUEST_INT) reads it back."""
    _, gcs = signed_fc
    item = {"frame": ML.MAV_FRAME_GLOBAL, "command": ML.MAV_CMD_NAV_WAYPOINT, "param1": 0.0,
            "param2": 0.0, "param3": 0.0, "param4": 0.0, "x": 352000000, "y": -1178839000,
            "z": 28000.0, "autocontinue": 1}
    assert gcs.send_mission([item], timeout_s=1.5) == (None, [])
    gcs.setup_signing(hashlib.sha256(PASSPHRASE).digest(), sign_outgoing=True)
    ack, asked = gcs.send_mission([item], timeout_s=5.0)
    assert asked == [0] and ack.type == ML.MAV_MISSION_ACCEPTED
    gcs.setup_signing(hashlib.sha256(PASSPHRASE).digest(), sign_outgoing=False)
    (got,) = gcs.download_mission()
    assert got is not None and got.x == 352000000 and got.z == 28000.0
