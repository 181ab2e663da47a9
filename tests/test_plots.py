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
