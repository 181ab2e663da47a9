"""Identity of results across a refactoring, within tolerance (not part of the suite).

Captures, with the code of the current checkout, what a refactoring must not change:
Monte Carlo chunk rows (three configurations: the paper's law with oracle adaptation;
ASC, realizable, projection and boundary layer, realistic limits, D drawn; avr-pss),
critical clearing times (two gain sets; avr-pss under the synchronism criterion), the
tuner's exact validation metrics and population scores, and a two-step tuning run
(gains and history). Then compares two captures within tolerance (issue 44): verdicts,
counts and names identical, times (settling, loss of synchronism, CCTs) within 1e-6 s,
angles and every other float within 1e-9 (relative above magnitude 1), the history's
wall-clock seconds aside. Bit-identity is no longer required, so that the solver may
change.

    git worktree add /tmp/before <old commit>
    (cd /tmp/before && PYTHONPATH=src:. python tests/identity.py capture /tmp/a)
    PYTHONPATH=src:. python tests/identity.py capture /tmp/b
    python tests/identity.py compare /tmp/a /tmp/b

Last result (2026-11-30, the core/edges restructuring of issue 17 against 2c89a96):
every array, the CCT JSON, the gains files and the history identical.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np


def capture(out: Path) -> None:
    from smibjax import configure

    configure(cache=False)
    import jax

    import smibjax as sj
    from smibjax._cct import critical_clearing_times
    from smibjax._montecarlo import MonteCarloSpec, compute_chunk
    from smibjax._scenarios import ScenarioDistribution
    from smibjax.controllers import make_controller
    from tuning.config import check_config, load_config
    from tuning.problem import build
    from tuning.search import make_population_score
    from tuning.train import draw_scenarios, make_validate

    out.mkdir(parents=True, exist_ok=True)
    limits = {"uf_min": -5.0, "uf_max": 5.0, "ur_min": -1.0, "ur_max": 1.0}
    dist_d = {**ScenarioDistribution().to_dict(), "D": [0.1, 0.4]}
    stable = {"beta1": -1.0, "beta2": -1.0}
    specs = {
        "aftsc": MonteCarloSpec(n=6, chunk=4, t_end=3.0, gains=stable),
        "asc_real": MonteCarloSpec(
            n=6,
            chunk=4,
            t_end=3.0,
            gains={**stable, "alpha": 1.0},
            adaptation="realizable",
            controller="asc",
            options={"projection": [[-1.0, 0.0], [0.0, 2.0]], "phi_layer": 0.01},
            plant=limits,
            dist=dist_d,
        ),
        "avrpss": MonteCarloSpec(
            n=6, chunk=4, t_end=3.0, controller="avr-pss", plant=limits, dist=dist_d
        ),
    }
    for name, spec in specs.items():
        for k in range(spec.n_chunks):
            np.savez(out / f"mc_{name}_{k}.npz", **compute_chunk(spec, k))
    g = sj.Gains.paper("aftsc", **stable)
    kw = dict(t_end=3.0, tol=0.01, scan_step=0.2)
    cct = critical_clearing_times(
        {"a": g, "b": sj.Gains.paper("aftsc", beta1=-2.0, beta2=-1.0)},
        fault_locations=(0.3, 0.7),
        **kw,
    )
    cct_avr = critical_clearing_times(
        {"n": make_controller("avr-pss", {})},
        plant=sj.Plant.preset("realistic"),
        fault_locations=(0.5,),
        criterion="synchronism",
        **kw,
    )
    (out / "cct.json").write_text(
        json.dumps({"cct": cct.to_dict(), "cct_avr": cct_avr.to_dict()})
    )
    cfg = load_config(None)
    cfg.update(steps=2, batch=2, seed=3)
    cfg["validation"].update(n=4, every=2, t_end=4.0)
    cfg["train"].update(t_end=4.0)
    check_config(cfg)
    problem = build(cfg)
    sc = draw_scenarios(jax.random.PRNGKey(5), 4, problem.dist, problem.setup.plant)
    m = make_validate(problem.setup)(g, sc)
    np.savez(out / "validate.npz", **{k: np.asarray(v) for k, v in m._asdict().items()})
    score = make_population_score(problem.setup)
    cost, st = score([g, sj.Gains.paper("aftsc", beta1=-2.0, beta2=-1.0)], sc)
    np.savez(out / "search.npz", cost=cost, stable=st)
    tiny = out / "tiny.toml"
    tiny.write_text(
        "steps = 2\nbatch = 2\n[validation]\nn = 4\nevery = 2\nt_end = 4.0\n"
        "[train]\nt_end = 4.0\n"
    )
    subprocess.run(
        [sys.executable, "-m", "tuning.optimize", "--config", str(tiny), "--out"]
        + [str(out / "tune"), "--quiet"],
        check=True,
    )


ANGLE_TOL = 1e-9  # rad, and every other float (relative to max(1, |x|))
TIME_TOL = 1e-6  # s: settling times, loss-of-synchronism times, CCTs
TIME_KEYS = ("settl", "t_", "time", "cct")


def _tol(key: str) -> float:
    """The tolerance of one stored quantity, from its name: times (s) 1e-6, the rest
    (angles in rad, speeds, losses, gains) 1e-9, relative above magnitude 1."""
    k = key.lower()
    return TIME_TOL if any(t in k for t in TIME_KEYS) else ANGLE_TOL


def _close(x, y, tol: float) -> bool:
    """Same shape; booleans, integers and strings (verdicts, counts, names) equal;
    floats within tol * max(1, |x|), with infinities and NaNs in the same places."""
    x, y = np.asarray(x), np.asarray(y)
    if x.shape != y.shape:
        return False
    if not (np.issubdtype(x.dtype, np.floating) or np.issubdtype(y.dtype, np.floating)):
        return bool(np.array_equal(x, y))
    x, y = x.astype(float), y.astype(float)
    same_special = np.array_equal(np.isnan(x), np.isnan(y)) and np.array_equal(
        np.where(np.isinf(x), x, 0.0), np.where(np.isinf(y), y, 0.0)
    )
    ok = np.isfinite(x) & np.isfinite(y)
    xs, ys = np.where(ok, x, 0.0), np.where(ok, y, 0.0)
    err = np.abs(xs - ys) / np.maximum(1.0, np.abs(xs))
    return bool(same_special and np.all(err <= tol))


def _json_close(x, y, key: str = "") -> bool:
    """Two JSON values alike: the same keys and strings, numbers within `_tol(key)`."""
    if isinstance(x, dict) and isinstance(y, dict):
        return x.keys() == y.keys() and all(
            _json_close(x[k], y[k], f"{key}.{k}") for k in x
        )
    if isinstance(x, list) and isinstance(y, list):
        return len(x) == len(y) and all(
            _json_close(u, v, key) for u, v in zip(x, y, strict=True)
        )
    if isinstance(x, bool) or isinstance(y, bool) or isinstance(x, str):
        return x == y
    if isinstance(x, int | float) and isinstance(y, int | float):
        return _close(float(x), float(y), _tol(key))
    return x == y


def _number(v: str):
    try:
        return float(v)
    except ValueError:
        return v


def compare(a: Path, b: Path) -> int:
    """Compare two captures within tolerance (issue 44): verdicts (booleans, counts,
    strings) identical, times within 1e-6 s, angles and every other float within
    1e-9 (relative above 1). Prints "identical within tolerance" or the names that
    differ; returns the exit status."""
    diffs = []
    for f in sorted(a.glob("*.npz")):
        x, y = np.load(f), np.load(b / f.name)
        if sorted(x.files) != sorted(y.files):
            diffs.append(f"{f.name}: keys")
            continue
        diffs += [f"{f.name}:{k}" for k in x.files if not _close(x[k], y[k], _tol(k))]
    if not _json_close(
        json.loads((a / "cct.json").read_text()),
        json.loads((b / "cct.json").read_text()),
    ):
        diffs.append("cct.json")
    for name in ("gains.json", "gains_last.json"):
        ja = json.loads((a / "tune" / name).read_text())
        jb = json.loads((b / "tune" / name).read_text())
        if not _json_close(ja, jb):
            diffs.append(name)

    def rows(p):
        return [
            {k: _number(v) for k, v in r.items() if k != "seconds"}
            for r in csv.DictReader((p / "tune" / "history.csv").open())
        ]

    if not _json_close(rows(a), rows(b)):
        diffs.append("history.csv")
    print(
        "identical within tolerance" if not diffs else "DIFFERENT: " + ", ".join(diffs)
    )
    return 1 if diffs else 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["capture"]:
        capture(Path(sys.argv[2]))
    elif sys.argv[1:2] == ["compare"]:
        sys.exit(compare(Path(sys.argv[2]), Path(sys.argv[3])))
    else:
        sys.exit(__doc__)
