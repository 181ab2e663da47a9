"""Make andes_exciters.json: ANDES 2.0's ESST3A and ESDC2A on its IEEE 14-bus case
(andes/cases/ieee14: ieee14.raw, ieee14.dyr), after the case's own event (line
Line_1 tripped at t = 1.0 s and reclosed at 1.1 s): generator 6 keeps its ESST3A
(the file's data, TA = 0), generator 8's ESST3A is replaced by an ESDC2A (WECC
179 data with KE = 1, VRMAX = 5 and TR = 0: where ANDES and PSS/E agree; ANDES
2.0's ESDC2A computes its sensing lag but feeds the unfiltered voltage to the
error, so TR = 0 makes the two the same model). Both machines are on a 100 MVA
base, the system's: ANDES hands its ESST3A the terminal current on the system
base, smibjax on the machine base (PSS/E), the same numbers here. (Not on Kundur:
on its 900 MVA machines ANDES 2.0's ESST3A fails its own initialization check.
A second run on Kundur, its own event (line Line_8 tripped at t = 2 s), gives
generator 4 an IEEET1 in place of its EXDC2: record "kundur".
No IEEEVC: ANDES 2.0 fails to initialize an exciter behind one, its own
ieee14_ieeevc case included; smibjax's IEEEVC is checked against its closed form.)

Each record holds the device's measured inputs (terminal voltage magnitude, the
machine's d/q voltage and current, the field current XadIfd) and its output,
sampled at ANDES's fixed step (2 ms, implicit trapezoid) every 10 ms (every
2 ms from 0.99 s to 1.3 s), so
tests/test_grid_exciters.py drives smibjax's model with the same inputs and
compares the outputs without ANDES.

Run from the repository root (ANDES installed):

    python tests/data/controls/make_andes_exciters.py
"""

from __future__ import annotations

import json
import re
import tempfile
from pathlib import Path

import andes
import numpy as np

HERE = Path(__file__).resolve().parent
CASES = Path(andes.get_case("ieee14/ieee14.raw")).parent
T_END, STEP, EVERY = 5.0, 0.002, 5  # s, s, keep every 5th step (10 ms)
T_TRIP = 1.0  # s, the case's Toggle of Line_1 (reclosed at 1.1 s)

ESDC2A = dict(
    TR=0.0,
    KA=50.0,
    TA=0.05,
    TB=0.02,
    TC=0.0,
    VRMAX=5.0,
    VRMIN=-3.0,
    KE=1.0,
    TE=0.512,
    KF=0.07,
    TF1=1.3,
    SWITCH=0.0,
    E1=3.9825,
    SE1=0.5,
    E2=5.31,
    SE2=1.049,
)


# Kundur (a second run): generator 4's EXDC2 becomes an IEEET1 (the EXDC2's data
# without its lead-lag). (No ESDC1A: ANDES 2.0's ESDC1A raises a TypeError in its
# own initialization, in do_adjust_upper; smibjax's IEEET1 runs through its ESDC1A.)
KUNDUR = Path(andes.get_case("kundur/kundur.raw")).parent
T_END_K, T_TRIP_K = 6.0, 2.0  # s; the case's Toggle of Line_8
IEEET1 = dict(
    TR=0.02,
    KA=20.0,
    TA=0.02,
    VRMAX=5.2,
    VRMIN=-4.16,
    KE=1.0,
    TE=0.83,
    KF=0.0754,
    TF=1.246,
    SWITCH=0.0,
    E1=1.5,
    SE1=0.03,
    E2=2.5,
    SE2=0.2,
)


def _record(bus, model, cons):
    return f"{bus} '{model}' 1 " + " ".join(f"{c:.10g}" for c in cons) + " /\n"


def dyr_text() -> str:
    text = (CASES / "ieee14.dyr").read_text()
    # generator 8's ESST3A record out, an ESDC2A in
    text, n = re.subn(r"\n\s*8 'ESST3A' 1[^/]*/", "\n", text, count=1)
    assert n == 1
    # (the file ends without a newline: text after a "/" would be a comment)
    return text.rstrip() + "\n" + _record(8, "ESDC2A", list(ESDC2A.values()))


def kundur_dyr_text() -> str:
    text = (KUNDUR / "kundur_full.dyr").read_text()
    text, n = re.subn(r"\s*4 'EXDC2 ' 1[^/]*/", "\n", text, count=1)
    assert n == 1  # generator 4's EXDC2 out, an IEEET1 in
    return text.rstrip() + "\n" + _record(4, "IEEET1", list(IEEET1.values()))


def _run(raw, dyr_text, t_end):
    with tempfile.TemporaryDirectory() as tmp:
        dyr = Path(tmp) / "exc.dyr"
        dyr.write_text(dyr_text)
        ss = andes.load(
            str(raw),
            addfile=str(dyr),
            setup=False,
            no_output=True,
            default_config=True,
        )
        ss.setup()
        ss.PFlow.run()
        ss.TDS.config.tf = t_end
        ss.TDS.config.tstep = STEP
        ss.TDS.config.fixt = 1
        ss.TDS.config.shrinkt = 0
        ss.TDS.config.no_tqdm = 1
        ss.TDS.run()
    assert ss.TDS.initialized
    return ss


def _sampler(ss, t_trip):
    """(t, y): the kept sample times and a function of a variable (and a device
    index) giving its samples."""
    ts = ss.dae.ts
    t = np.asarray(ts.t)
    # every 5th step, and every step over the 0.3 s after the trip (the inputs
    # move fastest there; the test interpolates them linearly between samples)
    dense = (t >= t_trip - 0.01) & (t <= t_trip + 0.3)
    keep = np.unique(
        np.r_[np.arange(0, t.size, EVERY), np.flatnonzero(dense), t.size - 1]
    )
    rnd = lambda a: [float(f"{v:.12g}") for v in np.asarray(a)]  # noqa: E731

    def y(var, i=0):
        """A variable's samples: states from ts.x, algebraic variables from ts.y."""
        arr = ts.x if var.v_code == "x" else ts.y
        return rnd(np.asarray(arr[:, var.a[i]])[keep])

    return rnd(t[keep]), y


def main() -> None:
    ss = _run(CASES / "ieee14.raw", dyr_text(), T_END)
    t, y = _sampler(ss, T_TRIP)
    gen_of = {g: k for k, g in enumerate(ss.GENROU.idx.v)}
    bus_of = dict(zip(ss.GENROU.idx.v, ss.GENROU.bus.v, strict=True))
    e3 = list(ss.ESST3A.syn.v).index(
        [g for g in ss.ESST3A.syn.v if int(bus_of[g]) == 6][0]
    )
    g1 = gen_of[ss.ESST3A.syn.v[e3]]
    g2 = gen_of[ss.ESDC2A.syn.v[0]]
    assert float(ss.GENROU.Sn.v[g1]) == float(ss.GENROU.Sn.v[g2]) == ss.config.mva

    def machine(g, ss=ss, y=y):
        m = ss.GENROU
        return {
            "Vt": y(m.v, g),
            "vd": y(m.vd, g),
            "vq": y(m.vq, g),
            "Id": y(m.Id, g),
            "Iq": y(m.Iq, g),
            "XadIfd": y(m.XadIfd, g),
            "Pe": y(m.Pe, g),
        }

    out = {
        "source": "ANDES " + andes.__version__ + ", andes/cases/ieee14 (ieee14.raw, "
        "ieee14.dyr with generator 8's ESST3A replaced by an ESDC2A), line Line_1 "
        "tripped at t = 1.0 s, reclosed at 1.1 s; fixed step 2 ms, samples every 10 "
        "ms (2 ms from 0.99 s to 1.3 s); made by tests/data/controls/make_andes_exciters.py",
        "t_events": [1.0, 1.1],
        "t": t,
        "ESST3A": {
            "params": {
                k: float(getattr(ss.ESST3A, k).v[e3])
                for k in (
                    "TR VIMAX VIMIN KM TC TB KA TA VRMAX VRMIN KG KP KI VBMAX KC XL "
                    "VGMAX THETAP TM VMMAX VMMIN"
                ).split()
            },
            **machine(g1),
            "Efd": y(ss.ESST3A.vout, e3),
            "vref0": float(ss.ESST3A.vref0.v[e3]),
        },
        "ESDC2A": {
            "params": ESDC2A,
            **machine(g2),
            "Efd": y(ss.ESDC2A.vout),
            "vref0": float(ss.ESDC2A.vref0.v[0]),
        },
    }
    ssk = _run(KUNDUR / "kundur.raw", kundur_dyr_text(), T_END_K)
    tk, yk = _sampler(ssk, T_TRIP_K)
    genk = {g: k for k, g in enumerate(ssk.GENROU.idx.v)}
    out["kundur"] = {
        "source": "ANDES " + andes.__version__ + ", andes/cases/kundur (kundur.raw, "
        "kundur_full.dyr with generator 4's EXDC2 an IEEET1), line Line_8 tripped "
        "at t = 2 s; fixed step 2 ms, samples every 10 ms (2 ms from 1.99 s to 2.3 s)",
        "t_events": [T_TRIP_K],
        "t": tk,
    }
    for name, data in (("IEEET1", IEEET1),):
        model = getattr(ssk, name)
        g = genk[model.syn.v[0]]
        out["kundur"][name] = {
            "params": data,
            "Vt": yk(ssk.GENROU.v, g),
            "Efd": yk(model.vout),
            "vref0": float(model.vref0.v[0]),
        }
    (HERE / "andes_exciters.json").write_text(json.dumps(out, indent=0) + "\n")


if __name__ == "__main__":
    main()
