"""The measurement vector and the GNSS sample: the plant writes them, the fc reads them.

``float64[M_N]`` measurement vector (docs/architecture.md section 4), SI; the wire carries
it as ATTITUDE + AOA_SSA + VFR_HUD (docs/wire.md section 2). ``float64[G_N]`` GNSS sample
(docs/wire.md section 2, GPS_INPUT), degrees for latitude/longitude, SI otherwise.
Plain integers: numba kernels freeze them as constants (callers list this file among their
numba cache dependencies, hyfc_wire.numba_cache).
"""
from __future__ import annotations

# Measurement vector layout (docs/architecture.md section 4).
M_T_S = 0            # sensor time stamp = frame stamp (s, sim time)
M_ROLL = 1           # rad
M_PITCH = 2          # rad
M_YAW = 3            # rad
M_P = 4              # rad/s, body
M_Q = 5              # rad/s, body
M_R = 6              # rad/s, body
M_AOA = 7            # rad
M_SSA = 8            # rad
M_AIRSPEED = 9       # m/s
M_ALT = 10           # m
M_CLIMB = 11         # m/s, up positive
M_GROUNDSPEED = 12   # m/s
M_HEADING = 13       # rad, [0, 2 pi)
M_N = 14

#: names with units of the measurement fields, index = M_*
MEAS_NAMES = ("t_s", "roll_rad", "pitch_rad", "yaw_rad", "p_rad_s", "q_rad_s", "r_rad_s",
              "aoa_rad", "ssa_rad", "airspeed_m_s", "alt_m", "climb_m_s", "groundspeed_m_s",
              "heading_rad")

# GNSS sample layout (docs/wire.md section 2).
G_T_S = 0            # stamp of the frame that carries the sample (s)
G_LAT_DEG = 1
G_LON_DEG = 2
G_ALT_M = 3          # MSL
G_VN = 4             # m/s, NED
G_VE = 5
G_VD = 6
G_FIX = 7            # GPS_FIX_TYPE (3 = 3D fix)
G_SATS = 8
G_HACC_M = 9         # reported 1-sigma accuracies
G_VACC_M = 10
G_SACC_M_S = 11
G_N = 12

__all__ = ["M_T_S", "M_ROLL", "M_PITCH", "M_YAW", "M_P", "M_Q", "M_R", "M_AOA", "M_SSA",
           "M_AIRSPEED", "M_ALT", "M_CLIMB", "M_GROUNDSPEED", "M_HEADING", "M_N", "MEAS_NAMES",
           "G_T_S", "G_LAT_DEG", "G_LON_DEG", "G_ALT_M", "G_VN", "G_VE", "G_VD", "G_FIX",
           "G_SATS", "G_HACC_M", "G_VACC_M", "G_SACC_M_S", "G_N"]
