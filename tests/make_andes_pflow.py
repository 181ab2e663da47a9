"""Write ANDES's power flow of every built-in case to tests/data/andes_pflow.json.

Run from the repository root with ANDES installed (the `bench` environment):

    PYTHONPATH=src:. python tests/make_andes_pflow.py

For each raw file of `src/smibjax/grid/cases/` the JSON holds, in the raw file's order,
the bus numbers, voltage magnitudes (pu) and angles (deg), and the generators' bus,
P (MW) and Q (Mvar), solved by ANDES's Newton-Raphson power flow to a mismatch of
1e-10 pu, generator reactive limits not enforced. Tests that compare against ANDES read
this file, so they run without ANDES; tests/test_cases_data.py checks that the file
still matches ANDES when ANDES is installed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

CASES_DIR = Path(__file__).resolve().parents[1] / "src" / "smibjax" / "grid" / "cases"
OUT = Path(__file__).resolve().parent / "data" / "andes_pflow.json"
CASES = ("kundur", "ieee39", "smib", "ieee14", "wecc179", "npcc")
# nordic44.raw: ANDES 2.0's Newton does not converge (102 iterations); not stored
TOL = 1e-10


def andes_pflow(raw: Path) -> dict:
    """ANDES's power-flow solution of one raw file: buses (number, V pu, angle deg) and
    generators (bus, P MW, Q Mvar) in file order; raises RuntimeError if it does not
    converge."""
    import andes

    andes.config_logger(stream_level=40)
    ss = andes.load(str(raw), no_output=True, default_config=True)
    ss.PFlow.config.tol = TOL
    ss.PFlow.run()
    if not ss.PFlow.converged:
        raise RuntimeError(f"ANDES power flow of {raw.name} did not converge")
    mva = ss.config.mva
    gens = []
    for model in (ss.PV, ss.Slack):
        for i, idx in enumerate(model.idx.v):
            gens.append(
                (int(idx), int(model.bus.v[i]), model.p.v[i] * mva, model.q.v[i] * mva)
            )
    gens.sort()  # ANDES numbers the generator records in file order
    return {
        "bus": [int(b) for b in ss.Bus.idx.v],
        "V": [float(v) for v in ss.Bus.v.v],
        "angle_deg": [math.degrees(float(a)) for a in ss.Bus.a.v],
        "gen_bus": [g[1] for g in gens],
        "gen_P_MW": [float(g[2]) for g in gens],
        "gen_Q_Mvar": [float(g[3]) for g in gens],
        "iterations": int(ss.PFlow.niter),
    }


def main() -> None:
    import andes

    out = {
        "about": "ANDES power flow of src/smibjax/grid/cases/*.raw; made by "
        "tests/make_andes_pflow.py",
        "andes_version": andes.__version__,
        "tol_pu": TOL,
        "cases": {name: andes_pflow(CASES_DIR / f"{name}.raw") for name in CASES},
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
