"""Write ANDES 2.0's Kundur GENCLS trajectory for a bus-8 fault to
tests/data/andes/kundur_gencls_bus8.npz, for tests/test_vs_andes.py (which then runs
without ANDES).

Run from the repository root with ANDES installed (the `bench` environment):

    PYTHONPATH=src:. python tests/data/andes/make_kundur_gencls_bus8.py

The run is benchmarks/vs_andes.py's accuracy case "kundur-gencls bus 8":
`kundur.raw` + `kundur_gencls.dyr`, a three-phase fault at bus 8 through
rf = 0, xf = 1e-4 pu (ANDES's default xf) from 1.0 s to 1.1 s, 10 s, constant-impedance
loads (ANDES's TDS default), the power flow to 1e-12, TDS trapezoid at a fixed 1 ms step,
tol 1e-8. The file holds t (s) on a 10 ms grid (0 .. 10 s), delta (rad, ANDES's 1 ms
samples interpolated linearly; ANDES's
synchronous frame, columns in ANDES's GENCLS order), the machines' bus numbers, and
the settings.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "benchmarks"))
OUT = Path(__file__).resolve().parent / "kundur_gencls_bus8.npz"
TSTEP, TOL, XF = 1e-3, 1e-8, 1e-4


def main() -> None:
    import andes
    from vs_andes import T_CLEAR, T_FAULT, andes_run, case_path

    t, d, buses, _, done = andes_run(
        case_path("kundur.raw"),
        case_path("kundur_gencls.dyr"),
        "GENCLS",
        8,
        T_FAULT,
        T_CLEAR,
        tstep=TSTEP,
        tol=TOL,
    )
    if not done:
        raise SystemExit("ANDES stopped before 10 s")
    grid = np.round(np.arange(0, 1001) * 0.01, 10)
    # ANDES's 1 ms samples interpolated linearly onto the grid (error below 2e-6 rad:
    # h^2/8 times |d2 delta/dt2| < 15 rad/s^2); the angle is continuous at the switches
    dg = np.stack([np.interp(grid, t, d[:, k]) for k in range(d.shape[1])], axis=1)
    np.savez(
        OUT,
        t=grid,
        delta=dg,
        buses=np.asarray(buses),
        fault_bus=8,
        t_fault=T_FAULT,
        t_clear=T_CLEAR,
        xf=XF,
        tstep=TSTEP,
        tol=TOL,
        andes=andes.__version__,
    )
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
