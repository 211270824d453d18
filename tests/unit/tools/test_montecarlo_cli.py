"""Campaign command-line polish (issue 12 point 7): an unreachable or malformed ``--scheduler``
is one clean line, exit 2, and leaves no campaign directory; ``rerun --case`` outside the
campaign is refused; the LocalCluster's Dask dashboard answers (bokeh in the campaign extra).
"""
from __future__ import annotations

import socket
import subprocess
import sys
import threading
import urllib.request
from pathlib import Path

import pytest

from tools.evidence.montecarlo import __main__ as cli
from tools.evidence.montecarlo import dispersions as dsp
from tools.evidence.montecarlo.campaign import (CampaignError, cluster_client, prepare_dir, run_campaign,
                                       scheduler_address)
from tools.evidence.montecarlo.case import CampaignConfig

pytest.importorskip("distributed")
ROOT = Path(__file__).resolve().parents[3]


def _cfg() -> CampaignConfig:
    d = dsp.load("paper")
    return CampaignConfig(scenario="paper", dispersions_text=d.source_text,
                          dispersions_name=d.name, seed=3, duration_s=2.0, backend="standin")


def _dead_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _campaign_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tools.evidence.montecarlo", "--runs", "2",
                           "--backend", "standin", "--no-plots", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("address, says", [
    (None, "cannot reach the Dask scheduler"),               # nothing listening there
    ("nonsense", "malformed address"),
    ("tcp://127.0.0.1:99999", "port must be 1..65535"),
])
def test_bad_scheduler_is_one_line_exit_2_and_no_directory(tmp_path, address, says):
    address = address or f"tcp://127.0.0.1:{_dead_tcp_port()}"
    out = tmp_path / "campaign"
    r = _campaign_cli("--scheduler", address, "--connect-timeout", "3", "--out", str(out))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and "Traceback" not in r.stderr, r.stderr
    assert not out.exists()


def test_scheduler_address_forms():
    assert scheduler_address("tcp://10.0.0.2:8786") == ("tcp://10.0.0.2:8786", "10.0.0.2", 8786)
    assert scheduler_address("host:8786") == ("tcp://host:8786", "host", 8786)
    assert scheduler_address("tls://h:1")[0] == "tls://h:1"
    for bad in ("", "tcp://host", "tcp://:8786", "http://h:1", "tcp://h:port", "tcp://h:0",
                "inproc://x", "tcp://h:1/path"):
        with pytest.raises(CampaignError):
            scheduler_address(bad)


def test_a_silent_listener_is_not_taken_for_a_scheduler(tmp_path):
    # GIVEN something that accepts TCP connections but never speaks (not a Dask scheduler)
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    held = []
    stop = threading.Event()

    def _accept():
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                held.append(srv.accept()[0])
            except OSError:
                continue

    th = threading.Thread(target=_accept, daemon=True)
    th.start()
    out = tmp_path / "campaign"
    try:
        # WHEN a campaign is sent there THEN it is refused within the bound, nothing written
        with pytest.raises(CampaignError, match="not a Dask scheduler"):
            run_campaign(_cfg(), 2, out, scheduler=f"tcp://127.0.0.1:{srv.getsockname()[1]}",
                         connect_timeout_s=1.0)
    finally:
        stop.set()
        th.join(timeout=5)
        for c in held:
            c.close()
        srv.close()
    assert not out.exists()


@pytest.mark.parametrize("case", ["3", "-1"])
def test_rerun_outside_the_campaign_is_refused(tmp_path, capsys, case):
    prepare_dir(_cfg(), 3, tmp_path)                         # a campaign of cases 0..2
    assert cli.main(["rerun", str(tmp_path), "--case", case]) == 2
    err = capsys.readouterr().err
    assert f"--case {case} is not a case of the campaign" in err and "0..2" in err
    assert not (tmp_path / f"case-{case}").exists()


def test_local_cluster_dashboard_answers(tmp_path):
    # without bokeh (the campaign extra) the page only says that the dashboard needs it
    with cluster_client(workers=1) as client:
        link = client.dashboard_link
        with urllib.request.urlopen(link, timeout=30) as r:
            body = r.read()
            status = r.status
    assert status == 200
    assert b"bokeh.min.js" in body, body[:500]
