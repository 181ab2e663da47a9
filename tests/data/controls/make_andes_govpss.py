"""Make andes_kundur_govpss.json: ANDES 2.0's IEEEG1, HYGOV, IEESGO, GAST, ST2CUT on
the Kundur two-area case (andes/cases/kundur), after the case's own event: line
Line_8 tripped at t = 2 s.

Generator 1's governor is an IEEEG1 and its stabilizer an ST2CUT reading speed
(ICS1 = 1) and electrical power (ICS2 = 3); generator 2's governor a HYGOV (with
r Tr = Sn/Sb, where ANDES's integral gain equals PSS/E's 1/(r Tr)); generator 3's
an IEESGO; generator 4's a GAST. ANDES applies some governor parameters on
the system base that PSS/E gives on the machine base (`machine_base`): each record
keeps the dyr values ANDES read ("dyr") and the PSS/E parameters of the model ANDES
ran ("params"), which smibjax reads. Each record holds one device's measured inputs
(as ANDES computes them) and its output, sampled at ANDES's fixed step (2 ms,
implicit trapezoid), so tests/test_grid_govpss.py drives smibjax's model with the
same inputs and compares the outputs without ANDES. ANDES keeps governor powers on
the system base: the outputs are stored on the machine base (divided by Sn/Sb).

Run from the repository root (ANDES installed):

    python tests/data/controls/make_andes_govpss.py
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
T_END, STEP, EVERY = 8.0, 0.002, 5  # s, s, keep every 5th step (10 ms)

# parameters in PSS/E CON order (machine base); ICONs first
IEEEG1 = dict(
    JBUS=0,
    M=0,
    K=20.0,
    T1=0.1,
    T2=0.05,
    T3=0.2,
    UO=1.0,
    UC=-1.0,
    PMAX=0.95,
    PMIN=0.0,
    T4=0.1,
    K1=0.3,
    K2=0.0,
    T5=7.0,
    K3=0.3,
    K4=0.0,
    T6=0.5,
    K5=0.4,
    K6=0.0,
    T7=0.05,
    K7=0.0,
    K8=0.0,
)
HYGOV = dict(
    R=0.06,
    r=0.45,
    Tr=20.0,
    Tf=0.05,
    Tg=0.2,
    VELM=0.2,
    GMAX=1.0,
    GMIN=0.0,
    TW=0.2,
    At=1.1,
    Dturb=0.05,
    qNL=0.1,
)
IEESGO = dict(
    T1=0.01,
    T2=0.0,
    T3=0.15,
    T4=0.3,
    T5=8.0,
    T6=0.4,
    K1=20.0,
    K2=0.7,
    K3=0.43,
    PMAX=1.0,
    PMIN=0.0,
)
ST2CUT = dict(
    ICS1=1,
    IB1=0,
    ICS2=3,
    IB2=0,
    K1=20.0,
    K2=-0.5,
    T1=0.02,
    T2=0.02,
    T3=10.0,
    T4=10.0,
    T5=0.05,
    T6=0.02,
    T7=3.0,
    T8=5.4,
    T9=0.0,
    T10=0.0,
    LSMAX=0.2,
    LSMIN=-0.2,
    VCU=0.0,
    VCL=0.0,
)
GAST = dict(
    R=0.05, T1=0.4, T2=0.1, T3=3.0, AT=1.0, KT=2.0, VMAX=1.0, VMIN=0.0, Dturb=0.1
)
ICONS = {"IEEEG1": ("JBUS", "M"), "ST2CUT": ("ICS1", "IB1", "ICS2", "IB2")}


def machine_base(model: str, p: dict, ratio: float) -> dict:
    """The PSS/E (machine-base) parameters of the model ANDES runs from the dyr
    values `p`, with ratio = Sn/Sb. ANDES converts a governor's power parameters to
    the system base, but not all of them consistently:
    - IEEEG1: the valve rates UO, UC stay as read, so on the machine base they are
      UO/ratio, UC/ratio;
    - IEESGO: the gain K1 (pu power/pu speed) stays as read: K1/ratio;
    - HYGOV: the water time constant multiplies a system-base flow (TW ratio on the
      machine base), Dturb is scaled although it multiplies a system-base gate
      (Dturb ratio), and the integral gain is 1 on the system base, PSS/E's 1/(r Tr)
      on the machine base only where r Tr = ratio (asserted)."""
    p = dict(p)
    if model == "IEEEG1":
        p["UO"], p["UC"] = p["UO"] / ratio, p["UC"] / ratio
    elif model == "IEESGO":
        p["K1"] = p["K1"] / ratio
    elif model == "HYGOV":
        assert abs(p["r"] * p["Tr"] - ratio) < 1e-12, (p["r"] * p["Tr"], ratio)
        p["TW"], p["Dturb"] = p["TW"] * ratio, p["Dturb"] * ratio
    return p


def _record(bus, model, p):
    ints = ICONS.get(model, ())
    vals = [str(int(p[k])) for k in ints] + [
        f"{v:.10g}" for k, v in p.items() if k not in ints
    ]
    return f"{bus} '{model}' 1 {' '.join(vals)} /\n"


def dyr_text() -> str:
    text = (CASES / "kundur_full.dyr").read_text()
    for bus in (1, 2, 3, 4):  # the generators' TGOV1 records are replaced
        text = re.sub(rf"\s*{bus} 'TGOV1'  1[^/]*/", "\n", text, count=1)
    text += _record(1, "IEEEG1", IEEEG1)
    text += _record(1, "ST2CUT", ST2CUT)
    text += _record(2, "HYGOV", HYGOV)
    text += _record(3, "IEESGO", IEESGO)
    text += _record(4, "GAST", GAST)
    return text


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        dyr = Path(tmp) / "kundur_govpss.dyr"
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
    ratio = [float(ss.GENROU.Sn.v[k]) / float(ss.config.mva) for k in range(4)]
    rnd = lambda a: [float(f"{v:.12g}") for v in np.asarray(a)]  # noqa: E731

    def gov(model, params):
        g = gen_of[getattr(ss, model).syn.v[0]]
        return {
            "dyr": params,
            "params": machine_base(model, params, ratio[g]),
            "omega": rnd(x(ss.GENROU.omega, g) - 1.0),
            "Pm": rnd(y(getattr(ss, model).pout) / ratio[g]),
        }

    out = {
        "source": "ANDES " + andes.__version__ + ", andes/cases/kundur (kundur.raw, "
        "kundur_full.dyr with the governors an IEEEG1, a HYGOV, an IEESGO and a "
        "GAST, and an ST2CUT on generator 1), line Line_8 tripped at t = 2 s; fixed "
        "step 2 ms, samples every 10 ms; made by "
        "tests/data/controls/make_andes_govpss.py",
        "t_event": 2.0,
        "t": rnd(t[keep]),
        "IEEEG1": gov("IEEEG1", IEEEG1),
        "HYGOV": gov("HYGOV", HYGOV),
        "IEESGO": gov("IEESGO", IEESGO),
        "GAST": gov("GAST", GAST),
        "ST2CUT": {
            "params": ST2CUT,
            "signal1": rnd(y(ss.ST2CUT.sig)),
            "signal2": rnd(y(ss.ST2CUT.sig2)),
            "Vs": rnd(y(ss.ST2CUT.vsout)),
        },
    }
    (HERE / "andes_kundur_govpss.json").write_text(json.dumps(out, indent=0) + "\n")


if __name__ == "__main__":
    main()
