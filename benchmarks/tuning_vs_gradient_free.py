"""Gradient (Adam through the differentiable simulator) against gradient-free
(SciPy Nelder-Mead) tuning of the same loss, on the same fixed batch of fault
scenarios, from the paper's gains, with the same budget of scenario simulations.

Prints a table, writes benchmarks/results/tuning_vs_gradient_free.json and
tuning_vs_gradient_free.png (loss against wall time and against simulations).

    python benchmarks/tuning_vs_gradient_free.py [--batch 32] [--budget 6400]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from smibjax.parallel import use_host_devices  # noqa: E402

use_host_devices()  # one host device per core, before JAX starts its CPU backend

import jax  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
import optax  # noqa: E402
from scipy.optimize import minimize  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from _results import write_results  # noqa: E402

from smibjax.scenarios import sample_faults  # noqa: E402
from tuning.config import load_config  # noqa: E402
from tuning.optimize import build  # noqa: E402
from tuning.train import make_loss, make_train_step  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--budget", type=int, default=6400, help="scenario simulations")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    cfg = load_config()
    init, space, setup, dist, _ = build(cfg)
    step = make_train_step(setup)
    faults = sample_faults(jax.random.PRNGKey(42), args.batch, dist)
    raw0 = space.to_raw(init)
    names = list(raw0)
    step(raw0, faults)  # compile (forward and backward)

    # --- gradient: Adam, one batch evaluation (value and gradient) per step
    opt = optax.chain(
        optax.zero_nans(),
        optax.clip_by_global_norm(1.0),
        optax.adam(float(cfg["optimizer"]["learning_rate"])),
    )
    raw, state = raw0, opt.init(raw0)
    grad_curve, t0, sims = [], time.perf_counter(), 0
    while sims < args.budget:
        loss, _, _, _, g, _ = step(raw, faults)
        sims += args.batch
        grad_curve.append((sims, time.perf_counter() - t0, float(loss)))
        upd, state = opt.update(g, state, raw)
        raw = optax.apply_updates(raw, upd)

    # --- gradient-free: Nelder-Mead on the same loss (forward only)
    loss_fn = make_loss(setup)
    loss_fn(raw0, faults)  # compile the forward pass
    nm_curve, t0, count = [], time.perf_counter(), [0]

    def objective(x):
        r = {k: jax.numpy.asarray(v) for k, v in zip(names, x, strict=True)}
        loss = float(loss_fn(r, faults))
        count[0] += args.batch
        nm_curve.append((count[0], time.perf_counter() - t0, loss))
        return loss if np.isfinite(loss) else 1e6

    x0 = np.array([float(raw0[k]) for k in names])
    minimize(
        objective,
        x0,
        method="Nelder-Mead",
        options={
            "maxfev": args.budget // args.batch,
            "xatol": 1e-6,
            "fatol": 1e-6,
            "initial_simplex": x0
            + 0.5 * np.vstack([np.zeros(len(x0)), np.eye(len(x0))]),
        },
    )
    best_nm = np.minimum.accumulate([c[2] for c in nm_curve])
    best_gd = np.minimum.accumulate([c[2] for c in grad_curve])
    rows = {
        "adam": {
            "final_best_loss": float(best_gd[-1]),
            "evaluations": len(grad_curve),
            "wall_s": grad_curve[-1][1],
        },
        "nelder_mead": {
            "final_best_loss": float(best_nm[-1]),
            "evaluations": len(nm_curve),
            "wall_s": nm_curve[-1][1],
        },
    }
    print(f"{'method':12} {'best loss':>10} {'evals':>6} {'wall s':>8}")
    for k, r in rows.items():
        print(
            f"{k:12} {r['final_best_loss']:10.4f} {r['evaluations']:6d} "
            f"{r['wall_s']:8.1f}"
        )
    write_results(
        args.out,
        "tuning_vs_gradient_free",
        {
            "batch": args.batch,
            "budget_simulations": args.budget,
            "note": "Adam evaluations include the reverse pass",
        },
        {"rows": rows, "adam_curve": grad_curve, "nm_curve": nm_curve},
    )
    out = Path(args.out)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for curve, best, label in (
        (grad_curve, best_gd, "Adam (gradients)"),
        (nm_curve, best_nm, "Nelder-Mead"),
    ):
        ax[0].plot([c[1] for c in curve], best, label=label)
        ax[1].plot([c[0] for c in curve], best, label=label)
    ax[0].set_xlabel("wall time (s)")
    ax[1].set_xlabel("scenario simulations")
    for a in ax:
        a.set_ylabel("best loss so far")
        a.set_yscale("log")
        a.grid(alpha=0.3)
        a.legend()
    fig.suptitle(f"Tuning from the paper's gains, fixed batch of {args.batch} faults")
    fig.tight_layout()
    fig.savefig(out / "tuning_vs_gradient_free.png", dpi=110)


if __name__ == "__main__":
    main()
