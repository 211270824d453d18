"""Unit tier: the log download service (fc/gcs_logs.py): requests in, LOG_ENTRY/LOG_DATA out,
the file read from a temporary .tlog; time is passed in."""
from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"
from fc.gcs_logs import CHUNK, LOG_ID, LogService, Pacer  # noqa: E402
from fc.link import mavlink as ML  # noqa: E402
from tests.fc_harness import received  # noqa: E402

PEER = ("127.0.0.1", 14550)


def _download(svc: LogService, ofs: int = 0, count: int = 0xFFFFFFFF, t0: float = 0.0):
    """Request data and take until the transfer ends (bounded); returns the LOG_DATA list."""
    out = svc.handle(received(ML.MAVLink_log_request_data_message(1, 1, LOG_ID, ofs, count)),
                     PEER, t0)
    t = t0
    for _ in range(100_000):
        if not svc.busy:
            break
        t += 0.001
        out += svc.take(t, 6)
    assert not svc.busy
    return [m for _, m in out]


def _log(tmp_path, n: int) -> str:
    path = tmp_path / "fc.tlog"
    path.write_bytes(bytes(i % 251 for i in range(n)))
    return str(path)


def test_list_gives_one_log_with_its_size_and_the_start_time(tmp_path):
    svc = LogService(_log(tmp_path, 1000), time_utc_s=1_764_000_000)
    out = svc.handle(received(ML.MAVLink_log_request_list_message(1, 1, 0, 0xFFFF)), PEER, 0.0)
    (peer, e), = out
    assert peer == PEER and e.get_type() == "LOG_ENTRY"
    assert (e.id, e.num_logs, e.last_log_num, e.size, e.time_utc) == (1, 1, 1, 1000,
                                                                       1_764_000_000)
    # the log grows: a new list (no transfer running) has the new size
    with open(svc.path, "ab") as f:
        f.write(b"y" * 500)
    (_, e), = svc.handle(received(ML.MAVLink_log_request_list_message(1, 1, 0, 0xFFFF)), PEER, 0)
    assert e.size == 1500
    # a range without log 1: nothing; a run without a log: "No logs"
    assert svc.handle(received(ML.MAVLink_log_request_list_message(1, 1, 2, 5)), PEER, 0) == []
    (_, none), = LogService(None, 0).handle(
        received(ML.MAVLink_log_request_list_message(1, 1, 0, 0xFFFF)), PEER, 0.0)
    assert none.num_logs == 0


def test_download_returns_the_file_byte_for_byte_and_ends_as_mavproxy_expects(tmp_path):
    for n in (1000, 900):                # a short last chunk; a multiple of 90 (count-0 end)
        path = _log(tmp_path, n)
        svc = LogService(path, 0)
        svc.handle(received(ML.MAVLink_log_request_list_message(1, 1, 0, 0xFFFF)), PEER, 0.0)
        with open(path, "ab") as f:      # the log grows after the list: the size holds
            f.write(b"x" * 500)
        msgs = _download(svc)
        data = b"".join(bytes(m.data[:m.count]) for m in msgs)
        with open(path, "rb") as f:
            assert data == f.read()[:n]
        assert [m.ofs for m in msgs if m.count] == list(range(0, n, CHUNK))
        assert msgs[-1].count < CHUNK                   # MAVProxy's end test
        assert (msgs[-1].count == 0) == (n % CHUNK == 0)
        svc.close()


def test_a_gap_request_returns_that_range_and_past_the_end_count_zero(tmp_path):
    svc = LogService(_log(tmp_path, 1000), 0)
    msgs = _download(svc, ofs=180, count=180)
    assert [(m.ofs, m.count) for m in msgs] == [(180, 90), (270, 90)]
    (end,) = _download(svc, ofs=1000)
    assert (end.ofs, end.count) == (1000, 0)
    svc.close()


def test_log_data_is_paced_and_bounded_per_call(tmp_path):
    svc = LogService(_log(tmp_path, 90 * 100), 0, rate_hz=100.0, per_call=4)
    svc.handle(received(ML.MAVLink_log_request_data_message(1, 1, 1, 0, 0xFFFFFFFF)), PEER, 0)
    assert len(svc.take(0.0, 6)) == 4            # the burst
    assert svc.take(0.0, 6) == []                # nothing left in the bucket
    assert len(svc.take(0.02, 6)) == 2           # 100/s: 2 in 20 ms
    assert len(svc.take(10.0, 2)) == 2           # the caller's budget caps it
    svc.handle(received(ML.MAVLink_log_request_end_message(1, 1)), PEER, 10.0)
    assert not svc.busy and svc.take(20.0, 6) == []
    svc.close()


def test_erase_is_refused_with_a_reason(tmp_path):
    path = _log(tmp_path, 100)
    out = LogService(path, 0).handle(received(ML.MAVLink_log_erase_message(1, 1)), PEER, 0.0)
    assert out[0][0] == "text" and "refused" in out[0][2]
    assert os.path.getsize(path) == 100


def test_pacer_refills_at_its_rate_up_to_the_burst():
    p = Pacer(rate_hz=10.0, per_call=3)
    assert p.allowance(0.0, 10) == 3
    p.spend(3)
    assert p.allowance(0.05, 10) == 0
    assert p.allowance(0.1, 10) == 1
    assert p.allowance(100.0, 10) == 3


def test_a_burst_of_gap_requests_is_served_whole_slower_and_a_new_download_starts_over(
        tmp_path):
    # GIVEN a download that lost three ranges, asked for at once (MAVProxy's missing handler)
    svc = LogService(_log(tmp_path, 1000), 0, rate_hz=1000.0)
    for ofs, count in ((180, 180), (450, 90), (900, 100)):
        assert svc.handle(received(ML.MAVLink_log_request_data_message(1, 1, 1, ofs, count)),
                          PEER, 5.0) == []
    # THEN the station could not keep up: the rate halved once for the burst
    assert svc.pacer.rate_hz == 500.0 and svc.gap_requests == 3
    # WHEN the service streams  THEN every range is sent, in order, the last with the end
    msgs = _download(svc, ofs=900, count=100, t0=5.1)     # a repeated request is queued once
    assert [(m.ofs, m.count) for m in msgs] == [(180, 90), (270, 90), (450, 90), (900, 90),
                                                 (990, 10)]
    # a request for the whole log is a new download: queued gaps dropped, full rate again
    svc.handle(received(ML.MAVLink_log_request_data_message(1, 1, 1, 180, 90)), PEER, 10.0)
    msgs = _download(svc, ofs=0, t0=10.0)
    assert svc.pacer.rate_hz == 1000.0
    assert [m.ofs for m in msgs if m.count] == list(range(0, 1000, CHUNK))
    svc.close()
