"""What the figures show (issue 32): every state and input, labels with units,
event markers, panels only for what the controller has, an axis that one run's
spike does not squash (its peak stated), the tuner's inputs, a legible compare
figure. The figures are captured before they are written and read back as data."""

import types
from pathlib import Path

import numpy as np
import pytest

from smibjax.cli import plotting


@pytest.fixture
def captured(monkeypatch):
    figs = []

    def keep(fig, path, dpi=110):
        figs.append(fig)

    monkeypatch.setattr(plotting, "save_figure", keep)
    return figs


def _run(t_stop=10.0, lost=False, spike=None):
    t = np.linspace(0.0, 10.0, 1001)
    a = {
        "t": t,
        "delta": 0.5 + 0.1 * np.sin(t),
        "omega": 0.01 * np.cos(t),
        "E": 1.0 + 0 * t,
        "B": 0.1 * np.sin(2 * t),
        "Vt": 1.0 + 0 * t,
        "theta_hat": np.stack([-0.2 + 0 * t, 1.0 + 0 * t], axis=1),
        "phi": np.stack([np.sin(t), np.cos(t)], axis=1),
        "u_f": np.clip(3 * np.sin(5 * t), -1, 1),
        "u_r": 0.5 * np.sin(t),
        "u_f_cmd": 3 * np.sin(5 * t),
        "u_r_cmd": 0.5 * np.sin(t),
        "stable": np.asarray(not lost),
        "lost_sync": np.asarray(lost),
        "budget_exhausted": np.asarray(False),
        "t_stop": np.asarray(t_stop),
    }
    if spike is not None:
        a["u_f"] = a["u_f"].copy()
        a["u_f"][900] = spike
    return a


def _labels(fig):
    return [ax.get_ylabel() for ax in fig.axes if ax.get_visible()]


def _event_lines(ax):
    return sorted(
        round(float(line.get_xdata()[0]), 6)
        for line in ax.lines
        if line.get_linestyle() == ":" and len(set(line.get_xdata())) == 1
    )


def test_simulate_plot_shows_every_state_and_input_with_events(captured):
    """B was missing, omega (a deviation) was labelled 'omega (rad/s)'; the
    commanded inputs were only numbers; no event markers."""
    plotting.plot_trajectory(_run(), "x.png", "t", (-0.2, 1.0), events=(0.5, 0.7, 2))
    (fig,) = captured
    labels = _labels(fig)
    for want in (
        "delta (rad)",
        "omega - omega_s (rad/s)",
        "Vt (pu)",
        "E' (pu)",
        "SVC susceptance B (pu)",
        "u_f (pu)",
        "u_r (pu)",
        "th1_hat (-D)",
        "phi2",
    ):
        assert want in labels, want
    assert "omega (rad/s)" not in labels
    for ax in fig.axes:
        if ax.get_visible():
            assert _event_lines(ax) == [0.5, 0.7, 2.0], ax.get_ylabel()
    uf = next(ax for ax in fig.axes if ax.get_ylabel() == "u_f (pu)")
    assert len(uf.lines) >= 2  # applied and commanded
    # the commanded u_f (peak 3) is clipped to the applied range (+-1), stated
    assert uf.get_ylim()[1] < 1.5
    assert any("peak 3 pu" in t.get_text() for t in uf.texts)


def test_panels_only_for_what_the_controller_has(captured):
    """avr-pss drew flat estimate and phi panels titled 'oracle adaptation'."""
    plotting.plot_trajectory(_run(), "x.png", "t", (-0.2, 1.0), adaptive=False)
    labels = _labels(captured[0])
    assert not any(x.startswith(("th1", "th2", "phi")) for x in labels), labels
    assert "SVC susceptance B (pu)" in labels and "u_r (pu)" in labels


def test_a_spike_that_dwarfs_the_rest_gets_a_symlog_axis_with_its_peak(captured):
    """reproduce's paper-gain figures were squashed by ASC's last spike (680,000
    pu) on linear axes."""
    runs = {"AFTSC": _run(), "ASC": _run(spike=6.8e5)}
    plotting.plot_figure("inputs", runs, "x.png", "t", events=(0.5, 0.7, 2.0))
    (fig,) = captured
    uf, ur = fig.axes[0], fig.axes[1]
    assert uf.get_yscale() == "symlog" and ur.get_yscale() == "linear"
    assert any("peak 6.8e+05" in t.get_text() for t in uf.texts)
    assert _event_lines(uf) == [0.5, 0.7, 2.0]
    fig.clear()
    plotting.plot_figure("states", {"a": _run()}, "x.png", "t")
    assert "omega - omega_s (rad/s)" in _labels(captured[-1])


def test_the_tuners_trajectories_show_the_inputs(monkeypatch):
    """trajectories.png showed delta only (the tuned AFTSC's 4-5 kpu command at
    t = 0 was visible only as a number)."""
    import tuning.report as report

    figs = []
    monkeypatch.setattr(
        report, "save_figure", lambda fig, path, dpi=110: figs.append(fig)
    )
    a = _run()
    a["u_f_cmd"] = a["u_f_cmd"].copy()
    a["u_f_cmd"][0] = 4500.0
    tr = types.SimpleNamespace(**{k: v for k, v in a.items()}, delta_e=np.asarray(0.5))
    report.plot_trajectories(
        Path("out"),
        {"paper fault": {"initial": tr, "tuned": tr}},
        {"paper fault": (0.5, 0.7, 2.0)},
    )
    (fig,) = figs
    assert _labels(fig) == ["delta (rad)", "u_f (pu)", "u_r (pu)"]
    uf = fig.axes[1]
    assert any("peak 4.5e+03 pu" in t.get_text() for t in uf.texts)
    assert _event_lines(fig.axes[0]) == [0.5, 0.7, 2.0]


def test_compare_figure_beyond_the_window_is_not_a_joined_point(monkeypatch):
    """compare.png drew 'beyond the window' as points on the window line joined by
    lines, and spent a panel on a stable fraction of 100% everywhere."""
    import smibjax.cli.compare as compare

    figs = []
    monkeypatch.setattr(
        plotting, "save_figure", lambda fig, path, dpi=110: figs.append(fig)
    )
    n = 8
    rows = {
        name: {
            "stable": np.ones(n),
            "settling_time": np.linspace(1, 3, n),
            "limit_time_uf": np.full(n, 0.1),
            "limit_time_ur": np.full(n, 0.0),
        }
        for name in ("a", "b")
    }
    cct = {
        "fault_location": [0.3, 0.5, 0.7],
        "window": 1.5,
        "criterion": "settled",
        "sets": {
            name: {
                "cct": [0.3, None, 0.35],
                "status": ["ok", "exceeds_window", "ok"],
                "islands": [[], [], []],
            }
            for name in ("a", "b")
        },
    }
    compare.plot_compare(rows, cct, "x.png")
    (fig,) = figs
    ax = fig.axes[1]
    curve = next(line for line in ax.lines if line.get_label() == "a")
    assert np.isnan(curve.get_ydata()[1])  # not joined at the window
    tri = [line for line in ax.lines if line.get_marker() == "^"]
    assert tri and all(line.get_linestyle() == "None" for line in tri)
    # equal curves stay visible: each set its own offset
    xb = next(line for line in ax.lines if line.get_label() == "b").get_xdata()
    assert not np.allclose(curve.get_xdata(), xb)
    assert fig.axes[2].get_ylabel() == "mean time on a limit (%)"


# --- multi-machine figures (issue 50) ---------------------------------------------


def _grid_run(n_gen=48, n_bus=60, swing=(5, 17, 30, 41, 2, 11, 23), vs_scale=1.0):
    """A synthetic `simulate --case` run: machine k swings by 1 + k/100 deg except
    the `swing` machines (40, 39, ... deg, in that order); bus 7 (column 6) dips to 0
    during the fault (1-1.1 s), bus 13 (column 12) stays lowest afterwards."""
    t = np.linspace(0.0, 5.0, 501)
    amp = 1.0 + np.arange(n_gen) / 100.0
    for rank, k in enumerate(swing):
        amp[k] = 40.0 - rank
    osc = np.where(t > 1.0, np.sin(4 * (t - 1.0)) * np.exp(-(t - 1.0)), 0.0)
    delta = np.radians(10.0 + amp[None, :] * osc[:, None])
    v_bus = 1.0 + 0.02 * np.sin(np.arange(n_bus))[None, :] + 0 * t[:, None]
    v_bus[(t >= 1.0) & (t < 1.1), 6] = 0.0
    v_bus[t >= 1.1, 12] = 0.9
    ones = np.ones((t.size, n_gen))
    return {
        "t": t,
        "gen": np.array([f"{k + 1}:1" for k in range(n_gen)]),
        "bus": np.arange(1, n_bus + 1),
        "delta_coi": delta,
        "omega": 1e-3 * osc[:, None] * amp[None, :],
        "pe": ones + 0.1 * osc[:, None],
        "pm": ones,
        "efd": 2 * ones,
        "vs": vs_scale * 0.05 * osc[:, None] * ones,
        "vt": ones,
        "v_bus": v_bus,
    }


EVENTS = [
    (1.0, "fault at bus 7 at 1 s"),
    (1.1, "clear: fault at bus 7 removed at 1.1 s"),
]


def _legend_texts(fig):
    return [t.get_text() for leg in fig.legends for t in leg.get_texts()]


def test_a_48_machine_run_names_the_largest_swings_and_bands_the_rest(captured):
    plotting.plot_grid_run(_grid_run(), "x.png", "npcc-like", events=EVENTS)
    fig = captured[-1]
    entries = _legend_texts(fig)
    # the six largest swings, largest first, then the band and the events
    assert entries[:6] == ["G 6:1", "G 18:1", "G 31:1", "G 42:1", "G 3:1", "G 12:1"]
    assert "other 42 machines" in entries
    # the events with their times, wrapped to the legend's column
    assert [t.replace("\n", " ") for t in entries[-2:]] == [e[1] for e in EVENTS]
    assert all(len(line) <= 30 for t in entries for line in t.split("\n"))
    assert fig.legends[0].get_title().get_text() == (
        "6 of 48 machines: largest angle swings"
    )
    # one legend, outside the axes: no axes legend on the machine panels
    axes = fig.axes
    assert all(ax.get_legend() is None for ax in axes[:7])
    right = max(ax.get_position().x1 for ax in axes)
    assert right < 0.82  # the legend's column (bbox at x = 0.81) is free
    labels = [ax.get_ylabel() for ax in axes]
    assert labels[0] == "angle - COI (deg)"
    assert all("(" in lab and lab.endswith(")") for lab in labels)  # units on each
    assert any("Pm" in lab for lab in labels) and any("Vs" in lab for lab in labels)
    for ax in axes:  # six lines per machine panel; event lines at 1 and 1.1 s
        assert _event_lines(ax) == [1.0, 1.1]
    for ax in axes[:7]:
        assert len(ax.collections) == 1  # the band of the 42 others
        assert len([ln for ln in ax.lines if ln.get_linestyle() == "-"]) == 6
    # the angle panel in degrees: the largest swing peaks near 40 * 0.6 deg + 10
    top = max(np.nanmax(ln.get_ydata()) for ln in axes[0].lines[:6])
    assert 30 < top < 40
    # the bus panel names the lowest bus after clearing (13), the highest, the
    # lowest overall (7, the faulted bus)
    bus_legend = [t.get_text() for t in axes[7].get_legend().get_texts()]
    assert "bus 13: lowest after 1.1 s" in bus_legend
    assert "bus 7: lowest" in bus_legend
    assert any(s.endswith(": highest") for s in bus_legend)


def test_a_four_machine_run_draws_every_machine_without_a_band(captured):
    a = _grid_run(n_gen=4, n_bus=13, swing=(2,))
    plotting.plot_grid_run(a, "x.png", "kundur-like", events=EVENTS)
    fig = captured[-1]
    entries = _legend_texts(fig)
    assert entries[:4] == ["G 1:1", "G 2:1", "G 3:1", "G 4:1"]  # column order
    assert not any(e.startswith("other") for e in entries)
    assert all(len(ax.collections) == 0 for ax in fig.axes[:7])


def test_a_case_without_stabilizers_says_so_on_the_vs_panel(captured):
    plotting.plot_grid_run(_grid_run(vs_scale=0.0), "x.png", "t", events=EVENTS)
    ax = next(ax for ax in captured[-1].axes if "Vs" in ax.get_ylabel())
    assert [t.get_text() for t in ax.texts] == [
        "zero throughout (no stabilizer in this case)"
    ]


def test_the_tuners_before_after_figure_shares_its_y_axes(captured):
    """A three-fold larger stabilizer output after tuning shows as a three-fold
    taller curve on the same axis, not only in the tick labels (issue 50)."""
    sw = (5, 2, 0, 1, 3, 4)
    before = _grid_run(n_gen=10, swing=sw)
    after = _grid_run(n_gen=10, swing=sw, vs_scale=3.0)
    plotting.plot_grid_compare({"start": before, "tuned": after}, "x.png", "", EVENTS)
    fig = captured[-1]
    axs = np.array(fig.axes).reshape(4, 2)
    for r in range(4):
        assert axs[r, 0].get_ylim() == axs[r, 1].get_ylim()
    assert axs[0, 0].get_ylabel() == "angle - COI (deg)"
    vs_peak = [max(np.nanmax(ln.get_ydata()) for ln in ax.lines[:6]) for ax in axs[3]]
    assert vs_peak[1] == pytest.approx(3 * vs_peak[0])
    assert axs[3, 1].get_ylim()[1] >= vs_peak[1]
    entries = _legend_texts(fig)
    assert entries[:6] == ["G 6:1", "G 3:1", "G 1:1", "G 2:1", "G 4:1", "G 5:1"]
    assert "other 4 machines" in entries
    for ax in fig.axes:
        assert _event_lines(ax) == [1.0, 1.1]


def test_the_case_cct_chart_names_buses_shortest_first(captured):
    rows = [
        {"bus": 7, "name": "", "cct": 0.21, "status": "found"},
        {"bus": 3, "name": "", "cct": None, "status": "exceeds_max"},
        {"bus": 9, "name": "", "cct": 0.0, "status": "unstable_at_min"},
        {"bus": 1, "name": "", "cct": 0.12, "status": "found"},
    ]
    plotting.plot_case_cct(rows, 1.0, "x.png", "t")
    ax = captured[-1].axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["9", "1", "7", "3"]
    heights = [p.get_height() for p in ax.patches]
    assert heights == [0.12, 0.21, 1.0]  # the last: hatched, stable at 1 s
    assert ax.patches[-1].get_hatch() == "//"
    crosses = [ln for ln in ax.lines if ln.get_marker() == "x"]
    assert len(crosses) == 1 and list(crosses[0].get_xdata()) == [0]
    assert ax.get_ylabel() == "critical clearing time (s)"


def test_the_case_compare_figure_has_a_curve_per_set(captured):
    rng = np.random.default_rng(0)
    rows = {
        k: {
            "stable": np.array([True, True, False, True]),
            "settling_angle": rng.uniform(1, 3, 4),
            "overshoot": rng.uniform(0.1, 0.3, 4),
        }
        for k in ("case", "heavy")
    }
    ccts = {
        "case": {"cct": {2: 0.2, 5: 0.1, 8: None}},
        "heavy": {"cct": {2: 0.3, 5: 0.2, 8: 0.4}},
    }
    plotting.plot_case_compare(rows, ccts, "x.png")
    fig = captured[-1]
    assert len(fig.axes) == 3
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend == ["case (3 of 4 stable)", "heavy (3 of 4 stable)"]
    assert fig.axes[1].get_xlabel() == "first-swing overshoot (deg)"
    ax = fig.axes[2]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["5", "2", "8"]
    ys = [list(ln.get_ydata()) for ln in ax.lines]
    assert ys[0][:2] == [0.1, 0.2] and np.isnan(ys[0][2]) and ys[1] == [0.2, 0.3, 0.4]
