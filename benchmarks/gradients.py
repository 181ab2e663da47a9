"""Value-and-grad of the tuning loss against its forward pass alone, peak memory, and
a finite-difference check of the gradient (issue 6).

The loss is the tuner's own (`tuning.train.make_loss` / `make_train_step` built by
`tuning.optimize.build` from tuning/configs/paper.toml (default) or --config: fixed-step Tsit5,
train.dt, train.t_end, soft input limits, mean + CVaR aggregate, the batch split over
all host devices), at the paper's gains (or beta1 = beta2 = -1 with --init stable)
mapped to the trainable raw parameters, on one batch of --batch faults.

Each pass runs in a fresh process of this script (forward, then value-and-grad), so
that its peak memory is its own: the peak RSS of the process after the first call
(compilation included), and the peak of a second, compiled call after freed memory
is returned to the system (malloc_trim, peak reset through /proc/self/clear_refs).
The baseline is this process after its imports (it compiles nothing). Times are the
best of --repeat calls after the warm-up (compiling) call. The gradient is checked
against central differences of the forward loss along --fd-params. Targets:
value-and-grad <= 5x the forward time, peak memory < 1 GB at batch 256. Prints a table
and writes benchmarks/results/gradients.json and gradients.png.

    python benchmarks/gradients.py [--batch 256] [--repeat 2] [--init paper|stable]
"""

from __future__ import annotations

import sys
from pathlib import Path

from smibjax import configure

# As an entry point: one host device per core (at least two), float64, equinox's
# checks as NaNs, before JAX loads (the cache: _common.enable_cache).
configure(min_devices=2, cache=False)
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))  # the tuning package

import argparse
import ctypes
import gc
import json
import re
import resource
import subprocess

import jax
import jax.numpy as jnp
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _common import DEFAULT_OUT, enable_cache, status, timed
from _results import write_results

from smibjax.cli.plotting import save_figure
from tuning.config import load_config
from tuning.problem import build
from tuning.train import draw_scenarios, make_loss, make_train_step

TARGET_RATIO, TARGET_MEMORY_MB = 5.0, 1000.0
CHILD_TAG = "GRADIENTS_CHILD "


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=2, help="timed calls (best kept)")
    ap.add_argument("--config", help="tuning TOML overriding configs/default.toml")
    ap.add_argument("--controller", choices=["aftsc", "asc"], default="aftsc")
    ap.add_argument(
        "--init",
        choices=["paper", "stable"],
        default="paper",
        help="paper gains (the tuner's start), or paper with beta1 = beta2 = -1",
    )
    ap.add_argument(
        "--t-end", type=float, help="override train.t_end (s) of the config"
    )
    ap.add_argument("--seed", type=int, default=0, help="seed of the fault batch")
    ap.add_argument(
        "--fd-params",
        nargs="+",
        default=["T2", "gamma2"],
        help="raw parameters to check by central differences",
    )
    ap.add_argument("--fd-eps", type=float, default=1e-6, help="step in raw units")
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--child", choices=["forward", "grad"], help=argparse.SUPPRESS)
    return ap.parse_args(argv)


def problem(args):
    """(setup, raw parameters, faults, description) of the benchmarked loss."""
    from tuning.config import CONFIG_DIR

    # Default: the paper config (the fixed 2 ms training path these figures measure);
    # --config tuning/configs/default.toml for the default (adaptive) path.
    cfg = load_config(args.config or CONFIG_DIR / "paper.toml")
    cfg["controller"] = args.controller
    cfg["batch"] = args.batch
    if args.t_end is not None:
        cfg["train"]["t_end"] = float(args.t_end)
    init, space, setup, dist, _ = build(cfg)
    values = dict(init)
    if args.init == "stable":
        values.update(beta1=-1.0, beta2=-1.0)
    raw = space.to_raw(values)
    for name in args.fd_params:
        if name not in raw:
            raise SystemExit(f"--fd-params: {name!r} is not trainable: {list(raw)}")
    faults = draw_scenarios(
        jax.random.PRNGKey(args.seed), args.batch, dist, setup.plant
    )
    desc = {
        "controller": args.controller,
        "init": args.init,
        "gains": values,
        "trainable": list(space.trainable),
        "train_t_end_s": setup.train_t_end,
        "train_dt_s": setup.train_solver.dt,
        "solver": "fixed-step Tsit5 (tuning.train.train_run)",
        "adaptation": setup.adaptation,
        "input_smoothing": setup.input_smoothing,
        "aggregate": f"mean + {setup.tail_weight} CVaR_{setup.cvar_q}",
        "config": args.config or "tuning/configs/default.toml",
    }
    return setup, raw, faults, desc


def _status_kb(field: str) -> float | None:
    try:
        text = Path("/proc/self/status").read_text()
        return int(re.search(rf"{field}:\s+(\d+) kB", text).group(1)) / 1024
    except (OSError, AttributeError):
        return None


def peak_rss_mb() -> float:
    """Peak resident set size (MB) of this process since it started or since the last
    `reset_peak()` (VmHWM on Linux, else ru_maxrss)."""
    hwm = _status_kb("VmHWM")
    return ru_maxrss_mb() if hwm is None else hwm


def ru_maxrss_mb() -> float:
    """getrusage's peak RSS (MB); on Linux at least the parent's RSS at the spawn."""
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return r / 2**20 if sys.platform == "darwin" else r / 2**10  # bytes / KiB


def trim_and_reset_peak() -> float | None:
    """Return freed heap memory to the system and reset the peak RSS to the current
    RSS (Linux); the current RSS (MB), or None where this is not possible."""
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return None
    return _status_kb("VmRSS")


def child(args) -> None:
    """One pass in this fresh process: time it, measure its memory, and (forward)
    the central differences or (grad) the gradient. One tagged JSON line."""
    setup, raw, faults, _ = problem(args)
    out = {}
    if args.child == "forward":
        loss_fn = make_loss(setup)

        def call():
            return jax.block_until_ready(loss_fn(raw, faults))

    else:
        step = make_train_step(setup)

        def call():
            return jax.block_until_ready(step(raw, faults))

    first, best, res = timed(call, args.repeat)
    out.update(first_call_s=first, seconds=best)
    out["peak_rss_mb"] = peak_rss_mb()
    out["ru_maxrss_mb"] = ru_maxrss_mb()
    del res
    before = trim_and_reset_peak()
    res = call()
    if before is not None:
        out["rss_before_compiled_call_mb"] = before
        out["peak_rss_compiled_call_mb"] = peak_rss_mb()
    if args.child == "forward":
        out["loss"] = float(res)
        fd = {}
        for name in args.fd_params:

            def shifted(s, name=name):
                return float(loss_fn({**raw, name: raw[name] + s}, faults))

            fd[name] = (shifted(args.fd_eps) - shifted(-args.fd_eps)) / (
                2 * args.fd_eps
            )
        out["finite_differences"] = fd
    else:
        loss, _, _, stable, grad, dropped = res
        out.update(
            loss=float(loss),
            grad={k: float(v) for k, v in grad.items()},
            grad_norm=float(
                jnp.sqrt(sum(jnp.sum(g**2) for g in jax.tree_util.tree_leaves(grad)))
            ),
            train_stable_fraction=float(np.mean(np.asarray(stable))),
            dropped_scenarios=int(dropped),
        )
    print(CHILD_TAG + json.dumps(out), flush=True)


def run_child(mode: str, argv) -> dict:
    p = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), *argv, "--child", mode],
        capture_output=True,
        text=True,
    )
    line = [s for s in p.stdout.splitlines() if s.startswith(CHILD_TAG)]
    if p.returncode != 0 or not line:
        raise SystemExit(f"the {mode} process failed:\n{p.stderr[-4000:]}")
    r = json.loads(line[-1][len(CHILD_TAG) :])
    print(
        f"  {mode}: {r['seconds']:.3f} s (first call {r['first_call_s']:.1f} s), "
        f"peak RSS {r['peak_rss_mb']:.0f} MB",
        flush=True,
    )
    return r


def memory_summary(base: float, fwd: dict, vg: dict) -> dict:
    """Peaks (MB), their excess over the baseline, and the target status."""
    mem = {"baseline_peak_rss": base}
    for k, r in (("forward", fwd), ("grad", vg)):
        mem[f"{k}_peak_rss"] = r["peak_rss_mb"]
        mem[f"{k}_over_baseline"] = r["peak_rss_mb"] - base
        if "peak_rss_compiled_call_mb" in r:
            mem[f"{k}_peak_rss_compiled_call"] = r["peak_rss_compiled_call_mb"]
            mem[f"{k}_rss_before_compiled_call"] = r["rss_before_compiled_call_mb"]
            mem[f"{k}_compiled_call_over_baseline"] = (
                r["peak_rss_compiled_call_mb"] - base
            )
    mem["target_peak"] = TARGET_MEMORY_MB
    mem["status"] = status(mem["grad_peak_rss"], TARGET_MEMORY_MB, False)
    if "grad_peak_rss_compiled_call" in mem:
        mem["status_compiled_call"] = status(
            mem["grad_peak_rss_compiled_call"], TARGET_MEMORY_MB, False
        )
    return mem


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_args(argv)
    cache = enable_cache()
    if args.child:
        child(args)
        return
    base = peak_rss_mb()  # this process: imports only, nothing compiled
    _, _, _, desc = problem(args)
    fwd = run_child("forward", argv)
    vg = run_child("grad", argv)

    ratio = vg["seconds"] / fwd["seconds"]
    fd = {}
    for name, num in fwd["finite_differences"].items():
        ad = vg["grad"][name]
        fd[name] = {
            "autodiff": ad,
            "finite_difference": num,
            "relative_error": abs(ad - num) / max(abs(num), 1e-300),
        }
    mem = memory_summary(base, fwd, vg)
    payload = {
        "loss": fwd["loss"],
        "loss_from_value_and_grad": vg["loss"],
        "train_stable_fraction": vg["train_stable_fraction"],
        "dropped_scenarios": vg["dropped_scenarios"],
        "grad_norm": vg["grad_norm"],
        "forward_s": fwd["seconds"],
        "forward_first_call_s": fwd["first_call_s"],
        "value_and_grad_s": vg["seconds"],
        "value_and_grad_first_call_s": vg["first_call_s"],
        "ratio": ratio,
        "ratio_target": TARGET_RATIO,
        "ratio_status": status(ratio, TARGET_RATIO, higher_is_better=False),
        "finite_differences": fd,
        "memory_mb": mem,
    }

    print()
    print(f"{'quantity':44} {'value':>10} {'target':>8} {'status':>7}")
    print(f"{'forward s (batch ' + str(args.batch) + ')':44} {fwd['seconds']:10.3f}")
    print(f"{'value-and-grad s':44} {vg['seconds']:10.3f}")
    print(
        f"{'value-and-grad / forward':44} {ratio:10.2f} {'<= 5':>8} "
        f"{payload['ratio_status']:>7}"
    )
    lines = [("baseline (imports only)", "baseline_peak_rss", None)]
    for k, label in (("forward", "forward"), ("grad", "value-and-grad")):
        lines += [
            (f"{label} process", f"{k}_peak_rss", k == "grad" and "status"),
            (f"  {label} over baseline", f"{k}_over_baseline", None),
            (
                f"  {label}, a compiled call",
                f"{k}_peak_rss_compiled_call",
                k == "grad" and "status_compiled_call",
            ),
        ]
    for label, key, st in lines:
        if key in mem:
            print(
                f"{'peak RSS MB, ' + label:44} {mem[key]:10.0f} "
                f"{'< 1000' if st else '':>8} {mem[st] if st else '':>7}"
            )
    print(
        f"loss {fwd['loss']:.6g} (value-and-grad: {vg['loss']:.6g}); training runs "
        f"stable: {vg['train_stable_fraction']:.2f}; gradient norm {vg['grad_norm']:.3g}"
    )
    if not np.isfinite(fwd["loss"]):
        print("warning: the loss is not finite (a horizon shorter than the faults?)")
    for name, r in fd.items():
        print(
            f"d loss / d raw {name}: autodiff {r['autodiff']:.6e}, central difference "
            f"{r['finite_difference']:.6e} (eps {args.fd_eps:g}): relative error "
            f"{r['relative_error']:.1e}"
        )

    config = {
        "batch": args.batch,
        "faults": f"draw_scenarios(PRNGKey({args.seed}), batch, config scenarios)",
        "problem": desc,
        "devices": len(jax.devices()),
        "repeat": args.repeat,
        "timing": "in a fresh process per pass: best of repeat calls after the "
        "warm-up (compiling) call",
        "value_and_grad": "tuning.train.make_train_step (per-scenario vmapped "
        "value_and_grad on each device, then the aggregate's chain rule)",
        "forward": "tuning.train.make_loss",
        "memory": "peak RSS (VmHWM) of the pass's fresh process after its calls "
        "(compilation included); compiled call: after malloc_trim and a peak reset "
        "(/proc/self/clear_refs), the peak of one more call; baseline: the parent "
        "process after its imports",
        "fd_eps_raw": args.fd_eps,
        "persistent_cache": cache,
    }
    path = write_results(args.out, "gradients", config, payload)

    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    bars = ax[0].bar(
        ["forward", "value-and-grad"],
        [fwd["seconds"], vg["seconds"]],
        color=["C0", "C1"],
    )
    ax[0].axhline(
        TARGET_RATIO * fwd["seconds"], color="C1", ls=":", label="5x forward (target)"
    )
    ax[0].bar_label(bars, fmt="%.3g s")
    ax[0].set_ylabel("seconds per batch")
    ax[0].set_title(
        f"tuning loss, batch {args.batch}, {len(jax.devices())} host devices"
    )
    ax[0].legend(fontsize=8)
    keys = ["baseline", "forward", "grad"]
    first = [mem[f"{k}_peak_rss"] for k in keys]
    second = [mem.get(f"{k}_peak_rss_compiled_call", np.nan) for k in keys]
    x = np.arange(3)
    b1 = ax[1].bar(x - 0.2, first, 0.4, color="C7", label="process (compiles)")
    b2 = ax[1].bar(x + 0.2, second, 0.4, color="C1", label="a compiled call")
    ax[1].bar_label(b1, fmt="%.0f", fontsize=7)
    ax[1].bar_label(b2, fmt="%.0f", fontsize=7)
    ax[1].axhline(TARGET_MEMORY_MB, color="C3", ls=":", label="1 GB (target)")
    ax[1].set_xticks(x)
    ax[1].set_xticklabels(["baseline", "forward", "value-and-grad"])
    ax[1].set_ylabel("peak RSS (MB)")
    ax[1].set_title("fresh process per pass")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, Path(args.out) / "gradients.png")
    print(f"wrote {path} and gradients.png")


if __name__ == "__main__":
    main()
