"""The command-line contract: files, summary, and one-line errors without traceback."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import smibjax as sj
from conftest import ROOT
from smibjax.cli import main

KEYS = [
    "t",
    "delta",
    "omega",
    "E",
    "B",
    "Vt",
    "theta_hat",
    "phi",
    "u_f",
    "u_r",
    "stable",
]


def test_simulate_writes_npz_and_plot(tmp_path, capsys):
    gains = tmp_path / "g.toml"
    gains.write_text("beta1 = -1.0\nbeta2 = -1.0\n")
    out, png = tmp_path / "run.npz", tmp_path / "run.png"
    rc = main(
        [
            "simulate",
            "--controller",
            "asc",
            "--gains",
            str(gains),
            "--set",
            "T2=0.8",
            "--t-end",
            "6",
            "--out",
            str(out),
            "--plot",
            str(png),
        ]
    )
    assert rc == 0
    text = capsys.readouterr().out
    assert "stable" in text and "settling time delta" in text
    data = np.load(out)
    for k in KEYS:
        assert k in data.files
    n = data["t"].shape[0]
    assert np.max(np.diff(data["t"])) <= 0.01 + 1e-12
    assert data["theta_hat"].shape == (n, 2) and data["phi"].shape == (n, 2)
    assert bool(data["stable"])
    meta = json.loads(str(data["meta"]))
    assert meta["gains"]["T2"] == 0.8 and meta["gains"]["alpha"] == 1.0
    # the values, not just the keys: the same run through the library
    tr = sj.simulate(sj.Gains.paper("asc", beta1=-1.0, beta2=-1.0, T2=0.8), t_end=6.0)
    for k in KEYS:
        np.testing.assert_allclose(
            data[k], np.asarray(getattr(tr, k)), rtol=1e-12, atol=1e-12, err_msg=k
        )
    assert png.stat().st_size > 10_000


def test_simulate_paper_case_reports_instability(capsys):
    assert main(["simulate", "--t-end", "3"]) == 0
    assert "UNSTABLE: lost synchronism" in capsys.readouterr().out


def test_solver_tolerances_reach_the_run(capsys):
    stable = ["--set", "beta1=-1", "--set", "beta2=-1"]
    assert main(["simulate", *stable, "--atol", "1e-6"]) == 0
    out = capsys.readouterr().out
    steps = int(out.split("solver: ")[1].split(" steps")[0])
    assert 1500 < steps < 2600  # 3801 at the default atol 1e-8
    assert "result:              stable" in out


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["simulate", "--clear-time", "0.4"], "t_clear = 0.4"),
        (["simulate", "--set", "alpha=1.5"], "alpha = 1.5"),
        (["simulate", "--set", "T1=-1"], "T1 = -1"),
        (["simulate", "--set", "bogus=1"], "bogus"),
        (["simulate", "--set", "alpha"], "NAME=VALUE"),
        (["simulate", "--gains", "/nonexistent/g.json"], "does not exist"),
        (["simulate", "--fault-location", "1.5"], "lam = 1.5"),
        (["simulate", "--t-end", "-2"], "t_end = -2"),
        (["simulate", "--controller", "pid"], "invalid choice"),
        (["simulate", "--fault-time", "abc"], "invalid float"),
        (["simulate", "--atol=-1e-6"], "--atol: -1e-6 is not allowed"),
        (["montecarlo", "--n", "4", "--rtol", "0"], "--rtol: 0 is not allowed"),
    ],
)
def test_bad_input_is_one_line_and_nonzero(argv, needle, capsys):
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2
    assert needle in err
    assert err.count("\n") == 1 and err.startswith("smibjax: error:")


def test_bad_gains_files(tmp_path, capsys):
    bad = tmp_path / "g.json"
    bad.write_text('{"beta1": -1, "zeta": 2}')
    assert main(["simulate", "--gains", str(bad)]) == 2
    assert "unknown gain 'zeta'" in capsys.readouterr().err
    bad.write_text("{not json")
    assert main(["simulate", "--gains", str(bad)]) == 2
    assert "not valid json" in capsys.readouterr().err


def test_command_line_process_has_no_traceback():
    env = {**os.environ, "SMIBJAX_CACHE_DIR": str(ROOT / ".jax_cache")}
    p = subprocess.run(
        [sys.executable, "-m", "smibjax", "simulate", "--clear-time", "0.4"],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
    )
    assert p.returncode == 2
    assert "Traceback" not in p.stderr
    assert p.stderr.strip().splitlines() == [
        "smibjax: error: Fault.t_clear = 0.4 is not allowed: must be > t_fault = 0.5"
    ]


def test_reproduce_writes_figures_data_and_table(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--t-end", "6"]) == 0
    for name in [
        "paper_fig3_states.png",
        "paper_fig4_estimates.png",
        "paper_fig5_macro.png",
        "stabilized_fig3_states.png",
        "stabilized_aftsc.csv",
        "paper_asc.npz",
        "metrics.md",
    ]:
        assert (tmp_path / name).stat().st_size > 0, name
    table = json.loads((tmp_path / "metrics.json").read_text())
    assert table["paper AFTSC"]["stable"] is False
    assert table["stabilized AFTSC"]["stable"] is True
    # README "What reproduces": loss of synchronism at t = 1.83 s under both
    # controllers, delta settles 4.48 s (AFTSC) and 4.47 s (ASC) after fault inception
    # (two decimals there, so within 0.005 s)
    for c in ("AFTSC", "ASC"):
        assert table[f"paper {c}"]["lost_sync_at"] == pytest.approx(1.83, abs=0.005)
        assert table[f"paper {c}"]["settling_delta"] is None  # never settles
    assert table["stabilized AFTSC"]["settling_delta"] == pytest.approx(4.48, abs=5e-3)
    assert table["stabilized ASC"]["settling_delta"] == pytest.approx(4.47, abs=5e-3)
    assert table["stabilized AFTSC"]["overshoot"] == pytest.approx(0.154, abs=5e-4)
    csv = np.loadtxt(tmp_path / "stabilized_asc.csv", delimiter=",", skiprows=1)
    assert csv.shape[1] == 12
