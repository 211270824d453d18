"""HIL tier: the fc on a tiny filesystem (issue 22, item 5; fc/storage.py).

The run directory is a 3 MB tmpfs (mounted by the test: root here and in CI; skipped cleanly
where mount is not permitted), filled up by a file while the fc runs. The fc must say it
(STATUSTEXT ERROR, SYS_STATUS logging health bit cleared), report a parameter it cannot save,
recover when the space returns, and exit 0 at SIGINT without partial files.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import time

import pytest

from tests.fc_harness import fc_with_gcs, mavlink as ML

pytestmark = pytest.mark.hil

LOGGING = ML.MAV_SYS_STATUS_LOGGING


@pytest.fixture()
def tiny_fs(tmp_path):
    mnt = tmp_path / "tmpfs"
    mnt.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mnt)],
                         capture_output=True, text=True, timeout=30)
    if res.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {res.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True, timeout=30)


def _fill(path) -> None:
    """Write ``path`` until the filesystem is full."""
    with open(path, "wb") as f:
        try:
            while True:
                f.write(b"\0" * 65536)
                f.flush()
        except OSError:
            pass


def _logging_health(gcs, ok: bool, timeout_s: float) -> bool:
    m = gcs.wait("SYS_STATUS", timeout_s, since=time.monotonic(),
                 cond=lambda m: bool(m.onboard_control_sensors_health & LOGGING) == ok
                 and m.onboard_control_sensors_present & LOGGING)
    return m is not None


def test_a_full_disk_is_said_and_survived_and_the_exit_is_clean(tiny_fs):
    run = tiny_fs / "run"
    with fc_with_gcs(str(run), "--mode", "realtime", "--rt-priority", "0") as (fc, gcs):
        assert _logging_health(gcs, True, 5.0), "logging healthy on an empty disk"
        # GIVEN the disk fills up while the fc runs
        filler = tiny_fs / "filler"
        _fill(filler)
        # THEN it is said as an ERROR STATUSTEXT, and in SYS_STATUS's logging health bit
        text = gcs.wait("STATUSTEXT", 10.0, cond=lambda m: m.text.startswith("DISK:"))
        assert text is not None and text.severity == ML.MAV_SEVERITY_ERROR
        assert _logging_health(gcs, False, 5.0)
        # a parameter set now is reported as not saved (set in memory: the echo says so)
        since = time.monotonic()
        reply = gcs.param_set("TRIM_RUD_DEG", 1.5)
        assert reply is not None and reply.param_value == 1.5
        assert gcs.wait("STATUSTEXT", 5.0, since=since,
                        cond=lambda m: "NOT saved" in m.text) is not None
        # WHEN space returns: the writes succeed again and the bit comes back
        os.unlink(filler)
        assert _logging_health(gcs, True, 10.0), "logging health back when space returns"
        # the disk fills again before SIGINT: the exit is still clean
        _fill(filler)
        time.sleep(0)  # noqa: the next line waits on the fc, bounded
        assert gcs.wait("STATUSTEXT", 10.0, since=time.monotonic() - 1.0,
                        cond=lambda m: m.text.startswith("DISK:")) is not None
        rc = fc.stop()
        assert rc == 0, fc.stderr
        assert "Traceback" not in fc.stderr
    # THEN no partial file: no temp files, no empty npz
    names = os.listdir(run)
    assert not [n for n in names if ".tmp" in n or n.startswith(".")], names
    for n in names:
        if n.endswith(".npz"):
            assert os.path.getsize(run / n) > 0
    assert "fc_internals.raw" in names or "fc_internals.npz" in names
