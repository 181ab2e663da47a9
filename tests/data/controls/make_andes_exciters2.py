"""Make andes_exciters2.json: ANDES 2.0's ESST4B on its IEEE 14-bus case
(andes/cases/ieee14: ieee14.raw, ieee14.dyr), after the case's own event (line
Line_1 tripped at t = 1.0 s and reclosed at 1.1 s). Generator 6's ESST3A is
replaced by an ESST4B with the data of the first ESST4B record of ACTIVSg2000's
dyr file (NREL-Sienna/PowerSystemsTestData, psse_dyr/ACTIVSg2000_dynamics.dyr,
bus 1048: PI outer loop, proportional inner loop, KG = 0). The generator has no
stabilizer (ANDES 2.0's ESST4B has no stabilizer input) and is on the system's
100 MVA base (ANDES hands ESST4B the terminal current on the system base, smibjax
on the machine base: the same numbers here). (No EXAC2: ANDES 2.0's EXAC2 fails
its own initialization on this case, a residual of 15.6 in its exciter equation;
its Vref formula has KL where KH belongs.)

Each record holds the device's measured inputs (terminal voltage magnitude, the
machine's d/q voltage and current, the field current XadIfd) and its output,
sampled at ANDES's fixed step (2 ms, implicit trapezoid) every 10 ms (every 2 ms
from 0.99 s to 1.3 s), so tests/test_grid_exciters2.py drives smibjax's model
with the same inputs and compares the outputs without ANDES.

Run from the repository root (ANDES installed):

    python tests/data/controls/make_andes_exciters2.py
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import andes

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from make_andes_exciters import CASES, T_END, T_TRIP, _record, _run, _sampler  # noqa: E402

ESST4B = dict(
    TR=0.0,
    KPR=3.9436,
    KIR=3.9436,
    VRMAX=1.0,
    VRMIN=-1.0,
    TA=0.0,
    KPM=1.0,
    KIM=0.0,
    VMMAX=1.0,
    VMMIN=-1.0,
    KG=0.0,
    KP=6.8885,
    KI=0.0,
    VBMAX=8.7286,
    KC=0.08,
    XL=0.0,
    THETAP=0.0,
)


def dyr_text() -> str:
    text = (CASES / "ieee14.dyr").read_text()
    text, n = re.subn(r"\n\s*6 'ESST3A' 1[^/]*/", "\n", text, count=1)
    assert n == 1
    return text.rstrip() + "\n" + _record(6, "ESST4B", list(ESST4B.values()))


def main() -> None:
    ss = _run(CASES / "ieee14.raw", dyr_text(), T_END)
    t, y = _sampler(ss, T_TRIP)
    gen_of = {g: k for k, g in enumerate(ss.GENROU.idx.v)}

    def machine(g, ss=ss, y=y):
        m = ss.GENROU
        assert float(m.Sn.v[g]) == ss.config.mva
        return {
            "Vt": y(m.v, g),
            "vd": y(m.vd, g),
            "vq": y(m.vq, g),
            "Id": y(m.Id, g),
            "Iq": y(m.Iq, g),
            "XadIfd": y(m.XadIfd, g),
        }

    out = {
        "source": "ANDES " + andes.__version__ + ", andes/cases/ieee14 (ieee14.raw, "
        "ieee14.dyr with generator 6's ESST3A an ESST4B, ACTIVSg2000's data), "
        "line Line_1 tripped at t = 1.0 s, reclosed at 1.1 s; "
        "fixed step 2 ms, samples every 10 ms (2 ms from 0.99 s to 1.3 s); made by "
        "tests/data/controls/make_andes_exciters2.py",
        "t_events": [1.0, 1.1],
        "t": t,
    }
    for name, data in (("ESST4B", ESST4B),):
        model = getattr(ss, name)
        g = gen_of[model.syn.v[0]]
        out[name] = {
            "params": data,
            **machine(g),
            "Efd": y(model.vout),
            "vref0": float(model.vref0.v[0]),
        }
    (HERE / "andes_exciters2.json").write_text(json.dumps(out, indent=0) + "\n")


if __name__ == "__main__":
    main()
