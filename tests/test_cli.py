"""The command-line contract: files, summary, and one-line errors without traceback."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import smibjax as sj
from helpers import ROOT, cli_env
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
    assert main(["simulate", "--t-end", "2"]) == 0
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
        (["simulate", "--t-end", "-2"], "--t-end: -2 is not allowed: must be > 0"),
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


def test_a_command_run_in_process_keeps_the_suites_cache_and_devices(capsys):
    """`main()` sets up its process (`smibjax.configure`) even when a test calls it:
    it must find the suite's settings in the environment (conftest), so that this
    worker keeps compiling into .jax_cache/ (where the command-line processes of the
    suite look) and never into the user's ~/.cache, and later processes get one host
    device."""
    import jax

    from helpers import CACHE

    assert main(["simulate", "--t-end", "x"]) == 2
    capsys.readouterr()
    assert jax.config.jax_compilation_cache_dir == CACHE
    # every program is cached, also eager code's one-operation ones (conftest)
    assert jax.config.jax_persistent_cache_min_compile_time_secs == 0.0
    assert "--xla_force_host_platform_device_count=1" in os.environ["XLA_FLAGS"]
    assert "multi_thread_eigen" not in os.environ["XLA_FLAGS"]


@pytest.mark.parametrize("value", ["x", "-1", "nan", "inf"])
def test_a_bad_cache_threshold_in_the_environment_is_one_line(value, capsys):
    import jax

    saved = os.environ["SMIBJAX_CACHE_MIN_COMPILE_S"]
    os.environ["SMIBJAX_CACHE_MIN_COMPILE_S"] = value
    try:
        assert main(["simulate", "--t-end", "1"]) == 2
    finally:
        os.environ["SMIBJAX_CACHE_MIN_COMPILE_S"] = saved
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("smibjax: error:")
    assert f"SMIBJAX_CACHE_MIN_COMPILE_S = {value!r} is not allowed" in err
    main(["simulate", "--t-end", "x"])  # the suite's setting back in this process
    capsys.readouterr()
    assert jax.config.jax_persistent_cache_min_compile_time_secs == 0.0


def test_bad_gains_files(tmp_path, capsys):
    bad = tmp_path / "g.json"
    bad.write_text('{"beta1": -1, "zeta": 2}')
    assert main(["simulate", "--gains", str(bad)]) == 2
    assert "unknown gain 'zeta'" in capsys.readouterr().err
    bad.write_text("{not json")
    assert main(["simulate", "--gains", str(bad)]) == 2
    assert "not valid json" in capsys.readouterr().err


def test_command_line_process_has_no_traceback():
    env = cli_env()
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
        "paper_inputs.png",
        "stabilized_inputs.png",
        "stabilized_aftsc.csv",
        "paper_asc.npz",
        "metrics.md",
    ]:
        assert (tmp_path / name).stat().st_size > 0, name
    assert not list(tmp_path.glob("*_inputs_inputs*"))  # issue 32: one name
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


# Issue 16: no wrong answer, no lost file.


def _one_line(capsys, needle):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("smibjax: error:"), err
    assert needle in err, err
    return err


def test_a_run_that_stopped_early_reports_not_reached(tmp_path, capsys):
    out = tmp_path / "r.npz"
    assert (
        main(["simulate", "--max-steps", "1", "--t-end", "2", "--out", str(out)]) == 0
    )
    text = capsys.readouterr().out
    assert "UNDECIDED" in text
    assert "settling time delta: not reached" in text
    assert "first-swing overshoot: not reached" in text
    assert "0.000 s" not in text.split("settling time delta")[1].split("solver:")[0]
    meta = json.loads(str(np.load(out)["meta"]))
    assert meta["metrics"]["settling_delta"] is None
    assert meta["metrics"]["overshoot"] is None and meta["metrics"]["stable"] is False


@pytest.mark.parametrize(
    "argv, needle",
    [
        (
            ["--t-end", "2", "--fault-time", "5", "--clear-time", "5.2"]
            + ["--reclose-time", "6"],
            "Fault.t_fault = 5 is not allowed: must be < --t-end 2",
        ),
        (
            ["--t-end", "2", "--fault-time", "1", "--clear-time", "2.5"]
            + ["--reclose-time", "3"],
            "Fault.t_clear = 2.5 is not allowed: must be < --t-end 2",
        ),
        (["--dt-save", "1e-300"], "t_end / dt_save = 10 / 1e-300 is not allowed"),
        (["--t-end", "1e308"], "t_end / dt_save = 1e+308 / 0.01 is not allowed"),
        (["--t-end", "nan"], "argument --t-end: nan is not allowed"),
        (["--set", "H=inf"], "Plant.H = inf is not allowed"),
        (["--set", "Xd=inf"], "Plant.Xd = inf is not allowed"),
        (["--set", "Pm_ref=inf"], "OperatingPoint.Pm_ref = inf is not allowed"),
        (["--set", "th2=1e308"], "InitialEstimates.th2 = 1e+308 is not allowed"),
        (["--set", "D=nan"], "Plant.D = nan is not allowed"),
        (["--fault-reactance", "inf"], "Fault.Xf = inf is not allowed"),
        (["--reclose-time", "inf"], "Fault.t_reclose = inf is not allowed"),
    ],
)
def test_simulate_refuses_what_it_cannot_answer(argv, needle, tmp_path, capsys):
    out = tmp_path / "r.npz"
    assert main(["simulate", *argv, "--out", str(out)]) == 2
    _one_line(capsys, needle)
    assert not out.exists()


def test_cct_and_compare_refuse_a_fault_outside_the_horizon(tmp_path, capsys):
    assert main(["cct", "--t-end", "1.5", "--fault-location", "0.5"]) == 2
    _one_line(capsys, "--t-end 1.5 s is not allowed: must be after --reclose-time 2 s")
    out = tmp_path / "cmp"
    argv = ["compare", "--t-end", "1.0", "--n", "2", "--out", str(out)]
    assert main([*argv, "--reclose-time", "0.9"]) == 2  # CCT fits, Monte Carlo not
    _one_line(capsys, "--t-end 1 is not allowed: must be > 1.25 s")
    assert not out.exists()


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--tol", "1e-300"], "--tol 1e-300 is not allowed: must be within [1e-09, "),
        (["--tol", "nan"], "--tol: nan is not allowed"),
        (["--fault-location", "0.5", "nan"], "--fault-location nan is not allowed"),
        (["--reclose-time", "inf"], "--reclose-time inf s is not allowed"),
    ],
)
def test_cct_and_compare_options_are_checked_before_any_work(
    argv, needle, tmp_path, capsys
):
    assert main(["cct", *argv, "--out", str(tmp_path / "c.json")]) == 2
    _one_line(capsys, needle)
    assert main(["compare", "--n", "2", *argv, "--out", str(tmp_path / "k")]) == 2
    _one_line(capsys, needle)
    assert list(tmp_path.iterdir()) == []
    if "--fault-location" not in argv:
        assert main(["cct", "--fault-reactance", "inf", *argv[:0]]) == 2
        _one_line(capsys, "Fault.Xf = inf is not allowed")


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_files_that_are_not_utf8_are_one_line(tmp_path, capsys, suffix):
    bad = tmp_path / f"g{suffix}"
    bad.write_bytes(b"beta1 = -1\n# caf\xe9 \xff\n")
    assert main(["simulate", "--gains", str(bad)]) == 2
    _one_line(capsys, "must be UTF-8 text")
    assert main(["montecarlo", "--dist", str(bad), "--out", str(tmp_path / "o")]) == 2
    _one_line(capsys, "must be UTF-8 text")
    assert not (tmp_path / "o").exists()


def test_process_errors_have_no_traceback(tmp_path):
    """A few of the probe's inputs, through a real process."""
    env = cli_env()
    bad = tmp_path / "g.toml"
    bad.write_bytes(b"\xff\xfe")
    for argv in (
        ["simulate", "--dt-save", "1e-300"],
        ["simulate", "--gains", str(bad)],
        ["montecarlo", "--seed", "-1", "--out", str(tmp_path / "o")],
    ):
        p = subprocess.run(
            [sys.executable, "-m", "smibjax", *argv],
            capture_output=True,
            text=True,
            env=env,
            cwd=ROOT,
        )
        assert p.returncode == 2, argv
        assert "Traceback" not in p.stderr
        assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert not (tmp_path / "o").exists()


def test_simulate_never_replaces_a_file_without_force(tmp_path, capsys):
    out, png = tmp_path / "r.npz", tmp_path / "r.png"
    out.write_bytes(b"precious")
    argv = ["simulate", "--t-end", "2", "--out", str(out)]
    assert main(argv) == 2
    _one_line(capsys, f"--out = '{out}' is not allowed: must be a new file")
    assert out.read_bytes() == b"precious"
    # the name without .npz is the same file
    assert main(["simulate", "--t-end", "2", "--out", str(tmp_path / "r")]) == 2
    _one_line(capsys, "add --force")
    png.write_bytes(b"precious")
    assert main(["simulate", "--t-end", "2", "--plot", str(png)]) == 2
    _one_line(capsys, f"--plot = '{png}' is not allowed: must be a new file")
    assert png.read_bytes() == b"precious"
    assert main([*argv, "--plot", str(png), "--force"]) == 0
    assert np.load(out)["t"][-1] == 2.0 and png.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    "name, magic", [("p.pdf", b"%PDF"), ("p.svg", b"<?xml"), ("p.PNG", b"\x89PNG")]
)
def test_plot_writes_the_format_of_its_suffix(tmp_path, capsys, name, magic):
    path = tmp_path / name
    assert main(["simulate", "--t-end", "2", "--plot", str(path)]) == 0
    assert path.read_bytes()[: len(magic)] == magic


@pytest.mark.parametrize("name", ["p.foo", "p", "p.pgf"])
def test_plot_refuses_unknown_formats_before_the_run(tmp_path, capsys, name):
    assert main(["simulate", "--t-end", "2", "--plot", str(tmp_path / name)]) == 2
    _one_line(capsys, "is not allowed: must end in one of .eps")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_output_files_honour_the_umask(tmp_path, capsys, mask, mode):
    old = os.umask(mask)
    try:
        out = tmp_path / "r.npz"
        assert main(["simulate", "--t-end", "2", "--out", str(out)]) == 0
        assert out.stat().st_mode & 0o777 == mode
    finally:
        os.umask(old)


def test_cct_never_replaces_a_file_without_force(tmp_path, capsys):
    out = tmp_path / "c.json"
    out.write_text("precious")
    argv = ["cct", "--fault-location", "0.5", "--tol", "0.2", "--out", str(out)]
    assert main(argv) == 2  # refused before any simulation
    _one_line(capsys, "must be a new file (it exists; add --force")
    assert out.read_text() == "precious"
    out.unlink()
    (tmp_path / "c.png").write_text("precious")  # its plot is a file it writes too
    assert main(argv) == 2
    _one_line(capsys, "c.png")
    assert not out.exists()
    assert main([*argv, "--force"]) == 0
    assert json.loads(out.read_text())["fault_location"] == [0.5]
    assert (tmp_path / "c.png").read_bytes()[:4] == b"\x89PNG"


def test_reproduce_never_replaces_files_without_force(tmp_path, capsys):
    (tmp_path / "metrics.md").write_text("precious")
    assert main(["reproduce", "--out", str(tmp_path), "--t-end", "3"]) == 2
    _one_line(capsys, "add --force")
    assert (tmp_path / "metrics.md").read_text() == "precious"
    assert list(tmp_path.iterdir()) == [tmp_path / "metrics.md"]


def test_version_and_help_hint(capsys):
    from smibjax import __version__

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"smibjax {__version__}"
    for sub in ("simulate", "montecarlo", "cct"):
        assert main([sub, "--bogus", "1"]) == 2
        _one_line(capsys, f"(see `python -m smibjax {sub} --help`)")
    assert main(["simulate", "--t-end", "x"]) == 2
    _one_line(capsys, "(see `python -m smibjax simulate --help`)")


def test_dt_save_that_does_not_divide_the_horizon_says_what_it_did(capsys):
    assert main(["simulate", "--t-end", "2", "--dt-save", "0.03"]) == 0
    err = capsys.readouterr().err
    assert "--dt-save 0.03 does not divide --t-end 2: sampling 67 equal" in err
    assert main(["simulate", "--t-end", "2", "--dt-save", "0.02"]) == 0
    assert "warning" not in capsys.readouterr().err
    # a refusal stays one line: no warning before it
    assert main(["simulate", "--t-end", "2", "--dt-save", "0.03", "--set", "H=0"]) == 2
    _one_line(capsys, "Plant.H = 0 is not allowed")


def test_every_summary_names_its_plant_and_limits(tmp_path, capsys):
    """Issue 32: `simulate --controller avr-pss` ran on the unlimited paper plant (Vt
    up to 1.89 pu) and its summary never named the plant."""
    assert main(["simulate", "--controller", "avr-pss", "--t-end", "3"]) == 0
    out = capsys.readouterr().out
    assert "on:                  paper plant (no input limits)" in out
    assert "adaptation" not in out.splitlines()[1]  # avr-pss has none
    argv = ["simulate", "--controller", "avr-pss", "--preset", "realistic"]
    assert main([*argv, "--t-end", "3"]) == 0
    out = capsys.readouterr().out
    assert "realistic plant (u_f in [-5, 5], u_r in [-1, 1] pu)" in out


def test_every_command_default_output_shares_one_root(tmp_path, monkeypatch):
    """Issue 32 item 6: simulate/cct (`--out` alone), montecarlo, compare, reproduce
    and the tuner name their default outputs under the one root runs/, one name per
    command; an explicit --out is kept as given."""
    import argparse

    from smibjax._commandline import OUTPUT_ROOT
    from smibjax.cli import _parser, cct, compare, montecarlo, reproduce, simulate
    from tuning import optimize

    monkeypatch.chdir(tmp_path)
    parser = _parser()

    def parse(argv):
        return parser.parse_args(argv)

    picked = {
        "simulate": simulate.output(parse(["simulate", "--out"])),
        "cct": cct.output(parse(["cct", "--out"])),
        "montecarlo": montecarlo.output(parse(["montecarlo"])),
        "compare": compare.output(parse(["compare"])),
        "reproduce": reproduce.output(parse(["reproduce"])),
        "tune": optimize.output(argparse.Namespace(out=None)),
    }
    assert OUTPUT_ROOT == type(OUTPUT_ROOT)("runs")
    for command, path in picked.items():
        assert path.parent == OUTPUT_ROOT, (command, path)
        assert path.name.startswith(f"{command}-"), (command, path)
    assert picked["simulate"].suffix == ".npz" and picked["cct"].suffix == ".json"
    # a taken name is never reused: the next run of the same second gets a suffix
    (tmp_path / picked["montecarlo"]).mkdir(parents=True)
    again = montecarlo.output(parse(["montecarlo"]))
    assert again != picked["montecarlo"] and again.parent == OUTPUT_ROOT
    # nothing written without --out by simulate and cct; --out as given elsewhere
    assert simulate.output(parse(["simulate"])) is None
    assert cct.output(parse(["cct"])) is None
    assert str(reproduce.output(parse(["reproduce", "--out", "x/y"]))) == "x/y"
    assert str(optimize.output(argparse.Namespace(out="z"))) == "z"


@pytest.mark.parametrize(
    "argv, noted",
    [
        (["simulate", "--controller", "avr-pss"], True),
        (["montecarlo", "--controller", "avr-pss"], True),
        (["cct", "--controller", "avr-pss"], True),
        (["simulate", "--controller", "avr-pss", "--preset", "realistic"], False),
        (["simulate", "--controller", "avr-pss", "--set", "uf_max=5"], False),
        (["simulate"], False),  # the paper's law on the paper's plant: its case
        (["simulate", "--controller", "none"], False),
    ],
)
def test_conventional_controller_on_the_unlimited_plant_is_noted(argv, noted, capsys):
    """Issue 32 item 1: `simulate --controller avr-pss` runs on the paper plant (no
    input limits; Vt up to 1.89 pu) without a word. The default plant stays (the
    SMIB identity); one note line suggests --preset realistic."""
    from smibjax.cli import _parser
    from smibjax.cli.options import build_from_args

    args = _parser().parse_args(argv)
    if argv[0] == "cct":  # one build per --controller (repeatable)
        from smibjax.cli.cct import _sets

        plant = _sets(args)[1][0]
    else:
        plant = build_from_args(args, complete=True)[1]
    err = capsys.readouterr().err
    notes = [ln for ln in err.splitlines() if "--preset realistic" in ln]
    assert len(notes) == (1 if noted else 0), err
    if noted:
        assert notes[0].startswith("smibjax: note: avr-pss runs on the paper plant")
        assert "no input limits" in notes[0]
        assert math.isinf(float(plant.uf_max))  # the default plant is unchanged


def test_cct_table_names_the_plant_and_its_limits(capsys):
    """Issue 32 item 1: every summary names its plant and limits; the CCT table
    said 'plant paper' without the limits."""
    from smibjax._parameters import PLANT_NAMES, Plant
    from smibjax.cli.cct import print_cct

    for preset, limits in (
        ("paper", "(no input limits)"),
        ("realistic", "(u_f in [-5, 5], u_r in [-1, 1] pu)"),
    ):
        plant = Plant.preset(preset)
        res = {
            "fault_location": [0.5],
            "fault_time": 0.5,
            "reclose_time": 1.5,
            "tol": 1e-3,
            "window": 1.0,
            "context": {
                "avr-pss": {
                    "controller": "avr-pss",
                    "plant": {"preset": preset},
                    "options": {},
                }
            },
            "plant": {k: float(getattr(plant, k)) for k in PLANT_NAMES},
            "sets": {"avr-pss": {"cct": [0.2], "status": ["ok"], "islands": [False]}},
        }
        print_cct(res)
        out = capsys.readouterr().out
        assert f"controller avr-pss, adaptation -, plant {preset} {limits}" in out
