"""Make andes_kundur.json: ANDES 2.0's IEEEX1, TGOV1 and IEEEST on the Kundur
two-area case (andes/cases/kundur), with generator 1's exciter an IEEEX1 with
saturation and two IEEEST stabilizers (speed on generator 1, electrical power on
generator 3), after the case's own event: line Line_8 tripped at t = 2 s.

Each record holds one device's measured inputs and its output, sampled at ANDES's
fixed step (2 ms, implicit trapezoid), so tests/test_grid_controls.py can drive
smibjax's model with the same inputs and compare the outputs without ANDES.

Run from the repository root (ANDES installed):

    python tests/data/controls/make_andes_fixture.py
"""

from __future__ import annotations

import json
import re
import tempfile
from pathlib import Path

import andes
import numpy as np

HERE = Path(__file__).resolve().parent
CASES = Path(andes.get_case("kundur/kundur.raw")).parent
T_END, STEP, EVERY = 6.0, 0.002, 5  # s, s, keep every 5th step (10 ms)

IEEEX1 = dict(
    TR=0.02,
    KA=20.0,
    TA=0.02,
    TB=1.0,
    TC=1.0,
    VRMAX=5.2,
    VRMIN=-4.16,
    KE=1.0,
    TE=0.83,
    KF=0.0754,
    TF1=1.246,
    SWITCH=0.0,
    E1=1.5,
    SE1=0.03,
    E2=2.5,
    SE2=0.2,
)
IEEEST_W = dict(
    ICS=1,
    IB=0,
    A1=0.05,
    A2=0.001,
    A3=0.03,
    A4=0.0004,
    A5=0.02,
    A6=0.0002,
    T1=0.15,
    T2=0.05,
    T3=0.2,
    T4=0.04,
    T5=1.0,
    T6=1.0,
    KS=10.0,
    LSMAX=0.1,
    LSMIN=-0.1,
    VCU=0.0,
    VCL=0.0,
)
IEEEST_P = dict(
    ICS=3,
    IB=0,
    A1=0.0,
    A2=0.0,
    A3=0.0,
    A4=0.0,
    A5=0.0,
    A6=0.0,
    T1=0.0,
    T2=0.0,
    T3=0.0,
    T4=0.75,
    T5=1.0,
    T6=4.2,
    KS=-2.0,
    LSMAX=0.1,
    LSMIN=-0.1,
    VCU=0.0,
    VCL=0.0,
)
X1_ORDER = [
    "TR",
    "KA",
    "TA",
    "TB",
    "TC",
    "VRMAX",
    "VRMIN",
    "KE",
    "TE",
    "KF",
    "TF1",
    "SWITCH",
    "E1",
    "SE1",
    "E2",
    "SE2",
]
ST_ORDER = [
    "A1",
    "A2",
    "A3",
    "A4",
    "A5",
    "A6",
    "T1",
    "T2",
    "T3",
    "T4",
    "T5",
    "T6",
    "KS",
    "LSMAX",
    "LSMIN",
    "VCU",
    "VCL",
]


def _record(bus, model, ints, cons):
    vals = (
        " ".join(str(int(i)) for i in ints) + " " + " ".join(f"{c:.10g}" for c in cons)
    )
    return f"{bus} '{model}' 1 {vals} /\n"


def dyr_text() -> str:
    text = (CASES / "kundur_full.dyr").read_text()
    # generator 1's EXDC2 record becomes an IEEEX1 with the data above
    text = re.sub(r"\s*1 'EXDC2 ' 1[^/]*/", "\n", text, count=1)
    text += _record(1, "IEEEX1", [], [IEEEX1[k] for k in X1_ORDER])
    text += _record(1, "IEEEST", [IEEEST_W["ICS"], 0], [IEEEST_W[k] for k in ST_ORDER])
    text += _record(3, "IEEEST", [IEEEST_P["ICS"], 0], [IEEEST_P[k] for k in ST_ORDER])
    return text


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        dyr = Path(tmp) / "kundur_x1.dyr"
        dyr.write_text(dyr_text())
        ss = andes.load(
            str(CASES / "kundur.raw"),
            addfile=str(dyr),
            setup=False,
            no_output=True,
            default_config=True,
        )
        ss.setup()
        ss.PFlow.run()
        ss.TDS.config.tf = T_END
        ss.TDS.config.tstep = STEP
        ss.TDS.config.fixt = 1
        ss.TDS.config.shrinkt = 0
        ss.TDS.config.no_tqdm = 1
        ss.TDS.run()
    ts = ss.dae.ts
    t = np.asarray(ts.t)
    keep = np.unique(np.r_[np.arange(0, t.size, EVERY), t.size - 1])

    def y(var, i=0):
        return np.asarray(ts.y[:, var.a[i]])[keep]

    def x(var, i=0):
        return np.asarray(ts.x[:, var.a[i]])[keep]

    gen_of = {g: k for k, g in enumerate(ss.GENROU.idx.v)}
    tg = [i for i, s in enumerate(ss.TGOV1.syn.v) if gen_of[s] == 0][0]
    st = {int(m): k for k, m in enumerate(ss.IEEEST.MODE.v)}
    ratio = float(ss.GENROU.Sn.v[0]) / float(ss.config.mva)
    base = {"R": ratio, "VMAX": 1 / ratio, "VMIN": 1 / ratio, "Dt": 1 / ratio}
    rnd = lambda a: [float(f"{v:.12g}") for v in np.asarray(a)]  # noqa: E731
    out = {
        "source": "ANDES " + andes.__version__ + ", andes/cases/kundur (kundur.raw, "
        "kundur_full.dyr with generator 1's exciter an IEEEX1 and two IEEEST), line "
        "Line_8 tripped at t = 2 s; fixed step 2 ms, samples every 10 ms; made by "
        "tests/data/controls/make_andes_fixture.py",
        "t_event": 2.0,
        "t": rnd(t[keep]),
        "IEEEX1": {
            "params": IEEEX1,
            "Vt": rnd(y(ss.IEEEX1.v)),
            "Vs": rnd(y(ss.IEEEST.vsout, st[1])),
            "Efd": rnd(y(ss.IEEEX1.vout)),
            "vref0": float(ss.IEEEX1.vref0.v[0]),
        },
        # ANDES keeps TGOV1's R, VMAX, VMIN, Dt and its output on the system base:
        # back to the machine base (smibjax's), with Sn/Sb of generator 1
        "TGOV1": {
            "params": {
                k: float(getattr(ss.TGOV1, k).v[tg]) * base.get(k, 1.0)
                for k in ("R", "T1", "VMAX", "VMIN", "T2", "T3", "Dt")
            },
            "omega": rnd(x(ss.GENROU.omega, 0) - 1.0),
            "Pm": rnd(y(ss.TGOV1.pout, tg) / ratio),
        },
        "IEEEST_omega": {
            "params": IEEEST_W,
            "signal": rnd(y(ss.IEEEST.sig, st[1])),
            "Vs": rnd(y(ss.IEEEST.vsout, st[1])),
        },
        "IEEEST_Pe": {
            "params": IEEEST_P,
            "signal": rnd(y(ss.IEEEST.sig, st[3])),
            "Vs": rnd(y(ss.IEEEST.vsout, st[3])),
        },
    }
    (HERE / "andes_kundur.json").write_text(json.dumps(out, indent=0) + "\n")


if __name__ == "__main__":
    main()
