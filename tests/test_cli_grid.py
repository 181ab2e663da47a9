"""The commands on a multi-machine case (`--case`): outputs that name what they hold,
and bad input as one line with exit 2 and nothing written."""

import json

import numpy as np
import pytest

from smibjax.cli import main

# The tests that run smib-gencls's batch program (3 scenarios per chunk, 2 s) run on
# one worker: they share it in memory (cold, the output-root test took 14.3 s alone
# and 4.7 s after the compare test, 2026-12-02 at load 8). They all run at the
# tolerances `TOL` (not the default ones): the cct test needs values other than the
# defaults to see that the command passes them on, and at the same values its scan
# and bisection programs are the compare test's (the solver's options are static:
# other tolerances, other programs). The six tests cold in one process: 181 -> 149
# CPU-s, the cct test 266 -> 2.5 s (2026-12-03 at load 19).
CASE_BATCH = pytest.mark.xdist_group("case_batch")
TOL = ["--rtol", "1e-7", "--atol", "1e-9"]
TOL_KW = dict(rtol=1e-7, atol=1e-9)


def test_simulate_a_case_writes_named_arrays_and_a_plot(tmp_path, capsys):
    out, plot = tmp_path / "run.npz", tmp_path / "run.png"
    argv = [
        "simulate",
        "--case",
        "smib-gencls",
        "--fault-bus",
        "2",
        "--fault-time",
        "0.2",
    ]
    argv += [
        "--clear-time",
        "0.3",
        "--t-end",
        "2",
        "--out",
        str(out),
        "--plot",
        str(plot),
    ]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert text.startswith("stable")
    a = np.load(out)
    assert list(a["gen"]) == ["1:1", "2:1", "3:1"]
    assert list(a["bus"]) == [1, 2, 3]
    assert a["delta"].shape == (201, 3) and a["v_bus"].shape == (201, 3)
    meta = json.loads(str(a["meta"]))
    assert meta["case"] == "smib-gencls" and meta["stable"] is True
    # the faulted bus is at zero during the fault, the machine accelerates
    k = int(np.searchsorted(a["t"], 0.25))
    assert abs(a["v_bus"][k, 1]) < 1e-9 and a["omega"][k, 0] > 0
    assert plot.stat().st_size > 10_000


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--case", "nope", "--fault-bus", "1"], "case 'nope' is not built in"),
        (["--case", "smib-gencls", "--fault-bus", "99"], "bus 99 is not in the system"),
        (["--case", "smib-gencls", "--fault-line", "2-9"], "branch 2-9 does not exist"),
        (["--case", "smib-gencls", "--fault-line", "x"], "expected FROM-TO[:CKT]"),
        (["--case", "smib-gencls"], "a --case run needs an event"),
        (
            ["--case", "smib-gencls", "--fault-bus", "2", "--clear-time", "0.4"],
            "must satisfy 0 <= fault < clear",
        ),
        (["--case", "smib-gencls", "--trip-gen", "7"], "no generator 7:1"),
        (["--case", "x.raw"], "a raw file needs its dyr file"),
        (
            ["--case", "smib-gencls", "--param", "GENCLS.Q=1", "--fault-bus", "2"],
            "no parameter",
        ),
        (
            ["--case", "smib-gencls", "--param", "IEEEST.KS=1", "--fault-bus", "2"],
            "no IEEEST",
        ),
        (
            ["--case", "smib-gencls", "--load-factor", "-1", "--fault-bus", "2"],
            "must be > 0",
        ),
        (
            ["--case", "smib-gencls", "--load-factor", "40", "--fault-bus", "2"],
            "did not converge",
        ),
        # the SMIB's options were ignored on a case (found running kundur-synex)
        (
            ["--case", "smib-gencls", "--set", "H=6", "--fault-bus", "2"],
            "--set is not allowed with --case",
        ),
        (
            ["--case", "smib-gencls", "--gains", "g.json", "--fault-bus", "2"],
            "--gains is not allowed with --case",
        ),
    ],
)
def test_bad_case_input_is_one_line(argv, needle, tmp_path, capsys):
    out = tmp_path / "x.npz"
    assert main(["simulate", "--fault-time", "0.5", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("smibjax: error: ") and needle in err[-1], err
    assert not out.exists()


def test_a_trip_that_islands_is_refused(tmp_path, capsys):
    argv = ["simulate", "--case", "smib-gencls", "--trip-line", "1-2"]
    assert main(argv) == 2
    assert "islands the system" in capsys.readouterr().err


@CASE_BATCH
def test_compare_a_case_against_its_parameter_sets(tmp_path, capsys):
    """Issue 28 item 7: `compare --case` runs each parameter set on the same fault
    scenarios; a machine with 4x the inertia swings less on the same faults."""
    out = tmp_path / "cmp"
    argv = ["compare", "--case", "smib-gencls", "--variant", "heavy:GENCLS.H=12"]
    argv += ["--param", "GENCLS.D=1", "--n", "3", "--chunk", "3", "--t-end", "2"]
    argv += ["--fault-buses", "2", "--fault-times", "0.2:0.3"]
    argv += ["--clear-after", "0.05:0.1", "--out", str(out), *TOL]
    assert main(argv) == 0
    data = json.loads((out / "compare.json").read_text())
    assert list(data["summary"]) == ["case", "param", "heavy"]
    assert data["sets"]["heavy"] == ["GENCLS.H=12"]
    s = data["summary"]
    assert all(v["n"] == 3 for v in s.values())
    assert s["case"]["stable_fraction"] == 1.0
    assert s["heavy"]["overshoot_mean"] < s["case"]["overshoot_mean"]
    table = (out / "compare.md").read_text()
    assert "| heavy | GENCLS.H=12 |" in table and "| case | the case's own |" in table
    assert "peak Efd (pu)" in table and "the same for every set" in table
    assert (out / "compare.png").stat().st_size > 10_000  # issue 50: as the SMIB's
    # issue 32: the CCT of a bolted fault at each fault bus (bus 2, at 0.5 s), one
    # per set (H = 12 on every GENCLS, the infinite bus's machine too: not longer)
    cct = {k: v["cct"]["2"] for k, v in data["cct"].items()}
    assert list(cct) == ["case", "param", "heavy"]
    assert all(0 < c < 1 for c in cct.values()) and cct["heavy"] != cct["case"]
    assert s["case"]["cct_shortest"] == {"bus": 2, "cct": cct["case"]}
    assert f"| {cct['case']:.3f} (bus 2) |" in table and "shortest CCT (s)" in table
    # independently: the case's own machine survives a fault of cct, not of cct + tol
    import jax.numpy as jnp

    from smibjax.grid.case import load_case
    from smibjax.grid.events import BusFault
    from smibjax.grid.operating import operating_point
    from smibjax.grid.simulate import simulate_jit

    case = load_case("smib-gencls")
    op, _ = operating_point(case)
    pos = case.system.bus_index(2)
    for d, survives in ((cct["case"], True), (cct["case"] + 1e-3, False)):
        ev = BusFault(bus=jnp.asarray(pos), t_on=jnp.asarray(0.5), t_off=0.5 + d)
        tr = simulate_jit(case, op, (ev,), t_end=2.0, dt_save=0.05, **TOL_KW)
        assert bool(tr.stable) is survives, d


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ([], "needs a set to compare"),
        (["--variant", "x"], "expected LABEL:MODEL.PARAM=VALUE"),
        (["--variant", "a:GENCLS.H=2", "--variant", "a:GENCLS.H=3"], "given twice"),
        (["--variant", "a:GENCLS.Q=2"], "GENCLS"),
    ],
)
def test_compare_a_case_refuses_in_one_line(tmp_path, capsys, extra, needle):
    out = tmp_path / "cmp"
    argv = ["compare", "--case", "smib-gencls", "--n", "2", "--out", str(out)]
    assert main([*argv, *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
    assert not out.exists()


@CASE_BATCH
def test_montecarlo_on_a_case_writes_to_the_output_root_without_out(
    tmp_path, monkeypatch
):
    """Issue 32: `montecarlo --case` without --out computed and wrote nothing. It
    writes a new folder runs/montecarlo-<time> like the SMIB's montecarlo:
    scenarios.csv (one row per scenario) and summary.json (n, seed, stable fraction = the rows'
    mean)."""
    import json

    monkeypatch.chdir(tmp_path)
    # n = 3 (one chunk of 3) and 2 s: the batch program of the compare test below
    argv = ["montecarlo", "--case", "smib-gencls", "--n", "3", "--t-end", "2"]
    argv += ["--fault-times", "0.2:0.3", "--clear-after", "0.05:0.1", "--seed", "2"]
    argv += TOL
    assert main(argv) == 0
    (out,) = (tmp_path / "runs").glob("montecarlo-*")
    lines = (out / "scenarios.csv").read_text().strip().splitlines()
    assert len(lines) == 1 + 3
    stable = [row.split(",")[lines[0].split(",").index("stable")] for row in lines[1:]]
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["n"], summary["spec"]["seed"]) == (3, 2)
    assert summary["stable_fraction"] == round(sum(s == "1" for s in stable) / 3, 6)
    assert main(argv) == 0  # a second run: a new folder, the first one kept
    assert len(list((tmp_path / "runs").glob("montecarlo-*"))) == 2


@CASE_BATCH
def test_montecarlo_on_a_case_rows_match_single_runs_and_not_the_chunk(tmp_path):
    """`montecarlo --case`: every row is the metrics of its own scenario (the same
    events through `simulate_jit` + `grid_metrics`, independently), and the rows do
    not depend on --chunk (5 scenarios in chunks of 3, the last padded, against one
    chunk of 5; a chunk of 3 at 2 s is the compare test's batch program)."""
    import jax.numpy as jnp

    from smibjax.grid.case import load_case
    from smibjax.grid.metrics import GridMetrics, grid_metrics
    from smibjax.grid.operating import operating_point
    from smibjax.grid.scenarios import FaultDistribution, sample_events
    from smibjax.grid.simulate import simulate_jit

    common = ["montecarlo", "--case", "smib-gencls", "--n", "5", "--t-end", "2"]
    common += ["--fault-times", "0.2:0.3", "--clear-after", "0.1:1.2", "--seed", "4"]
    common += TOL
    tables = []
    for chunk in ("3", "5"):
        out = tmp_path / f"c{chunk}"
        assert main([*common, "--chunk", chunk, "--out", str(out)]) == 0
        lines = (out / "scenarios.csv").read_text().strip().splitlines()
        head = lines[0].split(",")
        scen = ["index", "fault_bus", "t_fault", "t_clear", "t_reclose"]
        assert head == [*scen, "fault_r", "fault_x", *GridMetrics.FIELDS]
        tables.append([dict(zip(head, s.split(","), strict=True)) for s in lines[1:]])
    a, b = tables
    assert len(a) == len(b) == 5
    case = load_case("smib-gencls")
    op, _ = operating_point(case)
    dist = FaultDistribution(t_fault=(0.2, 0.3), clear_after=(0.1, 1.2))
    (ev,) = sample_events(case.system, dist, 5, 4)
    stable = []
    for i in range(5):
        one = type(ev)(
            bus=int(ev.bus[i]), t_on=float(ev.t_on[i]), t_off=float(ev.t_off[i])
        )
        tr = simulate_jit(case, op, (one,), t_end=2.0, **TOL_KW)
        m = grid_metrics(case, tr, jnp.asarray(float(ev.t_on[i])))
        stable.append(bool(m.stable))
        for row in (a[i], b[i]):
            # the PSS/E bus number (smib-gencls: position + 1), not the position
            assert int(row["fault_bus"]) == int(ev.bus[i]) + 1
            assert float(row["t_clear"]) == pytest.approx(float(ev.t_off[i]), rel=1e-9)
            assert (row["stable"] == "1") == bool(m.stable)
            for f in ("max_spread", "v_min", "v_max", "efd_max"):
                np.testing.assert_allclose(
                    float(row[f]), float(getattr(m, f)), rtol=1e-4, err_msg=f
                )
    # the draw covers both verdicts, so the stable column is not trivially constant
    assert any(stable) and not all(stable)


@CASE_BATCH
def test_cct_on_a_case_uses_the_commands_tolerances(tmp_path, monkeypatch, capsys):
    """`cct --case` ran its bisection at the library's default tolerances whatever
    --rtol/--atol said (compare --case passed them); both now go through one helper.
    The solver sees the command's values, and the CCT printed is the one written."""
    import smibjax.grid.cct as grid_cct

    seen = []
    real = grid_cct.critical_clearing_times_grid

    def spy(*a, **kw):
        seen.append(kw)
        return real(*a, **kw)

    monkeypatch.setattr(grid_cct, "critical_clearing_times_grid", spy)
    out = tmp_path / "cct"  # issue 50: written as cct.json (was: no extension)
    argv = ["cct", "--case", "smib-gencls", "--fault-buses", "2", "--t-end", "2"]
    argv += [*TOL, "--tol", "0.01", "--out", str(out)]
    assert main(argv) == 0
    assert [(k["rtol"], k["atol"], k["tol"]) for k in seen] == [(1e-7, 1e-9, 0.01)]
    assert not out.exists()
    data = json.loads((tmp_path / "cct.json").read_text())
    printed = capsys.readouterr().out
    assert f"{data['cct']['2']:.4f}" in printed
    # rows by PSS/E bus number and name, and the plot beside the JSON (as the SMIB's)
    assert data["rows"] == [
        {
            "bus": 2,
            "name": data["rows"][0]["name"],
            "cct": data["cct"]["2"],
            "status": "found",
        }
    ]
    assert (tmp_path / "cct.png").stat().st_size > 5_000
    assert f"wrote {tmp_path / 'cct.json'} and {tmp_path / 'cct.png'}" in printed
    # the result's context (issue 49, class 9) and the engine's search per bus
    assert (data["load_factor"], data["t_end"], data["params"]) == (1.0, 2.0, {})
    assert (data["rtol"], data["atol"]) == (1e-7, 1e-9)
    assert (
        data["status"] == {"2": "ok"} and data["first_unstable"]["2"] > data["cct"]["2"]
    )


def test_cct_out_of_another_format_is_refused_before_the_run(tmp_path, capsys):
    out = tmp_path / "cct.csv"
    argv = ["cct", "--case", "smib-gencls", "--fault-buses", "2", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"smibjax: error: --out = {str(out)!r} is not allowed: must end in .json (the "
        "CCTs are written as JSON, their plot beside them as .png)"
    ]
    assert not out.exists()


def test_skip_unsupported_drops_the_records_with_one_warning(tmp_path, capsys):
    """A dyr file with a record of a model smibjax lacks (a PSS/E user model,
    USRMDL, twice) is refused in one line naming it; with --skip-unsupported the
    command warns once and runs the case without it: the same angles as the file
    without those records."""
    from smibjax.grid.cases import case_file

    raw = case_file("smib.raw")
    dyr = tmp_path / "extra.dyr"
    dyr.write_text(
        case_file("smib_gencls.dyr").read_text()
        + "     1 'USRMDL' 1  0.02 0.2 -0.2 /\n     3 'USRMDL' 1  1 2 3 /\n"
    )
    run = ["simulate", "--fault-bus", "2", "--fault-time", "0.2", "--clear-time", "0.3"]
    run += ["--t-end", "2"]
    base = ["--case", str(raw), "--dyr", str(dyr)]
    out = tmp_path / "x.npz"
    assert main([*run, *base, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'USRMDL' is not supported (supported: GENCLS" in err[0]
    assert not out.exists()
    assert main([*run, *base, "--skip-unsupported", "--out", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    warned = [e for e in err if e.startswith("smibjax: warning: ")]
    assert len(warned) == 1 and "'USRMDL' is not supported" in warned[0]
    ref = tmp_path / "ref.npz"
    assert main([*run, "--case", "smib-gencls", "--out", str(ref)]) == 0
    np.testing.assert_array_equal(np.load(out)["delta"], np.load(ref)["delta"])


@pytest.mark.parametrize("suffix", [".csv", ".mat", ".cfg"])
def test_simulate_a_case_writes_the_format_its_out_suffix_names(
    tmp_path, suffix, capsys, monkeypatch
):
    """`--out run.csv` is a CSV table (it was an npz under a .csv name), `.mat`
    MATLAB, `.cfg` COMTRADE with its .dat; devices by PSS/E bus number and
    generator bus:id (issue 50)."""
    out = tmp_path / f"run{suffix}"
    argv = ["simulate", "--case", "smib-gencls", "--fault-bus", "2"]
    argv += ["--fault-time", "0.2", "--clear-time", "0.3", "--t-end", "2"]
    # traced, not from a stored program nor this process's (which need no compile,
    # and no line)
    from smibjax.cli import _exported

    monkeypatch.setenv("SMIBJAX_EXPORTED", "0")
    monkeypatch.setattr(_exported, "_GRID", None)
    assert main([*argv, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    # the phase line before the compile (issue 50: no silent wait)
    assert (
        "compiling the simulation of smib-gencls (3 machines, 3 buses): about 22 s "
        "the first time, a few s once cached" in err
    )
    if suffix == ".csv":
        import csv

        with open(out, newline="") as fh:
            rows = list(csv.reader(fh))
        assert rows[0][:2] == ["t (s)", "delta_coi G 1:1 (rad)"]
        assert "v_bus bus 2 (pu)" in rows[0] and len(rows) == 202
        k = rows[0].index("v_bus bus 2 (pu)")
        t = [float(r[0]) for r in rows[1:]]
        i = int(np.searchsorted(t, 0.25))
        assert abs(float(rows[1 + i][k])) < 1e-9  # the faulted bus during the fault
    elif suffix == ".mat":
        from scipy.io import loadmat

        m = loadmat(out)
        assert m["delta"].shape == (201, 3) and m["t"].shape == (201, 1)
        assert [s.strip() for s in m["gen"]] == ["1:1", "2:1", "3:1"]
    else:
        cfg = out.read_bytes().decode().split("\r\n")
        assert cfg[0] == "smib-gencls,smibjax,1999"
        n = int(cfg[1].split(",")[0])
        assert n == 8 * 3 + 3 and cfg[1] == f"{n},{n}A,0D"
        assert cfg[2 + n + 2] == "100,201"  # 100 samples/s, 201 samples
        dat = out.with_suffix(".dat").read_bytes().decode().split("\r\n")
        assert len([r for r in dat if r]) == 201
        assert all(len(r.split(",")) == 2 + n for r in dat if r)


# --- issue 49: a flag a case cannot use, and a value a device cannot take, are one
# line (exit 2, nothing written) whatever the entry --------------------------------

_CASE = ["--case", "smib-gencls"]


@pytest.mark.parametrize(
    "argv, needle",
    [
        *(
            (["simulate", *_CASE, "--fault-bus", "2", flag, value], f"{flag} is not")
            for flag, value in (
                ("--max-steps", "10"),
                ("--max-steps", "50000"),  # given at its default: still refused
                ("--controller", "asc"),
                ("--preset", "realistic"),
                ("--adaptation", "realizable"),
                ("--phi-layer", "0.1"),
            )
        ),
        (["simulate", *_CASE, "--fault-bus", "2", "--max-st", "9"], "--max-steps is"),
        (["simulate", *_CASE, "--fault-bus", "2", "--reclose"], "without --fault-line"),
        (
            ["simulate", *_CASE, "--fault-bus", "2", "--reclose-time", "1"],
            "--reclose-time is not allowed without --reclose",
        ),
        (["cct", *_CASE, "--criterion", "settled"], "--criterion is not allowed"),
        (["cct", *_CASE, "--fault-reactance", "0.1"], "--fault-reactance is not"),
        (["montecarlo", *_CASE, "--dist", "d.toml"], "--dist is not allowed"),
        (["compare", *_CASE, "--scan-step", "0.1"], "--scan-step is not allowed"),
        (
            ["simulate", *_CASE, "--fault-bus", "2", "--fault-reactance", "nan"],
            "--fault-reactance nan is not allowed",
        ),
        (
            ["simulate", *_CASE, "--fault-bus", "2", "--param", "GENCLS.H=1e308"],
            "GENCLS.H = ",
        ),
        (
            ["simulate", *_CASE, "--fault-bus", "2", "--param", "GENCLS.H=-6.5"],
            "must be > 0",
        ),
        (
            ["simulate", *_CASE, "--fault-bus", "2", "--param", "GENCLS.xdp=0"],
            "GENCLS.xdp = ",
        ),
        (
            ["simulate", *_CASE, "--fault-bus", "2", "--param", "GENCLS.state_names=1"],
            "GENCLS has no parameter 'state_names'",
        ),
    ],
)
def test_case_flags_and_values_are_refused_in_one_line(argv, needle, tmp_path, capsys):
    out = tmp_path / "o"
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("smibjax: error: ") and needle in err[-1], err
    assert not out.exists()


def test_input_files_that_were_tracebacks_are_one_line(tmp_path, capsys):
    """Issue 49, classes 7 and 10: a 30-digit bus number in a raw file
    (OverflowError), an unsupported dyr model under `modes` (25 lines), a generator
    voltage set point of 0 (a power flow "not converged" with a NaN mismatch), a
    `--dist` range written as a table (KeyError), a gains file's plant preset
    written as a list (TypeError)."""
    from smibjax.grid.case import case_files

    raw, dyr = case_files("kundur-gencls")
    big = tmp_path / "big.raw"
    lines = raw.read_text().splitlines()
    k = next(i for i, s in enumerate(lines) if s.lstrip().startswith("1,"))
    lines[k] = "123456789012345678901234567890" + lines[k][lines[k].index(",") :]
    big.write_text("\n".join(lines) + "\n")
    vs0 = tmp_path / "vs0.raw"  # a generator's voltage set point 0: a NaN mismatch
    g = next(i for i, s in enumerate(lines) if "GENERATOR DATA" in s) + 1
    fields = raw.read_text().splitlines()[g].split(",")
    fields[6] = " 0.0"
    vs0.write_text(
        "\n".join(
            [
                *raw.read_text().splitlines()[:g],
                ",".join(fields),
                *raw.read_text().splitlines()[g + 1 :],
            ]
        )
        + "\n"
    )
    odd = tmp_path / "odd.dyr"
    odd.write_text(dyr.read_text() + "     1 'WT3G1' 1 0 400 0.04 7.3 -7.3 1 /\n")
    dist = tmp_path / "d.toml"
    dist.write_text("t_fault = {lo = 0.5, hi = 1.0}\n")
    gains = tmp_path / "g.toml"
    gains.write_text(
        'schema = "smibjax.gains/1"\ncontroller = "aftsc"\nadaptation = "oracle"\n'
        '[plant]\npreset = ["paper"]\n[gains]\nk1 = 1.0\n'
    )
    for argv, needle in (
        (
            ["simulate", "--case", str(big), "--dyr", str(dyr), "--fault-bus", "7"],
            "bus field I: 1.23456789012e+29 is not a bus number",
        ),
        (["modes", "--case", str(raw), "--dyr", str(odd)], "'WT3G1' is not supported"),
        (
            ["simulate", "--case", str(vs0), "--dyr", str(dyr), "--fault-bus", "7"],
            "generator field VS: 0.0 is not a positive voltage set point",
        ),
        (["montecarlo", "--dist", str(dist), "--n", "2"], "must be a range [lo, hi]"),
        (["simulate", "--gains", str(gains)], "plant preset = ['paper']"),
    ):
        assert main([*argv, "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("smibjax: error: "), err
        assert needle in err[0], err
    assert not (tmp_path / "o").exists()


# the grid Monte Carlo of the tests below: 6 scenarios in chunks of 3 at 2 s (the
# batch program of the tests above, at their tolerances)
_MC = ["montecarlo", "--case", "smib-gencls", "--n", "6", "--chunk", "3"]
_MC += ["--t-end", "2", "--fault-times", "0.2:0.3", "--clear-after", "0.1:1.2", *TOL]

_KILLED = """
import os, signal, sys
import smibjax.cli.grid as g
from smibjax.cli import main
write = g._write_chunk
def write_then_die(path, rows):
    write(path, rows)
    os.kill(os.getpid(), signal.SIGKILL)  # kill -9 after the first chunk
g._write_chunk = write_then_die
sys.exit(main(sys.argv[1:]))
"""


@CASE_BATCH
def test_grid_montecarlo_killed_and_resumed_writes_the_uninterrupted_rows(tmp_path):
    """Issue 49, class 4: a run killed with SIGKILL after its first chunk, then
    `--resume`d, writes the rows of an uninterrupted run (before: nothing was
    written until the end, and --resume ran everything again); the chunk on disk
    is not recomputed."""
    import os
    import signal
    import subprocess
    import sys

    killed, whole = tmp_path / "killed", tmp_path / "whole"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    p = subprocess.run(
        [sys.executable, "-c", _KILLED, *_MC, "--out", str(killed)],
        env=env,
        capture_output=True,
    )
    assert p.returncode == -signal.SIGKILL, p.stderr.decode()[-2000:]
    first = killed / "chunks" / "000000.npz"
    assert first.is_file() and not (killed / "chunks" / "000001.npz").exists()
    assert not (killed / "scenarios.csv").exists()
    stamp = first.stat().st_mtime_ns
    assert main([*_MC, "--out", str(killed)]) == 2  # not empty: resume or new folder
    assert main([*_MC, "--out", str(killed), "--resume", "--seed", "1"]) == 2
    assert main([*_MC, "--out", str(killed), "--resume"]) == 0
    assert first.stat().st_mtime_ns == stamp
    assert main([*_MC, "--out", str(whole)]) == 0
    for name in ("scenarios.csv", "summary.md"):
        assert (killed / name).read_text() == (whole / name).read_text()
    assert (whole / "montecarlo.png").stat().st_size > 5_000  # as the SMIB's
    assert main([*_MC, "--out", str(killed), "--resume"]) == 2  # complete


@CASE_BATCH
def test_grid_montecarlo_never_replaces_another_runs_output(tmp_path, monkeypatch):
    """Two runs on one --out: a file another run put there while this one worked is
    kept and this run refuses in one line (before: os.replace, the other run's
    results silently lost)."""
    import smibjax.cli.grid as g

    out = tmp_path / "mc"
    write = g._write_chunk

    def other_run_meanwhile(path, rows):
        write(path, rows)
        (out / "scenarios.csv").write_text("the other run's rows\n")

    monkeypatch.setattr(g, "_write_chunk", other_run_meanwhile)
    assert main([*_MC, "--out", str(out)]) == 2
    assert (out / "scenarios.csv").read_text() == "the other run's rows\n"


def test_compare_summary_of_a_set_with_a_lost_run_has_no_nan():
    """Issue 49, class 3: one unstable scenario made compare --case's overshoot mean
    and p95 NaN. A lost run's overshoot is inf (`grid_metrics`), and the overshoot
    figures are over the stable scenarios, as the settling figures."""
    from smibjax.cli.grid import case_summary

    rows = {
        "stable": [True, True, False],
        "settling_angle": [2.0, np.inf, np.inf],
        "overshoot": [0.2, 0.4, np.inf],
        "efd_max": [1.5, 1.6, 1.7],
        "v_min": [0.0, 0.1, 0.2],
        "exhausted": [False, False, False],
    }
    s = case_summary(rows)
    assert s["overshoot_mean"] == pytest.approx(0.3)
    assert s["overshoot_p95"] == pytest.approx(0.39)
    assert s["settling_mean"] == 2.0 and s["stable_fraction"] == pytest.approx(2 / 3)
    none = case_summary({**rows, "stable": [False] * 3})
    assert none["overshoot_mean"] is None and none["settling_mean"] is None


def test_recorded_coi_angles_leave_a_tripped_machine_out():
    """`simulate --case`'s delta_coi (issue 49, class 2): from a machine's trip on,
    the centre of inertia is that of the machines still in service (their
    inertia-weighted angles sum to 0) and the tripped machine's column is NaN."""
    from types import SimpleNamespace

    from smibjax.cli.grid import coi_record
    from smibjax.grid.case import load_case
    from smibjax.grid.simulate import coi_weights

    case = load_case("kundur-gencls")
    rng = np.random.default_rng(0)
    delta = rng.normal(size=(5, case.n_gen))
    on = np.ones((5, case.n_gen))
    on[3:, 0] = 0.0  # G1 trips between the third and fourth samples
    rel = coi_record(case, SimpleNamespace(delta=delta, gen_on=on))
    assert np.all(np.isnan(rel[3:, 0])) and np.all(np.isfinite(rel[:3]))
    w = np.asarray(coi_weights(case, np.ones(case.n_gen)))
    for k in range(5):
        live = on[k] > 0
        assert abs(np.sum(w[live] * rel[k, live])) < 1e-12 * np.sum(w[live])
    assert abs(rel[4, 1] - (delta[4, 1] - w[1:] @ delta[4, 1:] / w[1:].sum())) < 1e-12


def _simulate_args(*flags):
    from smibjax.cli import _parser

    args = _parser().parse_args(["simulate", "--case", "kundur-gencls", *flags])
    args.argv = ["simulate", "--case", "kundur-gencls", *flags]
    return args


def test_a_bus_fault_cleared_by_opening_a_line():
    """`--fault-bus B --open-line A-B[:CKT]` (issue 47, events): the fault at bus 7
    from --fault-time to --clear-time, and circuit 1 of the 7-8 tie opened at the
    clearing (and left open); the events in switch order, positions resolved."""
    from smibjax.cli.grid import events_from_args, refuse_smib_flags
    from smibjax.grid.case import load_case
    from smibjax.grid.events import BranchTrip, BusFault

    case = load_case("kundur-gencls")
    args = _simulate_args(
        "--fault-bus", "7", "--open-line", "7-8:1", "--fault-time", "1",
        "--clear-time", "1.1", "--t-end", "5",
    )  # fmt: skip
    refuse_smib_flags(args)
    ev = events_from_args(case, args)
    assert [type(e) for e in ev] == [BusFault, BranchTrip]
    assert int(ev[0].bus) == case.system.bus_index(7) and float(ev[0].t_off) == 1.1
    br = case.system.branches
    num = np.asarray(case.system.buses.number)
    k = int(ev[1].branch)
    assert {int(num[br.fr[k]]), int(num[br.to[k]])} == {7, 8}
    assert float(ev[1].t) == 1.1


@pytest.mark.parametrize(
    "flags, needle",
    [
        (
            ("--open-line", "7-8", "--trip-gen", "1"),
            "--open-line is not allowed without",
        ),
        (
            ("--trip-gen", "1", "--clear-time", "2"),
            "--clear-time is not allowed without",
        ),
        (("--fault-bus", "7", "--open-line", "7-99"), "branch 7-99 does not exist"),
    ],
)
def test_event_flags_that_do_not_fit_are_one_line(flags, needle):
    from smibjax.cli.grid import events_from_args, refuse_smib_flags
    from smibjax.cli.options import CLIError
    from smibjax.grid.case import load_case

    args = _simulate_args(*flags)
    with pytest.raises(CLIError, match=needle):
        refuse_smib_flags(args)
        events_from_args(load_case("kundur-gencls"), args)


def test_a_trip_needs_no_clearing_time():
    """`--trip-gen` (and `--trip-line`) at --fault-time needs no --clear-time: a
    trip at 2 s with the default clearing time (before it) was refused."""
    from smibjax.cli.grid import events_from_args
    from smibjax.grid.case import load_case
    from smibjax.grid.events import GenTrip

    args = _simulate_args("--trip-gen", "1", "--fault-time", "2", "--t-end", "5")
    ev = events_from_args(load_case("kundur-gencls"), args)
    assert [type(e) for e in ev] == [GenTrip] and float(ev[0].t) == 2.0
