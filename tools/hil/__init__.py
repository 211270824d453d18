"""tools.hil - the main job: plant and controller as two processes over loopback MAVLink/UDP.

``python -m tools.hil run`` flies a scenario (both controller variants by default) and writes
a run directory; ``python -m tools.hil report RUN_DIR`` rebuilds its summary and plots from the
logs. See docs/hil.md.

Modules: ``cli`` (command line, summary table). The machinery is the SITL harness's:
``tools.sitl.runner`` (one variant: start, drive, watch, stop), ``tools.sitl.rundata`` (logs ->
summary and plot data), ``tools.sitl.procs`` (the child processes), ``tools.sitl.gcs`` (the
scripted ground station, the only MAVLink import of this process), ``tools.sitl.plots``.
"""
