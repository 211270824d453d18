"""Winged-cone mass properties, reference geometry and the aerodynamic data's validity box.

Every number here is cited in /work/shared/docs/winged_cone.md (sections 1, 2 and 4; sources
S1 = NASA TM-102610, S2 = Keshmiri et al. AIAA 2005-6257, R1 = GHV_open). These are the
defaults; scenarios may override mass, inertia and x_cg (plant_sim/scenario.py).
"""
from __future__ import annotations

FT_M = 0.3048

# Reference geometry [S1 Table I, S2 Table 1].
S_REF_M2 = 334.73          # reference area (3603 ft^2)
B_REF_M = 18.288           # span (60 ft)
C_REF_M = 24.384           # mean aerodynamic chord (80 ft)
MRC_FROM_NOSE_M = 37.80    # moment reference centre station (124.01 ft)

# Full-mass properties [S1, S2; inertias as coded in R1 rot_dyn.m "max mass"].
MASS_KG = 136078.0         # 300,000 lb
IXX_KG_M2 = 1.36e6
IYY_KG_M2 = 1.5e7
IZZ_KG_M2 = 1.36e7
IXZ_KG_M2 = 0.0            # "products of inertia negligible" [S1, S2]

# MRC -> c.g. distance, positive aft [R1 Get_Aerodynamic.m: 9.51 ft at 300 klb].
X_CG_FULL_MASS_M = 9.51 * FT_M   # 2.8987 m

# Validity of the hypersonic-branch fits [S1, S2; winged_cone.md section 2]; inputs to
# plant_sim.aero.coefficients are clipped to this box.
ALPHA_MIN_DEG = 0.0
ALPHA_MAX_DEG = 12.0
MACH_MIN = 4.0             # hypersonic branch is built on the M 6 and M 10 data, used for M >= 4
MACH_MAX = 24.0
DEFLECTION_MAX_DEG = 20.0  # each elevon and the rudder, taken separately
