"""report.md and plots of a tuning run."""

from __future__ import annotations

import math
from pathlib import Path

import jax
import numpy as np

import smibjax as sj
from smibjax._figures import clip_to_applied, mark_events, save_figure, subplots
from smibjax._files import write_text
from smibjax.controllers import CONTROLLERS

from .params import gains_to_dict
from .train import with_damping


def plot_history(out: Path, history: list[dict], validation: list[dict]) -> None:
    fig, ax = subplots(3, 1, figsize=(8, 8), sharex=True)
    s = [r["step"] for r in history]
    ax[0].plot(s, [r["loss"] for r in history], lw=1)
    ax[0].set_ylabel("training loss")
    ax[0].set_yscale("log")
    vs = [v["step"] for v in validation]
    ax[1].plot(vs, [v["stable_fraction"] for v in validation], "o-")
    ax[1].set_ylabel("validation\nstable fraction")
    ax[1].set_ylim(-0.05, 1.05)
    ax[2].plot(vs, [v["settling_delta_mean"] for v in validation], "o-", label="mean")
    ax[2].plot(vs, [v["settling_delta_p95"] for v in validation], "s--", label="p95")
    ax[2].set_ylabel("validation delta\nsettling time (s)")
    ax[2].set_xlabel("optimizer step")
    ax[2].legend()
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, out / "history.png")


def plot_hist(out: Path, m0, m1) -> None:
    fig, ax = subplots(figsize=(7, 4))
    for m, label in ((m0, "initial"), (m1, "tuned")):
        st = np.asarray(m.stable)
        ts = np.asarray(m.settling_delta)[st]
        if ts.size:
            ax.hist(
                ts,
                bins=30,
                alpha=0.6,
                label=f"{label}: {st.mean():.0%} stable, mean {ts.mean():.2f} s",
            )
        else:
            ax.plot([], [], label=f"{label}: 0% stable")
    ax.set_xlabel("delta settling time from fault inception (s), stable scenarios")
    ax.set_ylabel("scenarios")
    ax.legend()
    fig.tight_layout()
    save_figure(fig, out / "settling_hist.png")


def plot_trajectories(out: Path, runs: dict, events: dict | None = None) -> None:
    """One row per representative scenario: delta (rad), the field voltage u_f and
    the SVC input u_r (pu; applied, and the tuned controller's command before the
    limits, dotted, clipped to the applied range with its peak stated), initial
    (dashed) against tuned (solid) gains; the fault, clearing and reclosing times
    (`events`: title -> (t_fault, t_clear, t_reclose)) marked."""

    events = events or {}
    n = len(runs)
    fig, axes = subplots(n, 3, figsize=(15, 2.9 * n + 0.4), sharex=True, squeeze=False)
    for row, (title, pair) in zip(axes, runs.items(), strict=True):
        for (label, tr), style in zip(pair.items(), ("--", "-"), strict=True):
            t = np.asarray(tr.t)
            cut = t > float(tr.t_stop) if bool(tr.lost_sync) else np.zeros_like(t, bool)
            if bool(tr.lost_sync):
                label += f" (lost sync at {float(tr.t_stop):.2f} s)"
            for ax, key in zip(row, ("delta", "u_f", "u_r"), strict=True):
                y = np.array(getattr(tr, key), dtype=float)
                y[cut] = np.nan
                ax.plot(t, y, style, lw=1.3, label=label)
            if label.startswith("tuned"):
                for ax, key, applied in zip(
                    row[1:], ("u_f_cmd", "u_r_cmd"), ("u_f", "u_r"), strict=True
                ):
                    c = np.array(getattr(tr, key), dtype=float)
                    a = np.array(getattr(tr, applied), dtype=float)
                    c[cut], a[cut] = np.nan, np.nan
                    ax.plot(t, c, ":", lw=0.9, color="gray", label="tuned, commanded")
                    clip_to_applied(ax, a, c)
        row[0].axhline(float(tr.delta_e), color="k", lw=0.6)
        row[0].set_title(title, fontsize=9, loc="left")
        for ax, ylabel in zip(
            row, ("delta (rad)", "u_f (pu)", "u_r (pu)"), strict=True
        ):
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            mark_events(ax, events.get(title), legend=ax is row[0])
        row[0].legend(fontsize=7, loc="best")
        row[1].legend(fontsize=7, loc="lower right")
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    fig.tight_layout()
    save_figure(fig, out / "trajectories.png")


def _fmt(x):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.3f}"


def _search_lines(cfg: dict, state) -> list[str]:
    """The gradient-free warm start, if the config ran one."""
    hist = state.search
    if not hist:
        return []
    sc = cfg["search"]
    last = hist[-1]
    narrowed = "".join(
        f", {k} in [{v[0]:g}, {v[1]:g}]" for k, v in sc.get("scenarios", {}).items()
    )
    return [
        "## Gradient-free warm start",
        "",
        f"CMA-ES (pycma) over the raw gains: {len(hist)} generations of "
        f"{sc['population']} candidates (initial step size {sc['sigma']}, final "
        f"{last.get('sigma', float('nan')):.3g}), each scored on {sc['batch']} "
        f"fixed faults (seed "
        f"{sc['seed']}{narrowed}) with the adaptive solver: mean delta settling time, "
        f"{2 * float(cfg['validation']['t_end']):g} s for an unstable run. Score of "
        f"the start {hist[0]['mean_score']:.3f} s; best score "
        f"{last['best_score']:.3f} s. The gradient steps start from the best "
        "candidate (its validation is step 0 below).",
        "",
        "| generation | best score so far (s) | generation best (s) | its stable "
        "fraction |",
        "|---|---|---|---|",
        *[
            f"| {r['generation']} | {r['best_score']:.3f} | "
            f"{r['generation_best']:.3f} | {r['generation_best_stable']:.2f} |"
            for r in hist
        ],
        "",
    ]


def _d_range(cfg) -> str:
    d = cfg["scenarios"].get("D") or []
    return f"uniform in [{d[0]:g}, {d[1]:g}]" if d else "nominal"


def _train_solver(setup) -> str:
    solver = setup.train_solver
    if solver.kind == "adaptive":
        return (
            f"Tsit5 with adaptive steps (rtol {solver.rtol:g}, atol "
            f"{solver.atol:g}), step lengths held fixed in the reverse pass"
        )
    return (
        f"Tsit5 on a fixed grid dt = {solver.dt:g} s (stopping exactly at "
        "every switch time)"
    )


def _paper_fault_lines(tr, setup) -> list[str]:
    """The tuned controller on the paper's fault: its physics, in one table."""
    from smibjax import metrics

    m = metrics(tr)
    after = np.asarray(tr.t) >= float(tr.t_fault) + 0.2
    th = np.asarray(tr.theta_hat)[-1]
    rows = [
        ("stable", str(bool(m.stable))),
        ("delta settling from fault inception (s)", _fmt(float(m.settling_delta))),
        ("overshoot (rad)", _fmt(float(m.overshoot))),
        (
            "peak commanded u_f / u_r (pu)",
            f"{float(m.peak_uf_cmd):.4g} / {float(m.peak_ur_cmd):.4g}",
        ),
        (
            "time on a limit u_f / u_r",
            f"{float(m.limit_time_uf):.3f} / {float(m.limit_time_ur):.3f}",
        ),
        (
            "total variation u_f / u_r, whole run (pu)",
            f"{float(m.tv_uf):.4g} / {float(m.tv_ur):.4g}",
        ),
        (
            "total variation u_f after clearing (pu)",
            f"{float(np.sum(np.abs(np.diff(np.asarray(tr.u_f)[after])))):.4g}",
        ),
        (
            "Vt, B, E' ranges (pu)",
            f"{float(m.Vt_min):.3f}..{float(m.Vt_max):.3f}, "
            f"{float(m.B_min):.3f}..{float(m.B_max):.3f}, "
            f"{float(m.E_min):.3f}..{float(m.E_max):.3f}",
        ),
    ]
    if setup.controller in ("aftsc", "asc"):  # the paper's law has estimates
        rows.append(
            (
                "final estimates (th1, th2) vs true (-D, Pm)",
                f"({th[0]:.4f}, {th[1]:.4f}) vs ({-float(setup.plant.D):g}, "
                f"{float(setup.plant.Pm):g})",
            )
        )
    return [
        "## The tuned controller on the paper's fault",
        "",
        "| quantity | value |",
        "|---|---|",
        *[f"| {a} | {b} |" for a, b in rows],
        "",
    ]


def write_report(cfg: dict, out: Path, state, problem, validate, val_scenarios) -> None:
    """report.md and the plots of a finished run: `state` (`tuning.loop.TrainState`),
    `problem` (`tuning.problem.Problem`), `validate` (raw -> (summary, metrics)) and
    the validation scenarios (faults, D)."""
    space, setup = problem.space, problem.setup
    raw0 = space.to_raw(problem.init)
    best = state.best
    g0, g1 = space.to_gains(raw0), space.to_gains(best.raw)
    v0s, m0 = validate(raw0)
    v1s, m1 = validate(best.raw)
    plot_history(out, state.history, state.validation)
    plot_hist(out, m0, m1)
    # representative scenarios: the paper's fault, the median and worst tuned ones
    ts = np.where(np.asarray(m1.stable), np.asarray(m1.settling_delta), np.inf)
    order = np.argsort(ts)
    picks = {
        "paper fault (0.5 -> 0.7 s, reclose 2.0 s), nominal D": (
            sj.Fault(),
            setup.plant.D,
        )
    }
    vf, vd = val_scenarios
    for name, i in (
        ("median tuned", order[len(order) // 2]),
        ("worst tuned", order[-1]),
    ):
        f = jax.tree_util.tree_map(lambda a, i=i: a[i], vf)
        picks[
            f"{name} validation scenario: fault {float(f.t_fault):.2f} -> "
            f"{float(f.t_clear):.2f} s, reclose {float(f.t_reclose):.2f} s, "
            f"lam {float(f.lam):.2f}, Xf {float(f.Xf):.3f}, D {float(vd[i]):.3f}"
        ] = (f, vd[i])
    runs = {
        title: {
            label: sj.simulate(
                setup.controller_of(g),
                f,
                with_damping(setup.plant, d),
                save=sj.SaveOptions(t_end=setup.val_t_end),
            )
            for label, g in (("initial", g0), ("tuned", g1))
        }
        for title, (f, d) in picks.items()
    }
    paper_tuned = runs[next(iter(runs))]["tuned"]
    plot_trajectories(
        out,
        runs,
        {
            title: (float(f.t_fault), float(f.t_clear), float(f.t_reclose))
            for title, (f, _) in picks.items()
        },
    )
    names = tuple(space.kinds)
    d0, d1 = gains_to_dict(g0, names), gains_to_dict(g1, names)
    rows = [
        ("stable fraction", "stable_fraction", ""),
        ("mean delta settling (s)", "settling_delta_mean", ""),
        ("p95 delta settling (s)", "settling_delta_p95", ""),
        ("mean Vt settling (s)", "settling_Vt_mean", ""),
        ("mean overshoot (rad)", "overshoot_mean", ""),
        ("mean effort (pu^2 s)", "effort_mean", ""),
        ("peak commanded u_f, before limits (pu)", "peak_uf_cmd_max", ""),
        ("peak commanded u_r, before limits (pu)", "peak_ur_cmd_max", ""),
        ("mean fraction of time u_f on a limit", "limit_time_uf_mean", ""),
        ("mean fraction of time u_r on a limit", "limit_time_ur_mean", ""),
        ("mean total variation of u_f (pu, chatter)", "tv_uf_mean", ""),
        ("mean total variation of u_r (pu, chatter)", "tv_ur_mean", ""),
        ("Vt range (pu)", "Vt_min", "Vt_max"),
        ("B range (pu)", "B_min", "B_max"),
        ("E' range (pu)", "E_min", "E_max"),
    ]

    def cell(v, k, k2):
        return _fmt(v[k]) if not k2 else f"{_fmt(v[k])} .. {_fmt(v[k2])}"

    n_val = int(cfg["validation"]["n"])
    # the paper's law (adaptation, options)
    synergetic = CONTROLLERS[cfg["controller"]].has_adaptation
    md = [
        "# Tuning report",
        "",
        f"Controller {cfg['controller'].upper()}, {cfg['preset']} plant"
        + (f", {cfg['adaptation']} adaptation" if synergetic else "")
        + (
            f", estimates projected onto {cfg['options']['projection']}"
            if setup.projection is not None
            else ""
        )
        + (
            f", evolution-law boundary layer {setup.phi_layer:g}"
            if setup.phi_layer and synergetic
            else ""
        )
        + f"; true damping D {_d_range(cfg)}; {state.step} steps of batch "
        f"{cfg['batch']} (seed {cfg['seed']}), start "
        + (
            f"`{cfg['init']}`"
            if cfg["init"] != "paper"
            else ("the paper's gains" if synergetic else "the controller's defaults")
        )
        + "."
        + (
            f" Wall time {state.wall_seconds:.0f} s"
            + (
                f" (sum over {state.wall_sessions} sessions)."
                if state.wall_sessions > 1
                else "."
            )
            if state.wall_seconds is not None
            else ""
        ),
        "",
        *_search_lines(cfg, state),
        "## Exact validation metrics",
        "",
        f"`gains.json` holds the gains of the best validation (step {best.step}: "
        "most stable scenarios, then fastest mean settling); `gains_last.json` those "
        "of the last step.",
        "",
        f"{n_val} fixed scenarios (seed {cfg['validation']['seed']}), "
        f"{setup.val_t_end:g} s each, settling from fault inception, band "
        f"{setup.weights.delta_band} rad; settling statistics over the stable ones.",
        "",
        "| metric | initial | tuned |",
        "|---|---|---|",
        *[
            f"| {name} | {cell(v0s, k, k2)} | {cell(v1s, k, k2)} |"
            for name, k, k2 in rows
        ],
        "",
        "Peaks and ranges: the largest over the set; fractions and total variations: "
        "means over the set (10 ms samples of the whole run).",
        "",
        *_paper_fault_lines(paper_tuned, setup),
        "",
        "## Gains",
        "",
        "| gain | initial | tuned |",
        "|---|---|---|",
        *[f"| {k} | {d0[k]:.6g} | {d1[k]:.6g} |" for k in d0],
        "",
        f"Trained: {', '.join(space.trainable)}; frozen: "
        f"{', '.join(space.frozen) or 'none'}.",
        "",
        "## Solvers",
        "",
        f"- Training (differentiated): {_train_solver(setup)}, horizon "
        f"{setup.train_t_end:g} s, soft input limiter of width "
        f"{setup.input_smoothing:g} pu"
        + (
            f" (limits x {cfg['continuation']['start']:g} at step 0, falling "
            f"geometrically to x1 at step {cfg['continuation']['steps']})"
            if int(cfg["continuation"]["steps"]) > 0
            else ""
        )
        + ", smooth surrogate losses; gradients of this path match central finite "
        "differences (tests/test_gradients.py, tests/test_losses.py).",
        f"- Validation: Tsit5 with adaptive steps (rtol 1e-6, atol 1e-8), horizon "
        f"{setup.val_t_end:g} s, hard input limits, exact metrics (docs/model.md section 4).",
        "",
        "![history](history.png)",
        "![settling](settling_hist.png)",
        "![trajectories](trajectories.png)",
        "",
    ]
    write_text(out / "report.md", "\n".join(md))
