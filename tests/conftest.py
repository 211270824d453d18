"""Shared fixtures of the test suite (tier 1 ``unit/`` and tier 2 ``hil/``, tests/README.md).

The helpers behind them live in ``tests/fc_harness.py`` (a scripted plant, the fc as a process,
a lockstep closed loop over UDP) and in the SITL harness ``tools.sitl`` (free ports, child
processes, the scripted ground station ``ScriptedGcs``, the reliability rig). Every fixture that starts
something stops it at teardown.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.fc_harness import (FLYING_FS_TIMEOUT_S, ClosedLoop, FcProcess, ScriptedPlant,
                              free_udp_port)
from tools.sitl.gcs import ScriptedGcs

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """The repository root (where ``python -m fc`` and ``python -m plant_sim`` run)."""
    return ROOT


@pytest.fixture()
def udp_port():
    """A callable returning a UDP port free on 127.0.0.1 right now."""
    return free_udp_port


@pytest.fixture()
def scripted_plant():
    """Factory ``scripted_plant(fc_port, sysid=2) -> ScriptedPlant``; all closed at teardown."""
    made: list[ScriptedPlant] = []

    def make(fc_port: int, sysid: int = 2) -> ScriptedPlant:
        made.append(ScriptedPlant(fc_port, sysid))
        return made[-1]

    yield make
    for plant in made:
        plant.close()


@pytest.fixture()
def flying(tmp_path):
    """The fc as a process, armed in COORDINATED with FS_TIMEOUT_S ``FLYING_FS_TIMEOUT_S`` and
    FS_RECOVER_S 0.2 s, the scripted ground station on its telemetry port and a lockstep
    ``ClosedLoop`` (the plant in process over UDP); yields ``(fc, gcs, loop)``."""
    out = str(tmp_path)
    with open(os.path.join(out, "params.parm"), "w") as f:
        f.write(f"FS_TIMEOUT_S {FLYING_FS_TIMEOUT_S}\nFS_RECOVER_S 0.2\nCMD_ALPHA_DEG 3\n")
    gcs_port = free_udp_port()
    with FcProcess(out, "--arm", "--flight-mode", "COORDINATED", gcs_ports=(gcs_port,)) as fc:
        gcs = ScriptedGcs(port=gcs_port)
        loop = ClosedLoop(fc.plant_port)
        try:
            assert gcs.wait("HEARTBEAT", 10) is not None
            yield fc, gcs, loop
        finally:
            loop.close()
            gcs.close()
