"""``tools.bench``'s fcpath part (issues 16, 24): the fc's CPU per plant frame, in process, and
the floor under it (the link's receive and answer alone). A smoke test of the tool, not of any
time: ``part_fcpath`` reports the part as skipped when the fc's loop methods it drives change,
so a renamed method must fail here rather than vanish from the bench."""
from __future__ import annotations

from tools.bench.fcpath import fc_frame_path


def test_every_part_of_the_frame_and_its_floor_are_measured():
    r = fc_frame_path(frames=300)
    assert r["frames"] == 300
    for part in ("read_frame", "frame", "housekeeping", "total", "link_only",
                 "loop_recv_and_frame", "loop_housekeeping", "loop_total"):
        assert r[part]["median_us"] > 0.0, part
    # the total is the three parts frame by frame (medians of sums need not add up exactly)
    assert r["total"]["median_us"] >= r["frame"]["median_us"]
