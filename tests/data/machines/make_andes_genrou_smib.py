"""Make andes_genrou_smib.npz: ANDES's GENROU on a machine-infinite bus system through
a three-phase fault at the machine terminal, the reference of tests/test_machines.py.

    python tests/data/machines/make_andes_genrou_smib.py   (needs andes; ~10 s)

The case is built in code (`build`): bus 1 holds a PV generator with a GENROU (no
exciter, no governor: Efd and Pm stay at their initial values), bus 2 a slack bus
without a dynamic machine, which ANDES keeps at its voltage and angle through the
simulation (an infinite bus), and a lossless line between them. A fault to ground
through the reactance XF at bus 1 from T_FAULT to T_CLEAR. ANDES integrates with its
implicit trapezoidal rule at a fixed step of 1 ms; the file keeps every 10th point.

One setting differs from ANDES's defaults: ANDES puts extra steps eps before and after
each event (`System.store_switch_times`, eps = 1e-4 s) and takes the first step after
the event with the trapezoidal average of the pre- and post-event derivatives, an
O(eps) error in the states (5e-4 pu in the damper fluxes, 7e-5 rad in the angle for
this case). The script sets eps = 1e-6 s (EVENT_EPS), which leaves ANDES's own
1 ms trapezoidal error (about 1e-6 rad).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "andes_genrou_smib.npz"

S_BASE = 100.0  # MVA
F_BASE = 60.0  # Hz
# GENROU on its own base SN (pu machine base, s); ANDES's names
GEN = dict(
    Sn=200.0, M=8.0, D=1.0, ra=0.003, xl=0.15, xd=1.8, xq=1.7, xd1=0.3, xq1=0.55,
    xd2=0.25, xq2=0.25, Td10=6.0, Td20=0.05, Tq10=0.8, Tq20=0.06, S10=0.1, S12=0.4,
)  # fmt: skip
P_GEN = 1.5  # pu system base (0.75 on the machine base)
V_GEN = 1.02  # pu
V_INF = 1.0  # pu, angle 0
X_LINE = 0.12  # pu system base
XF = 0.05  # fault reactance, pu system base
T_FAULT, T_CLEAR, T_END = 0.5, 0.6, 5.0
STEP = 1e-3  # ANDES's fixed step (s)
EVENT_EPS = 1e-6  # ANDES's steps around an event (s); its default is 1e-4
KEEP_EVERY = 10


def build():
    """The ANDES system, set up (not yet solved)."""
    import andes

    andes.config_logger(stream_level=40)
    ss = andes.System()
    ss.config.freq = F_BASE
    ss.config.mva = S_BASE
    for idx in (1, 2):
        ss.add("Bus", dict(idx=idx, name=f"B{idx}", Vn=110.0, v0=1.0, a0=0.0))
    ss.add("Line", dict(idx="L1", bus1=1, bus2=2, r=0.0, x=X_LINE, b=0.0, Vn1=110.0,
                        Vn2=110.0))  # fmt: skip
    ss.add("PV", dict(idx="G1", bus=1, Sn=GEN["Sn"], Vn=110.0, p0=P_GEN, q0=0.0,
                      v0=V_GEN, pmax=99, pmin=-99, qmax=99, qmin=-99))  # fmt: skip
    ss.add("Slack", dict(idx="G2", bus=2, Sn=S_BASE, Vn=110.0, p0=0.0, q0=0.0,
                         v0=V_INF, a0=0.0, pmax=99, pmin=-99, qmax=99, qmin=-99))  # fmt: skip
    ss.add("GENROU", dict(idx="M1", bus=1, gen="G1", Vn=110.0, fn=F_BASE, **GEN))
    ss.add("Fault", dict(idx="F1", bus=1, tf=T_FAULT, tc=T_CLEAR, xf=XF, rf=0.0))
    ss.setup()
    return ss


def run_andes(t_end=T_END, keep_every=KEEP_EVERY):
    """ANDES's run to t_end (s): a dict of the power flow (bus-1 voltage, generator
    P, Q on the system base), the time grid (s), the GENROU states on it (every
    keep_every-th step and the last) and the case's data."""
    ss = build()
    cls = type(ss)
    ss.store_switch_times = lambda models, eps=EVENT_EPS: cls.store_switch_times(
        ss, models, eps=EVENT_EPS
    )
    ss.PFlow.run()
    assert ss.PFlow.converged
    v1 = ss.Bus.v.v[0] * np.exp(1j * ss.Bus.a.v[0])
    q1 = float(ss.PV.q.v[0])
    ss.TDS.config.tf = t_end
    ss.TDS.config.tstep = STEP
    ss.TDS.config.fixt = 1
    ss.TDS.config.shrinkt = 0
    ss.TDS.config.no_tqdm = 1
    ss.TDS.config.criteria = 0
    ss.TDS.run()
    assert ss.exit_code == 0, ss.exit_code
    ts = ss.dae.ts
    t = np.asarray(ts.t)
    m = ss.GENROU
    cols = {n: np.asarray(ts.x[:, getattr(m, n).a[0]]) for n in
            ("delta", "omega", "e1q", "e1d", "e2d", "e2q")}  # fmt: skip
    keep = np.zeros(t.size, bool)
    keep[::keep_every] = True
    keep[-1] = True
    return dict(
        t=t[keep],
        **{n: c[keep] for n, c in cols.items()},
        vt=np.asarray(ts.y[:, ss.Bus.v.a[0]])[keep],
        v1=np.complex128(v1),
        p1=np.float64(P_GEN),
        q1=np.float64(q1),
        gen_names=np.array(list(GEN)),
        gen_values=np.array([float(GEN[k]) for k in GEN]),
        case=np.array(
            [
                S_BASE,
                F_BASE,
                P_GEN,
                V_GEN,
                V_INF,
                X_LINE,
                XF,
                T_FAULT,
                T_CLEAR,
                t_end,
                STEP,
                EVENT_EPS,
            ]  # fmt: skip
        ),
        andes_version=np.array(__import__("andes").__version__),
    )


def main() -> int:
    data = run_andes()
    np.savez_compressed(OUT, **data)
    print(f"wrote {OUT} ({data['t'].size} points)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
