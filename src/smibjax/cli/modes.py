"""`python -m smibjax modes`: the small-signal modes of a multi-machine case (table,
JSON, CSV, complex-plane and mode-shape plots) and their root locus over one
parameter (`--sweep`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

import csv
import io
import math
import sys

from .options import CLIError, parse_sets

__all__ = ["add_parser", "run", "parse_sweep"]


def add_parser(sub) -> None:
    s = sub.add_parser(
        "modes",
        help="small-signal modes of a multi-machine case: damping, participation",
    )
    s.add_argument(
        "--case",
        required=True,
        help="a built-in case (kundur, kundur-nopss, kundur-gencls, kundur-synex, ieee39, ...) or "
        "a PSS/E raw file (with --dyr)",
    )
    s.add_argument("--dyr", metavar="FILE", help="the dyr file of a raw --case")
    s.add_argument(
        "--skip-unsupported",
        action="store_true",
        help="skip the dyr records of models smibjax does not have (one warning per "
        "model) instead of refusing the file",
    )
    s.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="MODEL.PARAM=VALUE",
        help="set a device parameter (IEEEST.KS=10, SEXS[1:1].K=100); repeatable",
    )
    s.add_argument(
        "--gains",
        metavar="FILE",
        help='device parameters from a JSON or TOML table {"MODEL.PARAM": value} '
        "(e.g. tuned PSS settings); --set entries override it",
    )
    s.add_argument(
        "--load-factor",
        type=float,
        default=1.0,
        help="scale every load (and the non-slack generation) by this factor",
    )
    s.add_argument("--out", metavar="FILE.json", help="every eigenvalue, JSON")
    s.add_argument("--csv", metavar="FILE.csv", help="every eigenvalue, CSV")
    s.add_argument(
        "--plot",
        metavar="FILE.png",
        help="eigenvalues on the complex plane and the electromechanical mode shapes "
        "(with --sweep: the root locus)",
    )
    s.add_argument(
        "--sweep",
        metavar="PARAM=lo:hi:n",
        help="trace the electromechanical modes as PARAM goes from lo to hi in n steps",
    )
    s.add_argument("--force", action="store_true", help="replace existing output files")
    s.set_defaults(func=run, flags=s.flags)


def parse_sweep(text: str) -> tuple[str, np.ndarray]:
    """`PARAM=lo:hi:n` as (PARAM, n values from lo to hi); one-line `CLIError`."""
    import numpy as np

    name, sep, rng = text.partition("=")
    parts = rng.split(":")
    if not sep or not name.strip() or len(parts) != 3:
        raise CLIError(f"--sweep {text!r} is not allowed: expected PARAM=lo:hi:n")
    try:
        lo, hi = float(parts[0]), float(parts[1])
        n = int(parts[2])
    except ValueError:
        raise CLIError(
            f"--sweep {text!r} is not allowed: lo and hi must be numbers, n an integer"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise CLIError(f"--sweep {text!r} is not allowed: lo and hi must be finite")
    if n < 2:
        raise CLIError(f"--sweep {text!r} is not allowed: n must be at least 2")
    if not hi > lo:
        raise CLIError(
            f"--sweep {text!r} is not allowed: the range is empty or reversed"
        )
    return name.strip(), np.linspace(lo, hi, n)


def _outputs(args):
    """The output paths, checked before any work."""
    from .._figures import check_plot_path
    from .._files import check_new_file

    out = {}
    for opt, key in (("--out", "out"), ("--csv", "csv"), ("--plot", "plot")):
        path = getattr(args, key)
        if path is not None:
            if key == "plot":
                check_plot_path(path)
            out[key] = check_new_file(path, args.force, opt)
    return out


def _gains_file(path) -> dict:
    """{name: value} from a --gains file: a JSON or TOML table of device parameters
    by name (`smibjax.grid.params`), numbers only."""
    if not path:
        return {}
    from .._files import read_data

    try:
        table = read_data(path)
    except OSError as e:
        raise CLIError(f"--gains {path}: {e.strerror or e}") from None
    except ValueError as e:
        raise CLIError(f"--gains {path}: {str(e).splitlines()[0]}") from None
    if not isinstance(table, dict):
        raise CLIError(f"--gains {path}: must be a table of MODEL.PARAM = value")
    out = {}
    for k, v in table.items():
        if (
            isinstance(v, bool)
            or not isinstance(v, int | float)
            or not math.isfinite(v)
        ):
            raise CLIError(f"--gains {path}: {k} = {v!r} is not a finite number")
        out[str(k)] = float(v)
    return out


def _load(args):
    from ..grid.case import CaseError
    from ..grid.params import ParamError, get_param, set_params
    from ..grid.psse import PsseError
    from .grid import load_case_reporting

    try:
        case = load_case_reporting(args.case, args.dyr, args.skip_unsupported)
    except (CaseError, FileNotFoundError) as e:
        raise CLIError(f"--case {args.case!r} is not allowed: {e}") from None
    except PsseError as e:  # a record the reader refuses: file:line: what
        raise CLIError(str(e)) from None
    sets = {**_gains_file(args.gains), **parse_sets(args.set)}
    try:
        for name in sets:
            get_param(case, name)
        case = set_params(case, sets) if sets else case
    except ParamError as e:
        raise CLIError(f"--set: {e}") from None
    return case, sets


def _operating(case, load_factor):
    from ..grid.modes import check_equilibrium
    from ..grid.operating import operating_point
    from ..grid.powerflow import PowerFlowError

    try:
        op, _ = operating_point(case, load_factor=load_factor)
    except PowerFlowError as e:
        raise CLIError(f"the power flow failed: {e}") from None
    try:
        check_equilibrium(case, op)
    except ValueError as e:
        raise CLIError(str(e)) from None
    return op


def _mode_dict(m, lin):
    from ..grid.modes import dominant_machines

    return {
        "index": m.index,
        "real": m.eigenvalue.real,
        "imag": m.eigenvalue.imag,
        "frequency_hz": m.frequency,
        "damping": m.damping,
        "kind": m.kind,
        "scope": m.scope,
        "dominant_states": [[name, p] for name, p in m.dominant],
        "dominant_machines": list(dominant_machines(m)),
        "speed_shape": {g: [v.real, v.imag] for g, v in m.shape.items()},
    }


def table(ms) -> str:
    """The electromechanical modes as a text table."""
    from ..grid.modes import dominant_machines

    lines = [
        f"{'mode':>4}  {'eigenvalue (1/s)':>22}  {'f (Hz)':>7}  {'zeta (%)':>8}  "
        f"{'scope':<10}  dominant machines"
    ]
    em = [m for m in ms if m.kind == "electromechanical"]
    for k, m in enumerate(em):
        lam = m.eigenvalue
        lines.append(
            f"{k + 1:>4}  {lam.real:>10.4f} {lam.imag:+10.4f}j  {m.frequency:>7.4f}  "
            f"{100 * m.damping:>8.3f}  {m.scope:<10}  {', '.join(dominant_machines(m))}"
        )
    others = {}
    for m in ms:
        if m.kind != "electromechanical":
            others[m.kind] = others.get(m.kind, 0) + 1
    if others:
        lines.append(
            "other modes: " + ", ".join(f"{n} {k}" for k, n in sorted(others.items()))
        )
    return "\n".join(lines)


def _csv_text(ms, lin) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    labels = [f"{lab[1]} {lab[2]} ({lab[0]})" for lab in lin.states]
    w.writerow(
        ["index", "real", "imag", "frequency_hz", "damping", "kind", "scope", *labels]
    )
    import numpy as _np

    lam, R = _np.linalg.eig(lin.A)
    from ..grid.modes import participation

    P = participation(R, _np.linalg.inv(R))
    for m in ms:
        w.writerow(
            [
                m.index,
                repr(m.eigenvalue.real),
                repr(m.eigenvalue.imag),
                repr(m.frequency),
                "" if math.isnan(m.damping) else repr(m.damping),
                m.kind,
                m.scope,
                *(f"{p:.6g}" for p in P[:, m.index]),
            ]
        )
    return buf.getvalue()


def _analyse(case, op):
    from ..grid.modes import linearize, modes

    lin = linearize(case, op)
    return lin, modes(case, lin)


def _plot_modes(path, ms, title):
    import numpy as np
    from matplotlib.figure import Figure

    from .plotting import save_figure

    em = [m for m in ms if m.kind == "electromechanical"]
    n_em = max(len(em), 1)
    ncol = max(min(n_em, 4), 2)
    nrow = 1 + math.ceil(n_em / ncol)
    fig = Figure(figsize=(3.4 * ncol, 3.6 * nrow), layout="constrained")
    gs = fig.add_gridspec(nrow, ncol)
    ax = fig.add_subplot(gs[0, :])
    _complex_plane(ax, ms)
    ax.set_title(title)
    for k, m in enumerate(em):
        a = fig.add_subplot(gs[1 + k // ncol, k % ncol], projection="polar")
        for g, v in m.shape.items():
            a.annotate(
                "",
                xy=(np.angle(v), abs(v)),
                xytext=(0, 0),
                arrowprops={"arrowstyle": "->", "lw": 1.5},
            )
            if abs(v) > 0.05:
                a.text(np.angle(v), abs(v) + 0.15, g, fontsize=8, ha="center")
        a.set_ylim(0, 1.3)
        a.set_yticklabels([])
        a.set_title(
            f"speed shape: {m.frequency:.3f} Hz, {100 * m.damping:.1f}%\n({m.scope})",
            fontsize=9,
            pad=12,
        )
    save_figure(fig, path)


def _damping_lines(ax, wmax, left):
    for z in (0.05, 0.1, 0.2, 0.3):
        slope = z / math.sqrt(1 - z * z)
        w_end = min(wmax, -left / slope)
        ax.plot([0, -slope * w_end], [0, w_end], ls="--", lw=0.8, color="0.6")
        ax.text(
            -slope * w_end * 0.97,
            w_end * 0.97,
            f"{int(100 * z)}%",
            fontsize=7,
            color="0.4",
            ha="right",
            va="top",
        )


def _window(lam_em, lam_all):
    """(left, wmax) of a complex-plane window around the electromechanical modes."""
    import numpy as np

    if lam_em.size:
        left = min(-1.0, 2.0 * float(lam_em.real.min()))
        wmax = 1.3 * float(lam_em.imag.max())
    else:
        left, wmax = -5.0, 1.1 * float(np.abs(lam_all.imag).max(initial=1.0))
    return left, max(wmax, 1.0)


def _complex_plane(ax, ms):
    import numpy as np

    lam = np.array([m.eigenvalue for m in ms])
    kinds = [m.kind for m in ms]
    em = lam[np.array([k == "electromechanical" for k in kinds], dtype=bool)]
    left, wmax = _window(em, lam)
    _damping_lines(ax, wmax, left)
    style = {
        "electromechanical": ("o", "C3"),
        "other": ("x", "C0"),
        "zero": ("s", "k"),
        "frozen": ("s", "0.7"),
    }
    for kind, (mk, col) in style.items():
        sel = np.array([k == kind for k in kinds], dtype=bool)
        if sel.any():
            ax.scatter(lam[sel].real, lam[sel].imag, marker=mk, color=col, label=kind)
    ax.set_xlim(left, max(0.5, -0.1 * left))
    ax.set_ylim(0, wmax)
    ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel("real part (1/s)")
    ax.set_ylabel("imaginary part (rad/s)")
    ax.legend(fontsize=8, loc="lower left")


def _plot_locus(path, param, values, tracks):
    import numpy as np

    from .plotting import save_figure, subplots

    fig, ax = subplots(figsize=(7, 5))
    allv = np.concatenate(list(tracks.values()))
    left, wmax = _window(allv, allv)
    _damping_lines(ax, wmax, left)
    for name, lam in tracks.items():
        ax.plot(lam.real, lam.imag, "-", lw=1)
        sc = ax.scatter(lam.real, lam.imag, c=values, cmap="viridis", s=18, zorder=3)
        ax.annotate(name, (lam.real[0], lam.imag[0]), fontsize=7)
    fig.colorbar(sc, ax=ax, label=param)
    ax.set_xlim(left, max(0.5, -0.1 * left))
    ax.set_ylim(0, wmax)
    ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel("real part (1/s)")
    ax.set_ylabel("imaginary part (rad/s)")
    ax.set_title(f"root locus of the electromechanical modes over {param}")
    fig.tight_layout()
    save_figure(fig, path)


def _assign(lam, last):
    """The eigenvalues of `lam` (upper half plane) matched one to one to `last`
    (minimum total distance), so that two tracked modes never take the same one."""
    import numpy as np
    from scipy.optimize import linear_sum_assignment

    cand = lam[lam.imag >= 0]
    rows, cols = linear_sum_assignment(np.abs(last[:, None] - cand[None, :]))
    out = np.empty(len(last), dtype=complex)
    out[rows] = cand[cols]
    return out


def _sweep(args, case, sets, param, values, outs):
    import numpy as np

    from .._files import write_json, write_text
    from ..grid.modes import damping_ratios, linearize
    from ..grid.params import ParamError, get_param, set_params

    try:
        get_param(case, param)
    except ParamError as e:
        raise CLIError(f"--sweep: {e}") from None
    op0 = _operating(case, args.load_factor)
    lin0, ms0 = _analyse(case, op0)
    ref = [m for m in ms0 if m.kind == "electromechanical"]
    names = [f"{m.frequency:.3f} Hz ({m.scope})" for m in ref]
    prev = np.array([m.eigenvalue for m in ref])
    order = np.argsort(np.abs(values - float(np.mean(get_param(case, param)))))
    tracks = np.zeros((len(values), len(ref)), dtype=complex)
    # Follow each mode from the value nearest the nominal outwards, by continuity
    # (a one-to-one assignment to the previous value's eigenvalues).
    start = int(order[0])
    for direction in (range(start, len(values)), range(start, -1, -1)):
        last = prev
        for i in direction:
            c = set_params(case, {param: float(values[i])})
            op = _operating(c, args.load_factor)
            lam = np.linalg.eigvals(linearize(c, op, inputs=(), outputs=()).A)
            pick = _assign(lam, last)
            tracks[i] = pick
            last = pick
    print(f"{param}: {len(values)} values from {values[0]:g} to {values[-1]:g}")
    head = f"{param:>14}  " + "  ".join(f"{n:>24}" for n in names)
    print(head)
    zeta = np.asarray(damping_ratios(tracks))
    for i, v in enumerate(values):
        cells = "  ".join(
            f"{tracks[i, j].imag / (2 * np.pi):>9.4f} Hz {100 * zeta[i, j]:>7.3f}%"
            for j in range(len(ref))
        )
        print(f"{v:>14.6g}  {cells}")
    data = {
        "case": args.case,
        "set": sets,
        "parameter": param,
        "values": values.tolist(),
        "modes": [
            {
                "name": names[j],
                "real": tracks[:, j].real.tolist(),
                "imag": tracks[:, j].imag.tolist(),
                "frequency_hz": (tracks[:, j].imag / (2 * np.pi)).tolist(),
                "damping": zeta[:, j].tolist(),
            }
            for j in range(len(ref))
        ],
    }
    if "out" in outs:
        write_json(outs["out"], data)
    if "csv" in outs:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow([param, *(f"{n} {q}" for n in names for q in ("f_hz", "zeta"))])
        for i, v in enumerate(values):
            row = [repr(float(v))]
            for j in range(len(ref)):
                row += [repr(tracks[i, j].imag / (2 * np.pi)), repr(float(zeta[i, j]))]
            w.writerow(row)
        write_text(outs["csv"], buf.getvalue())
    if "plot" in outs:
        _plot_locus(
            outs["plot"], param, values, dict(zip(names, tracks.T, strict=True))
        )
    return 0


def run(args) -> int:
    from .._files import write_json, write_text

    sweep = parse_sweep(args.sweep) if args.sweep is not None else None
    outs = _outputs(args)
    if not (math.isfinite(args.load_factor) and args.load_factor > 0):
        raise CLIError(
            f"--load-factor {args.load_factor} is not allowed: must be positive"
        )
    case, sets = _load(args)
    if sweep is not None:
        return _sweep(args, case, sets, *sweep, outs)
    op = _operating(case, args.load_factor)
    lin, ms = _analyse(case, op)
    print(f"case {args.case}: {lin.A.shape[0]} states")
    print(table(ms))
    sys.stdout.flush()
    if "out" in outs:
        write_json(
            outs["out"],
            {
                "case": args.case,
                "set": sets,
                "load_factor": args.load_factor,
                "states": [list(lab) for lab in lin.states],
                "modes": [_mode_dict(m, lin) for m in ms],
            },
        )
    if "csv" in outs:
        write_text(outs["csv"], _csv_text(ms, lin))
    if "plot" in outs:
        _plot_modes(outs["plot"], ms, f"{args.case}: eigenvalues")
    return 0
