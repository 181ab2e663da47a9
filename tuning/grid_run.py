"""`python -m tuning.optimize --config FILE` with a `[case]` table: the training loop,
validation, checkpoints and outputs of a tuning run on a multi-machine case.

The loop reuses the SMIB tuner's state and checkpoints (`tuning.loop.TrainState`,
an equinox Module; `save_checkpoint`/`load_checkpoint`; `tuning.resume` for
`--resume` and the session clock). Each validation (every `validation.every` steps
and at the end) writes a checkpoint and refreshes the damping term's reference modes
(computed from the parameters of that step, so a resumed run is the same run).

Outputs in `--out DIR`: `gains.json` (the best validated parameters as a flat table
of device parameters by name: `python -m smibjax modes --case NAME --gains
gains.json` reads it), `tuned.dyr` (the case's dyr file with the tuned records'
parameters, and those of `case.set`, replaced: `smibjax.grid.dyr_write`; `simulate
--case RAW --dyr tuned.dyr` runs the tuned case), `summary.json` (start and tuned
validation, modes, physics), `report.md` (with the table of tuned.dyr's changes),
`history.csv`, `trajectories.png` (every machine on the reference fault, textbook
and tuned), `config.json`, the checkpoint.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["main", "run_grid", "validate", "finish_grid"]


def _load_cfg(args) -> dict:
    from .grid_config import check_grid_config, load_grid_config

    cfg = load_grid_config(args.config)
    for key in ("steps", "batch", "seed"):
        v = getattr(args, key, None)
        if v is not None:
            cfg[key] = v
    for flag in ("init", "preset", "controller", "adaptation"):
        if getattr(args, flag, None) is not None:
            from smibjax import ParameterError

            raise ParameterError(
                f"--{flag} is not allowed with a [case] config (it is the SMIB's): "
                "set the start values in the case's dyr file"
            )
    check_grid_config(cfg)
    return cfg


def _modes_at(problem, raw, lfs):
    """Per load factor: the electromechanical modes (concrete) of the case at raw."""
    from smibjax.grid.modes import linearize, modes
    from smibjax.grid.operating import operating_point

    case = problem.case_at(raw)
    out = []
    for lf in lfs:
        op, _ = operating_point(case, load_factor=lf, gen_factor=lf)
        ms = modes(case, linearize(case, op, inputs=(), outputs=()))
        em = [m for m in ms if m.kind == "electromechanical"]
        osc = [
            float(m.damping)
            for m in ms
            if m.kind not in ("zero", "frozen")
            and m.eigenvalue.imag > 0
            and 0.05 <= m.frequency <= 5.0
        ]
        out.append(
            {
                "load_factor": lf,
                "oscillatory_min_damping": min(osc) if osc else math.nan,
                "modes": [
                    {
                        "real": float(m.eigenvalue.real),
                        "imag": float(m.eigenvalue.imag),
                        "frequency_hz": float(m.frequency),
                        "damping": float(m.damping),
                        "scope": m.scope,
                    }
                    for m in em
                ],
            }
        )
    return out


def _settling_time(ts, err, band, t0):
    """Time (s) from t0 after which err (T, n) stays at or below band in every
    column for at least the last `grid.metrics.WINDOW` s of the run; inf otherwise
    (the grid's one settling definition, `grid.metrics`)."""
    from smibjax.grid.metrics import WINDOW, settling_time

    return settling_time(ts, err, band, t0, WINDOW)


def _validation_fn(problem):
    from smibjax.grid.events import switch_times
    from smibjax.grid.metrics import grid_metrics

    from .grid_problem import _machine_mask, coi_speeds, simulate_scenarios

    mask = jnp.asarray(_machine_mask(problem.case))

    def metrics(case, tr, t0, band_angle, band_speed):
        m = grid_metrics(case, tr, t0, band_angle, band_speed)
        after = (tr.ts >= t0)[:, None]
        err = jnp.where(mask, jnp.abs(coi_speeds(case, tr.omega)), 0.0) * after
        s_w = _settling_time(tr.ts, jnp.nan_to_num(err, nan=jnp.inf), band_speed, t0)
        return dataclasses.replace(m, settling_speed=jnp.where(m.stable, s_w, jnp.inf))

    lc = problem.cfg["loss"]
    t_end = problem.cfg["validation"]["t_end"]

    @jax.jit
    def run(raw, events, lfs):
        trs, conv = simulate_scenarios(problem, raw, events, lfs, t_end)
        axes = jax.tree_util.tree_map(lambda x: 0 if jnp.ndim(x) else None, events)
        t0 = jax.vmap(lambda ev: switch_times(ev)[0], in_axes=(axes,))(events)
        m = jax.vmap(
            lambda tr, t: metrics(
                problem.case_at(raw), tr, t, lc["band_angle"], lc["band_speed"]
            )
        )(trs, t0)
        return m, conv

    return run


def _held_out(problem):
    v = problem.cfg["validation"]
    return problem.batch(0, n=int(v["n"]), seed=int(v["seed"]))


def _stats(x):
    x = np.asarray(x, dtype=float)
    fin = x[np.isfinite(x)]
    if fin.size != x.size or x.size == 0:
        return math.inf, math.inf
    return float(np.mean(x)), float(np.percentile(x, 95))


def validate(problem, raw, run_fn=None, held=None) -> dict:
    """The held-out summary of raw parameters: stable fraction, settling (s) of the
    COI angles and speeds (mean and p95 over the scenarios; inf when a scenario never
    settles or is unstable), the worst electromechanical damping ratio over
    `validation.load_factors`, field-voltage peak, bus-voltage range."""
    run_fn = run_fn or _validation_fn(problem)
    events, lfs = held if held is not None else _held_out(problem)
    m, conv = run_fn(raw, events, lfs)
    stable = np.asarray(m.stable) & np.asarray(conv)
    s_a = np.asarray(m.settling_angle)
    s_w = np.asarray(m.settling_speed)
    settle = np.maximum(s_a, s_w)
    mean, p95 = _stats(settle)
    ma, pa = _stats(s_a)
    modes = _modes_at(problem, raw, problem.cfg["validation"]["load_factors"])
    zetas = [d["damping"] for mm in modes for d in mm["modes"]]
    inter = [
        d["damping"] for mm in modes for d in mm["modes"] if d["scope"] == "inter-area"
    ]
    osc = [mm["oscillatory_min_damping"] for mm in modes]
    return {
        "stable_fraction": float(np.mean(stable)),
        "settling_mean": mean,
        "settling_p95": p95,
        "settling_angle_mean": ma,
        "settling_angle_p95": pa,
        "worst_damping": float(min(zetas)) if zetas else math.nan,
        "worst_inter_area_damping": float(min(inter)) if inter else math.nan,
        "worst_oscillatory_damping": float(min(osc)),
        "efd_max": float(np.nanmax(np.asarray(m.efd_max))),
        "v_min": float(np.nanmin(np.asarray(m.v_min))),
        "v_max": float(np.nanmax(np.asarray(m.v_max))),
    }


def _better(a: dict, b: dict, target: float) -> bool:
    """a beats b: more stable, then meeting the damping target, then faster mean
    settling."""

    def key(v):
        ok = v["worst_damping"] >= target - 1e-9
        s = v["settling_mean"]
        return (v["stable_fraction"], ok, -(s if s == s else math.inf))

    return key(a) > key(b)


_CACHE: dict = {}


def _compiled(cfg, build_grid, make_step):
    """(problem, step, validation) of a config, shared by the runs of one process
    whose configs differ at most in `steps` (their jitted programs are reused)."""
    key = json.dumps({k: v for k, v in cfg.items() if k != "steps"}, sort_keys=True)
    if key not in _CACHE:
        problem = build_grid(cfg)
        step_fn, grad_fn = make_step(problem)
        _CACHE.clear()
        _CACHE[key] = (problem, step_fn, _validation_fn(problem), grad_fn)
    return _CACHE[key][:3]


def compiled_grad(cfg):
    """(problem, value_and_grad of the loss) of a config, from the same cache as the
    runs: grad(raw, events, lfs, refs) -> ((loss, info), gradient)."""
    from .grid_problem import build_grid, make_step

    _compiled(cfg, build_grid, make_step)
    key = json.dumps({k: v for k, v in cfg.items() if k != "steps"}, sort_keys=True)
    return _CACHE[key][0], _CACHE[key][3]


# expected first compiles, as multiples of `smibjax.cli.grid.compile_s` (a + b *
# machines s): measured on WECC 179 (29 machines, 650 states) on the loaded 2-core
# machine, 2026-12-03: the held-out validation (forward runs, vmapped) 65 s, the
# modal gradient (power flow, Jacobian, eigenvalues at every load factor, vmapped)
# 69 s; the time-domain gradient (reverse mode through the adaptive solver, 4 faults
# of 6 s) had not finished compiling after 13 min wall at load 10-14, so its factor
# (6) is a lower bound, not a measurement
PHASE_FACTORS = {"validation": 2.0, "modal": 2.0, "time_domain": 6.0}


def _say_phase(problem, which: str) -> None:
    """The phase line (stderr) before a first compile: `which` = "validation" or
    "step"; what compiles, and about how long."""
    from smibjax.cli.grid import _size, compile_s, say_phase

    from .grid_problem import TERMS

    case, cfg = problem.case, problem.cfg
    lc = cfg["loss"]
    lfs = ", ".join(f"{x:g}" for x in lc["damping_load_factors"])
    v = cfg["validation"]
    if which == "validation":
        say_phase(
            f"the held-out validation of {_size(case)}: {v['n']} faults of "
            f"{v['t_end']:g} s in one vmapped program",
            "jit_run",
            compile_s(case, PHASE_FACTORS["validation"]),
        )
        return
    if not any(lc[k] for k in TERMS if k != "damping"):
        say_phase(
            f"the training step (the modal gradient at load factors {lfs}, one "
            "vmapped program; no fault simulated: every time-domain weight is 0)",
            "jit_value_and_grad",
            compile_s(case, PHASE_FACTORS["modal"]),
        )
    else:
        say_phase(
            f"the training step ({cfg['batch']} faults of {cfg['train']['t_end']:g}"
            f" s in reverse mode, vmapped, and the modal gradient at load factors "
            f"{lfs})",
            "jit_value_and_grad",
            compile_s(case, PHASE_FACTORS["modal"] + PHASE_FACTORS["time_domain"]),
        )


def run_grid(
    cfg: dict,
    out: Path,
    resume: bool = False,
    quiet: bool = False,
    stop_after: int | None = None,
):
    """Tune; returns (problem, final `TrainState`, start summary). Checkpoints at every
    validation; `resume` continues from the last; `stop_after` ends this call after
    that many steps (the tests' interruption)."""
    from .grid_problem import build_grid, make_step, reference
    from .loop import (
        Best,
        TrainState,
        advance,
        load_checkpoint,
        record_validation,
        save_checkpoint,
    )

    problem, step_fn, val_fn = _compiled(cfg, build_grid, make_step)
    space = problem.space
    raw0 = space.to_raw(space.start)
    every = int(cfg["validation"]["every"])
    steps = int(cfg["steps"])
    held = _held_out(problem)
    if not quiet:
        _say_phase(problem, "validation")
    if resume:
        state = load_checkpoint(out, problem.opt, raw0)
    else:
        v0 = validate(problem, raw0, val_fn, held)
        state = TrainState(
            raw=raw0,
            opt_state=problem.opt.init(raw0),
            best=Best(raw=raw0, step=0, summary=v0),
            step=0,
            seed=int(cfg["seed"]),
            validation=[{"step": 0, **v0}],
        )
        save_checkpoint(out, state)
    refs = reference(problem, state.raw)
    target = float(cfg["loss"]["target_damping"])
    done = 0
    while state.step < steps:
        k = state.step
        events, lfs = problem.batch(k)
        if done == 0 and not quiet:
            _say_phase(problem, "step")
        t0 = time.perf_counter()
        raw, opt_state, val, info, gn, skipped = step_fn(
            state.raw, state.opt_state, events, lfs, refs
        )
        row = {
            "step": k + 1,
            "loss": float(val),
            **{f"term_{n}": float(info[n]) for n in info},
            "grad_norm": gn,
            "skipped": bool(skipped),
            "seconds": time.perf_counter() - t0,
        }
        state = advance(state, raw, opt_state, row)
        if not quiet:
            print(
                f"step {k + 1}/{steps}: loss {row['loss']:.4f}, stable "
                f"{row['term_stable']:.2f}, zeta_min {row['term_zeta_min']:.3f} "
                f"({row['seconds']:.1f} s)",
                file=sys.stderr,
            )
        ref_every = int(cfg["loss"].get("reference_every", 0))
        if ref_every and (k + 1) % ref_every == 0 and (k + 1) % every:
            refs = reference(problem, raw)
        if (k + 1) % every == 0 or k + 1 == steps:
            v = validate(problem, raw, val_fn, held)
            state = record_validation(out, state, v, lambda a, b: _better(a, b, target))
            refs = reference(problem, raw)
            if not quiet:
                print(
                    f"validation at step {k + 1}: stable {v['stable_fraction']:.2f}, "
                    f"settling mean {v['settling_mean']:.2f} s, worst damping "
                    f"{v['worst_damping']:.3f}",
                    file=sys.stderr,
                )
        done += 1
        if stop_after is not None and done >= stop_after:
            break
    return problem, state


def _reference_runs(problem, raws: dict):
    """{label: GridTrajectory} of the reference fault for each raw parameter set."""
    from smibjax.grid.operating import operating_point
    from smibjax.grid.simulate import simulate_case

    from .grid_problem import reference_fault

    r = problem.cfg["report"]
    bus, events = reference_fault(problem.case, r, problem.dist)
    lf = float(r["load_factor"])
    opts = problem.options(r["t_end"])
    sim = jax.jit(lambda c, o: simulate_case(c, o, events, **opts))
    out = {}
    for label, raw in raws.items():
        case = problem.case_at(raw)
        op, _ = operating_point(case, load_factor=lf, gen_factor=lf)
        out[label] = sim(case, op)
    return bus, out


def _efd_limits(problem, raw):
    """(EMIN, EMAX) per generator where the exciter is SEXS, else None."""
    from smibjax.grid.params import get_param

    try:
        case = problem.case_at(raw)
        return np.asarray(get_param(case, "SEXS.EMIN")), np.asarray(
            get_param(case, "SEXS.EMAX")
        )
    except ValueError:
        return None


def _physics(problem, raw, tr) -> dict:
    """Field-voltage peaks and time on limits, voltage range of the reference run."""
    from smibjax.grid.loop import gen_names

    from .grid_problem import _machine_mask

    mask = _machine_mask(problem.case)
    names = gen_names(problem.case)
    efd = np.asarray(tr.efd)
    dt = float(tr.ts[1] - tr.ts[0])
    lim = _efd_limits(problem, raw)
    out = {"stable": bool(tr.stable), "machines": {}}
    k = 0
    for g in range(problem.case.n_gen):
        if not mask[g]:
            continue
        e = efd[:, g]
        row = {"efd_max": float(np.nanmax(e)), "efd_min": float(np.nanmin(e))}
        if lim is not None and k < len(lim[0]):
            lo, hi = float(lim[0][k]), float(lim[1][k])
            on = (e >= hi - 1e-6) | (e <= lo + 1e-6)
            row["time_on_limits_s"] = float(np.sum(on) * dt)
        out["machines"][names[g]] = row
        k += 1
    t_clear = 0.5 + float(problem.cfg["report"]["clear_after"])
    vb = np.asarray(tr.v_bus)[np.asarray(tr.ts) > t_clear + 1e-9]
    out["v_bus_min"] = float(np.nanmin(vb))
    out["v_bus_max"] = float(np.nanmax(vb))
    return out


def _plot(path: Path, problem, trs: dict, bus: int):
    """The before/after trajectories of the report's fault (`plot_grid_compare`):
    angles from the centre of inertia (deg), speeds, Efd and Vs on shared y axes
    per row, the same machines in the same colours in every column."""
    from smibjax.cli.plotting import plot_grid_compare
    from smibjax.grid.loop import gen_names
    from smibjax.grid.simulate import coi_angles

    from .grid_problem import _machine_mask

    mask = _machine_mask(problem.case)
    names = np.asarray(gen_names(problem.case))[mask]
    runs = {}
    for label, tr in trs.items():
        rel = np.asarray(coi_angles(problem.case, tr.delta, jnp.asarray(mask * 1.0)))
        runs[label] = {
            "t": np.asarray(tr.ts),
            "gen": names,
            "delta_coi": rel[:, mask],
            "omega": np.asarray(tr.omega)[:, mask],
            "efd": np.asarray(tr.efd)[:, mask],
            "vs": np.asarray(tr.vs)[:, mask],
        }
    t_clear = 0.5 + float(problem.cfg["report"]["clear_after"])
    plot_grid_compare(
        runs,
        path,
        f"{problem.case.name}: bolted fault at bus {bus}",
        events=[
            (0.5, f"fault at bus {bus} at 0.5 s"),
            (t_clear, f"clear: fault removed at {t_clear:g} s"),
        ],
    )


def _fmt(x, spec=".3f"):
    return "inf" if x == math.inf else ("nan" if x != x else format(x, spec))


def case_dyr(cfg) -> Path:
    """The dyr file of the config's case (a built-in case's from the package)."""
    from smibjax.grid.case import case_files

    c = cfg["case"]
    return Path(c["dyr"]) if c["dyr"] else case_files(c["name"])[1]


def tuned_dyr(cfg, problem, gains: dict):
    """The `DyrRewrite` of the case's dyr file with `gains` (parameter values by name,
    as in gains.json) written into its records; one-line `ParameterError` for a
    parameter that is not a dyr parameter or a record the file lacks."""
    from smibjax import ParameterError
    from smibjax.grid.dyr_write import dyr_updates, rewrite_dyr

    try:
        return rewrite_dyr(case_dyr(cfg), dyr_updates(problem.case, gains))
    except ParameterError as e:
        raise ParameterError(f"tuned.dyr: {e}") from None


def _gains(cfg, problem, raw) -> dict:
    """The flat table of gains.json: `case.set`, then the trained values and their
    ties at raw."""
    sp = problem.space
    vals = sp.values(raw)
    gains = {k: float(v) for k, v in cfg["case"]["set"].items()}
    return gains | {n: float(vals[n]) for n in (*sp.names, *(f for f, _ in sp.tie))}


def _dyr_table(rewrite, dyr_name: str) -> list[str]:
    """The report's table of the numbers changed in tuned.dyr."""
    lines = [
        "",
        "## tuned.dyr: old -> new per device and parameter",
        "",
        f"The case's dyr file ({dyr_name}) with these numbers replaced (written to "
        "round-trip float64); every other character as in the case's file.",
        "",
        "| device | parameter | line | old | new | change |",
        "|---|---|---|---|---|---|",
    ]
    for c in rewrite.changes:
        ch = f"{100 * (c.new - c.old) / c.old:+.1f}%" if c.old else ""
        lines.append(
            f"| {c.device} | {c.param} | {c.line} | {c.old:.6g} | {c.new:.6g} | {ch} |"
        )
    return lines


def _report(
    cfg,
    problem,
    state,
    start_raw,
    modes_before,
    modes_after,
    phys,
    wall,
    rewrite=None,
):
    v0 = state.validation[0]
    vb = state.best.summary
    target = cfg["loss"]["target_damping"]
    lines = [
        f"# Coordinated tuning: {problem.case.name}",
        "",
        f"{len(problem.space.names)} parameters trained "
        f"({', '.join(cfg['gains']['names'])}; per device: "
        f"{cfg['gains']['per_device']}), {state.step} Adam steps of "
        f"{cfg['batch']} scenarios, best at step {state.best.step}. "
        f"Wall time (all sessions, this machine): "
        f"{_fmt(wall or math.nan, '.0f')} s.",
        "",
        "Scenarios: "
        f"{cfg['scenarios']['kind']} faults at {cfg['scenarios']['buses'] or 'every bus'}"
        f", t_fault {cfg['scenarios']['t_fault']} s, cleared after "
        f"{cfg['scenarios']['clear_after']} s, load and generation factor uniform in "
        f"{cfg['scenarios']['load_factor']} (power flow re-solved per scenario).",
        "",
        "## Held-out validation",
        "",
        f"{cfg['validation']['n']} scenarios (seed {cfg['validation']['seed']}), "
        f"horizon {cfg['validation']['t_end']} s; settling = the later of the COI "
        f"angles within {cfg['loss']['band_angle']} rad of their final values and "
        f"the COI-referred speeds within {cfg['loss']['band_speed']} pu of 0 (the "
        "common frequency excursion, the governors', removed); damping over load "
        f"factors {cfg['validation']['load_factors']}.",
        "",
        "| | start (case values) | tuned | change |",
        "|---|---|---|---|",
    ]
    for key, spec in (
        ("stable_fraction", ".3f"),
        ("settling_mean", ".3f"),
        ("settling_p95", ".3f"),
        ("settling_angle_mean", ".3f"),
        ("worst_damping", ".4f"),
        ("worst_inter_area_damping", ".4f"),
        ("worst_oscillatory_damping", ".4f"),
        ("efd_max", ".3f"),
        ("v_min", ".3f"),
        ("v_max", ".3f"),
    ):
        a, b = v0[key], vb[key]
        ch = (
            f"{100 * (b - a) / a:+.1f}%"
            if isinstance(a, float) and a and math.isfinite(a) and math.isfinite(b)
            else ""
        )
        lines.append(f"| {key} | {_fmt(a, spec)} | {_fmt(b, spec)} | {ch} |")
    red = (
        1 - vb["settling_mean"] / v0["settling_mean"]
        if math.isfinite(v0["settling_mean"]) and math.isfinite(vb["settling_mean"])
        else math.nan
    )
    lines += [
        "",
        "## Targets (issue 30)",
        "",
        f"- inter-area damping >= {target} at every validation load factor: "
        f"{_fmt(vb['worst_inter_area_damping'], '.4f')} "
        f"({'met' if vb['worst_inter_area_damping'] >= target else 'NOT met'}); "
        f"every electromechanical mode >= {target}: "
        f"{'met' if vb['worst_damping'] >= target else 'NOT met'} "
        f"({_fmt(vb['worst_damping'], '.4f')}); every oscillatory mode of 0.05-5 Hz "
        f"(any kind, e.g. a local mode whose rotor participation fell below 0.5): "
        f"{_fmt(vb['worst_oscillatory_damping'], '.4f')}",
        f"- held-out stable: {100 * vb['stable_fraction']:.1f}% "
        f"({'met' if vb['stable_fraction'] == 1 else 'NOT met'})",
        f"- mean settling {_fmt(100 * red, '.1f')}% shorter than at the start "
        f"({'met' if red >= 0.2 else 'NOT met'}; target >= 20%)",
        "",
        "## Electromechanical modes before and after",
        "",
        "| load factor | start: f (Hz), zeta, scope | tuned: f (Hz), zeta, scope |",
        "|---|---|---|",
    ]
    for mb, ma in zip(modes_before, modes_after, strict=True):
        n = max(len(mb["modes"]), len(ma["modes"]))
        for i in range(n):
            cells = []
            for mm in (mb, ma):
                if i < len(mm["modes"]):
                    d = mm["modes"][i]
                    cells.append(
                        f"{d['frequency_hz']:.4f}, {100 * d['damping']:.2f}%, "
                        f"{d['scope']}"
                    )
                else:
                    cells.append("")
            lines.append(f"| {mb['load_factor']:g} | {cells[0]} | {cells[1]} |")
    lines += ["", "Worst electromechanical damping ratio per load factor:", ""]
    for mb, ma in zip(modes_before, modes_after, strict=True):
        zb = min((d["damping"] for d in mb["modes"]), default=math.nan)
        za = min((d["damping"] for d in ma["modes"]), default=math.nan)
        lines.append(
            f"- load factor {mb['load_factor']:g}: start {_fmt(zb, '.4f')}, tuned "
            f"{_fmt(za, '.4f')} ({len(ma['modes'])} modes)"
        )
    lines += [
        "",
        "## Reference fault: physics",
        "",
        f"Bolted fault at bus {phys['bus']}, 0.5 s, cleared after "
        f"{cfg['report']['clear_after']} s, load factor {cfg['report']['load_factor']}"
        " (`trajectories.png`: every machine's COI angle, speed, Efd, PSS output).",
        "",
        "| machine | Efd peak start | Efd peak tuned | time on Efd limits start / "
        "tuned (s) |",
        "|---|---|---|---|",
    ]
    for g in phys["start"]["machines"]:
        a, b = phys["start"]["machines"][g], phys["tuned"]["machines"][g]
        lines.append(
            f"| {g} | {a['efd_max']:.3f} | {b['efd_max']:.3f} | "
            f"{a.get('time_on_limits_s', math.nan):.2f} / "
            f"{b.get('time_on_limits_s', math.nan):.2f} |"
        )
    lines += [
        "",
        f"Bus voltages after clearing: start {phys['start']['v_bus_min']:.3f} .. "
        f"{phys['start']['v_bus_max']:.3f} pu, tuned {phys['tuned']['v_bus_min']:.3f}"
        f" .. {phys['tuned']['v_bus_max']:.3f} pu.",
        "",
        "## Parameters",
        "",
        "| parameter | start | tuned | bounds | transform |",
        "|---|---|---|---|---|",
    ]
    sp = problem.space
    tuned = sp.values(state.best.raw)
    for k, n in enumerate(sp.names):
        lines.append(
            f"| {n} | {sp.start[k]:.4g} | {float(tuned[n]):.4g} | "
            f"[{sp.lower[k]:.4g}, {sp.upper[k]:.4g}] | {sp.transforms[k]} |"
        )
    for f, lead in sp.tie:
        lines.append(f"| {f} | (follows {lead}) | {float(tuned[f]):.4g} | | |")
    if sp.skipped:
        lines += [
            "",
            "Not trained (0 in the case: a block the device does not have): "
            + ", ".join(sp.skipped)
            + ".",
        ]
    if rewrite is not None:
        lines += _dyr_table(rewrite, case_dyr(cfg).name)
    return "\n".join(lines) + "\n"


def finish_grid(cfg, out: Path, problem, state, wall=None) -> dict:
    """Write gains.json, tuned.dyr, summary.json, report.md, history.csv,
    trajectories.png."""
    from smibjax._files import atomic_write, write_json, write_text

    from .outputs import write_history

    sp = problem.space
    raw0 = sp.to_raw(sp.start)
    best = state.best.raw
    gains = _gains(cfg, problem, best)
    rewrite = tuned_dyr(cfg, problem, gains)
    lfs = cfg["validation"]["load_factors"]
    modes_before = _modes_at(problem, raw0, lfs)
    modes_after = _modes_at(problem, best, lfs)
    bus, trs = _reference_runs(problem, {"start": raw0, "tuned": best})
    phys = {
        "bus": bus,
        "start": _physics(problem, raw0, trs["start"]),
        "tuned": _physics(problem, best, trs["tuned"]),
    }
    summary = {
        "case": problem.case.name,
        "steps": state.step,
        "best_step": state.best.step,
        "start": state.validation[0],
        "tuned": state.best.summary,
        "modes_before": modes_before,
        "modes_after": modes_after,
        "reference_fault": phys,
        "wall_seconds": wall,
    }
    write_history(out, state.history)
    _plot(out / "trajectories.png", problem, trs, bus)
    write_json(out / "summary.json", json.loads(json.dumps(summary, default=float)))
    write_text(
        out / "report.md",
        _report(
            cfg, problem, state, raw0, modes_before, modes_after, phys, wall, rewrite
        ),
    )

    def _dyr(tmp):  # the case file's bytes, those of the replaced numbers aside
        with open(tmp, "wb") as fh:
            fh.write(rewrite.text.encode("utf-8", errors="surrogateescape"))

    atomic_write(out / "tuned.dyr", _dyr)
    write_json(out / "gains.json", gains)
    return summary


def main(args) -> int:
    """The grid branch of `tuning.optimize.main` (args already parsed)."""
    from smibjax import ParameterError
    from smibjax._commandline import CLIError
    from smibjax._files import check_out_folder, write_json

    from .grid_problem import build_grid, make_step
    from .loop import CHECKPOINT
    from .optimize import output
    from .resume import SessionClock, start_mode

    try:
        cfg = _load_cfg(args)
        if args.resume and not args.out:
            raise ParameterError("--resume needs --out DIR (the run to continue)")
        # every check before anything is written; the problem is kept for run_grid
        problem0 = _compiled(cfg, build_grid, make_step)[0]
        # the tuned parameters can be written into the case's dyr file (tuned.dyr)
        tuned_dyr(
            cfg,
            problem0,
            _gains(cfg, problem0, problem0.space.to_raw(problem0.space.start)),
        )
        out = output(args)
        check_out_folder(out)  # writable, before any work
        resume = start_mode(out, cfg, args.resume, CHECKPOINT)
        out.mkdir(parents=True, exist_ok=True)
        if not resume:
            write_json(out / "config.json", cfg)
        clock, t0 = SessionClock(out, args.resume), time.perf_counter()
        problem, state = run_grid(cfg, out, resume=resume, quiet=args.quiet)
        total, _ = clock.finish(time.perf_counter() - t0)
        finish_grid(cfg, out, problem, state, wall=total)
        print(
            f"wrote {out}/gains.json, tuned.dyr, report.md, summary.json, "
            "history.csv and plots"
        )
        return 0
    except (CLIError, ParameterError, OSError) as e:
        print(f"tuning.optimize: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\ntuning.optimize: interrupted; continue with --resume", file=sys.stderr)
        return 130
