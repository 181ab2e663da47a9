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
    # multi-machine runs
    "machines_shown",
    "bus_extremes",
    "plot_grid_run",
    "plot_grid_compare",
    "plot_case_cct",
    "plot_case_compare",
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


def plot_montecarlo(
    rows: dict[str, np.ndarray], path, title: str = "", angle: str = "delta"
) -> None:
    """Histograms of the settling time of `angle` and the overshoot (stable
    scenarios) and the stability/settling map over (fault time, clearing duration):
    colour = settling time, red x = unstable."""
    stable = rows["stable"].astype(bool)
    ts = rows["settling_time"]
    fig, axes = subplots(1, 3, figsize=(15, 4.3))
    ax = axes[0]
    good = stable & np.isfinite(ts)
    if good.any():
        ax.hist(ts[good], bins=40, color="C0")
    ax.set_xlabel(f"{angle} settling time from fault (s)")
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


# --- multi-machine runs (`simulate --case`, the grid tuner's before/after) ---------

SHOWN = 6
"""The most machines a multi-machine figure draws one by one: beyond `SHOWN + 2`
machines, the `SHOWN` with the largest angle excursions get a line and a legend
entry, the others one light band (their range at each instant)."""

_EVENT_COLORS = {
    "fault": "firebrick",
    "clear": "darkorange",
    "open": "darkorange",
    "close": "seagreen",
    "reclose": "seagreen",
    "trip": "purple",
}


def machines_shown(angles: np.ndarray, n_max: int = SHOWN) -> np.ndarray:
    """The columns (machines) of `angles` (samples x machines, any angle unit) a
    figure draws one by one: all of them when there are at most `n_max + 2`, else
    the `n_max` whose angle moves furthest from its first sample (max |a(t) - a(0)|,
    NaN ignored), largest first."""
    a = np.asarray(angles, dtype=float)
    n = a.shape[1]
    if n <= n_max + 2:
        return np.arange(n)
    swing = np.nanmax(np.abs(a - a[:1]), axis=0, initial=0.0)
    swing = np.where(np.isfinite(swing), swing, 0.0)
    return np.argsort(-swing, kind="stable")[:n_max]


def _machine_panel(ax, t, y, shown, colors, labels) -> None:
    """Lines for the `shown` columns of `y`, the others as one light band (drawn
    under the lines, listed after them)."""
    y = np.asarray(y, dtype=float)
    for i in shown:
        ax.plot(t, y[:, i], lw=1.2, color=colors[i], label=labels[i])
    rest = np.setdiff1d(np.arange(y.shape[1]), shown)
    if rest.size:
        with np.errstate(all="ignore"):
            lo = np.nanmin(y[:, rest], axis=1)
            hi = np.nanmax(y[:, rest], axis=1)
        ax.fill_between(
            t,
            lo,
            hi,
            color="0.6",
            alpha=0.3,
            lw=0,
            zorder=0.5,
            label=f"other {rest.size} machines",
        )
    ax.grid(alpha=0.3)


def _event_marks(ax, events, legend: bool) -> None:
    """Dotted vertical lines at `events` [(t (s), text)], coloured by the first
    word of the text (fault, clear/open, close, trip)."""
    for t, text in events:
        word = text.split()[0] if text.split() else ""
        color = next((c for k, c in _EVENT_COLORS.items() if word.startswith(k)), "k")
        ax.axvline(t, color=color, ls=":", lw=1.1, label=f"{text}" if legend else None)


def _change(y) -> np.ndarray:
    """`y` (samples x devices) less its first sample."""
    y = np.asarray(y, dtype=float)
    return y - y[:1]


def _note_if_zero(ax, y, ylabel: str) -> None:
    """State on the panel that a signal is zero throughout (a case without
    stabilizers, governors that hold their power), instead of a flat line."""
    y = np.asarray(y, dtype=float)
    if y.size and not np.any(np.abs(y[np.isfinite(y)]) > 0):
        what = (
            "no stabilizer in this case"
            if "Vs" in ylabel
            else ("no governor in this case" if "Pm" in ylabel else "constant")
        )
        ax.text(
            0.5,
            0.75,
            f"zero throughout ({what})",
            transform=ax.transAxes,
            ha="center",
            va="center",
            fontsize=9,
            color="dimgray",
            bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8},
        )


def _colors(n: int, shown) -> dict:
    """One colour per shown machine (tab10, no repeats among `SHOWN`)."""
    return {int(i): f"C{k % 10}" for k, i in enumerate(shown)}


def _wrap(text: str, width: int = 30) -> str:
    """A legend entry on lines of at most `width` characters (the legend column
    right of the axes is narrow)."""
    import textwrap

    return "\n".join(textwrap.wrap(text, width)) or text


def _legend_outside(fig, axes, extra: str = "") -> None:
    """One legend, right of the axes, from the first panel's entries."""
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(
        handles,
        [_wrap(label) for label in labels],
        loc="upper left",
        bbox_to_anchor=(0.81, 0.93),
        fontsize=8,
        frameon=False,
        title=extra or None,
        title_fontsize=8,
    )


def bus_extremes(v_bus, t, bus_numbers, after: float) -> list[tuple[int, str]]:
    """The buses a voltage panel names: (column, text) for the bus with the lowest
    voltage after `after` (s; the last switching), the one with the highest, and the
    lowest at any time (the faulted bus, usually) when it is another."""
    v = np.asarray(v_bus, dtype=float)
    late = np.asarray(t) > after
    late = late if late.any() else np.ones_like(late)
    with np.errstate(all="ignore"):
        lo_late = np.nanmin(v[late], axis=0)
        hi_all = np.nanmax(v, axis=0)
        lo_all = np.nanmin(v, axis=0)
    picks = []
    k = int(np.nanargmin(lo_late))
    picks.append((k, f"bus {bus_numbers[k]}: lowest after {after:g} s"))
    k = int(np.nanargmax(hi_all))
    picks.append((k, f"bus {bus_numbers[k]}: highest"))
    k = int(np.nanargmin(lo_all))
    if k not in [p[0] for p in picks]:
        picks.append((k, f"bus {bus_numbers[k]}: lowest"))
    return picks


def plot_grid_run(
    a: dict, path, title: str, events=(), bus_names=None, n_shown: int = SHOWN
) -> None:
    """A multi-machine run (`simulate --case`): angles from the centre of inertia
    (deg), speed deviations (pu), electrical and mechanical power (pu machine base),
    field voltages Efd and stabilizer outputs Vs (pu), terminal voltages (pu) and
    the bus voltages (pu: all buses as a band, the lowest after the last event, the
    highest and the lowest overall named by PSS/E number). Beyond `n_shown + 2`
    machines the `n_shown` with the largest angle excursions are drawn one by one,
    the others as a band; one legend right of the axes. `events` = [(t (s),
    text)] are dotted lines with their text in the legend. `a`: the arrays of
    `simulate --case` (t, gen, bus, delta_coi (rad), omega, pe, pm, efd, vs, vt,
    v_bus)."""
    t = np.asarray(a["t"], dtype=float)
    gens = [str(g) for g in a["gen"]]
    ang = np.degrees(np.asarray(a["delta_coi"], dtype=float))
    shown = machines_shown(ang, n_shown)
    colors = _colors(len(gens), shown)
    labels = {int(i): f"G {gens[i]}" for i in shown}
    panels = [
        (ang, "angle - COI (deg)"),
        (a["omega"], "speed deviation (pu)"),
        (_change(a["pe"]), "electrical power Pe - Pe(0)\n(pu machine base)"),
        (_change(a["pm"]), "mechanical power Pm - Pm(0)\n(pu machine base)"),
        (a["efd"], "field voltage Efd (pu)"),
        (a["vs"], "stabilizer output Vs (pu)"),
        (a["vt"], "terminal voltage (pu)"),
    ]
    ibr = "ibr_gen" in a  # issue 47: a row for the renewables
    fig, axs = subplots(
        5 if ibr else 4, 2, figsize=(13, 13 if ibr else 10.5), sharex=True
    )
    flat = list(axs.flat)
    if ibr:
        _ibr_panels(flat[8], flat[9], t, a)
    for ax, (y, ylabel) in zip(flat, panels, strict=False):
        _machine_panel(ax, t, y, shown, colors, labels)
        ax.set_ylabel(ylabel, fontsize=9)
        _note_if_zero(ax, y, ylabel)
    ax = flat[7]
    vb = np.asarray(a["v_bus"], dtype=float)
    numbers = [int(b) for b in a["bus"]]
    with np.errstate(all="ignore"):
        ax.fill_between(
            t,
            np.nanmin(vb, axis=1),
            np.nanmax(vb, axis=1),
            color="0.6",
            alpha=0.3,
            lw=0,
            label=f"all {vb.shape[1]} buses",
        )
    last = max([e[0] for e in events], default=float(t[0]))
    for k, (col, text) in enumerate(bus_extremes(vb, t, numbers, last)):
        name = bus_names[col].strip() if bus_names is not None else ""
        ax.plot(
            t,
            vb[:, col],
            lw=1.1,
            color=("navy", "teal", "black")[k],
            ls=("-", "-", "--")[k],
            label=text + (f" ({name})" if name else ""),
        )
    ax.set_ylabel("bus voltage (pu)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    for i, ax in enumerate(flat):
        _event_marks(ax, events, legend=i == 0)
    for ax in axs[-1]:
        ax.set_xlabel("t (s)")
    n = len(gens)
    note = (
        f"{len(shown)} of {n} machines: largest angle swings"
        if len(shown) < n
        else f"all {n} machines"
    )
    _legend_outside(fig, flat, note)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0, 0.8, 0.97))
    save_figure(fig, path)


# issue 47: inverter-based resources
def _ibr_panels(ax_p, ax_q, t, a, n_named: int = 3) -> None:
    """The renewables' active and reactive currents Ip, Iq (pu machine base): all
    plants as a band, the `n_named` with the largest current excursion drawn and
    named, with their current limits (Ipmax, and the LVPL where it binds; +-Iqmax)
    dashed."""
    plants = [str(g) for g in a["ibr_gen"]]
    ip = np.asarray(a["ibr_Ip"], dtype=float)
    iq = np.asarray(a["ibr_Iq"], dtype=float)
    with np.errstate(all="ignore"):
        swing = np.nan_to_num(np.nanmax(np.abs(ip - ip[:1]), axis=0))
    named = list(np.argsort(-swing)[:n_named])
    colors = ("tab:red", "tab:blue", "tab:green")
    for ax, y, lim, what in (
        (ax_p, ip, ("ibr_Ipmax", "ibr_LVPL"), "active current Ip"),
        (ax_q, iq, ("ibr_Iqmax",), "reactive current Iq"),
    ):
        with np.errstate(all="ignore"):
            ax.fill_between(
                t, np.nanmin(y, axis=1), np.nanmax(y, axis=1), color="0.6",
                alpha=0.3, lw=0, label=f"all {len(plants)} plants",
            )  # fmt: skip
        for c, i in zip(colors, named, strict=False):
            ax.plot(t, y[:, i], lw=1.1, color=c, label=f"plant {plants[i]}")
            for key in lim:
                bound = np.asarray(a[key], dtype=float)[:, i]
                bound = np.where(bound < 1e5, bound, np.nan)  # "no limit" not drawn
                ax.plot(t, bound, lw=0.8, ls="--", color=c)
                if key == "ibr_Iqmax":
                    ax.plot(t, -bound, lw=0.8, ls="--", color=c)
        ax.set_ylabel(f"{what} (pu machine base)\n(dashed: its limits)", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")


def plot_grid_compare(
    runs: dict[str, dict], path, title: str = "", events=(), n_shown: int = SHOWN
) -> None:
    """Runs of one case side by side (the grid tuner's before/after), one column per
    run, on shared y axes per row: angles from the centre of inertia (deg), speed
    deviations (pu), field voltages Efd and stabilizer outputs Vs (pu). The same
    machines (the largest angle excursions over all runs) in the same colours in
    every column, the others as a band. `runs`: label -> arrays as
    `plot_grid_run`'s; `events` = [(t (s), text)]."""
    items = list(runs.items())
    gens = [str(g) for g in items[0][1]["gen"]]
    angs = [np.degrees(np.asarray(a["delta_coi"], dtype=float)) for _, a in items]
    shown = machines_shown(np.concatenate(angs, axis=0), n_shown)
    colors = _colors(len(gens), shown)
    labels = {int(i): f"G {gens[i]}" for i in shown}
    rows = [
        ("delta_coi", "angle - COI (deg)"),
        ("omega", "speed deviation (pu)"),
        ("efd", "field voltage Efd (pu)"),
        ("vs", "stabilizer output Vs (pu)"),
    ]
    fig, axs = subplots(
        len(rows),
        len(items),
        figsize=(4.6 * len(items) + 2.6, 9.5),
        sharex=True,
        sharey="row",
        squeeze=False,
    )
    for col, ((label, a), ang) in enumerate(zip(items, angs, strict=True)):
        t = np.asarray(a["t"], dtype=float)
        for r, (key, ylabel) in enumerate(rows):
            ax = axs[r, col]
            y = ang if key == "delta_coi" else a[key]
            _machine_panel(ax, t, y, shown, colors, labels)
            _note_if_zero(ax, y, ylabel)
            _event_marks(ax, events, legend=(r, col) == (0, 0))
            if col == 0:
                ax.set_ylabel(ylabel, fontsize=9)
        axs[0, col].set_title(label, fontsize=10)
        axs[-1, col].set_xlabel("t (s)")
    n = len(gens)
    note = (
        f"{len(shown)} of {n} machines: largest angle swings"
        if len(shown) < n
        else f"all {n} machines"
    )
    right = 1 - 2.4 / (4.6 * len(items) + 2.6)
    handles, labs = axs[0, 0].get_legend_handles_labels()
    fig.legend(
        handles,
        [_wrap(label) for label in labs],
        loc="upper left",
        bbox_to_anchor=(right + 0.01, 0.93),
        fontsize=8,
        frameon=False,
        title=note,
        title_fontsize=8,
    )
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0, right, 0.97))
    save_figure(fig, path)


CCT_SHOWN = 30
"""The most fault buses a CCT bar chart names (the shortest CCTs)."""


def plot_case_cct(rows: list[dict], t_max: float, path, title: str = "") -> None:
    """The critical clearing time (s) of a fault at each bus (`rows`: bus, name,
    cct, status as `cli.grid.cct_rows`), shortest first, one bar per bus labelled
    with its PSS/E number: at most `CCT_SHOWN` buses (the shortest), a bar to
    `t_max` hatched where the run is stable even then, a red cross at 0 where it is
    unstable at the shortest duration tried."""

    def key(r):
        return t_max * 2 if r["cct"] is None else r["cct"]

    rows = sorted(rows, key=key)
    shown = rows[:CCT_SHOWN]
    fig, ax = subplots(figsize=(max(6.0, 0.28 * len(shown) + 2.5), 4.3))
    x = np.arange(len(shown))
    for i, r in enumerate(shown):
        if r["status"] == "exceeds_max":
            ax.bar(i, t_max, color="none", edgecolor="C0", hatch="//", lw=0.8)
        elif r["status"] == "unstable_at_min":
            ax.plot(i, 0.0, "x", color="red", ms=8, mew=2)
        else:
            ax.bar(i, r["cct"], color="C0")
    ax.set_xticks(x)
    ax.set_xticklabels([str(r["bus"]) for r in shown], rotation=90, fontsize=7)
    ax.set_xlim(-0.7, max(len(shown) - 0.3, 0.7))
    ax.set_ylim(0, 1.08 * t_max)
    ax.axhline(t_max, color="k", ls="--", lw=0.8)
    ax.set_xlabel(
        "fault bus (PSS/E number)"
        + (
            f", the {len(shown)} shortest of {len(rows)}"
            if len(shown) < len(rows)
            else ""
        )
    )
    ax.set_ylabel("critical clearing time (s)")
    ax.grid(alpha=0.3, axis="y")
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    ax.legend(
        handles=[
            Patch(color="C0", label="CCT"),
            Patch(facecolor="none", edgecolor="C0", hatch="//", label=f"> {t_max:g} s"),
            Line2D([], [], ls="", marker="x", color="red", mew=2, label="none"),
            Line2D([], [], ls="--", color="k", lw=0.8, label="longest tried"),
        ],
        fontsize=7,
        loc="upper left",
        bbox_to_anchor=(1.0, 1.0),
        frameon=False,
    )
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)


def plot_case_compare(rows: dict[str, dict], ccts: dict, path, title: str = "") -> None:
    """`compare --case`: per parameter set, the settling time of the angles from the
    centre of inertia (s; stable scenarios) and the first-swing overshoot (deg) as
    histograms on shared bins, and (when computed) the critical clearing time (s) of
    a bolted fault at each bus, buses by PSS/E number in the order of the first
    set's CCTs. `rows`: label -> `GridMetrics` rows; `ccts`: label -> a
    `critical_clearing_times_grid` result (may be empty)."""
    n = 3 if ccts else 2
    fig, axes = subplots(1, n, figsize=(5.2 * n, 4.2))
    settle = {}
    for label, r in rows.items():
        st = np.asarray(r["stable"], dtype=bool)
        ts = np.asarray(r["settling_angle"], dtype=float)[st]
        settle[label] = ts[np.isfinite(ts)]
    every = np.concatenate([v for v in settle.values()] + [np.zeros(1)])
    bins = np.linspace(0.0, max(float(every.max()), 1e-3), 31)
    for i, (label, v) in enumerate(settle.items()):
        n_st = int(np.sum(np.asarray(rows[label]["stable"], dtype=bool)))
        axes[0].hist(
            v,
            bins=bins,
            histtype="step",
            lw=1.5,
            color=f"C{i}",
            label=f"{label} ({n_st} of {len(rows[label]['stable'])} stable)",
        )
    axes[0].set_xlabel("settling time of the COI angles (s)")
    axes[0].set_ylabel("scenarios")
    over = {
        k: np.degrees(np.asarray(r["overshoot"], dtype=float)) for k, r in rows.items()
    }
    every = np.concatenate([v[np.isfinite(v)] for v in over.values()] + [np.zeros(1)])
    bins = np.linspace(0.0, max(float(every.max()), 1e-3), 31)
    for i, (label, v) in enumerate(over.items()):
        axes[1].hist(
            v[np.isfinite(v)],
            bins=bins,
            histtype="step",
            lw=1.5,
            color=f"C{i}",
            label=label,
        )
    axes[1].set_xlabel("first-swing overshoot (deg)")
    if ccts:
        ax = axes[2]
        first = next(iter(ccts.values()))["cct"]
        order = sorted(first, key=lambda b: np.inf if first[b] is None else first[b])
        x = np.arange(len(order))
        for i, (label, res) in enumerate(ccts.items()):
            y = [np.nan if res["cct"].get(b) is None else res["cct"][b] for b in order]
            ax.plot(x, y, "o-", ms=3, lw=1, color=f"C{i}", label=label)
        ax.set_xticks(x)
        ax.set_xticklabels([str(b) for b in order], rotation=90, fontsize=6)
        ax.set_xlabel("fault bus (PSS/E number; gaps: stable at the longest tried)")
        ax.set_ylabel("critical clearing time (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def plot_grid_montecarlo(rows: dict[str, np.ndarray], path, title: str = "") -> None:
    """A grid Monte Carlo's figure, as the SMIB's (`plot_montecarlo`): settling of
    the angles from the centre of inertia (s; inf: not settled, left out of the
    histogram), overshoot (rad) and the stability/settling map over (fault time,
    clearing duration) (s), from the rows of `scenarios.csv`."""
    plot_montecarlo(
        {
            "stable": np.asarray(rows["stable"]).astype(bool),
            "settling_time": np.asarray(rows["settling_angle"], dtype=float),
            "overshoot": np.asarray(rows["overshoot"], dtype=float),
            "t_fault": np.asarray(rows["t_fault"], dtype=float),
            "clear_duration": np.asarray(rows["t_clear"], dtype=float)
            - np.asarray(rows["t_fault"], dtype=float),
        },
        path,
        title,
        angle="COI angle",
    )
