"""How close a gain set's runs come to the model's domain boundary (issue 33): on the
held-out faults (seed 777, 1,024, paper.toml's distribution) near the SVC bus (fault
location < 0.35, where the mixed-sign gains' rare losses are), each run simulated
(paper plant, oracle adaptation, the validation's 10 s and solver defaults, 10 ms
samples) and, from fault inception on, the margin b_lim(stage) - B (pu): the SVC
susceptance's distance to where the stage's transfer reactance Xs - X1 X2 (B + Bf)
reaches the simulator's floor (`_closed_loop._b_max`; the nominal network's bound
too, as `healthy` tests it), with the peaks of B and Vt after inception. Prints one
line per gains file and writes margin.json here (a file's earlier entry replaced).

    python studies/paper_heldout/margin.py GAINS.json [...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from smibjax import configure

configure()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import smibjax as sj  # noqa: E402
from smibjax._closed_loop import _b_max  # noqa: E402
from smibjax._network import fault_stage, postfault_stage, prefault_stage  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the tuning package

from _cli import gains_args  # noqa: E402

from tuning.config import CONFIG_DIR, load_config  # noqa: E402
from tuning.problem import build, validation_scenarios  # noqa: E402

HERE = Path(__file__).resolve().parent
NEAR = 0.35


def margins(gains: Path, seed: int = 777, n: int = 1024) -> dict:
    """Per near-bus run: stable, min margin (pu) after inception, peak B, peak Vt."""
    cfg = load_config(CONFIG_DIR / "paper.toml")
    cfg["validation"].update(seed=seed, n=n)
    cfg["init"] = str(gains)
    problem = build(cfg)
    s = problem.setup
    ctrl = s.controller_of(problem.space.to_gains(problem.space.to_raw(problem.init)))
    faults, _ = validation_scenarios(cfg, problem)
    near = np.asarray(faults.lam) < NEAR
    f = jax.tree_util.tree_map(lambda a: jnp.asarray(a)[near], faults)
    plant = s.plant
    nominal = _b_max(prefault_stage(plant), plant)
    post = jnp.minimum(_b_max(postfault_stage(plant), plant), nominal)

    def one(fault):
        tr = sj.simulate(ctrl, fault, plant, save=sj.SaveOptions(t_end=s.val_t_end))
        t = tr.t
        during = jnp.minimum(
            _b_max(fault_stage(plant, fault.lam, fault.Xf), plant), nominal
        )
        lim = jnp.where(
            t < fault.t_fault,
            nominal,
            jnp.where(
                t < fault.t_clear, during, jnp.where(t < fault.t_reclose, post, nominal)
            ),
        )
        after = (t >= fault.t_fault) & (t <= tr.t_stop)
        m = jnp.min(jnp.where(after, lim - tr.B, jnp.inf))
        pb = jnp.max(jnp.where(after, tr.B, -jnp.inf))
        pv = jnp.max(jnp.where(after, tr.Vt, -jnp.inf))
        return tr.stable, m, pb, pv

    stable, m, pb, pv = (np.asarray(x) for x in jax.jit(jax.vmap(one))(f))
    return {
        "runs": int(near.sum()),
        "stable_fraction": float(stable.mean()),
        "margin_min": float(m.min()),
        "margin_p01": float(np.quantile(m, 0.01)),
        "margin_min_stable": float(m[stable].min()),
        "B_peak_max": float(pb.max()),
        "Vt_peak_max": float(pv.max()),
    }


def main() -> None:
    path = HERE / "margin.json"
    out = json.loads(path.read_text()) if path.exists() else {}
    for a in gains_args(sys.argv[1:], __doc__)[0]:
        r = out[Path(a).name] = margins(Path(a))
        print(
            f"{Path(a).name:28} {r['runs']} near-bus runs, "
            f"{100 * r['stable_fraction']:.1f}% stable; margin b_lim - B after "
            f"inception: min {r['margin_min']:.3f} pu (stable runs "
            f"{r['margin_min_stable']:.3f}), 1% quantile {r['margin_p01']:.3f}; peak B "
            f"{r['B_peak_max']:.2f} pu, peak Vt {r['Vt_peak_max']:.2f} pu",
            flush=True,
        )
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(out, indent=1) + "\n")
        tmp.replace(path)


if __name__ == "__main__":
    main()
