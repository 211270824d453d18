"""hyfc flight controller: the autopilot process (``python -m fc``, docs/fc.md); the control law
is the pure library ``fc.control`` (docs/control_law.md)."""
