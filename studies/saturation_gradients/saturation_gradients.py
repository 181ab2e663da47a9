"""Gradients through the input-limited loop: which training solver can be trusted?

For scenarios on the `realistic` plant (u_f in [-5, 5], u_r in [-1, 1]) with the
realizable adaptation and the estimate projection of the default tuning config, and
for each candidate training path (fixed Tsit5 grids, adaptive Tsit5 at two
tolerances, each with the exact finite-time law and with its boundary layer), this
measures:

- the trajectory error: max |delta - delta_ref| over the run against a tight adaptive
  reference (rtol 1e-10) of the same controller;
- the gradient error: the reverse-mode gradient of the scenario loss with respect to
  the trained (raw) gains against central finite differences of the *same*
  discretized loss (step 1e-4 in the raw coordinates), as ||AD - FD|| / ||FD||, and
  against the reference path's FD gradient (what the continuous loss's gradient is);
- the time of one value-and-grad (one scenario, warm).

    python studies/saturation_gradients/saturation_gradients.py [--quick] [--out DIR]

Writes `saturation_gradients.json` and `.png` beside this script (studies/saturation_gradients/).
"""

from __future__ import annotations

from smibjax import configure

# an entry point: float64, equinox's checks as NaNs, before JAX loads
configure(cache=False)

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent  # this study: its script and results
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # _common, _results
sys.path.insert(0, str(ROOT))  # the tuning package

import jax
import jax.numpy as jnp
import numpy as np
from _results import write_results

import smibjax as sj
from smibjax._losses import LossWeights, scenario_loss
from smibjax._process import enable_compilation_cache
from smibjax.cli.plotting import save_figure
from smibjax.controllers import EstimateBox, Synergetic
from tuning.params import GainSpace

PLANT = sj.Plant.preset("realistic")
BOX = EstimateBox(jnp.array([-1.0, 0.0]), jnp.array([0.0, 2.0]))
START = dict(
    beta1=-1.0,
    beta2=-1.0,
    T1=0.02,
    T2=0.5,
    alpha=5 / 7,
    gamma1=0.5,
    gamma2=0.5,
    k1=0.0,
    k2=0.0,
    c1=1.0,
    c2=1.0,
)
FAULTS = {
    "paper fault": sj.Fault(),
    "near fault, 0.15 s": sj.Fault(
        t_fault=0.3, t_clear=0.45, t_reclose=1.8, lam=0.2, Xf=0.01
    ),
}
PATHS = {
    "fixed 2 ms": dict(solver="fixed", dt=2e-3),
    "fixed 0.5 ms": dict(solver="fixed", dt=5e-4),
    "adaptive rtol 1e-6": dict(rtol=1e-6, atol=1e-8),
    "adaptive rtol 1e-8": dict(rtol=1e-8, atol=1e-10),
}
REFERENCE = dict(rtol=1e-10, atol=1e-12)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one path, one fault")
    ap.add_argument("--t-end", type=float, default=8.0)
    ap.add_argument("--out", default=str(HERE))
    args = ap.parse_args(argv)
    enable_compilation_cache()
    space = GainSpace.build(
        START,
        freeze=["k1", "k2", "c1", "c2"],
        bounds={"alpha": (0.6, 1.0), "T1": (0.002, 1.0)},
        beta_abs_min=0.1,
    )
    raw0 = space.to_raw(START)
    names = list(raw0)
    w = LossWeights()
    paths = dict(list(PATHS.items())[:1]) if args.quick else PATHS
    faults = dict(list(FAULTS.items())[:1]) if args.quick else FAULTS
    layers = (0.01,) if args.quick else (0.0, 0.01)
    t_end = 3.0 if args.quick else args.t_end

    def loss_fn(options, layer):
        def loss(raw, f):
            c = Synergetic(
                space.to_gains(raw), oracle=False, projection=BOX, phi_layer=layer
            )
            opts = dict(max_steps=400_000, input_smoothing=0.05, **options)
            tr = sj.simulate(c, f, PLANT, t_end=t_end, **opts)
            return scenario_loss(tr, w), tr.delta

        return loss

    def fd(f_loss, f):
        h = 1e-4
        out = []
        for n in names:
            up = {**raw0, n: raw0[n] + h}
            dn = {**raw0, n: raw0[n] - h}
            out.append((float(f_loss(up, f)[0]) - float(f_loss(dn, f)[0])) / (2 * h))
        return np.array(out)

    rows = []
    for layer in layers:
        ref = jax.jit(loss_fn(REFERENCE, layer))
        for fname, f in faults.items():
            _, d_ref = ref(raw0, f)
            g_ref = fd(ref, f)
            for pname, options in paths.items():
                lf = loss_fn(options, layer)
                vg = jax.jit(jax.value_and_grad(lambda r, f, lf=lf: lf(r, f)[0]))
                lj = jax.jit(lf)
                v, g = vg(raw0, f)
                jax.block_until_ready(g)
                t0 = time.perf_counter()
                v, g = vg(raw0, f)
                jax.block_until_ready(g)
                seconds = time.perf_counter() - t0
                ad = np.array([float(g[n]) for n in names])
                g_fd = fd(lj, f)
                d = np.asarray(lj(raw0, f)[1])
                row = {
                    "layer": layer,
                    "fault": fname,
                    "path": pname,
                    "loss": float(v),
                    "delta_error": float(np.max(np.abs(d - np.asarray(d_ref)))),
                    "ad_vs_own_fd": float(
                        np.linalg.norm(ad - g_fd) / np.linalg.norm(g_fd)
                    ),
                    "ad_vs_reference_fd": float(
                        np.linalg.norm(ad - g_ref) / np.linalg.norm(g_ref)
                    ),
                    "grad_norm": float(np.linalg.norm(ad)),
                    "seconds": seconds,
                }
                rows.append(row)
                print(
                    f"layer {layer:g} | {fname:20s} | {pname:20s} | "
                    f"|d delta| {row['delta_error']:.1e} rad | AD vs own FD "
                    f"{row['ad_vs_own_fd']:.2f} | vs reference "
                    f"{row['ad_vs_reference_fd']:.2f} | |grad| {row['grad_norm']:.3g} "
                    f"| {seconds:.2f} s",
                    flush=True,
                )
    config = {"t_end": t_end, "start": START, "quick": args.quick}
    path = write_results(args.out, "saturation_gradients", config, {"rows": rows})
    _plot(rows, Path(args.out) / "saturation_gradients.png")
    print(f"wrote {path}")
    return 0


def _plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [f"{r['path']}\nlayer {r['layer']:g}\n{r['fault']}" for r in rows]
    x = np.arange(len(rows))
    fig, ax = plt.subplots(figsize=(max(6, 0.9 * len(rows)), 4))
    ax.bar(x - 0.2, [r["ad_vs_own_fd"] for r in rows], 0.4, label="vs own FD")
    ax.bar(x + 0.2, [r["ad_vs_reference_fd"] for r in rows], 0.4, label="vs reference")
    ax.set_yscale("log")
    ax.axhline(0.1, color="k", lw=0.6)
    ax.set_ylabel("relative gradient error")
    ax.set_xticks(x, labels, fontsize=6)
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path)


if __name__ == "__main__":
    sys.exit(main())
