"""A trajectory in the file formats engineers open, chosen by the output's suffix:
`.npz` (NumPy, every array and a JSON `meta`), `.csv` (a wide table: one row per
sample, one column per signal, the header naming each signal, its device by PSS/E
number or generator bus:id, and its unit), `.mat` (MATLAB v5, `load run.mat`: every
array by name, time as a column, the signal table's names and units), and `.cfg`
(COMTRADE, IEEE C37.111-1999 ASCII: `run.cfg` and `run.dat`).

The columns are (name, device, unit, values): `grid_columns` for a multi-machine
run (`simulate --case`), `smib_columns` for the paper's SMIB. Writes are atomic
(`_files.atomic_write`). Importing this module loads neither JAX nor matplotlib
(`check_trajectory_path` answers before the command line starts JAX); SciPy (a
dependency of JAX) is loaded only to write `.mat`.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "FormatError",
    "TRAJECTORY_FORMATS",
    "Column",
    "check_trajectory_path",
    "grid_columns",
    "smib_columns",
    "write_trajectory",
    "write_csv",
    "write_mat",
    "write_comtrade",
    "COMTRADE_RANGE",
]


class FormatError(ValueError):
    """An output name whose suffix names no format written here (one line)."""


TRAJECTORY_FORMATS = {
    ".npz": "NumPy arrays",
    ".csv": "a wide CSV table",
    ".mat": "MATLAB v5",
    ".cfg": "COMTRADE (IEEE C37.111-1999 ASCII: .cfg + .dat)",
}
"""The suffixes `simulate --out` writes, with what each holds."""

Column = tuple[str, str, str, np.ndarray]
"""(signal, device, unit, values over the samples): ("delta", "G 23:2", "rad", ...)."""


def check_trajectory_path(path, option: str = "--out") -> Path:
    """`path` as a Path when its suffix names a trajectory format (`.npz`, `.csv`,
    `.mat`, `.cfg`; a name without a suffix gets `.npz`); any other suffix is a
    one-line `FormatError` naming the allowed ones, and so is `.mat` where SciPy
    (the optional extra `mat`; a dependency of JAX) is not installed."""
    p = Path(path)
    if not p.suffix:
        return p.with_name(p.name + ".npz")
    if p.suffix.lower() not in TRAJECTORY_FORMATS:
        allowed = ", ".join(f"{s} ({w})" for s, w in TRAJECTORY_FORMATS.items())
        raise FormatError(
            f"{option} = {str(p)!r} is not allowed: the suffix must be one of {allowed}"
        )
    if p.suffix.lower() == ".mat":
        import importlib.util

        if importlib.util.find_spec("scipy") is None:  # (JAX needs it: rare)
            raise FormatError(
                f"{option} = {str(p)!r} is not allowed here: .mat needs SciPy "
                "(pip install 'smibjax[mat]'); .npz, .csv and .cfg need nothing more"
            )
    return p


def companion_files(path) -> list[Path]:
    """The files a trajectory output writes: the path itself, and for COMTRADE its
    `.dat` beside the `.cfg`."""
    p = Path(path)
    return [p, p.with_suffix(".dat")] if p.suffix.lower() == ".cfg" else [p]


def grid_columns(a: dict) -> list[Column]:
    """The signals of a `simulate --case` run (`a`: its arrays) as columns: per
    generator (bus:id) the angle from the centre of inertia and the synchronous
    frame's angle (rad), the speed deviation (pu), Pe and Pm (pu machine base), Efd,
    Vs and the terminal voltage (pu); per bus (PSS/E number) the voltage magnitude
    (pu)."""
    gens = [f"G {g}" for g in a["gen"]]
    per_gen = (
        ("delta_coi", "rad"),
        ("delta", "rad"),
        ("omega", "pu"),
        ("pe", "pu"),
        ("pm", "pu"),
        ("efd", "pu"),
        ("vs", "pu"),
        ("vt", "pu"),
    )
    cols: list[Column] = []
    for key, unit in per_gen:
        y = np.asarray(a[key], dtype=float)
        cols += [(key, g, unit, y[:, i]) for i, g in enumerate(gens)]
    vb = np.asarray(a["v_bus"], dtype=float)
    cols += [("v_bus", f"bus {int(b)}", "pu", vb[:, i]) for i, b in enumerate(a["bus"])]
    # issue 47: per renewable plant (bus:id) its currents, limits and powers (pu
    # machine base) and its terminal voltage angle (rad)
    for key in [k for k in a if k.startswith("ibr_") and k != "ibr_gen"]:
        y = np.asarray(a[key], dtype=float)
        unit = "rad" if key == "ibr_Va" else "pu"
        cols += [(key, f"G {g}", unit, y[:, i]) for i, g in enumerate(a["ibr_gen"])]
    return cols


_SMIB_UNITS = {
    "delta": "rad",
    "omega": "rad/s",
    "E": "pu",
    "B": "pu",
    "Vt": "pu",
    "u_f": "pu",
    "u_r": "pu",
    "u_f_cmd": "pu",
    "u_r_cmd": "pu",
    "theta_hat": "-",
    "phi": "-",
}


def smib_columns(a: dict) -> list[Column]:
    """The signals of an SMIB run (`a`: `plotting.trajectory_arrays`) as columns:
    delta (rad), omega - omega_s (rad/s), E', B, Vt, u_f, u_r and their commands
    (pu), the estimates theta_hat and macro-variables phi (two columns each)."""
    cols: list[Column] = []
    for key, unit in _SMIB_UNITS.items():
        if key not in a:
            continue
        y = np.asarray(a[key], dtype=float)
        if y.ndim == 1:
            cols.append((key, "SMIB", unit, y))
        else:
            cols += [
                (f"{key}{j + 1}", "SMIB", unit, y[:, j]) for j in range(y.shape[1])
            ]
    return cols


def _header(col: Column) -> str:
    name, device, unit, _ = col
    return f"{name} {device} ({unit})"


def write_csv(path, t, columns: Sequence[Column]) -> None:
    """A wide table: the header `t (s)`, then `SIGNAL DEVICE (UNIT)` per column
    ("delta_coi G 23:2 (rad)", "v_bus bus 7 (pu)"), one row per sample; numbers
    with 10 significant digits, a missing sample (NaN) as an empty cell."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["t (s)", *(_header(c) for c in columns)])
    data = np.column_stack([np.asarray(t, dtype=float), *(c[3] for c in columns)])
    for row in data:
        w.writerow(["" if not np.isfinite(x) else f"{x:.10g}" for x in row])
    text = buf.getvalue()
    from ._files import atomic_write

    atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def write_mat(path, arrays: dict, columns: Sequence[Column]) -> None:
    """MATLAB v5 (`scipy.io.savemat`): every numeric array of `arrays` by its name
    (1-D arrays as columns), text arrays as char matrices, and the table of signals:
    `signals` (samples x columns), `signal_names` (one row per column, as the CSV
    header names it)."""
    from scipy.io import savemat

    from ._files import atomic_write

    out = {}
    for k, v in arrays.items():
        v = np.asarray(v)
        out[k] = v if v.dtype.kind in "biufcU" else str(v)
    out["signals"] = (
        np.column_stack([c[3] for c in columns]) if columns else np.zeros(0)
    )
    out["signal_names"] = np.array([_header(c) for c in columns])
    atomic_write(
        path,
        lambda tmp: savemat(tmp, out, oned_as="column", do_compression=True),
    )


COMTRADE_RANGE = 99998
"""The integers of a COMTRADE ASCII sample span +-`COMTRADE_RANGE`; 99999 marks a
missing sample (C37.111-1999)."""


def _comtrade_text(text: str) -> str:
    """A field of a COMTRADE configuration: no commas, at most 64 characters."""
    return str(text).replace(",", ";")[:64]


def _stamp(seconds: float) -> str:
    """A COMTRADE time stamp `seconds` (>= 0, < 1 day) after 01/01/2000 00:00:00."""
    us = int(round(max(seconds, 0.0) * 1e6))
    h, rest = divmod(us, 3_600_000_000)
    m, rest = divmod(rest, 60_000_000)
    return f"01/01/2000,{h:02d}:{m:02d}:{rest // 1_000_000:02d}.{rest % 1_000_000:06d}"


def write_comtrade(
    path,
    t,
    columns: Sequence[Column],
    station: str,
    frequency: float = 60.0,
    trigger: float = 0.0,
) -> None:
    """COMTRADE (IEEE C37.111-1999, ASCII): `path` (.cfg) and the `.dat` beside it.
    One analog channel per column (channel id `SIGNAL DEVICE`, circuit component
    the device, the unit), no digital channels; each sample an integer x in
    +-`COMTRADE_RANGE` with the value a*x + b (a, b per channel from its range),
    99999 where the sample is missing; one sampling rate (1/dt, Hz); time stamps in
    microseconds from the first sample (01/01/2000 00:00:00), the trigger at
    `trigger` s. `frequency`: the system's nominal frequency (Hz)."""
    t = np.asarray(t, dtype=float)
    n = t.size
    dt = float(t[1] - t[0]) if n > 1 else 1.0
    lines = [
        f"{_comtrade_text(station)},smibjax,1999",
        f"{len(columns)},{len(columns)}A,0D",
    ]
    ints = []
    for k, (name, device, unit, y) in enumerate(columns, start=1):
        y = np.asarray(y, dtype=float)
        ok = np.isfinite(y)
        lo, hi = (float(y[ok].min()), float(y[ok].max())) if ok.any() else (0.0, 0.0)
        b = 0.5 * (lo + hi)
        a = (hi - lo) / (2 * COMTRADE_RANGE) or max(abs(b), 1.0) * 1e-9
        x = np.full(n, 99999, dtype=np.int64)
        x[ok] = np.clip(np.rint((y[ok] - b) / a), -COMTRADE_RANGE, COMTRADE_RANGE)
        ints.append(x)
        lines.append(
            f"{k},{_comtrade_text(f'{name} {device}')},,{_comtrade_text(device)},"
            f"{_comtrade_text(unit)},{a:.9g},{b:.9g},0,{-COMTRADE_RANGE},"
            f"{COMTRADE_RANGE},1,1,P"
        )
    trig = float(trigger)
    lines += [
        f"{frequency:g}",
        "1",
        f"{1.0 / dt:.9g},{n}",
        _stamp(0.0),
        _stamp(trig),
        "ASCII",
        "1",
    ]
    us = np.rint((t - t[0]) * 1e6).astype(np.int64)
    data = np.column_stack([np.arange(1, n + 1), us, *ints]) if n else np.zeros((0, 2))
    dat = "".join(",".join(str(int(v)) for v in row) + "\r\n" for row in data)
    cfg = "\r\n".join(lines) + "\r\n"
    from ._files import atomic_write

    p = Path(path)
    atomic_write(p.with_suffix(".dat"), lambda tmp: Path(tmp).write_bytes(dat.encode()))
    atomic_write(p, lambda tmp: Path(tmp).write_bytes(cfg.encode()))


def write_trajectory(
    path: str | os.PathLike,
    arrays: dict,
    columns: Sequence[Column],
    station: str = "smibjax",
    frequency: float = 60.0,
    trigger: float = 0.0,
) -> list[Path]:
    """Write a run in the format `path`'s suffix names (`check_trajectory_path`):
    `.npz` every array of `arrays`; `.csv`, `.mat`, `.cfg` the `columns` against
    `arrays["t"]` (s) (`.mat` also every array). Returns the files written."""
    from ._files import write_npz

    p = Path(path)
    kind = p.suffix.lower()
    if kind == ".npz":
        write_npz(p, arrays)
    elif kind == ".csv":
        write_csv(p, arrays["t"], columns)
    elif kind == ".mat":
        write_mat(p, arrays, columns)
    elif kind == ".cfg":
        write_comtrade(p, arrays["t"], columns, station, frequency, trigger)
    else:  # pragma: no cover - check_trajectory_path refuses it first
        raise FormatError(f"{str(p)!r}: no trajectory format for {kind!r}")
    return companion_files(p)
