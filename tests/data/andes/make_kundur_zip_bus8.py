"""Write ANDES 2.0's Kundur GENCLS trajectory with ZIP loads to
tests/data/andes/kundur_zip_bus8.npz, for tests/test_grid_loads.py (which then runs
without ANDES).

Run from the repository root with ANDES installed:

    PYTHONPATH=src:. python tests/data/andes/make_kundur_zip_bus8.py

`kundur.raw` + `kundur_gencls.dyr`; ANDES's PQ loads converted for the time domain
with p2p, p2i, p2z = 0.4, 0.3, 0.3 and q2q, q2i, q2z = 0.2, 0.3, 0.5 (ANDES keeps
them so at every voltage: no low-voltage treatment); a three-phase fault at bus 8
through rf = 0, xf = 0.05 pu from 1.0 s to 1.1 s; the power flow to 1e-12,
TDS trapezoid at a fixed 1 ms step, tol 1e-8, 5 s. The file holds t (s) on a 10 ms
grid, delta (rad, ANDES's synchronous frame, columns in ANDES's GENCLS order, 1 ms
samples interpolated linearly), v (bus voltage magnitudes, pu, columns `bus_v`),
the machines' bus numbers and the settings.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2].parent
OUT = Path(__file__).resolve().parent / "kundur_zip_bus8.npz"
CASES = ROOT / "src" / "smibjax" / "grid" / "cases"
SHARES = dict(p2p=0.4, p2i=0.3, p2z=0.3, q2q=0.2, q2i=0.3, q2z=0.5)
TSTEP, TOL, XF, T_ON, T_OFF, T_END = 1e-3, 1e-8, 0.05, 1.0, 1.1, 5.0


def main() -> None:
    import andes

    andes.config_logger(stream_level=50)
    ss = andes.load(
        str(CASES / "kundur.raw"),
        addfile=str(CASES / "kundur_gencls.dyr"),
        setup=False,
        no_output=True,
        default_config=True,
    )
    ss.add("Fault", dict(bus=8, tf=T_ON, tc=T_OFF, xf=XF, rf=0.0))
    ss.setup()
    for k, v in dict(pq2z=1, **SHARES).items():
        setattr(ss.PQ.config, k, v)
    ss.PFlow.config.tol = 1e-12
    ss.PFlow.run()
    ss.TDS.config.tf = T_END
    ss.TDS.config.no_tqdm = 1
    ss.TDS.config.tstep = TSTEP
    ss.TDS.config.tol = TOL
    ss.TDS.run()
    t = np.asarray(ss.dae.ts.t)
    if t[-1] < T_END - 1e-9:
        raise SystemExit("ANDES stopped before the end")
    d = np.asarray(ss.dae.ts.x)[:, ss.GENCLS.delta.a]
    v = np.asarray(ss.dae.ts.y)[:, ss.Bus.v.a]
    grid = np.round(np.arange(0, int(T_END * 100) + 1) * 0.01, 10)

    def interp(a):
        return np.stack([np.interp(grid, t, a[:, k]) for k in range(a.shape[1])], 1)

    np.savez(
        OUT,
        t=grid,
        delta=interp(d),
        v=interp(v),
        bus_v=np.asarray([int(b) for b in ss.Bus.idx.v]),
        buses=np.asarray([int(b) for b in ss.GENCLS.bus.v]),
        shares=np.array(
            [SHARES[k] for k in ("p2p", "p2i", "p2z", "q2q", "q2i", "q2z")]
        ),
        xf=XF,
        t_fault=T_ON,
        t_clear=T_OFF,
        tstep=TSTEP,
        tol=TOL,
        andes=andes.__version__,
    )
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
