"""The settled tail: the same Monte Carlo with the exact finite-time law and with
boundary layers of the evolution law (`phi_layer` = W, README "Controllers"), through
`compute_chunk`, and the effect of each W on every Monte Carlo column against the exact
law; also the lockstep waste of the chunks (steps of the slowest lane against the
mean; a vmapped adaptive solve costs its slowest lane's steps times its width).

    python studies/tail/tail.py [--n 4096] [--chunk 256] [--controller aftsc]
        [--widths 1e-3 3e-3 1e-2] [--gains FILE]

Default: AFTSC, beta1 = beta2 = -1 (issue 15), oracle adaptation, the paper's plant,
the default scenario distribution, seed 0, rtol 1e-6, atol 1e-8. `--gains FILE`: a gains
file's gains, plant and options instead (its own phi_layer is replaced by each W).
Timing: chunk by chunk, the variants alternate, so that contention on the machine
affects them alike; each variant's first chunk (compile) is run once before. Writes
studies/tail/tail[_TAG].json and .md.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _common, _results

from smibjax import configure

configure(cache=False)

import argparse
import time

import jax
import numpy as np
from _common import result_name
from _results import write_results

import smibjax as sj
from smibjax._files import write_text
from smibjax._montecarlo import COLUMNS, MonteCarloSpec, compute_chunk
from smibjax._parameters import PLANT_NAMES

SETTLING_TARGET = 0.005  # s: settling times within 5 ms of the exact law's
INPUTS = COLUMNS[: COLUMNS.index("stable")]  # the scenario's own columns
VERDICTS = ("stable", "lost_sync", "budget_exhausted")


def spec_of(args, layer: float) -> MonteCarloSpec:
    if args.gains:
        from smibjax._files import read_gains_file
        from smibjax._gainsfile import resolve

        ctx, values, _ = resolve(read_gains_file(args.gains, complete=True))
        plant = sj.Plant.preset(ctx.preset, **ctx.plant)
        g = sj.Gains.paper(ctx.controller, **values)
        controller, adaptation, options = ctx.controller, ctx.adaptation, ctx.options
    else:
        plant = sj.Plant()
        g = sj.Gains.paper(args.controller, beta1=-1.0, beta2=-1.0)
        controller, adaptation, options = args.controller, "oracle", {}
    return MonteCarloSpec(
        n=args.n,
        seed=args.seed,
        chunk=min(args.chunk, args.n),
        gains={k: float(getattr(g, k)) for k in sj.GAIN_NAMES},
        plant={k: float(getattr(plant, k)) for k in PLANT_NAMES},
        controller=controller,
        adaptation=adaptation,
        options={**options, "phi_layer": float(layer)},
    )


def effect(ref: dict, rows: dict) -> dict:
    """Per column: changed verdicts (counts) or the |difference| against `ref` (max,
    mean over the rows where both are finite; `finite_changed`: rows where one is
    finite and the other not)."""
    out = {}
    for c in COLUMNS:
        if c in INPUTS:
            assert np.array_equal(ref[c], rows[c]), c  # same scenarios
            continue
        a, b = np.asarray(ref[c], float), np.asarray(rows[c], float)
        if c in VERDICTS:
            out[c] = {"changed": int(np.sum(a != b))}
            continue
        both = np.isfinite(a) & np.isfinite(b)
        d = np.abs(a - b)[both]
        out[c] = {
            "max_abs": float(d.max()) if d.size else 0.0,
            "mean_abs": float(d.mean()) if d.size else 0.0,
            "finite_changed": int(np.sum(np.isfinite(a) != np.isfinite(b))),
        }
        if c == "num_steps":
            out[c].update(mean=float(b.mean()), max=int(b.max()))
    return out


def lockstep(rows: dict, chunk: int, devices: int) -> dict:
    """Lockstep waste of the chunks: each device runs a contiguous slice of a chunk
    (`parallel.device_map`) and costs its slowest lane's steps times its width. Returns
    the efficiency mean/max (1: no waste) as run, and with the rows ordered by their
    own step counts (a perfect cost predictor: the most that ordering can give)."""
    steps = np.asarray(rows["num_steps"], float)
    n = steps.size
    width = -(-chunk // devices)

    def cost(s):
        groups = [s[i : i + width] for i in range(0, n, width)]
        return sum(len(g) * g.max() for g in groups)

    per_chunk = [
        float(steps[i : i + chunk].max() / steps[i : i + chunk].mean())
        for i in range(0, n, chunk)
    ]
    return {
        "slice_width": width,
        "efficiency_as_run": float(steps.sum() / cost(steps)),
        "efficiency_sorted_by_steps": float(steps.sum() / cost(np.sort(steps))),
        "chunk_max_over_mean": {
            "mean": float(np.mean(per_chunk)),
            "max": float(np.max(per_chunk)),
        },
    }


def predictors(rows: dict) -> dict:
    """Spearman rank correlation of the steps with each scenario input."""
    from scipy.stats import spearmanr

    s = np.asarray(rows["num_steps"], float)
    return {
        c: float(spearmanr(np.asarray(rows[c], float), s).statistic)
        for c in INPUTS
        if c != "index" and np.ptp(np.asarray(rows[c], float)) > 0
    }


def fmt(x: float) -> str:
    return f"{x:.3g}" if x else "0"


def markdown(widths, effects, rates, steps, label) -> str:
    head = ["column"] + [f"W = {w:g}" for w in widths[1:]]
    lines = [
        f"Effect of the boundary layer W against the exact law ({label}); cells: "
        "changed verdicts, or max / mean |difference| over the rows where both are "
        "finite (+k: rows where one is finite and the other not).",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for c in COLUMNS:
        if c in INPUTS:
            continue
        cells = []
        for w in widths[1:]:
            e = effects[w][c]
            if "changed" in e:
                cells.append(str(e["changed"]))
            else:
                extra = f" (+{e['finite_changed']})" if e["finite_changed"] else ""
                cells.append(f"{fmt(e['max_abs'])} / {fmt(e['mean_abs'])}{extra}")
        lines.append(f"| {c} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "| W | steps mean | steps max | scenarios/s | speed-up |",
        "|---|---|---|---|---|",
    ]
    for w in widths:
        lines.append(
            f"| {w:g} | {steps[w]['mean']:.0f} | {steps[w]['max']} | {rates[w]:.0f} | "
            f"{rates[w] / rates[widths[0]]:.2f}x |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=4096)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunk", type=int, default=256)
    ap.add_argument("--controller", choices=["aftsc", "asc"], default="aftsc")
    ap.add_argument("--widths", type=float, nargs="+", default=[1e-3, 3e-3, 1e-2])
    ap.add_argument("--gains", metavar="FILE", help="a gains file instead")
    ap.add_argument("--tag", default="")
    ap.add_argument("--out", default=str(HERE))
    args = ap.parse_args()
    widths = [0.0, *args.widths]
    specs = {w: spec_of(args, w) for w in widths}
    k0 = specs[0.0].n_chunks
    compile_s = {}
    for w, spec in specs.items():  # compile each variant once, untimed
        t0 = time.perf_counter()
        compute_chunk(spec, 0)
        compile_s[w] = time.perf_counter() - t0
    parts = {w: [] for w in widths}
    wall = dict.fromkeys(widths, 0.0)
    t_all = time.perf_counter()
    for k in range(k0):  # alternate the variants chunk by chunk
        for w in widths[k % len(widths) :] + widths[: k % len(widths)]:
            t0 = time.perf_counter()
            parts[w].append(compute_chunk(specs[w], k))
            wall[w] += time.perf_counter() - t0
    t_all = time.perf_counter() - t_all
    rows = {
        w: {c: np.concatenate([p[c] for p in parts[w]]) for c in COLUMNS}
        for w in widths
    }
    rates = {w: args.n / wall[w] for w in widths}
    effects = {w: effect(rows[0.0], rows[w]) for w in widths}
    steps = {w: effects[w]["num_steps"] for w in widths}
    devices = len(jax.devices())
    waste = {w: lockstep(rows[w], specs[w].chunk, devices) for w in widths}
    ok = [
        w
        for w in widths[1:]
        if all(effects[w][v]["changed"] == 0 for v in VERDICTS)
        and effects[w]["settling_time"]["max_abs"] <= SETTLING_TARGET
        and effects[w]["settling_time"]["finite_changed"] == 0
    ]
    widest = max(ok) if ok else None
    label = (
        f"--gains {args.gains}"
        if args.gains
        else f"{args.controller}, beta1 = beta2 = -1, oracle, paper plant"
    ) + f"; {args.n} scenarios, seed {args.seed}, chunk {specs[0.0].chunk}"
    md = markdown(widths, effects, rates, steps, label)
    md += (
        f"\nWidest W with every verdict unchanged and settling within "
        f"{SETTLING_TARGET * 1e3:g} ms: {widest if widest is not None else 'none'}.\n"
    )
    md += "\n| W | lockstep efficiency as run | ordered by steps | chunk max/mean |\n"
    md += "|---|---|---|---|\n"
    for w in widths:
        x = waste[w]
        md += (
            f"| {w:g} | {x['efficiency_as_run']:.3f} | "
            f"{x['efficiency_sorted_by_steps']:.3f} | "
            f"{x['chunk_max_over_mean']['mean']:.2f} (max "
            f"{x['chunk_max_over_mean']['max']:.2f}) |\n"
        )
    print(md)
    print(
        f"compile (first chunk) s: { {f'{w:g}': round(s, 1) for w, s in compile_s.items()} }"
    )
    print(f"timed loop: {t_all:.1f} s")
    out = Path(args.out)
    name = result_name("tail", args.tag)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / f"{name}.md", md)
    write_results(
        out,
        name,
        {
            "label": label,
            "widths": widths,
            "rtol": specs[0.0].solver.rtol,
            "atol": specs[0.0].solver.atol,
            "devices": devices,
        },
        {
            "wall_s": {f"{w:g}": wall[w] for w in widths},
            "scenarios_per_s": {f"{w:g}": rates[w] for w in widths},
            "compile_first_chunk_s": {f"{w:g}": compile_s[w] for w in widths},
            "effect": {f"{w:g}": effects[w] for w in widths},
            "lockstep": {f"{w:g}": waste[w] for w in widths},
            "step_predictors_spearman": predictors(rows[0.0]),
            "widest_ok": widest,
            "settling_target_s": SETTLING_TARGET,
        },
    )


if __name__ == "__main__":
    main()
