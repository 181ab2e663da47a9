"""Write ANDES 2.0's trajectory of IEEE 14 with a renewable plant at bus 8 to
tests/data/andes/ieee14_renewable.npz, for tests/test_renewables.py (which then runs
without ANDES).

Run from the repository root with ANDES installed:

    PYTHONPATH=src:. python tests/data/andes/make_ieee14_renewable.py

The case: smibjax's built-in `ieee14.raw` (ANDES's own file) with
`tests/data/andes/ieee14_renewable.dyr`: ANDES's ieee14.dyr with its Toggle records
removed and generator 8's GENROU, ESST3A and TGOV1 replaced by REGCA1 + REECB1 +
REPCA1 (the WECC 240-bus case's parameters, with REPCA1 in voltage control: RefFlag
= 1, no deadband; REECB1's VFLAG 0 and Vmin/Vmax -99/99, which do not act with QFLAG
= 0 in PSS/E's diagram but which ANDES 2.0's REECB1 needs to initialize: its Q PI
starts at 0, clamped to VMIN otherwise). A three-phase fault at bus 4 through xf =
1e-2 pu from 1.0 s to 1.05 s, 10 s, constant-impedance loads (ANDES's TDS default),
the power flow to 1e-12, TDS trapezoid at a fixed 5 ms step, tol 1e-8. The file
holds t (s) on a 10 ms grid, the rotor angles of the four GENROU (rad, ANDES's order
and bus numbers), every bus's voltage magnitude (pu) and angle (rad), the REGCA1's P
and Q (pu, system base), and the settings.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
OUT = HERE / "ieee14_renewable.npz"
RAW = ROOT / "src" / "smibjax" / "grid" / "cases" / "ieee14.raw"
DYR = HERE / "ieee14_renewable.dyr"
TSTEP, TOL, XF, BUS, T_ON, T_OFF, T_END = 5e-3, 1e-8, 1e-2, 4, 1.0, 1.05, 10.0


def main() -> None:
    import andes

    andes.config_logger(stream_level=50)
    ss = andes.load(
        str(RAW), addfile=str(DYR), setup=False, no_output=True, default_config=True
    )
    ss.add("Fault", dict(bus=BUS, tf=T_ON, tc=T_OFF, xf=XF, rf=0.0))
    ss.setup()
    for k, v in dict(
        pq2z=1, p2p=0.0, p2i=0.0, p2z=1.0, q2q=0.0, q2i=0.0, q2z=1.0
    ).items():
        setattr(ss.PQ.config, k, v)
    ss.PFlow.config.tol = 1e-12
    ss.PFlow.run()
    ss.TDS.config.tf = T_END
    ss.TDS.config.no_tqdm = 1
    ss.TDS.config.tstep = TSTEP
    ss.TDS.config.tol = TOL
    ss.TDS.config.fixt = 1
    ss.TDS.config.shrinkt = 0
    ss.TDS.run()
    if ss.exit_code != 0 or ss.dae.t < T_END - 1e-9:
        raise SystemExit("ANDES stopped before the end")
    ts = ss.dae.ts
    t = np.asarray(ts.t)
    grid = np.round(np.arange(0, int(round(T_END / 0.01)) + 1) * 0.01, 10)

    def on_grid(cols):
        return np.stack([np.interp(grid, t, c) for c in cols.T], axis=1)

    delta = on_grid(ts.x[:, ss.GENROU.delta.a])
    vm = on_grid(ts.y[:, ss.Bus.v.a])
    va = on_grid(ts.y[:, ss.Bus.a.a])
    pe = on_grid(ts.y[:, ss.REGCA1.Pe.a])
    qe = on_grid(ts.y[:, ss.REGCA1.Qe.a])
    np.savez(
        OUT,
        t=grid,
        delta=delta,
        gen_buses=np.asarray(ss.GENROU.bus.v, dtype=int),
        vm=vm,
        va=va,
        buses=np.asarray(ss.Bus.idx.v, dtype=int),
        pe=pe,
        qe=qe,
        fault_bus=BUS,
        t_fault=T_ON,
        t_clear=T_OFF,
        xf=XF,
        tstep=TSTEP,
        tol=TOL,
        andes=andes.__version__,
    )
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
