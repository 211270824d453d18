"""hyfc_wire - the contract between the flight controller and the plant (docs/architecture.md s. 1).

Both processes import it; it imports nothing of ours (only the standard library, numpy,
numba and pymavlink), so neither process has to import the other to agree with it.

Modules (import the one you need; this package file imports none of them):
- ``layout``: the measurement vector ``M_*`` and the GNSS sample ``G_*`` (architecture.md s. 4)
- ``pwm``: deflection / throttle <-> PWM (docs/wire.md s. 3)
- ``codec``: the MAVLink 2 ``ardupilotmega`` codec factory (the only pymavlink import here)
- ``framing``: CRC-16/MCRF4XX and the lean framing of the wire's messages (same bytes as the codec)
- ``frame_kernels``: the fc's frame path compiled (sensor decode, PWM map, SERVO_OUTPUT_RAW)
- ``udp``: ``HOST:PORT`` parsing and the non-blocking UDP endpoint
- ``timeline``: the ``[[command]]`` / ``[[target]]`` timeline reader (one reader, one meaning)
- ``numba_cache``: drop numba on-disk caches that are older than their dependencies
- ``rawnpz``: a raw row-major float64 log to ``.npz`` in bounded memory (both processes' logs)
"""
