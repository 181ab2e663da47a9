"""The paper's section 4 case, AFTSC against ASC, with the paper's gains and with a
stabilizing set (beta1 = beta2 = -1): figures in the spirit of Figs. 3-5, data files
and a metrics table. Called by `python -m smibjax reproduce`."""

from __future__ import annotations

from pathlib import Path

__all__ = ["GAIN_SETS", "reproduce", "add_parser", "run"]

GAIN_SETS = {
    "paper": {},  # beta1 = beta2 = 50: the paper's gains
    "stabilized": {"beta1": -1.0, "beta2": -1.0},
}
_CONTROLLERS = {"AFTSC": "aftsc", "ASC": "asc"}


def _write_csv(path: Path, a: dict) -> None:
    import numpy as np

    from .._files import atomic_write

    cols = [
        "t",
        "delta",
        "omega",
        "E",
        "B",
        "Vt",
        "th1_hat",
        "th2_hat",
        "phi1",
        "phi2",
        "u_f",
        "u_r",
    ]
    data = np.column_stack(
        [
            a["t"],
            a["delta"],
            a["omega"],
            a["E"],
            a["B"],
            a["Vt"],
            a["theta_hat"],
            a["phi"],
            a["u_f"],
            a["u_r"],
        ]
    )
    atomic_write(
        path,
        lambda tmp: np.savetxt(
            tmp, data, delimiter=",", header=",".join(cols), comments=""
        ),
    )


def reproduce(out: Path, preset: str = "paper", t_end: float = 10.0) -> dict:
    """Run the four cases, write figures/data/table under `out`; returns the metrics."""
    from .._commandline import announce_compile
    from .._files import write_json, write_npz, write_text
    from .._metrics import metrics
    from .._options import SaveOptions
    from .._parameters import Fault, Plant
    from .._simulate import simulate
    from ..controllers.synergetic import Gains
    from .plotting import plot_figure, trajectory_arrays
    from .report import markdown_table, metrics_dict

    plant = Plant.preset(preset)
    fault = Fault()
    theta = (-float(plant.D), float(plant.Pm))
    table: dict[str, dict] = {}
    for set_name, overrides in GAIN_SETS.items():
        runs = {}
        for label, ctrl in _CONTROLLERS.items():
            gains = Gains.paper(ctrl, **overrides)
            with announce_compile(f"the simulation ({set_name} {label})"):
                traj = simulate(gains, fault, plant, save=SaveOptions(t_end=t_end))
            a = trajectory_arrays(traj)
            runs[label] = a
            stem = f"{set_name}_{ctrl}"
            write_npz(out / f"{stem}.npz", a)
            _write_csv(out / f"{stem}.csv", a)
            m = metrics_dict(metrics(traj))
            m["lost_sync_at"] = float(a["t_stop"]) if a["lost_sync"] else None
            m["solver_steps"] = int(traj.num_steps)
            table[f"{set_name} {label}"] = m
            print(
                f"{set_name:>10} {label:5}: "
                + ("stable" if m["stable"] else "UNSTABLE")
                + (
                    f", lost synchronism at {m['lost_sync_at']:.3f} s"
                    if m["lost_sync_at"]
                    else f", delta settles in {m['settling_delta']:.2f} s"
                )
            )
        b = (
            "paper gains beta1 = beta2 = 50"
            if set_name == "paper"
            else "stabilizing gains beta1 = beta2 = -1"
        )
        for kind, name in (
            ("states", "fig3_states"),
            ("estimates", "fig4_estimates"),
            ("macro", "fig5_macro"),
            ("inputs", "inputs"),
        ):
            plot_figure(
                kind,
                runs,
                out / f"{set_name}_{name}.png",
                f"{b} (solid AFTSC alpha = 5/7, dotted ASC alpha = 1)",
                theta,
                events=(
                    float(fault.t_fault),
                    float(fault.t_clear),
                    float(fault.t_reclose),
                ),
            )
    md = [
        "# Paper section 4 case: fault 0.5 s, cleared 0.7 s, reclosed 2.0 s, "
        f"lam = 0.5, Xf = 0 ({preset} plant)",
        "",
        "Settling times from fault inception; bands 0.01 rad / 0.01 pu / "
        "0.01 rad/s; '-' = not settled.",
        "",
        markdown_table(table),
        "",
    ]
    write_text(out / "metrics.md", "\n".join(md))
    write_json(out / "metrics.json", table)
    print(f"wrote figures, data and metrics.md to {out}")
    return table


def add_parser(sub) -> None:
    from .options import add_force, positive

    r = sub.add_parser("reproduce", help="the paper's section 4 case, figures + table")
    r.add_argument(
        "--out", help="output folder (default: a new folder runs/reproduce-<time>)"
    )
    r.add_argument(
        "--preset",
        choices=["paper", "realistic"],
        default="paper",
        help="plant input limits: paper (none) or realistic",
    )
    r.add_argument("--t-end", type=positive, default=10.0, help="horizon (s)")
    add_force(r)
    r.set_defaults(func=run, flags=r.flags)


def output(args) -> Path:
    """The output folder: --out, else a new folder runs/reproduce-<time>
    (`OUTPUT_ROOT`)."""
    from .._commandline import out_path

    return out_path(args.out, "reproduce")


def run(args) -> int:
    from .._files import check_out_folder
    from .options import CLIError

    out = output(args)
    if out.exists() and not out.is_dir():
        raise CLIError(f"--out = {str(out)!r} is not allowed: must be a folder")
    if out.is_dir() and any(out.iterdir()) and not args.force:
        raise CLIError(
            f"--out = {str(out)!r} is not allowed: must be a new or empty folder (it "
            "holds files; add --force to replace the ones reproduce writes)"
        )
    check_out_folder(out)  # writable, before any work
    reproduce(out, preset=args.preset, t_end=args.t_end)
    return 0
