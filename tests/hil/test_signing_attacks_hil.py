"""HIL tier: the signing attacks of issue 22 against the fc process (fc/signing.py).

A sender without the key forges the signed GCS's stream with a timestamp near 2^48; then
signed commands captured in one run are replayed after the fc restarted (SIGINT, same run
directory). Neither may change anything, and the signed GCS keeps control throughout.
(The in-process versions, with the 256 link ids and the unsigned HEARTBEAT ports:
tests/unit/fc/test_gcs_signing_attacks.py.)
"""
from __future__ import annotations

import hashlib
import os
import socket
import time

import pytest

from tests.fc_harness import FcProcess, free_udp_port, mavlink as ML
from tools.sitl.gcs import GCS_COMPID, GCS_SYSID, ScriptedGcs

pytestmark = pytest.mark.hil

PASSPHRASE = b"correct horse battery staple"
KEY = hashlib.sha256(PASSPHRASE).digest()
CAPTURE_LINK = 7                       # the link id the captured commands were signed on


class _Null:
    def write(self, _b):
        return None


def _codec(key: bytes, link_id: int, timestamp: int | None = None, sysid: int = GCS_SYSID,
           compid: int = GCS_COMPID):
    mav = ML.MAVLink(_Null(), srcSystem=sysid, srcComponent=compid)
    mav.signing.secret_key = key
    mav.signing.sign_outgoing = True
    mav.signing.link_id = link_id
    mav.signing.timestamp = (int((time.time() - 1420070400) * 1e5) if timestamp is None
                             else timestamp)
    return mav


def _send_from(port_addr, bufs) -> None:
    """Send datagrams from a fresh port (another sender than the GCS)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for b in bufs:
            s.sendto(b, port_addr)
    finally:
        s.close()


def _rej_sign(gcs, at_least: int):
    return gcs.wait("NAMED_VALUE_FLOAT", 8.0, since=time.monotonic(),
                    cond=lambda m: m.name == "REJ_SIGN" and m.value >= at_least)


@pytest.fixture()
def key_file(tmp_path):
    path = tmp_path / "gcs.key"
    path.write_bytes(PASSPHRASE + b"\n")
    os.chmod(path, 0o600)
    return str(path)


def _signed_fc(out: str, key_file: str):
    gcs_port = free_udp_port()
    fc = FcProcess(out, "--signing-key-file", key_file, "--flight-mode", "COORDINATED",
                   gcs_ports=(gcs_port,))
    return fc, gcs_port


def test_forged_timestamp_and_replay_after_restart_change_nothing(tmp_path, key_file):
    out = str(tmp_path / "run")
    fc, gcs_port = _signed_fc(out, key_file)
    with fc:
        gcs = ScriptedGcs(port=gcs_port)
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None
            gcs.setup_signing(KEY)
            vehicle = ("127.0.0.1", fc.gcs_bind_port)
            # GIVEN a forged frame on the GCS's own stream (its link id, system, component, all
            # sent in the clear): timestamp 2^48-10, a garbage signature
            forged = _codec(os.urandom(32), gcs.mav.signing.link_id, timestamp=2**48 - 10)
            _send_from(vehicle, [forged.heartbeat_encode(6, 8, 0, 0, 0).pack(forged)])
            # THEN the GCS's signed commands are still obeyed
            reply = gcs.param_set("TRIM_RUD_DEG", 2.0)
            assert reply is not None and reply.param_value == 2.0
            # GIVEN signed commands captured on their way to the fc (another link id)
            cap = _codec(KEY, CAPTURE_LINK)
            captured = [cap.param_set_encode(1, 1, b"TRIM_RUD_DEG", 3.0,
                                             ML.MAV_PARAM_TYPE_REAL32).pack(cap),
                        cap.command_long_encode(1, 1, ML.MAV_CMD_DO_SET_MODE, 0, 1, 0, 0, 0, 0,
                                                0, 0).pack(cap)]
            _send_from(vehicle, captured)
            assert gcs.wait("HEARTBEAT", 5.0, since=time.monotonic(),
                            cond=lambda m: m.custom_mode & 0xFFFF == 0) is not None
            # the GCS goes on: its own values and mode
            assert gcs.param_set("TRIM_RUD_DEG", 4.0).param_value == 4.0
            assert gcs.command(ML.MAV_CMD_DO_SET_MODE, 1, 1).result == ML.MAV_RESULT_ACCEPTED
        finally:
            gcs.close()
        assert fc.stop() == 0
    # WHEN the fc restarts on the same run directory and the captures are replayed
    fc, gcs_port = _signed_fc(out, key_file)
    with fc:
        gcs = ScriptedGcs(port=gcs_port)
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None
            _send_from(("127.0.0.1", fc.gcs_bind_port), captured)
            # THEN nothing changed: value and mode are the GCS's last ones, both rejected
            assert _rej_sign(gcs, 2) is not None, "the replays are counted as rejected"
            assert gcs.param_get("TRIM_RUD_DEG").param_value == 4.0
            hb = gcs.wait("HEARTBEAT", 3.0, since=time.monotonic())
            assert hb.custom_mode & 0xFFFF == 1            # COORDINATED, not MANUAL
            # and the signed GCS, with new timestamps, is obeyed
            gcs.setup_signing(KEY)
            assert gcs.param_set("TRIM_RUD_DEG", 5.0).param_value == 5.0
        finally:
            gcs.close()
        assert fc.stop() == 0
