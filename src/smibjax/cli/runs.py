"""Monte Carlo run folders: chunk files, resume, CSV and markdown.

`run_montecarlo` runs the missing chunks of a `MonteCarloSpec` (in this process, or
through any `runner`, such as the Dask one in `smibjax.cli.cluster`), persists each as
`chunks/NNNNNN.npz` the moment it finishes (atomic rename), and assembles
`scenarios.csv`, `summary.json`, `summary.md` and the plots only when every chunk is
there. `run.json` records the spec and whether the run is complete.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import jax
import numpy as np

from .._files import write_json, write_npz, write_text
from .._montecarlo import (
    COLUMNS,
    INT_COLUMNS,
    MonteCarloSpec,
    in_process_runner,
    summarize,
)
from .._parameters import ParameterError
from .._validate import BYTES_PER_SAMPLE, check_tree, require_memory

__all__ = ["run_montecarlo", "read_rows", "write_csv", "summary_markdown"]


def summary_markdown(summary: dict, title: str = "Monte Carlo") -> str:
    """summary.json as a short markdown report."""
    s = summary
    lo, hi = s["stable_fraction_ci95"]
    lines = [
        f"# {title}",
        "",
        f"- scenarios: {s['n']}",
        f"- stable: {s['stable']} ({100 * s['stable_fraction']:.2f}%, 95% CI "
        f"{100 * lo:.2f}-{100 * hi:.2f}%)",
        f"- lost synchronism: {s['lost_sync']}",
        f"- step budget spent before t_end (counted as not stable): "
        f"{s.get('budget_exhausted', 0)}",
        f"- solver steps per scenario: mean {s['num_steps']['mean']:.0f}, "
        f"max {s['num_steps']['max']}",
        "",
        "Over the stable scenarios:",
        "",
        "| quantity | mean | p05 | p50 | p90 | p95 | p99 | max |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for key, label in (
        ("settling_time", "delta settling time (s, band 0.01 rad)"),
        ("settling_Vt", "Vt settling time (s, band 0.01 pu)"),
        ("overshoot", "first-swing overshoot (rad)"),
    ):
        q = s[key]
        if q["count"] == 0:
            lines.append(f"| {label} | - | - | - | - | - | - | - |")
            continue
        cols = [q[c] for c in ("mean", "p05", "p50", "p90", "p95", "p99", "max")]
        lines.append(f"| {label} | " + " | ".join(f"{v:.3f}" for v in cols) + " |")
    ph = s.get("physics") or {}
    if ph:
        lines += [
            "",
            "Physics, all scenarios (pu):",
            "",
            f"- peak commanded u_f / u_r (before limits): {ph['peak_uf_cmd_max']:.4g} "
            f"/ {ph['peak_ur_cmd_max']:.4g}",
            f"- mean fraction of time on a limit, u_f / u_r: "
            f"{ph['limit_time_uf_mean']:.3f} / {ph['limit_time_ur_mean']:.3f}",
            f"- mean total variation (chatter) of u_f / u_r: {ph['tv_uf_mean']:.4g} / "
            f"{ph['tv_ur_mean']:.4g}",
            f"- ranges: Vt {ph['Vt_min']:.3f}..{ph['Vt_max']:.3f}, "
            f"B {ph['B_min']:.3f}..{ph['B_max']:.3f}, "
            f"E' {ph['E_min']:.3f}..{ph['E_max']:.3f}",
        ]
    return "\n".join(lines) + "\n"


def write_csv(path: Path, rows: dict[str, np.ndarray]) -> None:
    """scenarios.csv: a header of `COLUMNS`, one line per scenario (inf: 'inf')."""
    # column by column as Python numbers (repr of a float round-trips it exactly)
    cols = [
        map(str, np.asarray(rows[c]).astype(np.int64).tolist())
        if c in INT_COLUMNS
        else map(repr, np.asarray(rows[c], dtype=np.float64).tolist())
        for c in COLUMNS
    ]
    lines = [",".join(COLUMNS), *map(",".join, zip(*cols, strict=True))]
    write_text(path, "\n".join(lines) + "\n")


def read_rows(path: str | Path) -> dict[str, np.ndarray]:
    """scenarios.csv back as a dict of arrays."""
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=float)
    return {
        c: data[c].astype(int) if c in INT_COLUMNS else data[c].astype(float)
        for c in COLUMNS
    }


def _chunk_path(out: Path, k: int) -> Path:
    return out / "chunks" / f"{k:06d}.npz"


def _chunk_ok(out: Path, spec: MonteCarloSpec, k: int) -> bool:
    """Chunk k is on disk and whole (`chunk_is_whole`); older chunks lack the
    budget_exhausted column."""
    start, stop = spec.chunk_range(k)
    must = [c for c in COLUMNS if c != "budget_exhausted"]
    return chunk_is_whole(_chunk_path(out, k), start, stop, must)


def chunk_is_whole(path: Path, start: int, stop: int, must) -> bool:
    """A Monte Carlo chunk file (SMIB or grid) is on disk and whole: it loads, holds
    the rows start..stop-1 in every column of `must`, and its `index` column is that
    range. A chunk that is not (truncated or damaged by something other than the
    atomic writes) is recomputed."""
    if not path.is_file():
        return False
    try:
        with np.load(path) as z:
            cols = {c: np.asarray(z[c]) for c in z.files}
    except Exception:  # a truncated zip raises BadZipFile, EOFError, ValueError...
        return False
    return all(
        c in cols and cols[c].shape == (stop - start,) for c in must
    ) and np.array_equal(cols["index"], np.arange(start, stop))


def _flat(spec: dict) -> dict:
    """A spec's dict with its solver table spread out as solver.NAME keys."""
    out = {k: v for k, v in spec.items() if k != "solver"}
    out.update({f"solver.{k}": v for k, v in spec.get("solver", {}).items()})
    return out


def _check_resume(out: Path, spec: MonteCarloSpec) -> dict:
    manifest = out / "run.json"
    if not manifest.is_file():
        raise ParameterError(
            f"--resume: {str(out)!r} holds no Monte Carlo run (no run.json)"
        )
    try:
        saved = json.loads(manifest.read_text())
        if not isinstance(saved, dict) or not isinstance(saved.get("spec", {}), dict):
            raise ValueError("not a table with a spec table")
        check_tree(saved, f"{str(manifest)!r}")
    except (ValueError, RecursionError, UnicodeDecodeError) as e:
        reason = str(e).splitlines()[0][:80] if str(e) else type(e).__name__
        raise ParameterError(
            f"--resume: {str(manifest)!r} is damaged ({reason}): start a new run "
            "in a new --out folder"
        ) from None
    # field by field, the solver's options as solver.NAME; a run written before 0.2
    # had rtol, atol, max_steps at the top level (`MonteCarloSpec.upgrade`)
    old = _flat(MonteCarloSpec.upgrade(saved.get("spec", {})))
    new = _flat(spec.to_dict())
    # a field added to the spec after the run was written: the run had its default
    defaults = _flat(MonteCarloSpec(n=max(spec.n, 1)).to_dict())
    for key in new:
        if old.get(key, defaults[key]) != new[key]:
            raise ParameterError(
                f"--resume: {key} = {new[key]!r} differs from the run in "
                f"{str(out)!r} ({key} = {old.get(key, defaults[key])!r}); repeat its "
                "options"
            )
    return saved


def preflight(spec: MonteCarloSpec) -> None:
    """Everything checked before the run folder is written: the memory of one chunk
    and of the assembled rows (`require_memory`), the parameter sets, the starting
    point, and the scenarios of the first chunk as drawn (with the plant at the
    extremes of the drawn D and Pm)."""
    samples = round(spec.t_end / spec.dt_save) + 1
    require_memory(
        f"--chunk {spec.chunk}",
        max(spec.chunk, 2),
        samples,
        "lower --chunk (the rows do not depend on it)",
    )
    require_memory(
        f"--n {spec.n}",
        spec.n,
        len(COLUMNS) / BYTES_PER_SAMPLE * 8,
        "lower --n (the rows of every scenario are assembled at the end)",
    )
    from dataclasses import replace

    from .._scenarios import sample_scenarios

    params = spec.parameters()
    dist = spec.distribution()
    for d_, pm in zip(dist.D or (None,) * 2, dist.Pm or (None,) * 2, strict=True):
        over = {k: v for k, v in (("D", d_), ("Pm", pm)) if v is not None}
        if over:
            replace(spec, plant={**spec.plant, **over})  # validates the plant
    sample_scenarios(spec.seed, 0, min(spec.n, spec.chunk), dist, params[1])


def run_montecarlo(
    spec: MonteCarloSpec,
    out: str | Path,
    *,
    resume: bool = False,
    runner: Callable | None = None,
    progress: bool = True,
    title: str = "Monte Carlo",
    plots: bool = True,
) -> tuple[dict[str, np.ndarray], dict]:
    """Run (or finish, with `resume`) the Monte Carlo `spec` into folder `out`.

    Returns (rows, summary). A fresh run refuses a non-empty `out`; `resume` refuses a
    folder without `run.json` or with a different spec. Chunks already on disk are not
    recomputed; the final files are the same as those of an uninterrupted run.
    """
    from .._commandline import progress_bars

    out = Path(out)
    if resume:
        manifest = _check_resume(out, spec)
        preflight(spec)
    else:
        if out.exists() and (not out.is_dir() or any(out.iterdir())):
            raise ParameterError(
                f"--out {str(out)!r} exists and is not empty: choose a new folder or "
                "add --resume to finish the run in it"
            )
        preflight(spec)
        manifest = {"spec": spec.to_dict(), "complete": False}
        write_json(out / "run.json", manifest)
    todo = [k for k in range(spec.n_chunks) if not _chunk_ok(out, spec, k)]
    done_rows = spec.n - sum(
        spec.chunk_range(k)[1] - spec.chunk_range(k)[0] for k in todo
    )
    if progress and todo:
        from .._commandline import say_compiling

        say_compiling(
            "the batched simulator" + (" on the workers" if runner else ""), "jit_run"
        )
    runner = runner or in_process_runner
    t0, computed = time.perf_counter(), 0
    with progress_bars() as make:  # closed also when a chunk fails
        bar = make(
            total=spec.n,
            initial=int(done_rows),
            unit="scen",
            disable=not progress,
            desc="monte carlo",
            smoothing=0.1,
        )
        for k, rows in runner(spec, todo):
            write_npz(_chunk_path(out, k), rows)
            computed += rows["index"].size
            bar.update(rows["index"].size)
    elapsed = time.perf_counter() - t0
    parts = []
    for k in range(spec.n_chunks):
        with np.load(_chunk_path(out, k)) as z:
            # chunks written before budget_exhausted was a column: never exhausted
            # there was reported as lost_sync, so 0 is what they recorded.
            parts.append(
                {c: z[c] if c in z else np.zeros_like(z["stable"]) for c in COLUMNS}
            )
    rows = {c: np.concatenate([p[c] for p in parts]) for c in COLUMNS}
    summary = summarize(rows)
    write_csv(out / "scenarios.csv", rows)
    write_json(out / "summary.json", summary)
    write_text(out / "summary.md", summary_markdown(summary, title))
    if plots:
        from .plotting import plot_montecarlo

        plot_montecarlo(rows, out / "montecarlo.png", title)
    runs = manifest.get("sessions", [])
    runs.append(
        {
            "scenarios_computed": int(computed),
            "seconds": elapsed,
            "scenarios_per_second": computed / elapsed if computed else None,
            "devices": len(jax.devices()),
        }
    )
    write_json(
        out / "run.json",
        {"spec": spec.to_dict(), "complete": True, "sessions": runs},
    )
    return rows, summary
