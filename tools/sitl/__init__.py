"""tools.sitl: the SITL harness the command lines of tools/ and the tests stand on.

Modules (imported explicitly; importing the package imports nothing):

- ``procs``: child processes in their own process group (start, read lines, bounded waits,
  SIGINT -> SIGTERM -> SIGKILL) and ``free_udp_port``;
- ``gcs``: the scripted ground station of the main job (own UDP socket, pymavlink's
  generated codec; commands, parameters, modes, arming, telemetry records);
- ``runner``: one variant of the main job (plant and fc as two processes over loopback UDP:
  start, drive, watch, stop) and ``rundata``: a run directory's logs -> summary and plot data;
- ``rig``: the real-time reliability rig (fc + impairment relay + plant + a recording ground
  station) of the reliability tests, the soak and the fuzz campaign;
- ``linkimpair``: the seeded UDP impairment relay (in process, or as ``python -m tools.relay``);
- ``closed_loop``: the one in-process closed loop (package: ``core`` the attitude law + plant,
  ``guided`` guidance + law + plant, ``reports`` their text reports; no UDP);
- ``metrics``: step-response and surface metrics (docs/metrics.md) of summary.json and the
  campaigns; ``plots``: the PNGs of a run.

Direction: tools.sitl imports fc, plant_sim and hyfc_wire only (no command line of tools/ and
no evidence tool); the commands (``python -m tools.X``) and the evidence tools
(``tools.evidence``) import tools.sitl, never the reverse (tests/unit/test_architecture.py).
"""
