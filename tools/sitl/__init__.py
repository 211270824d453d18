"""tools.sitl: the SITL harness the command lines of tools/ and the tests stand on.

Modules (imported explicitly; importing the package imports nothing):

- ``procs``: child processes in their own process group (start, read lines, bounded waits,
  SIGINT -> SIGTERM -> SIGKILL) and ``free_udp_port``;
- ``gcs``: the scripted ground station of the main job (own UDP socket, pymavlink's
  generated codec; commands, parameters, modes, arming, telemetry records);
- ``rig``: the real-time reliability rig (fc + impairment relay + plant + a recording ground
  station) of the reliability tests, the soak and the fuzz campaign;
- ``closed_loop``: the in-process closed loop (law + plant in one numba loop, no UDP);
- ``metrics``: step-response and surface metrics (docs/metrics.md) of summary.json and the
  campaigns.

Direction: tools.sitl imports fc, plant_sim and the link-impairment relay (tools.sitl.linkimpair)
only; the command lines (``python -m tools.X``) import tools.sitl, never the reverse
(tests/unit/test_architecture.py).
"""
