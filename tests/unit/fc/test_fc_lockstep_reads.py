"""fc/loops.py lockstep loop (issue 24): no receive that finds nothing on the frame path.

In process, on 127.0.0.1: a real controller's lockstep loop (``RunLoops.run``) gets the
sensor datagrams of a short flight one exchange at a time, as the plant sends them (frame
k+1 after the answer to k); the plant socket's receives are counted (by the plant link's
counters: the compiled receive, fc/frame_calls.py, is not a Python call to wrap).
"""
from __future__ import annotations

import select

from tools.bench.profile import _Rig, record

FRAMES = 60


def test_each_exchange_reads_the_plant_socket_once():
    # GIVEN a controller in its lockstep loop and a plant that sends the next frame only
    # after the answer to the previous one (the loop's ``stop`` callback plays the plant)
    datagrams = record(FRAMES, "COORDINATED")
    rig = _Rig("COORDINATED")
    try:
        c = rig.fc.plant.counters
        before = (c.datagrams, c.empty_reads)
        sent = answers = 0

        def stop():
            nonlocal sent, answers
            while select.select([rig.plant], [], [], 0.0)[0]:
                rig.plant.recv(65536)
                answers += 1
            if answers == sent and sent < FRAMES:
                rig.plant.sendto(datagrams[sent], rig.addr)
                sent += 1
            return answers == FRAMES

        # WHEN the loop runs the whole flight
        rig.fc.loops.run(stop)
        # THEN every frame was answered, each read found its frame, no read found nothing
        assert (sent, answers) == (FRAMES, FRAMES)
        reads = {"got": c.datagrams - before[0], "nothing": c.empty_reads - before[1]}
        assert reads == {"got": FRAMES, "nothing": 0}
    finally:
        rig.close()
