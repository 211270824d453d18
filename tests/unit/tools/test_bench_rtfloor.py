"""``tools.bench.rtfloor`` (issue 24): the bare receiver that measures the host's wake-up floor
under the real-time lateness rows of ``python -m tools.bench``.

The figures are checked on a known record; the receiver itself is run as a process on
loopback, fed frames by the test and checked to answer each one and to count them.
"""
from __future__ import annotations

import json
import socket
import subprocess
import sys

import numpy as np

from tools.bench.pingpong import _encode_sensor_frame
from tools.bench.rtfloor import lateness_figures
from tools.sitl.procs import free_udp_port


def test_lateness_figures_of_a_known_record():
    lat_ns = np.array([10_000] * 98 + [300_000, 900_000], dtype=np.int64)   # 10 us, two late
    f = lateness_figures(lat_ns, period_us=1000.0)
    assert f["frames"] == 100
    assert f["lateness_median_us"] == 10.0
    assert f["lateness_max_us"] == 900.0
    assert f["late_20pct_share_pct"] == 2.0          # above 200 us: the last two
    assert 10.0 < f["lateness_p99_us"] < 900.0
    # the warm-up is left out: the two late frames first, then skipped
    g = lateness_figures(lat_ns[::-1], period_us=1000.0, skip=2)
    assert g["frames"] == 98 and g["late_20pct_share_pct"] == 0.0
    assert np.isnan(lateness_figures(lat_ns[:0], 1000.0)["lateness_p99_us"])


def test_a_bad_address_is_a_clear_error(tmp_path):
    r = subprocess.run([sys.executable, "-m", "tools.bench.rtfloor", "--plant-bind", "nohost",
                        "--out", str(tmp_path / "f.json"), "--rt-priority", "0"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert "--plant-bind" in r.stderr and "HOST:PORT" in r.stderr
    assert not (tmp_path / "f.json").exists()


def test_the_receiver_answers_and_counts_every_frame(tmp_path):
    from fc.link import mavlink, new_codec
    port = free_udp_port()
    out = tmp_path / "f.json"
    p = subprocess.Popen([sys.executable, "-m", "tools.bench.rtfloor", "--plant-bind",
                          f"127.0.0.1:{port}", "--out", str(out), "--rt-priority", "0",
                          "--skip", "0", "--idle-s", "0.5"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        assert p.stdout.readline().strip() == "READY"
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(10.0)
        codec = new_codec(2)              # the plant's system id
        answers = 0
        for k in range(20):
            sock.sendto(_encode_sensor_frame(codec, mavlink, 2000 * (k + 1)), ("127.0.0.1", port))
            data, _ = sock.recvfrom(2048)                  # bounded: 10 s
            answers += data[0] in (0xFD, 0xFE)             # a MAVLink frame came back
        assert answers == 20
        assert p.wait(timeout=30) == 0
    finally:
        sock.close()
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    f = json.loads(out.read_text())
    assert f["frames_answered"] == 20
    # one lateness per wake-up: a frame that came in before the receiver looked again after
    # its answer is read in the same wake-up (as the fc's ticks), so at most one per frame
    assert 1 <= f["frames"] <= 20
    assert f["rx_timestamps"] is True
    assert 0.0 <= f["lateness_median_us"] < 1e6
