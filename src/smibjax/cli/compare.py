"""Several gain sets side by side: the same Monte Carlo (same seed, same scenarios) and
the same CCT sweep for each, in one table and one figure.

A gain set is named by a file (a tuner's `gains.json` with its context, schema
`smibjax.gains/1`, or a complete flat table of the nine gains) or by one of the
built-in names in `BUILTIN_SETS`. Each set runs under its own context (controller,
adaptation mode, plant): the flags if given, else the file's, else the paper's
(`gainsfile.resolve`); the table and the files show it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .._gainsfile import Context
    from ..controllers.synergetic import Gains

import argparse
import math
import re
import sys
from pathlib import Path

__all__ = [
    "BUILTIN_SETS",
    "resolve_gain_set",
    "resolve_gain_set_context",
    "compare_table",
    "plot_compare",
    "merge_cct",
    "add_parser",
    "run",
]

# Built-in gain sets: the paper's (which lose synchronism, docs/model.md section 2) and
# beta1 = beta2 = -1, the sign-corrected choice that stabilizes the loop.
BUILTIN_SETS = {
    "paper": ("aftsc", {}),
    "paper-asc": ("asc", {}),
    "stable": ("aftsc", {"beta1": -1.0, "beta2": -1.0}),
    "stable-asc": ("asc", {"beta1": -1.0, "beta2": -1.0}),
    "none": ("none", {}),
    "avr-pss": ("avr-pss", {}),
}


def _parameters(controller: str, values: dict):
    """The parameter set of `controller`: the paper's `Gains` for aftsc/asc (the
    controller's alpha), the controller itself otherwise."""
    from ..controllers import parameter_set

    return parameter_set(controller, values)


def resolve_gain_set_context(
    spec: str,
    sets: dict[str, float] | None = None,
    adaptation: str | None = None,
    preset: str | None = None,
) -> tuple[str, Gains, Context, list[str]]:
    """(label, Gains, context, messages) of a built-in name or a complete gains file,
    with `sets` (gain overrides) applied on top. The context is the flag
    (`adaptation`, `preset`; None = not given) if given, else the file's, else the
    paper's; `messages` are the one-line warnings and notes to print."""
    from .._files import read_gains_file
    from .._gainsfile import resolve
    from .._parameters import ParameterError

    sets = sets or {}
    if spec in BUILTIN_SETS:
        controller, values = BUILTIN_SETS[spec]
        ctx, _, messages = resolve(None, controller, adaptation, preset)
        mine = _own_sets(ctx.controller, sets)
        return spec, _parameters(controller, {**values, **mine}), ctx, messages
    path = Path(spec)
    if not path.exists():
        raise ParameterError(
            f"--gains {spec!r}: no such file, and not a built-in set "
            f"({', '.join(BUILTIN_SETS)})"
        )
    gf = read_gains_file(path, complete=True)
    ctx, values, messages = resolve(
        gf, None, adaptation, preset, source=f"--gains {spec}"
    )
    label = path.stem if path.stem != "gains" else path.parent.name or path.stem
    mine = _own_sets(ctx.controller, sets)
    return label, _parameters(ctx.controller, {**values, **mine}), ctx, messages


def _own_sets(controller: str, sets: dict) -> dict:
    """The --set values that are parameters of `controller` (the paper's law's
    gains for aftsc/asc, the AVR-PSS's K_A, T_A, ... for avr-pss); the others are
    another controller's or the plant's (`_warn_dropped_sets` names them)."""
    from ..controllers import CONTROLLERS

    names = set(CONTROLLERS[controller].parameter_kinds())
    return {k: v for k, v in sets.items() if k in names}


def _stated_context(spec: str):
    """The context a schema gains file states (None: a built-in set or a flat
    file, which state none)."""
    if spec in BUILTIN_SETS:
        return None
    from .._files import read_gains_file
    from .._gainsfile import resolve

    gf = read_gains_file(spec)
    return None if gf.legacy else resolve(gf)[0]


def split_label(spec: str) -> tuple[str | None, str]:
    """`--gains LABEL=FILE|NAME` as (LABEL, FILE|NAME); (None, spec) without a
    label (an existing file whose name holds '=' is a file)."""
    from .._parameters import ParameterError

    label, sep, rest = spec.partition("=")
    if not sep or Path(spec).exists():
        return None, spec
    if not label.strip() or not rest:
        raise ParameterError(
            f"--gains {spec!r} is not allowed: expected LABEL=FILE, LABEL=NAME, FILE "
            "or NAME"
        )
    return label.strip(), rest


def fair_contexts(
    contexts: dict, stated: dict, preset_flag, adaptation_flag
) -> tuple[dict, list[str]]:
    """One plant and one adaptation (where it applies) for every set:
    (contexts, notes). `stated`: label -> the context its gains file states (None
    for a built-in set or a flat file). A flag wins for all; else the context the
    files state (the most specific) is given to every set, with a note naming it;
    files that state different ones are refused in one line."""
    import dataclasses

    from .._parameters import ParameterError
    from ..controllers import CONTROLLERS
    from .report import plant_text

    notes = []

    def plant_of(c):
        return (c.preset, tuple(sorted(c.plant.items())))

    if preset_flag is None:
        plants = {plant_of(stated[n]) for n in stated if stated[n] is not None}
        if len(plants) > 1:
            named = ", ".join(
                f"{n}: {plant_text(stated[n].plant | _limits_of(stated[n]), stated[n].preset)}"
                for n in stated
                if stated[n] is not None
            )
            raise ParameterError(
                f"the gains files state different plants ({named}): give --preset "
                "to compare them on one"
            )
        if plants:
            (preset, items) = plants.pop()
            moved = [n for n, c in contexts.items() if plant_of(c) != (preset, items)]
            for n in moved:
                contexts[n] = dataclasses.replace(
                    contexts[n], preset=preset, plant=dict(items)
                )
            if moved:
                c = next(c for c in stated.values() if c is not None)
                notes.append(
                    f"note: every set runs on the "
                    f"{plant_text(c.plant | _limits_of(c), preset)} its gains "
                    f"file states ({', '.join(moved)} too; --preset overrides)"
                )
    if adaptation_flag is None:
        adaptive = {
            n for n, c in contexts.items() if CONTROLLERS[c.controller].has_adaptation
        }
        modes = {
            stated[n].adaptation
            for n in adaptive
            if stated[n] is not None and stated[n].controller in ("aftsc", "asc")
        }
        if len(modes) > 1:
            raise ParameterError(
                "the gains files state different adaptation modes "
                f"({', '.join(sorted(modes))}): give --adaptation to compare them "
                "under one"
            )
        if modes:
            mode = modes.pop()
            moved = [n for n in adaptive if contexts[n].adaptation != mode]
            for n in moved:
                contexts[n] = dataclasses.replace(contexts[n], adaptation=mode)
            if moved:
                notes.append(
                    f"note: {', '.join(moved)} run with {mode} adaptation, as the "
                    "gains files state (--adaptation overrides)"
                )
    return contexts, notes


def _preset_limits(plant: dict) -> dict:
    """A described plant's limits: its preset's, under its overrides (None: no
    limit)."""
    from .._names import PRESETS

    return {
        **PRESETS[plant["preset"]],
        **{k: v for k, v in plant.items() if k != "preset"},
    }


def _limits_of(ctx) -> dict:
    """The preset's own limits of a context (under its overrides)."""
    from .._names import PRESETS

    return {**PRESETS[ctx.preset], **ctx.plant}


def safe_label(label: str) -> str:
    """A set's label as a folder name inside --out: no separators, never '.' or
    '..' (`--gains ../gains.json` is labelled by its folder, '..', which would
    write outside --out)."""
    clean = re.sub(r"[^\w.+-]", "_", label)
    return clean if clean.strip(".") else "gains"


def _warn_dropped_sets(label: str, ctx: Context, sets: dict) -> None:
    """One warning line per --set gain that a set's controller does not take (it
    would otherwise be dropped silently)."""
    from ..controllers import CONTROLLERS

    names = set(CONTROLLERS[ctx.controller].parameter_kinds())
    anyone = {n for c in CONTROLLERS.values() for n in c.parameter_kinds()}
    for name in sets:
        if name in anyone and name not in names:
            print(
                f"smibjax: warning: --set {name} does not apply to set {label!r} "
                f"(controller {ctx.controller} has no parameter {name}): ignored there",
                file=sys.stderr,
            )


def resolve_gain_set(
    spec: str, sets: dict[str, float] | None = None
) -> tuple[str, Gains]:
    """(label, Gains) of a built-in name or a complete gains file, with `sets` (gain
    overrides) applied on top (`resolve_gain_set_context` without the context)."""
    label, gains, _, _ = resolve_gain_set_context(spec, sets)
    return label, gains


def context_text(ctx: dict) -> tuple[str, str, str]:
    """(controller, adaptation, plant) cells of a `Context.describe()` dict; the plant
    is its preset plus any field the file overrides, e.g. 'realistic (uf_max=3)'."""
    plant = dict(ctx["plant"])
    preset = plant.pop("preset")
    from .._parameters import PRESETS

    base = PRESETS[preset]
    extra = [
        f"{k}={'none' if v is None else format(v, 'g')}"
        for k, v in plant.items()
        if base.get(k, None) != v and not (v is None and k not in base)
    ]
    return (
        ctx["controller"],
        ctx.get("adaptation", "-"),  # (none, avr-pss: no adaptation)
        preset + (f" ({', '.join(extra)})" if extra else ""),
    )


def merge_cct(results: list[dict], order: list[str]) -> dict:
    """One CCT result from several (gain sets run under different plants or
    adaptation modes, each a `critical_clearing_times` result over the same locations
    and times): the sets in `order`; top-level "cct", "status", "islands" as the
    function gives them (a list for one set, a table name -> list for several)."""
    merged = {k: v for k, v in results[0].items() if k not in ("cct", "status")}
    merged.pop("islands", None)
    sets = {}
    for r in results:
        sets.update(r["sets"])
    merged["sets"] = {n: sets[n] for n in order}
    for key in ("cct", "status", "islands"):
        merged[key] = (
            sets[order[0]][key] if len(order) == 1 else {n: sets[n][key] for n in order}
        )
    return merged


def _fmt(x, spec=".2f") -> str:
    return (
        "-"
        if x is None or (isinstance(x, float) and not math.isfinite(x))
        else format(x, spec)
    )


def islands_text(islands) -> str:
    """Stable islands of clearing durations as '[0.4, 0.45] s'."""
    return ", ".join(f"[{lo:g}, {hi:g}] s" for lo, hi in islands)


def physics_cells(ph: dict) -> str:
    """The physics cells of a compare row (a Monte Carlo summary's "physics"): mean
    total variation of the applied inputs (chatter, pu), mean percentage of the run
    on a limit, the largest commanded inputs (pu, before limits), the range of Vt
    (pu) over all scenarios; "-" where the rows predate these columns."""
    if not ph:
        return " | ".join(["-"] * 4)
    return (
        f"{ph['tv_uf_mean']:.3g} / {ph['tv_ur_mean']:.3g} | "
        f"{100 * ph['limit_time_uf_mean']:.1f} / {100 * ph['limit_time_ur_mean']:.1f} | "
        f"{ph['peak_uf_cmd_max']:.3g} / {ph['peak_ur_cmd_max']:.3g} | "
        f"{ph['Vt_min']:.3f}..{ph['Vt_max']:.3f}"
    )


def compare_table(
    summaries: dict[str, dict], cct: dict, contexts: dict[str, dict] | None = None
) -> str:
    """Markdown: one row per gain set (its context: controller, adaptation, plant;
    Monte Carlo summary; CCT (s) per location under the CCT's criterion)."""
    locs = cct["fault_location"]
    contexts = contexts or {}
    head = (
        "| gain set | controller | adaptation | plant | stable % (95% CI) | "
        "mean t_s (s) | p95 t_s (s) | p95 overshoot (rad) | "
        "chatter u_f / u_r (pu) | time on a limit u_f / u_r (%) | "
        "peak commanded u_f / u_r (pu) | Vt range (pu) | "
        + " | ".join(f"CCT @ {lam:g} (s)" for lam in locs)
        + " |"
    )
    lines = [head, "|" + "---|" * (12 + len(locs))]
    for name, s in summaries.items():
        lo, hi = s["stable_fraction_ci95"]
        st, ov = s["settling_time"], s["overshoot"]
        r = cct["sets"][name]
        cells = []
        for v, status, isl in zip(
            r["cct"], r["status"], r.get("islands", [[]] * len(locs)), strict=True
        ):
            again = f" (stable again {islands_text(isl)})" if isl else ""
            if status == "exceeds_window":
                cells.append(f"> {cct['window']:.3g}")
            elif status == "unstable_at_min":
                cells.append("none" + again)
            else:
                cells.append(f"{v:.3f}" + (" non-monotone" + again if isl else ""))
        ctx = context_text(contexts[name]) if name in contexts else ("-", "-", "-")
        lines.append(
            f"| {name} | {' | '.join(ctx)} | {100 * s['stable_fraction']:.1f} "
            f"({100 * lo:.1f}-"
            f"{100 * hi:.1f}) | {_fmt(st.get('mean'))} | {_fmt(st.get('p95'))} | "
            f"{_fmt(ov.get('p95'), '.3f')} | {physics_cells(s.get('physics', {}))} | "
            + " | ".join(cells)
            + " |"
        )
    return "\n".join(lines) + "\n"


def plot_compare(rows: dict[str, dict], cct: dict, path) -> None:
    """Left: delta settling-time distributions (stable scenarios) per set; middle:
    CCT against fault location per set (each set its own marker and a small
    horizontal offset, so that equal curves stay visible; a CCT beyond the window
    is an open triangle on the window line, not joined); right: the stable
    fraction per set where it differs between sets, else the mean time on a
    limit of u_f and u_r (%)."""
    import numpy as np

    from .plotting import plot_islands, save_figure, subplots

    names = list(rows)
    fig, axes = subplots(1, 3, figsize=(17, 5.2))
    data = []
    for n in names:
        ts = rows[n]["settling_time"][rows[n]["stable"].astype(bool)]
        data.append(ts[np.isfinite(ts)] if ts.size else np.array([np.nan]))
    axes[0].boxplot(data, tick_labels=names)
    axes[0].tick_params(axis="x", rotation=20)
    axes[0].set_ylabel("delta settling time (s)")
    axes[0].set_title("settling, stable scenarios", fontsize=10)
    loc = np.asarray(cct["fault_location"], dtype=float)
    span = float(np.ptp(loc)) if loc.size > 1 else 1.0
    markers = "osD^vP*X"
    beyond_drawn = none_drawn = False
    for i, n in enumerate(names):
        dx = (i - (len(names) - 1) / 2) * 0.012 * span
        c = np.array(
            [np.nan if v is None else v for v in cct["sets"][n]["cct"]], dtype=float
        )
        st = np.asarray(cct["sets"][n]["status"])
        beyond = st == "exceeds_window"
        c[beyond] = np.nan
        (line,) = axes[1].plot(
            loc + dx, c, marker=markers[i % len(markers)], ls="-", label=n, ms=5
        )
        if beyond.any():
            axes[1].plot(
                loc[beyond] + dx,
                np.full(beyond.sum(), cct["window"]),
                "^",
                mfc="none",
                mec=line.get_color(),
                ms=8,
                ls="none",
                label=None if beyond_drawn else "beyond the window",
            )
            beyond_drawn = True
        none = st == "unstable_at_min"
        if none.any():
            axes[1].plot(
                loc[none] + dx,
                np.zeros(none.sum()),
                "x",
                color=line.get_color(),
                ms=9,
                mew=2,
                ls="none",
                label=None if none_drawn else "none (unstable at the shortest)",
            )
            none_drawn = True
        plot_islands(axes[1], cct, n, line.get_color())
    axes[1].set_ylim(bottom=-0.05)
    axes[1].axhline(cct["window"], color="k", ls="--", lw=1)
    axes[1].set_xlabel("fault location (fraction of the line)")
    axes[1].set_ylabel("CCT (s)")
    axes[1].set_title(
        f"critical clearing time ({cct.get('criterion', 'settled')}); dashed: window",
        fontsize=10,
    )
    axes[1].legend(fontsize=8, loc="best")
    frac = [100 * float(np.mean(rows[n]["stable"])) for n in names]
    x = np.arange(len(names))
    if len(set(frac)) > 1:
        axes[2].bar(x, frac, color="C0")
        axes[2].set_ylabel("stable scenarios (%)")
        axes[2].set_ylim(0, 105)
        axes[2].set_title("stable fraction", fontsize=10)
    else:
        for j, (key, label) in enumerate(
            (("limit_time_uf", "u_f"), ("limit_time_ur", "u_r"))
        ):
            vals = [
                100 * float(np.mean(rows[n][key])) if key in rows[n] else np.nan
                for n in names
            ]
            axes[2].bar(x + (j - 0.5) * 0.38, vals, width=0.38, label=label)
        axes[2].set_ylabel("mean time on a limit (%)")
        axes[2].set_title(
            f"input limits (every set {frac[0]:.0f}% stable)", fontsize=10
        )
        axes[2].legend(fontsize=8)
    axes[2].set_xticks(x, names, rotation=20)
    for a in axes:
        a.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path)


def _dist_items(dist) -> list:
    """(name, (lo, hi)) of a scenario distribution's ranges (a fixed value as
    lo = hi; the damping D, when not drawn, as the plant's 0.2)."""
    out = [] if "D" in dist.to_dict() else [("D (the plant's)", (0.2, 0.2))]
    for k, v in dist.to_dict().items():
        if isinstance(v, (list, tuple)) and len(v) == 2:
            out.append((k, (float(v[0]), float(v[1]))))
        elif isinstance(v, (int, float)):
            out.append((k, (float(v), float(v))))
    return out


def write_compare(out: Path, summaries, rows, cct, contexts=None) -> None:
    """compare.md, compare.json and compare.png in `out`; `contexts`: name ->
    `Context.describe()` of each set."""
    from .._files import write_json, write_text

    contexts = contexts or {}
    table = compare_table(summaries, cct, contexts)
    crit = cct.get("criterion", "settled")
    from .report import plant_text

    plants = sorted(
        {
            plant_text(c["plant"] | _preset_limits(c["plant"]), c["plant"]["preset"])
            for c in contexts.values()
        }
    )
    where = f"Plant: {'; '.join(plants)}.\n\n" if plants else ""
    write_text(
        out / "compare.md",
        f"# Gain sets compared\n\n{where}CCT criterion: {crit}.\n\n" + table,
    )
    write_json(
        out / "compare.json",
        {"context": contexts, "montecarlo": summaries, "cct": cct},
    )
    plot_compare(rows, cct, out / "compare.png")


def add_parser(sub) -> None:
    from .cct import add_cct_options
    from .grid import add_case_options, add_montecarlo_options
    from .montecarlo import add_mc_options
    from .options import add_max_steps, add_phi_layer, add_tolerances

    k = sub.add_parser(
        "compare", help="Monte Carlo and CCT of several gain sets side by side"
    )
    k.add_argument(
        "--gains",
        action="append",
        metavar="FILE|NAME",
        help="a complete gains file or a built-in set (paper, paper-asc, stable, "
        "stable-asc, none, avr-pss); repeat for each set (default: paper, "
        "paper-asc, stable)",
    )
    k.add_argument(
        "--set",
        metavar="NAME=VALUE",
        action="append",
        default=[],
        help="override a gain (all sets), plant or operating-point value",
    )
    k.add_argument(
        "--preset",
        choices=["paper", "realistic"],
        default=None,
        help="plant of every set (default: each file's, else paper)",
    )
    k.add_argument(
        "--adaptation",
        choices=["oracle", "realizable"],
        default=None,
        help="adaptation of every set (default: each file's, else oracle)",
    )
    add_max_steps(k)
    add_phi_layer(k)
    add_tolerances(k)
    add_mc_options(k, 1000)
    add_cct_options(k, with_reactance=False)
    k.add_argument(
        "--out", metavar="DIR", help="output folder (default: runs/compare-<time>)"
    )
    add_case_options(k, events=False)
    k.add_argument(
        "--variant",
        action="append",
        default=[],
        metavar="LABEL:MODEL.PARAM=VALUE[,...]",
        help="with --case: a further parameter set to compare (repeatable); --param "
        "values form the set 'param'; the case's own parameters are the set 'case'",
    )
    add_montecarlo_options(k)
    k.set_defaults(func=run, flags=k.flags)


def output(args) -> Path:
    """The output folder: --out, else a new folder runs/compare-<time>
    (`OUTPUT_ROOT`); also of `compare --case`."""
    from .._commandline import out_path

    return out_path(args.out, "compare")


def run(args) -> int:
    from .cct import check_args, progress_bar, run_grouped
    from .montecarlo import run_folder, runner_of, spec_from_args
    from .options import (
        CLIError,
        build_parameters,
        controller_of,
        parse_sets,
        plant_note,
        read_dist,
        warn_plant_sets,
        with_phi_layer,
    )

    if args.case:
        from .grid import run_compare

        return run_compare(args)
    check_args(args)
    sets = parse_sets(args.set)
    specs = args.gains or ["paper", "paper-asc", "stable"]
    gain_sets, contexts, stated = {}, {}, {}
    for item in specs:
        given, spec = split_label(item)
        label, g, ctx, messages = resolve_gain_set_context(
            spec, sets, args.adaptation, args.preset
        )
        label = given or label
        for m in messages:
            print(f"smibjax: {m}", file=sys.stderr)
        warn_plant_sets(ctx, sets)
        _warn_dropped_sets(label, ctx, sets)
        ctx = with_phi_layer(ctx, args.phi_layer)
        label = safe_label(label)
        base, i = label, 2
        while label in gain_sets:
            if given:
                raise CLIError(f"--gains label {given!r} is given twice")
            label, i = f"{base}-{i}", i + 1
        gain_sets[label], contexts[label] = g, ctx
        stated[label] = _stated_context(spec)
    contexts, notes = fair_contexts(contexts, stated, args.preset, args.adaptation)
    for note in notes:
        print(f"smibjax: {note}", file=sys.stderr)
    # each set under its own plant and adaptation: (plant, op, init) per set
    parts = {
        label: build_parameters(
            ctx.controller, ctx.preset, None, sets, plant_values=ctx.plant
        )[1:]
        for label, ctx in contexts.items()
    }
    for label, ctx in contexts.items():  # a conventional set on the unlimited plant
        note = plant_note(ctx.controller, ctx.preset, parts[label][0])
        if note:
            print(f"smibjax: {note} (set {label})", file=sys.stderr)
    dist = read_dist(args.dist)
    if args.dist is None and any(c is not None for c in stated.values()):
        print(
            "smibjax: note: the scenarios keep the damping D at the plant's 0.2, where "
            "the tuner draws it in [0.1, 0.4]: --dist tuning/configs/default.toml "
            "compares on the tuner's distribution",
            file=sys.stderr,
        )
    out = output(args)
    from .._files import check_out_folder

    check_out_folder(out)  # before any work
    if out.exists() and any(out.iterdir()) and not args.resume:
        raise CLIError(
            f"--out {str(out)!r} exists and is not empty: choose a new folder or add "
            "--resume"
        )
    summaries, rows = {}, {}
    with runner_of(args) as runner:
        for label, g in gain_sets.items():
            print(f"== {label}")
            plant, op, init = parts[label]
            args_set = argparse.Namespace(
                **{
                    **vars(args),
                    "adaptation": contexts[label].adaptation,
                    "controller": contexts[label].controller,
                    "context": contexts[label],
                }
            )
            spec = spec_from_args(args_set, g, plant, op, init, dist)
            sub = out / label
            resume = args.resume and (sub / "run.json").is_file()
            r, s = run_folder(spec, sub, resume, runner, label)
            summaries[label], rows[label] = s, r
    # one CCT sweep per (adaptation, plant) group of sets
    groups: dict[tuple, list[str]] = {}
    for label, ctx in contexts.items():
        key = (ctx.adaptation, ctx.preset, tuple(sorted(ctx.plant.items())))
        groups.setdefault(key, []).append(label)
    results = []
    for (adaptation, *_), labels in groups.items():
        plant, op, init = parts[labels[0]]
        lanes = {
            n: controller_of(gain_sets[n], adaptation, contexts[n]) for n in labels
        }
        args_group = argparse.Namespace(**{**vars(args), "adaptation": adaptation})
        from .._commandline import announce_compile, progress_bars

        with (
            progress_bars() as make,
            announce_compile("the CCT scan and bisection", "jit_run"),
        ):
            results.append(
                run_grouped(
                    args_group,
                    lanes,
                    plant,
                    op,
                    init,
                    lambda make=make: progress_bar(make=make),
                )
            )
    res = merge_cct(results, list(gain_sets))
    write_compare(
        out,
        summaries,
        rows,
        res,
        {label: ctx.describe() for label, ctx in contexts.items()},
    )
    print(
        "scenarios: "
        + ", ".join(f"{k} in [{lo:g}, {hi:g}]" for k, (lo, hi) in _dist_items(dist))
    )
    print((out / "compare.md").read_text())
    print(f"wrote {out}/compare.md, compare.json, compare.png")
    return 0
