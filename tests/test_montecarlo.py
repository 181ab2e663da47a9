"""Monte Carlo, critical clearing times and gain-set comparison: rows that agree with
single runs, chunking that changes nothing, resume after kill -9, one-line errors."""

import json
import math
import re
import signal
import subprocess
import sys
import time

import jax
import numpy as np
import pytest

import smibjax as sj
from helpers import ROOT, STABLE, cli_env
from smibjax._cct import critical_clearing_times
from smibjax._montecarlo import (
    COLUMNS,
    MonteCarloSpec,
    compute_chunk,
    summarize,
    wilson_interval,
)
from smibjax._scenarios import ScenarioDistribution, sample_scenarios
from smibjax.cli import main
from smibjax.cli.runs import read_rows, run_montecarlo

# one worker runs the module: its tests share the module fixture `reference_run`
# and its programs (under -n 2 a test on the other worker built them again)
pytestmark = pytest.mark.xdist_group("montecarlo")

T_END = 6.0  # a shorter horizon than 10 s, still long enough to settle
GAINS = {k: float(getattr(sj.Gains.paper("aftsc", **STABLE), k)) for k in sj.GAIN_NAMES}


def spec(**kw):
    base = dict(n=10, chunk=4, seed=3, gains=GAINS, t_end=T_END)
    return MonteCarloSpec(**{**base, **kw})


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("mc") / "ref"
    rows, summary = run_montecarlo(spec(), out, progress=False)
    return out, rows, summary


def test_scenarios_depend_on_seed_and_index_only():
    dist = ScenarioDistribution(D=(0.1, 0.3))
    plant = sj.Plant()
    whole = sample_scenarios(5, 0, 10, dist, plant)
    parts = [
        sample_scenarios(5, a, b, dist, plant) for a, b in ((0, 3), (3, 7), (7, 10))
    ]
    for i, leaf in enumerate(jax.tree_util.tree_leaves(whole)):
        joined = np.concatenate(
            [np.asarray(jax.tree_util.tree_leaves(p)[i]) for p in parts]
        )
        np.testing.assert_array_equal(np.asarray(leaf), joined)
    f, D, Pm = whole
    dur = np.asarray(f.t_clear - f.t_fault)
    assert np.all((0.05 <= dur) & (dur <= 0.25))
    assert np.all((0.2 <= np.asarray(f.t_fault)) & (np.asarray(f.t_fault) <= 1.0))
    assert np.all((0.1 <= np.asarray(D)) & (np.asarray(D) <= 0.3)) and np.ptp(D) > 0
    np.testing.assert_array_equal(np.asarray(Pm), 1.0)  # not drawn: the plant's value
    other = sample_scenarios(6, 0, 10, dist, plant)[0]
    assert not np.allclose(np.asarray(other.t_fault), np.asarray(f.t_fault))


def test_rows_agree_with_single_runs(reference_run):
    """A test picks rows and re-runs them through `simulate` and `metrics`."""
    _, rows, _ = reference_run
    g = sj.Gains(**GAINS)
    for i in (0, 7):
        f = sj.Fault(
            t_fault=rows["t_fault"][i],
            t_clear=rows["t_clear"][i],
            t_reclose=rows["t_reclose"][i],
            lam=rows["fault_location"][i],
            Xf=rows["fault_reactance"][i],
        )
        tr = sj.simulate(g, f, t_end=T_END)
        m = sj.metrics(tr)
        assert bool(m.stable) == bool(rows["stable"][i])
        # a batched run and a single one round differently (XLA fuses them
        # differently), so they agree to the solver's tolerance, not bit for bit
        assert (
            abs(int(tr.num_steps) - rows["num_steps"][i]) <= 0.01 * rows["num_steps"][i]
        )
        for col, v, rel in (
            ("settling_time", m.settling_delta, 1e-5),
            ("overshoot", m.overshoot, 1e-5),
            ("peak_B", m.peak_B, 1e-5),
            # the effort integrals are outside the error norm (they are outputs)
            ("effort_uf", m.effort_uf, 1e-3),
        ):
            assert rows[col][i] == pytest.approx(float(v), rel=rel, abs=1e-6), col


def test_same_rows_whatever_the_chunk_size(reference_run, tmp_path):
    out, rows, _ = reference_run
    rows3, _ = run_montecarlo(
        spec(chunk=3), tmp_path / "c3", progress=False, plots=False
    )
    for c in COLUMNS:
        np.testing.assert_array_equal(rows3[c], rows[c], err_msg=c)
    assert (tmp_path / "c3" / "scenarios.csv").read_text() == (
        out / "scenarios.csv"
    ).read_text()
    back = read_rows(out / "scenarios.csv")
    for c in COLUMNS:
        np.testing.assert_array_equal(back[c], rows[c], err_msg=c)
    # the library's own run (no run folder): its chunks joined in index order
    res = sj.monte_carlo(spec())
    assert isinstance(res, sj.MonteCarloResult) and res.spec == spec()
    for c in COLUMNS:
        np.testing.assert_array_equal(res.rows[c], rows[c], err_msg=c)
    assert res.to_dict()["summary"] == summarize(rows)


def test_resume_recomputes_only_missing_chunks(reference_run, tmp_path):
    out, rows, _ = reference_run
    run = tmp_path / "r"
    run_montecarlo(spec(), run, progress=False, plots=False)
    (run / "chunks" / "000001.npz").unlink()
    for f in ("scenarios.csv", "summary.json"):
        (run / f).unlink()
    mtime = (run / "chunks" / "000000.npz").stat().st_mtime_ns
    run_montecarlo(spec(), run, resume=True, progress=False, plots=False)
    assert (run / "chunks" / "000000.npz").stat().st_mtime_ns == mtime  # kept
    assert (run / "scenarios.csv").read_text() == (out / "scenarios.csv").read_text()
    assert (run / "summary.json").read_text() == (out / "summary.json").read_text()
    with pytest.raises(sj.ParameterError, match="seed = 4 differs"):
        run_montecarlo(spec(seed=4), run, resume=True, progress=False)
    with pytest.raises(sj.ParameterError, match="not empty"):
        run_montecarlo(spec(), run, progress=False)
    with pytest.raises(sj.ParameterError, match="no run.json"):
        run_montecarlo(spec(), tmp_path / "none", resume=True, progress=False)


def test_summary_statistics():
    assert wilson_interval(0, 10)[1] == pytest.approx(1.959964**2 / (10 + 1.959964**2))
    lo, hi = wilson_interval(50, 100)
    assert lo == pytest.approx(0.4038, abs=1e-4) and hi == pytest.approx(
        0.5962, abs=1e-4
    )
    rng = np.random.default_rng(0)
    n = 200
    rows = {
        "stable": (rng.random(n) < 0.9).astype(int),
        "lost_sync": np.zeros(n, int),
        "budget_exhausted": (rng.random(n) < 0.05).astype(int),
        "settling_time": rng.random(n) * 5,
        "settling_Vt": rng.random(n),
        "overshoot": rng.random(n),
        "num_steps": np.full(n, 7),
    }
    s = summarize(rows)
    st = rows["stable"].astype(bool)
    assert s["stable"] == st.sum() and s["stable_fraction"] == st.mean()
    assert s["budget_exhausted"] == rows["budget_exhausted"].sum() > 0
    ts = rows["settling_time"][st]
    assert s["settling_time"]["p95"] == pytest.approx(np.quantile(ts, 0.95))
    assert s["settling_time"]["mean"] == pytest.approx(ts.mean())


def test_bad_specs_are_one_clear_error():
    with pytest.raises(sj.ParameterError, match="n = 0 is not allowed"):
        spec(n=0)
    with pytest.raises(sj.ParameterError, match="empty range"):
        ScenarioDistribution.from_dict({"t_fault": [1.0, 0.5]})
    with pytest.raises(sj.ParameterError, match="clearing after the fault"):
        ScenarioDistribution.from_dict({"clear_duration": [-0.1, 0.2]})
    with pytest.raises(sj.ParameterError, match="unknown scenario key 'tfault'"):
        ScenarioDistribution.from_dict({"tfault": [0.1, 0.2]})
    with pytest.raises(sj.ParameterError, match="D = \\[-1, 0\\.2\\]"):
        ScenarioDistribution.from_dict({"D": [-1, 0.2]})
    with pytest.raises(sj.ParameterError, match="chunk 3 is not allowed"):
        compute_chunk(spec(), 3)


def test_kill_9_then_resume_matches_an_uninterrupted_run(reference_run, tmp_path):
    """A real SIGKILL after the first chunk is on disk, then `--resume`: at most the
    chunk in flight is lost and the final files equal the uninterrupted run's."""
    ref_out, _, _ = reference_run
    env = cli_env()
    out = tmp_path / "k"
    cmd = [sys.executable, "-m", "smibjax", "montecarlo", "--n", "10", "--chunk", "4"]
    cmd += ["--seed", "3", "--t-end", str(T_END), "--out", str(out)]
    cmd += ["--set", "beta1=-1", "--set", "beta2=-1"]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    while time.time() < deadline and not (out / "chunks" / "000000.npz").exists():
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not (out / "summary.json").exists()  # it really was cut short
    assert json.loads((out / "run.json").read_text())["complete"] is False
    subprocess.run(
        [*cmd, "--resume"], check=True, cwd=ROOT, env=env, capture_output=True
    )
    for f in ("scenarios.csv", "summary.json"):
        assert (out / f).read_text() == (ref_out / f).read_text(), f
    body = (out / "summary.md").read_text().split("\n", 1)[1]  # (titles differ)
    assert body == (ref_out / "summary.md").read_text().split("\n", 1)[1]
    assert json.loads((out / "run.json").read_text())["complete"] is True


def test_cct_bisection_brackets_the_stability_boundary():
    """At the returned CCT the run is stable, tol later it is not; the other lanes
    report 'beyond the window' and 'unstable even for the shortest fault'."""
    plant = sj.Plant.preset("realistic")
    good = sj.Gains.paper("aftsc", beta1=-1.0, beta2=-1.0, gamma1=0.5, gamma2=0.5)
    sets = {"good": good, "paper": sj.Gains.paper("aftsc")}
    tol = 0.01
    res = critical_clearing_times(sets, plant, fault_locations=[0.1, 0.9], tol=tol)
    assert res.sets["good"].status == ["ok", "exceeds_window"]
    assert res.sets["paper"].status == ["unstable_at_min"] * 2
    assert res.sets["paper"].cct == [None, None]
    assert res.to_dict()["cct"]["good"][1] is None and res.window == 1.5
    cct = res.sets["good"].cct[0]
    assert 0.2 < cct < 1.0

    def stable(duration):
        f = sj.Fault(t_fault=0.5, t_clear=0.5 + duration, t_reclose=2.0, lam=0.1)
        return bool(sj.simulate(good, f, plant).stable)

    assert stable(cct) and not stable(cct + tol)


def test_cct_solver_tolerances_reach_the_runs(monkeypatch):
    """The CCT engine's runs use the tolerances given (traced, not run)."""
    import smibjax._batch as cct_module

    seen = {}

    class Traced(Exception):
        pass

    def fake_simulate(*args, **kw):
        seen.update(kw)
        raise Traced

    monkeypatch.setattr(cct_module, "simulate", fake_simulate)
    with pytest.raises(Traced):
        critical_clearing_times(
            {"a": sj.Gains()},
            fault_locations=[0.5],
            solver=sj.SolverOptions(rtol=2e-6, atol=3e-7, max_steps=999),
        )
    solver = seen["solver"]  # the SolverOptions given, passed whole
    assert solver == sj.SolverOptions(rtol=2e-6, atol=3e-7, max_steps=999)
    seen.clear()
    with pytest.raises(Traced), pytest.warns(DeprecationWarning, match="rtol="):
        critical_clearing_times(  # the keywords of 0.1: deprecated, same options
            {"a": sj.Gains()}, fault_locations=[0.5], rtol=2e-6, atol=3e-7
        )
    assert seen["solver"] == sj.SolverOptions(rtol=2e-6, atol=3e-7)


@pytest.mark.parametrize(
    "argv, match",
    [
        (["montecarlo", "--n", "0"], "--n 0 is not allowed"),
        (["montecarlo", "--dist", "/nonexistent.toml"], "does not exist"),
        (["cct", "--reclose-time", "0.3"], "must be after --fault-time"),
        (["cct", "--fault-location", "1.5"], "within \\(0, 1\\)"),
        (["compare", "--gains", "nope.json"], "not a built-in set"),
        (["cct", "--atol=-1"], "--atol: -1 is not allowed"),
        (["compare", "--rtol", "0"], "--rtol: 0 is not allowed"),
    ],
)
def test_batch_commands_bad_input(argv, match, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("smibjax: error:")
    import re

    assert re.search(match, err), err


def test_bad_dist_and_gains_files(tmp_path, capsys):
    dist = tmp_path / "d.toml"
    dist.write_text("t_fault = [0.5, 0.2]\n")
    assert main(["montecarlo", "--dist", str(dist), "--out", str(tmp_path / "o")]) == 2
    assert "empty range" in capsys.readouterr().err
    dist.write_text("clear_duration = [0.0, 0.1]\n")
    assert main(["montecarlo", "--dist", str(dist), "--out", str(tmp_path / "o")]) == 2
    assert "clearing after the fault" in capsys.readouterr().err
    dist.write_text("speed = [0.0, 0.1]\n")
    assert main(["montecarlo", "--dist", str(dist), "--out", str(tmp_path / "o")]) == 2
    assert "unknown scenario key 'speed'" in capsys.readouterr().err
    gains = tmp_path / "g.json"
    gains.write_text(json.dumps({**GAINS, "beta3": 1.0}))
    assert main(["montecarlo", "--gains", str(gains)]) == 2
    assert "unknown gain 'beta3'" in capsys.readouterr().err
    gains.write_text(json.dumps({k: v for k, v in GAINS.items() if k != "T2"}))
    assert main(["montecarlo", "--gains", str(gains)]) == 2
    assert "gain 'T2' is missing" in capsys.readouterr().err
    assert main(["compare", "--gains", str(gains)]) == 2
    assert "gain 'T2' is missing" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # nothing passed off as output


def test_compare_and_montecarlo_commands(reference_run, tmp_path, capsys):
    ref_out, _, ref_summary = reference_run
    gains = tmp_path / "tuned.json"
    gains.write_text(json.dumps(GAINS))
    common = ["--n", "10", "--chunk", "4", "--seed", "3", "--t-end", str(T_END)]
    out = tmp_path / "mc"
    assert main(["montecarlo", "--gains", str(gains), *common, "--out", str(out)]) == 0
    assert (out / "scenarios.csv").read_text() == (
        ref_out / "scenarios.csv"
    ).read_text()
    assert (out / "montecarlo.png").stat().st_size > 10_000
    assert main(["montecarlo", "--gains", str(gains), *common, "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err  # nothing overwritten
    cmp = tmp_path / "cmp"
    argv = ["compare", "--gains", str(gains), "--gains", "paper", *common]
    argv += ["--fault-location", "0.5", "--tol", "0.05", "--out", str(cmp)]
    assert main(argv) == 0
    table = (cmp / "compare.md").read_text()
    frac = 100 * ref_summary["stable_fraction"]
    assert f"| tuned | aftsc | oracle | paper | {frac:.1f} (" in table  # flat file
    assert "| paper | aftsc | oracle | paper | 0.0 (0.0-27.8) |" in table
    assert table.rstrip().endswith("none |")
    data = json.loads((cmp / "compare.json").read_text())
    assert data["montecarlo"]["tuned"] == ref_summary
    assert data["cct"]["sets"]["paper"]["status"] == ["unstable_at_min"]
    assert data["cct"]["sets"]["tuned"]["status"] in (["ok"], ["exceeds_window"])
    assert (cmp / "tuned" / "scenarios.csv").read_text() == (
        ref_out / "scenarios.csv"
    ).read_text()
    assert (cmp / "compare.png").stat().st_size > 10_000
    assert not math.isnan(data["montecarlo"]["tuned"]["settling_time"]["mean"])


def test_runs_that_spend_the_step_budget_are_counted_apart(tmp_path, capsys):
    from smibjax.cli import main

    out = tmp_path / "budget"
    args = ["montecarlo", "--n", "4", "--chunk", "4", "--t-end", "2", "--max-steps"]
    stable = ["--set", "beta1=-1", "--set", "beta2=-1", "--atol", "1e-7"]
    assert main([*args, "300", *stable, "--out", str(out)]) == 0
    assert "raise --max-steps" in capsys.readouterr().err
    spec = json.loads((out / "run.json").read_text())["spec"]
    solver = spec["solver"]  # --atol, --max-steps reach the runs
    assert solver["atol"] == 1e-7 and solver["rtol"] == 1e-6
    assert solver["max_steps"] == 300 and solver["kind"] == "adaptive"
    rows = read_rows(out / "scenarios.csv")
    assert list(rows["budget_exhausted"]) == [1, 1, 1, 1]
    assert not rows["stable"].any() and not rows["lost_sync"].any()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["budget_exhausted"] == 4 and summary["stable"] == 0
    assert main(["montecarlo", "--max-steps", "0", "--out", str(tmp_path / "x")]) == 2


# Issue 16: Monte Carlo specs that would report runs that never got there, and
# resumes of damaged chunk files.


@pytest.mark.parametrize(
    "kw, match",
    [
        (
            dict(seed=-1),
            r"seed = -1 is not allowed: must be an integer in \[0, 2\*\*32\)",
        ),
        (dict(seed=2**32), r"seed = 4294967296 is not allowed"),
        (dict(seed=1.5), r"seed = 1.5 is not allowed"),
        (dict(t_end=1.1), r"t_end = 1.1 is not allowed: must be > 1.25 s"),
        (dict(t_end=1e308), r"t_end / dt_save = 1e\+308 / 0.01 is not allowed"),
        (
            dict(t_end=3.0, dist={"t_fault": [2.0, 5.0]}),
            r"t_end = 3 is not allowed: must be > 5.25 s",
        ),
        (dict(dist={"t_fault": [0.2, math.inf]}), r"t_fault = \[0.2, inf\] .*finite"),
        (dict(dist={"reclose_delay": [1.0, math.inf]}), r"reclose_delay = .*finite"),
        (dict(dist={"fault_reactance": [0.0, math.nan]}), r"fault_reactance = "),
        (dict(dist={"D": [0.1, math.inf]}), r"D = \[0.1, inf\] .*finite"),
        (dict(dist={"Pm": [0.5, 1e300]}), r"Pm = \[0.5, 1e\+300\] .*<= 1e\+06"),
    ],
)
def test_specs_that_cannot_be_run_honestly_are_refused(kw, match):
    with pytest.raises(sj.ParameterError, match=match):
        spec(**kw)


@pytest.mark.parametrize(
    "argv, match",
    [
        (["--seed", "-1"], r"--seed -1 is not allowed"),
        (["--seed", str(2**32)], r"--seed 4294967296 is not allowed"),
        (["--t-end", "1.0"], r"--t-end 1 is not allowed: must be > 1.25 s"),
        (["--set", "H=inf"], r"Plant.H = inf is not allowed"),
    ],
)
def test_montecarlo_refuses_before_writing_anything(argv, match, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["montecarlo", "--n", "4", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and re.search(match, err), err
    assert not out.exists()  # no run.json left to refuse the next, correct command


def test_dist_with_an_infinite_range_is_refused_before_the_run(tmp_path, capsys):
    dist = tmp_path / "d.toml"
    for text, match in (
        ("t_fault = [0.2, inf]\n", r"t_fault = \[0.2, inf\] is not allowed"),
        ("D = [0.1, nan]\n", r"D = \[0.1, nan\] is not allowed"),
    ):
        dist.write_text(text)
        out = tmp_path / "o"
        assert main(["montecarlo", "--dist", str(dist), "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("smibjax: error:") and len(err.splitlines()) == 1
        assert re.search(match, err), err
        assert not out.exists()


@pytest.mark.parametrize("damage", ["truncate", "empty", "garbage", "wrong_rows"])
def test_resume_recomputes_a_damaged_chunk(reference_run, tmp_path, damage):
    out, rows, _ = reference_run
    run = tmp_path / "r"
    run_montecarlo(spec(), run, progress=False, plots=False)
    chunk = run / "chunks" / "000001.npz"
    data = chunk.read_bytes()
    if damage == "truncate":
        chunk.write_bytes(data[: len(data) // 2])
    elif damage == "empty":
        chunk.write_bytes(b"")
    elif damage == "garbage":
        chunk.write_bytes(b"not a zip file at all" * 10)
    else:  # a whole file, but chunk 0's rows
        chunk.write_bytes((run / "chunks" / "000000.npz").read_bytes())
    (run / "scenarios.csv").unlink()
    run_montecarlo(spec(), run, resume=True, progress=False, plots=False)
    assert (run / "scenarios.csv").read_text() == (out / "scenarios.csv").read_text()


def test_resume_reads_a_run_written_before_a_spec_field_existed(tmp_path):
    """A run.json without a field added to the spec later (here `options`, `controller`)
    resumes as that field's default, and only then."""
    import json

    from smibjax.cli.runs import _check_resume

    s = MonteCarloSpec(n=4, chunk=2, t_end=3.0)
    old = s.to_dict()
    del old["options"], old["controller"]
    (tmp_path / "run.json").write_text(json.dumps({"spec": old}))
    assert _check_resume(tmp_path, s)["spec"] == old
    other = MonteCarloSpec(n=4, chunk=2, t_end=3.0, options={"phi_layer": 0.01})
    with pytest.raises(sj.ParameterError, match="--resume: options = .* differs"):
        _check_resume(tmp_path, other)


def test_a_spec_written_before_the_solver_options_reads_and_resumes_as_one(tmp_path):
    """A run.json of 0.1 held rtol, atol, max_steps at the top level: it reads back
    as the same spec with a solver table, and resumes only with those values."""
    import json

    from smibjax.cli.runs import _check_resume

    s = MonteCarloSpec(n=4, chunk=2, t_end=3.0, solver=sj.SolverOptions(atol=1e-7))
    old = s.to_dict()
    solver = old.pop("solver")
    old.update(rtol=solver["rtol"], atol=solver["atol"], max_steps=solver["max_steps"])
    assert MonteCarloSpec.from_dict(old) == s == MonteCarloSpec.from_dict(s.to_dict())
    (tmp_path / "run.json").write_text(json.dumps({"spec": old}))
    assert _check_resume(tmp_path, s)["spec"] == old
    with pytest.raises(sj.ParameterError, match="solver.atol = 1e-08 differs"):
        _check_resume(tmp_path, MonteCarloSpec(n=4, chunk=2, t_end=3.0))
    with pytest.warns(DeprecationWarning, match="MonteCarloSpec"):
        assert MonteCarloSpec(n=4, chunk=2, t_end=3.0, atol=1e-7) == s
