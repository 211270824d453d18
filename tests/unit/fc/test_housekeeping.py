"""Unit tier: fc.loops.Housekeeping reads the ground-station socket only when there can be
something to read (docs/fc.md, bounded work): lockstep passes its ``select``'s verdict, real
time (no verdict) reads at most every GCS_POLL_S and on every call while datagrams come."""
from __future__ import annotations

import logging
from types import SimpleNamespace

from fc.loops import GCS_POLL_S, Housekeeping


class _Gcs:
    """Counts reads; each read returns the next of ``found`` (datagrams read)."""

    def __init__(self, found=()) -> None:
        self.reads: list[float] = []
        self.found = list(found)
        self.services = 0

    def poll(self, now_s: float) -> int:
        self.reads.append(now_s)
        return self.found.pop(0) if self.found else 0

    def service(self, now_s: float) -> int:
        self.services += 1
        return 0


def _housekeeping(gcs: _Gcs) -> Housekeeping:
    plant = SimpleNamespace(counters=SimpleNamespace(goodbyes=0, relocks=0))
    return Housekeeping(gcs=gcs, plant=plant, intake=None,
                        mode_ctl=SimpleNamespace(check_data=lambda now_s: None), stats=None,
                        planner=None, counters=None, telemetry=None, param_svc=None, io=None,
                        event=lambda text, sev: None, log=logging.getLogger("test"),
                        next_1hz=1e9)       # the 1 Hz chores are not what is tested here


def test_lockstep_reads_the_gcs_socket_only_when_select_says_it_is_readable():
    gcs = _Gcs()
    hk = _housekeeping(gcs)
    hk(1.0, False)
    hk(1.001, False)
    assert gcs.reads == [] and gcs.services == 2       # streams still served every call
    hk(1.002, True)
    assert gcs.reads == [1.002]


def test_real_time_reads_at_most_every_poll_interval_and_every_call_while_data_comes():
    gcs = _Gcs(found=[0, 3, 2, 0])
    hk = _housekeeping(gcs)
    t0 = 10.0
    hk(t0)                                  # first call: read (nothing)
    hk(t0 + GCS_POLL_S / 2)                 # too soon: no read
    hk(t0 + GCS_POLL_S)                     # due: read, 3 datagrams
    hk(t0 + GCS_POLL_S + 1e-4)              # data came: read again at once (2)
    hk(t0 + GCS_POLL_S + 2e-4)              # and again (nothing now)
    hk(t0 + GCS_POLL_S + 3e-4)              # quiet again: wait the interval
    assert gcs.reads == [t0, t0 + GCS_POLL_S, t0 + GCS_POLL_S + 1e-4, t0 + GCS_POLL_S + 2e-4]
    assert gcs.services == 6


def test_dropped_gnss_samples_are_reported_once_per_round_that_sees_new_ones():
    # GIVEN a plant link that has dropped 3 GNSS samples, and the 1 Hz round at its telemetry
    # chore (where the drops are checked)
    events = []
    plant = SimpleNamespace(counters=SimpleNamespace(goodbyes=0, relocks=0, gnss_rejected=3))
    hk = Housekeeping(gcs=_Gcs(), plant=plant, intake=None,
                      mode_ctl=SimpleNamespace(check_data=lambda now_s: None), stats=None,
                      planner=None, counters=None,
                      telemetry=SimpleNamespace(refresh=lambda: None), param_svc=None, io=None,
                      event=lambda text, sev: events.append((text, sev)),
                      log=logging.getLogger("test"), chore=2, next_1hz=0.0)
    # WHEN the round runs, then again after 2 more drops, then once with none
    hk(1.0, False)
    plant.counters.gnss_rejected = 5
    hk.chore, hk.next_1hz = 2, 0.0
    hk(2.0, False)
    hk.chore, hk.next_1hz = 2, 0.0
    hk(3.0, False)
    # THEN one WARNING per round with new drops, with the new count and the total
    warn = 4   # MAV_SEVERITY_WARNING
    assert events == [("GNSS: 3 samples dropped (out of range or not finite), 3 in all", warn),
                      ("GNSS: 2 samples dropped (out of range or not finite), 5 in all", warn)]
