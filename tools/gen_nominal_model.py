"""Generate the control law's nominal model tables: fc/control/data/nominal_model.npz.

The controller carries its own copy of the nominal aerodynamics and atmosphere (it never runs
the plant's code): a gain-schedule table over (Mach, alpha) and an atmosphere table over
altitude, generated here offline from the published fits as the plant implements them
(``plant_sim.aero.coefficients``, Keshmiri et al. 2005, hypersonic branch; ``plant_sim.atmosphere
.us76``, US Standard Atmosphere 1976) at zero uncertainty, by central finite differences.
At run time ``fc.control.nominal`` interpolates them bilinearly (linearly for altitude).

Columns (fc/control/layout.py T_*): coefficients about the moment reference centre at zero
sideslip, rates and deflections; their derivatives with respect to beta (rad), the
dimensionless rates p b/2V, q c/2V, r b/2V, and each surface's deflection (per rad, at zero
deflection). All quantities the paper's model needs (Eqs. 2, 6, 22, 45).

Usage::

    python -m tools.gen_nominal_model            # (re)write the committed file
    python -m tools.gen_nominal_model --check    # exit 1 if the committed file differs

tests/unit/control/test_law_nominal.py regenerates the tables and checks they match the committed file.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from fc.control import layout as L
from fc.control.nominal import B_REF_M, C_REF_M, S_REF_M2, TABLE_PATH

DEG = math.pi / 180.0

# Grids. Mach 4..24 is the hypersonic branch's whole range, where the plant clips the fits
# (plant_sim.aero MACH_MIN, MACH_MAX): it contains the envelope (Mach 6-15) and the paper's
# point (M 7.44), and the law's model ends where the plant's does (nodes of the old 4..12 grid
# unchanged, so the model inside it is unchanged); alpha spans the fits' validity (0..12 deg,
# where the plant clips); altitude 0..60 km.
MACH_GRID = (4.0, 0.25, 81)        # start, step, count
ALPHA_GRID_DEG = (0.0, 0.5, 25)
H_GRID_M = (0.0, 100.0, 601)

H_BETA_RAD = 0.01       # finite-difference steps (the fits are linear in beta and the rates)
H_RATE = 0.01
H_DEFL_DEG = 0.01       # at most quadratic in a deflection near 0: central differences exact


def build_tables():
    """Return (tab, atm, grid) as numpy arrays (see fc/control/layout.py)."""
    from plant_sim.aero import coefficients
    from plant_sim.atmosphere import A_G_M_S2, A_N, A_RHO_KG_M3, A_SOUND_M_S, us76

    m0, dm, nm = MACH_GRID
    a0, da, na = ALPHA_GRID_DEG
    h0, dh, nh = H_GRID_M
    tab = np.zeros((nm, na, L.T_N))
    cp = np.empty(6)
    cm = np.empty(6)
    c0 = np.empty(6)

    def fd(a, M, beta, ph, qh, rh, d0, d1, d2, k, step):
        """Central difference of all six coefficients along input number k (0..6)."""
        args_p = [beta, ph, qh, rh, d0, d1, d2]
        args_m = list(args_p)
        args_p[k] += step
        args_m[k] -= step
        coefficients(a, M, *args_p, cp)
        coefficients(a, M, *args_m, cm)
        return (cp - cm) / (2.0 * step)

    for i in range(nm):
        M = m0 + i * dm
        for j in range(na):
            a = a0 + j * da
            row = tab[i, j]
            coefficients(a, M, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, c0)
            row[L.T_CL0] = c0[L.C_LIFT]
            row[L.T_CD0] = c0[L.C_DRAG]
            row[L.T_CY0] = c0[L.C_SIDE]
            row[L.T_CROLL0] = c0[L.C_ROLL]
            row[L.T_CPITCH0] = c0[L.C_PITCH]
            row[L.T_CYAW0] = c0[L.C_YAW]
            dbeta = fd(a, M, 0, 0, 0, 0, 0, 0, 0, 0, H_BETA_RAD)
            row[L.T_CY_B] = dbeta[L.C_SIDE]
            row[L.T_CROLL_B] = dbeta[L.C_ROLL]
            row[L.T_CYAW_B] = dbeta[L.C_YAW]
            dp = fd(a, M, 0, 0, 0, 0, 0, 0, 0, 1, H_RATE)
            dq = fd(a, M, 0, 0, 0, 0, 0, 0, 0, 2, H_RATE)
            dr = fd(a, M, 0, 0, 0, 0, 0, 0, 0, 3, H_RATE)
            row[L.T_CROLL_P] = dp[L.C_ROLL]
            row[L.T_CYAW_P] = dp[L.C_YAW]
            row[L.T_CPITCH_Q] = dq[L.C_PITCH]
            row[L.T_CROLL_R] = dr[L.C_ROLL]
            row[L.T_CYAW_R] = dr[L.C_YAW]
            for s in range(3):
                dd = fd(a, M, 0, 0, 0, 0, 0, 0, 0, 4 + s, H_DEFL_DEG) / DEG   # per rad
                for k in range(6):
                    row[L.T_DEL + 3 * k + s] = dd[k]

    atm = np.zeros((nh, L.ATM_N))
    out = np.empty(A_N)
    for i in range(nh):
        us76(h0 + i * dh, out)
        atm[i, L.ATM_RHO] = out[A_RHO_KG_M3]
        atm[i, L.ATM_SOUND] = out[A_SOUND_M_S]
        atm[i, L.ATM_G] = out[A_G_M_S2]

    grid = np.zeros(L.G_N)
    grid[L.G_MACH0], grid[L.G_DMACH], grid[L.G_NMACH] = m0, dm, nm
    grid[L.G_ALPHA0], grid[L.G_DALPHA], grid[L.G_NALPHA] = a0 * DEG, da * DEG, na
    grid[L.G_H0], grid[L.G_DH], grid[L.G_NH] = h0, dh, nh
    return tab, atm, grid


def check_geometry():
    """The controller's copy of S, b, c must equal the plant's reference geometry."""
    from plant_sim.vehicle import B_REF_M as pb, C_REF_M as pc, S_REF_M2 as ps
    if (ps, pb, pc) != (S_REF_M2, B_REF_M, C_REF_M):
        raise SystemExit(f"reference geometry differs: plant {(ps, pb, pc)} vs "
                         f"fc.control.nominal {(S_REF_M2, B_REF_M, C_REF_M)}")


def write(path: Path = TABLE_PATH) -> None:
    check_geometry()
    tab, atm, grid = build_tables()
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, tab=tab, atm=atm, grid=grid,
                        geometry=np.array([S_REF_M2, B_REF_M, C_REF_M]),
                        source=np.array("plant_sim.aero.coefficients + plant_sim.atmosphere.us76 "
                                        "at zero uncertainty, central differences "
                                        "(tools/gen_nominal_model.py)"))


def compare(path: Path = TABLE_PATH) -> float:
    """Largest relative difference between the committed tables and freshly built ones."""
    tab, atm, grid = build_tables()
    with np.load(path) as z:
        worst = 0.0
        for name, new in (("tab", tab), ("atm", atm), ("grid", grid)):
            old = z[name]
            if old.shape != new.shape:
                return math.inf
            scale = np.maximum(np.abs(new), 1e-12)
            worst = max(worst, float(np.max(np.abs(old - new) / scale)))
    return worst


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="compare with the committed file")
    ap.add_argument("--out", type=Path, default=TABLE_PATH,
                    help="where to write the table (default: the committed file the law loads, "
                         "fc/control/data/)")
    a = ap.parse_args(argv)
    if a.check:
        d = compare(a.out)
        print(f"max relative difference {d:.3e}")
        return 0 if d < 1e-9 else 1
    write(a.out)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
