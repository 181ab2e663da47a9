"""Figures of trajectories, written atomically in the format their file name's suffix
names (.png, .pdf, .svg, ...).

Figures are made with matplotlib's object-oriented API (`matplotlib.figure.Figure`),
not pyplot: nothing here selects a backend or keeps figures in a global registry, so
importing this module changes nothing in the user's matplotlib session.
"""

from __future__ import annotations

import os

import numpy as np

from .._figures import clip_to_applied, mark_events, save_figure, subplots

__all__ = [
    "trajectory_arrays",
    "plot_trajectory",
    "plot_figure",
    "plot_montecarlo",
    "plot_cct",
    "plot_islands",
    "subplots",
    "save_figure",
]

_STYLES = ["-", ":", "--", "-."]


def trajectory_arrays(traj, numpy: bool = True) -> dict[str, np.ndarray]:
    """The trajectory's signals as NumPy arrays (the npz/CSV/plot layout); with
    `numpy=False` as the JAX values (to compute them inside a jitted function)."""
    import jax.numpy as jnp

    xp = np if numpy else jnp
    keys = ("t", "delta", "omega", "E", "B", "Vt", "theta_hat", "phi", "u_f", "u_r")
    keys += ("u_f_cmd", "u_r_cmd")
    out = {k: xp.asarray(getattr(traj, k)) for k in keys}
    out["stable"] = xp.asarray(traj.stable, dtype=bool)
    out["lost_sync"] = xp.asarray(traj.lost_sync, dtype=bool)
    out["budget_exhausted"] = xp.asarray(traj.budget_exhausted, dtype=bool)
    out["t_stop"] = xp.asarray(traj.t_stop, dtype=float)
    return out


def _stopped(a: dict) -> bool:
    """The run ended before t_end: lost synchronism or a spent step budget."""
    return bool(a["lost_sync"]) or bool(a.get("budget_exhausted", False))


def _masked(a: dict, key: str) -> np.ndarray:
    """Signal with the samples after an early stop hidden (NaN)."""
    y = np.array(a[key], dtype=float)
    if _stopped(a):
        y[a["t"] > a["t_stop"]] = np.nan
    return y


def _panels(ax, runs: dict[str, dict], key: str, col=None, ylabel="", true=None):
    for i, (label, a) in enumerate(runs.items()):
        y = _masked(a, key)
        y = y if col is None else y[:, col]
        ax.plot(a["t"], y, _STYLES[i % len(_STYLES)], lw=1.4, label=label)
        if _stopped(a):
            j = np.searchsorted(a["t"], a["t_stop"]) - 1
            ax.plot(a["t"][j], y[j], "x", color=ax.lines[-1].get_color(), ms=8)
    if true is not None:
        ax.axhline(true, color="k", ls="--", lw=1, label="true value")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)


def tame_scale(ax, values, ratio: float = 20.0) -> str | None:
    """Where one run dwarfs the rest (the largest |value| more than `ratio` times
    the 98th percentile of all |values|), a symmetric-log y axis, linear up to
    that percentile, with the peak stated on the panel; returns the note (None:
    the linear axis was kept)."""
    v = np.concatenate([np.ravel(np.asarray(x, dtype=float)) for x in values])
    v = np.abs(v[np.isfinite(v)])
    if v.size == 0:
        return None
    peak, typical = float(v.max()), float(np.percentile(v, 98))
    if typical <= 0 or peak <= ratio * typical:
        return None
    ax.set_yscale("symlog", linthresh=typical)
    note = f"symlog beyond |y| = {typical:.3g}; peak {peak:.3g}"
    ax.text(
        0.01,
        0.04,
        note,
        transform=ax.transAxes,
        ha="left",
        va="bottom",
        fontsize=7,
        color="dimgray",
    )
    return note


def _clip_commanded(ax, t, applied, commanded, label) -> None:
    """The applied input (solid) and the commanded one before the limits (dashed);
    the axis spans the applied input (with room), the commanded one is clipped to
    it with its peak stated."""
    ax.plot(t, applied, "-", lw=1.4, label=f"{label} applied")
    ax.plot(t, commanded, "--", lw=1.0, alpha=0.8, label=f"{label} commanded")
    clip_to_applied(ax, applied, commanded)


def _note_lost(fig, runs):
    lost = [
        f"{k}: lost synchronism at t = {a['t_stop']:.3f} s (x)"
        if a["lost_sync"]
        else f"{k}: solver step budget spent at t = {a['t_stop']:.3f} s (x)"
        for k, a in runs.items()
        if _stopped(a)
    ]
    if lost:
        fig.text(0.01, 0.005, "; ".join(lost), fontsize=8, color="firebrick")


def plot_figure(
    kind: str,
    runs: dict[str, dict],
    path: str | os.PathLike,
    title: str,
    theta_true: tuple[float, float] = (-0.2, 1.0),
    events=None,
) -> None:
    """One of the paper's figures for several runs (dict label -> arrays):
    `states` (Fig. 3: delta, omega deviation, Vt), `estimates` (Fig. 4: th_hat
    against the true theta), `macro` (Fig. 5: phi1, phi2) or `inputs` (u_f, u_r, B).
    A panel where one run dwarfs the rest gets a symmetric-log axis with the peak
    stated (`tame_scale`); `events` = (t_fault, t_clear, t_reclose) are marked."""
    spec = {
        "states": [
            ("delta", None, "delta (rad)", None),
            ("omega", None, "omega - omega_s (rad/s)", None),
            ("Vt", None, "Vt (pu)", None),
        ],
        "estimates": [
            ("theta_hat", 0, "th1_hat (-D)", theta_true[0]),
            ("theta_hat", 1, "th2_hat (Pm)", theta_true[1]),
        ],
        "macro": [("phi", 0, "phi1", None), ("phi", 1, "phi2", None)],
        "inputs": [
            ("u_f", None, "u_f (pu)", None),
            ("u_r", None, "u_r (pu)", None),
            ("B", None, "B (pu)", None),
        ],
    }[kind]
    fig, axes = subplots(len(spec), 1, figsize=(8, 2.3 * len(spec) + 0.6), sharex=True)
    for i, (ax, (key, col, ylabel, true)) in enumerate(zip(axes, spec, strict=True)):
        _panels(ax, runs, key, col, ylabel, true)
        ys = [
            _masked(a, key) if col is None else _masked(a, key)[:, col]
            for a in runs.values()
        ]
        tame_scale(ax, ys)
        mark_events(ax, events, legend=i == 0)
    axes[0].legend(fontsize=8, loc="best")
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(title, fontsize=11)
    _note_lost(fig, runs)
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    save_figure(fig, path)


def plot_trajectory(
    a: dict,
    path: str | os.PathLike,
    title: str,
    theta_true: tuple[float, float],
    events=None,
    adaptive: bool = True,
) -> None:
    """Every state and input of one run: delta, the speed deviation omega -
    omega_s, Vt, E', the SVC susceptance B, the field voltage u_f and the SVC input
    u_r (applied, and commanded before the limits, clipped with its peak stated);
    for the paper's law (`adaptive`) also its estimates th_hat and macro-variables
    phi. `events` = (t_fault, t_clear, t_reclose) are marked on every panel."""
    rows = [
        ("delta", None, "delta (rad)", None),
        ("omega", None, "omega - omega_s (rad/s)", None),
        ("Vt", None, "Vt (pu)", None),
        ("E", None, "E' (pu)", None),
        ("B", None, "SVC susceptance B (pu)", None),
    ]
    if adaptive:
        rows += [
            ("theta_hat", 0, "th1_hat (-D)", theta_true[0]),
            ("theta_hat", 1, "th2_hat (Pm)", theta_true[1]),
            ("phi", 0, "phi1", None),
            ("phi", 1, "phi2", None),
        ]
    inputs = [("u_f", "u_f_cmd", "u_f (pu)"), ("u_r", "u_r_cmd", "u_r (pu)")]
    n = len(rows) + len(inputs)
    nrows = (n + 1) // 2
    fig, axes = subplots(nrows, 2, figsize=(11, 2.1 * nrows + 0.8), sharex=True)
    flat = list(axes.T.ravel())
    for ax, (key, col, ylabel, true) in zip(flat, rows, strict=False):
        _panels(ax, {"run": a}, key, col, ylabel, true)
    for ax, (key, cmd, ylabel) in zip(flat[len(rows) :], inputs, strict=False):
        y = _masked(a, key)
        c = _masked(a, cmd) if cmd in a else y
        _clip_commanded(ax, a["t"], y, c, key)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    for i, ax in enumerate(flat[:n]):
        mark_events(ax, events, legend=i == 0)
    flat[0].legend(fontsize=7, loc="best")
    for ax in flat[n:]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    if n % 2:
        axes[-2][1].xaxis.set_tick_params(labelbottom=True)
        axes[-2][1].set_xlabel("t (s)")
    fig.suptitle(title, fontsize=11)
    _note_lost(fig, {"run": a})
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    save_figure(fig, path)


def plot_montecarlo(rows: dict[str, np.ndarray], path, title: str = "") -> None:
    """Histograms of delta settling time and overshoot (stable scenarios) and the
    stability/settling map over (fault time, clearing duration): colour = settling
    time, red x = unstable."""
    stable = rows["stable"].astype(bool)
    ts = rows["settling_time"]
    fig, axes = subplots(1, 3, figsize=(15, 4.3))
    ax = axes[0]
    good = stable & np.isfinite(ts)
    if good.any():
        ax.hist(ts[good], bins=40, color="C0")
    ax.set_xlabel("delta settling time from fault (s)")
    ax.set_ylabel("scenarios")
    ax.set_title(f"settling ({good.sum()} stable of {stable.size})")
    ax = axes[1]
    if stable.any():
        ax.hist(rows["overshoot"][stable], bins=40, color="C1")
    ax.set_xlabel("first-swing overshoot (rad)")
    ax.set_title("overshoot (stable scenarios)")
    ax = axes[2]
    x, y = rows["t_fault"], rows["clear_duration"]
    if good.any():
        sc = ax.scatter(x[good], y[good], c=ts[good], s=8, cmap="viridis")
        fig.colorbar(sc, ax=ax, label="settling time (s)")
    if (~stable).any():
        ax.scatter(x[~stable], y[~stable], marker="x", s=14, c="red", label="unstable")
        ax.legend(loc="upper right")
    ax.set_xlabel("fault time (s)")
    ax.set_ylabel("clearing duration (s)")
    ax.set_title("stability / settling map")
    for a in axes:
        a.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path)


def plot_islands(ax, result: dict, label: str, color) -> None:
    """Mark a gain set's non-monotone CCTs on `ax`: a ring on the CCT and a vertical
    bar over each later stable island [lo, hi] (s) at its fault location."""
    r = result["sets"][label]
    loc = np.asarray(result["fault_location"], dtype=float)
    first = True
    for j, isl in enumerate(r.get("islands", [[]] * len(loc))):
        if not isl:
            continue
        if r["cct"][j] is not None:
            ax.plot(loc[j], r["cct"][j], "o", mfc="none", mec="r", ms=11, mew=1.5)
        for lo, hi in isl:
            ax.plot(
                [loc[j], loc[j]],
                [lo, hi + 1e-9],
                "-",
                color=color,
                lw=6,
                alpha=0.45,
                solid_capstyle="butt",
                label=f"{label}: stable again" if first else None,
            )
            ax.plot([loc[j]] * 2, [lo, hi], "_", color=color, ms=10)
            first = False


def plot_cct(result: dict, path, title: str = "") -> None:
    """CCT against fault location, one line per gain set (`cct` results); a marker on
    the top edge where the CCT exceeds the window, on the bottom where the run is
    unstable even for the shortest fault; where stability is not monotone, a red ring
    on the CCT and bars over the later stable islands of clearing durations (s)."""
    fig, ax = subplots(figsize=(7, 4.3))
    window = result["window"]
    for label, r in result["sets"].items():
        loc = np.asarray(result["fault_location"], dtype=float)
        cct = np.array([np.nan if v is None else v for v in r["cct"]], dtype=float)
        (line,) = ax.plot(loc, cct, "o-", label=label, ms=4)
        st = np.asarray(r["status"])
        if (st == "exceeds_window").any():
            ax.plot(
                loc[st == "exceeds_window"],
                [window] * (st == "exceeds_window").sum(),
                "^",
                color=line.get_color(),
                ms=9,
            )
        if (st == "unstable_at_min").any():
            ax.plot(
                loc[st == "unstable_at_min"],
                [0.0] * (st == "unstable_at_min").sum(),
                "v",
                color=line.get_color(),
                ms=9,
            )
        plot_islands(ax, result, label, line.get_color())
    ax.axhline(window, color="k", ls="--", lw=1, label="window (reclose - fault)")
    ax.set_xlabel("fault location (fraction of circuit 1 from the SVC bus)")
    ax.set_ylabel(
        f"critical clearing time (s), criterion {result.get('criterion', 'settled')}"
    )
    ax.set_ylim(bottom=-0.03 * window, top=1.08 * window)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(
        title
        or "critical clearing time (^: beyond window, v: none, ring: non-monotone)"
    )
    fig.tight_layout()
    save_figure(fig, path)
