"""Text forms of results: the CLI summary, metric tables (plain data, markdown)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..controllers import describe

if TYPE_CHECKING:  # (the class lives beside the solver: diffrax)
    from .._metrics import Metrics

__all__ = ["metrics_dict", "format_summary", "markdown_table", "plant_text"]


def _limit(lo: float, hi: float) -> str | None:
    if math.isinf(lo) and math.isinf(hi):
        return None
    return f"[{lo:g}, {hi:g}]"


def plant_text(plant, preset: str | None = None) -> str:
    """The plant a result is for, with its input limits (pu), e.g. 'realistic plant
    (u_f in [-5, 5], u_r in [-1, 1] pu)' or 'paper plant (no input limits)'; `plant`
    is a `Plant` or a table of its fields."""

    def get(k):
        v = plant.get(k, math.inf) if isinstance(plant, dict) else getattr(plant, k)
        return math.inf if v is None else float(v)

    uf = _limit(get("uf_min"), get("uf_max"))
    ur = _limit(get("ur_min"), get("ur_max"))
    parts = [f"u_f in {uf}" if uf else None, f"u_r in {ur}" if ur else None]
    parts = [x for x in parts if x]
    limits = ", ".join(parts) + " pu" if parts else "no input limits"
    return f"{preset + ' ' if preset else ''}plant ({limits})"


def metrics_dict(m: Metrics) -> dict:
    """Metrics as plain Python values (inf where not settled, NaN where not reached:
    written to JSON as null)."""
    return {k: (bool(v) if k == "stable" else float(v)) for k, v in m._asdict().items()}


NOT_REACHED = "not reached (the run stopped before t_end)"


def _s(x: float, unit: str = "s", spec: str = ".3f") -> str:
    if math.isnan(x):
        return NOT_REACHED
    return "not settled" if math.isinf(x) else f"{x:{spec}} {unit}"


def _g(x: float, spec: str) -> str:
    return "not reached" if math.isnan(x) else format(x, spec)


def format_summary(gains, fault, plant, traj, m: Metrics, args=None) -> str:
    """A few lines: verdict, settling times, overshoot, effort, solver steps."""
    d = metrics_dict(m)
    head = describe(gains)
    if bool(traj.lost_sync):
        verdict = f"UNSTABLE: lost synchronism at t = {float(traj.t_stop):.3f} s"
    elif bool(traj.budget_exhausted):
        verdict = (
            f"UNDECIDED: the solver spent its step budget at t = "
            f"{float(traj.t_stop):.3f} s (raise --max-steps)"
        )
    elif d["stable"]:
        verdict = "stable"
    else:
        verdict = "UNSTABLE: delta not back in its band at t_end"
    where = plant_text(plant, getattr(args, "preset", None))
    adaptation = getattr(args, "adaptation", None)
    context = getattr(args, "context", None)
    if context is not None and "adaptation" not in context.describe():
        adaptation = None  # (none, avr-pss: no adaptation)
    if adaptation:
        where += f", {adaptation} adaptation"
    lines = [
        f"{head}; fault {float(fault.t_fault):g} s, cleared "
        f"{float(fault.t_clear):g} s, reclosed {float(fault.t_reclose):g} s, "
        f"lam = {float(fault.lam):g}, Xf = {float(fault.Xf):g}",
        f"  on:                  {where}",
        f"  result:              {verdict}",
        f"  settling time delta: {_s(d['settling_delta'])} (band 0.01 rad, from fault)",
        f"  settling time Vt:    {_s(d['settling_Vt'])} (band 0.01 pu)",
        f"  settling time omega: {_s(d['settling_omega'])} (band 0.01 rad/s)",
        f"  first-swing overshoot: {_s(d['overshoot'], 'rad', '.4f')}",
        f"  effort: int u_f^2 = {_g(d['effort_uf'], '.4g')}, int u_r^2 = "
        f"{_g(d['effort_ur'], '.4g')} (pu^2 s); peak |u_f| = "
        f"{_g(d['peak_uf'], '.4g')}, |u_r| = {_g(d['peak_ur'], '.4g')}",
        f"  commanded (before limits): peak |u_f| = {_g(d['peak_uf_cmd'], '.4g')}, "
        f"|u_r| = {_g(d['peak_ur_cmd'], '.4g')}; time on a limit: u_f "
        f"{_g(d['limit_time_uf'], '.3f')}, u_r {_g(d['limit_time_ur'], '.3f')}",
        f"  chatter (total variation): u_f {_g(d['tv_uf'], '.4g')}, u_r "
        f"{_g(d['tv_ur'], '.4g')} pu",
        f"  ranges: Vt {_g(d['Vt_min'], '.3f')}..{_g(d['Vt_max'], '.3f')}, B "
        f"{_g(d['B_min'], '.3f')}..{_g(d['B_max'], '.3f')}, E' "
        f"{_g(d['E_min'], '.3f')}..{_g(d['E_max'], '.3f')} pu",
        f"  solver: {int(traj.num_steps)} steps ({int(traj.num_rejected)} rejected)",
    ]
    return "\n".join(lines)


_COLUMNS = [
    ("stable", "stable", lambda v: "yes" if v else "**no**"),
    ("settling_delta", "t_s delta (s)", lambda v: "-" if math.isinf(v) else f"{v:.2f}"),
    ("settling_Vt", "t_s Vt (s)", lambda v: "-" if math.isinf(v) else f"{v:.2f}"),
    ("settling_omega", "t_s omega (s)", lambda v: "-" if math.isinf(v) else f"{v:.2f}"),
    ("overshoot", "overshoot (rad)", lambda v: f"{v:.3f}"),
    ("effort_uf", "int u_f^2", lambda v: f"{v:.3g}"),
    ("effort_ur", "int u_r^2", lambda v: f"{v:.3g}"),
    ("peak_uf", "peak u_f", lambda v: f"{v:.3g}"),
]


def _cell(f, v) -> str:
    return "not reached" if isinstance(v, float) and math.isnan(v) else f(v)


def markdown_table(rows: dict[str, dict]) -> str:
    """A markdown table of metric dicts, one row per labelled run ("not reached" where
    the run stopped before t_end)."""
    head = "| run | " + " | ".join(h for _, h, _ in _COLUMNS) + " |"
    sep = "|---|" + "---|" * len(_COLUMNS)
    body = [
        f"| {label} | " + " | ".join(_cell(f, d[k]) for k, _, f in _COLUMNS) + " |"
        for label, d in rows.items()
    ]
    return "\n".join([head, sep, *body])
