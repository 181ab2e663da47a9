"""The second hostile probe (issue 34): one test (or parametrized family) per class of
defect. Bad input is one line on stderr, exit 2, nothing written; every way a run ends
has defined metrics; outputs are never clobbered at write time."""

import json
import math
import os

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import tomllib
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import smibjax as sj
from smibjax import ParameterError
from smibjax._files import check_new_file, read_data, write_text
from smibjax._metrics import metrics
from smibjax.cli import main


def _err(capsys) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("smibjax: error:"), err
    return lines[0]


# 1. A loss of synchronism before the first saved sample: unstable, never settled.
def test_loss_before_first_sample_is_unstable_with_explicit_metrics():
    # B0 = 20 starts outside the domain (refused by the CLI and `simulate`, class 2);
    # inside jit the values are unknown, so the run happens and must be reported.
    bad = eqx.tree_at(lambda p: p.B0, sj.Plant(), jnp.asarray(20.0))

    @eqx.filter_jit
    def run(plant):
        tr = sj.simulate(sj.Gains(), plant=plant, save=sj.SaveOptions(2.0, 0.1))
        return tr, metrics(tr)

    tr, m = run(bad)
    assert bool(tr.lost_sync) and not bool(m.stable)
    for k in ("settling_delta", "settling_Vt", "settling_omega", "overshoot"):
        assert math.isinf(float(getattr(m, k))), (k, float(getattr(m, k)))
    assert not any(np.isnan(float(v)) for v in m)


# 2. A starting point outside the model's domain is refused in one line.
@pytest.mark.parametrize("sets", [["B0=20"], ["B0=9"], ["Pm_ref=1e-9"]])
def test_start_outside_domain_is_one_line(sets, capsys):
    argv = ["simulate"]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 2
    assert "outside the model's domain" in _err(capsys)


# 3. Nonsense solver settings are refused before any work.
@pytest.mark.parametrize(
    "argv",
    [
        ["--rtol", "1e3", "--atol", "1e3"],
        ["--rtol", "0.5"],
        ["--atol", "1"],
        ["--max-steps", "99999999999999999999"],
        ["--max-steps", "200000000"],
        ["--max-steps", "0"],
    ],
)
def test_solver_settings_bounded(argv, capsys):
    assert main(["simulate", *argv]) == 2
    assert "is not allowed" in _err(capsys)


@pytest.mark.parametrize(
    "kw", [{"rtol": 1.0}, {"atol": 0.5}, {"max_steps": 10**9}, {"max_steps": True}]
)
def test_solver_options_bounded_in_the_library(kw):
    with pytest.raises(ParameterError):
        sj.SolverOptions(**kw)
    with pytest.raises(ParameterError):
        sj.MonteCarloSpec(n=2, **kw)


# 5. Tuner configurations that make the task meaningless, or of the wrong type.
BAD_CONFIGS = [
    ("[validation]\nt_end = 0.5\n", "validation.t_end = 0.5"),
    ("[train]\nt_end = 1.1\n", "train.t_end = 1.1"),
    ("[gains.bounds]\nalpah = [0.6, 1.0]\n", "unknown gain 'alpah'"),
    ("[optimizer]\nclip_norm = -1.0\n", "optimizer.clip_norm"),
    ("[loss]\ndelta_band = -0.01\n", "loss.delta_band"),
    ("[loss]\nVt_band = 0.0\n", "loss.Vt_band"),
    (
        "[validation]\nn = 2.5\n",
        "validation.n = 2.5 is not allowed: must be an integer",
    ),
    ('[optimizer]\nlearning_rate = "0.1"\n', "must be a number"),
    ("init = 5\n", "init = 5 is not allowed: must be a string"),
    ("seed = true\n", "seed = True is not allowed: must be an integer"),
    ("steps = 1.5\n", "must be an integer"),
    ('[gains.bounds]\nT1 = "x"\n', "gains.bounds.T1"),
    ("[gains.bounds]\nT1 = 0.1\n", "gains.bounds.T1"),
    ("[gains.bounds]\nT1 = {lo = 1}\n", "gains.bounds.T1"),
    ("[scenarios]\nt_fault = {lo = 1}\n", "scenarios.t_fault"),
    ("[train]\nrtol = 0.5\n", "train.rtol"),
    ("batch = 100000000\n", "batch = 100000000"),
    (f"seed = {2**40}\n", "seed"),
]


@pytest.mark.parametrize("body, needle", BAD_CONFIGS)
def test_tuner_config_refused(body, needle, tmp_path):
    from tuning.config import check_config, load_config

    path = tmp_path / "c.toml"
    path.write_text(body)
    with pytest.raises(ParameterError, match="not allowed") as e:
        check_config(load_config(path))
    assert needle in str(e.value), str(e.value)
    assert "\n" not in str(e.value)


_VALUES = st.one_of(
    st.booleans(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=5),
    st.lists(st.integers(-3, 3), max_size=3),
    st.dictionaries(st.sampled_from(["lo", "hi"]), st.integers(0, 2), max_size=2),
)
_KEYS = [
    ("steps",),
    ("batch",),
    ("seed",),
    ("init",),
    ("validation", "n"),
    ("validation", "t_end"),
    ("train", "t_end"),
    ("train", "max_steps"),
    ("optimizer", "learning_rate"),
    ("optimizer", "clip_norm"),
    ("loss", "delta_band"),
    ("scenarios", "t_fault"),
    ("search", "population"),
    ("gains", "freeze"),
]


@settings(max_examples=60, deadline=None)
# horizons whose sample count overflowed (found by this test at 1,500 examples)
@example(key=("train", "t_end"), value=1.797693134862316e306)
@example(key=("validation", "t_end"), value=4.49423283715579e305)
@given(key=st.sampled_from(_KEYS), value=_VALUES)
def test_tuner_config_any_value_is_checked_or_one_line(key, value):
    """Any value of any type at a key: accepted, or one ParameterError line."""
    from tuning.config import check_config, load_config

    cfg = load_config()
    here = cfg
    for k in key[:-1]:
        here = here[k]
    here[key[-1]] = value
    try:
        check_config(cfg)
    except ParameterError as e:
        assert "\n" not in str(e)


@pytest.mark.parametrize(
    "part, value", [("train", 1e306), ("validation", 1e306), ("validation", -1.0)]
)
def test_tuner_horizon_is_bounded_and_named(part, value):
    """A horizon of more than a million 10 ms samples, or none, is refused under its
    own key (before: an OverflowError from the memory plan for train.t_end, a
    refusal that blamed validation.n for validation.t_end, and "t_end" with the
    training value for a bad validation.t_end)."""
    from tuning.config import check_config, load_config

    cfg = load_config()
    cfg[part]["t_end"] = value
    with pytest.raises(ParameterError) as e:
        check_config(cfg)
    assert str(e.value).startswith(f"{part}.t_end = {value!r} is not allowed")
    assert "(0, 10000] s" in str(e.value)


# 6. Options silently dropped; 7. cct --out records what the CCTs were computed for.
def test_cct_budget_warning_and_out_records_gains_and_plant(tmp_path, capsys):
    out = tmp_path / "cct.json"
    argv = ["cct", "--max-steps", "20", "--fault-location", "0.5", "--out", str(out)]
    assert main([*argv, "--set", "Pm=0.9", "--set", "beta1=40"]) == 0
    cap = capsys.readouterr()
    assert "none (unstable)" in cap.out
    assert "spent the solver's step budget" in cap.err
    data = json.loads(out.read_text())
    assert data["plant"]["Pm"] == 0.9
    assert data["gains"]["aftsc"]["beta1"] == 40.0
    assert data["sets_given"] == ["Pm=0.9", "beta1=40"]


# 8. No clobber at write time: a file created meanwhile by another process is kept.
def test_output_created_during_the_run_is_not_replaced(tmp_path):
    p = check_new_file(tmp_path / "out.json")
    p.write_text("theirs")  # another process, while this one works
    with pytest.raises(ParameterError, match="created by another process"):
        write_text(p, "ours")
    assert p.read_text() == "theirs"
    assert sorted(os.listdir(tmp_path)) == ["out.json"]  # no temporary left
    q = check_new_file(tmp_path / "new.json")
    write_text(q, "ours")
    assert q.read_text() == "ours"
    r = check_new_file(tmp_path / "forced.json", force=True)
    r.write_text("old")
    write_text(r, "new")  # --force replaces
    assert r.read_text() == "new"


# 9. Nothing written before validation (montecarlo's run.json); 12. memory planning.
@pytest.mark.parametrize(
    "argv",
    [
        ["--n", "100000000", "--chunk", "100000000"],
        ["--n", "4", "--set", "B0=20"],
        ["--n", "4", "--rtol", "2"],
    ],
)
def test_montecarlo_writes_nothing_before_validation(argv, tmp_path, capsys):
    out = tmp_path / "mc"
    assert main(["montecarlo", *argv, "--out", str(out)]) == 2
    _err(capsys)
    assert not out.exists()


def test_cct_memory_planned_before_work(capsys):
    assert main(["cct", "--tol", "1e-9", "--scan-step", "1e-9"]) == 2
    assert "needs about" in _err(capsys)


def test_tuner_batch_memory_refused_before_config_json(tmp_path):
    from tuning.optimize import main as tune

    out = tmp_path / "run"
    assert tune(["--batch", "100000000", "--out", str(out)]) == 2
    assert not out.exists()


# 11. Huge integers, wrong types, deep nesting, damaged resume files: one line.
@pytest.mark.parametrize(
    "name, text",
    [
        ("g.json", '{"beta1": 1' + "0" * 400 + "}"),
        ("g.json", "[" * 100_000 + "]" * 100_000),
        ("g.json", '{"beta1": [1, 2]}'),
        ("g.json", '{"beta1": true}'),
        ("g.toml", "beta1 = " + "[" * 5000 + "]" * 5000),
        ("g.json", '{"beta1": {"a": 1}}'),
    ],
)
def test_bad_gains_files_one_line(name, text, tmp_path, capsys):
    path = tmp_path / name
    path.write_text(text)
    assert main(["simulate", "--gains", str(path)]) == 2
    _err(capsys)


@pytest.mark.parametrize(
    "text",
    [
        '{"Pm": [0.5, 1' + "0" * 400 + "]}",
        '{"t_fault": {"lo": 0.2}}',
        '{"t_fault": "0.2"}',
        "[" * 100_000,
        '{"D": [true, 0.3]}',
    ],
)
def test_bad_dist_files_one_line(text, tmp_path, capsys):
    path = tmp_path / "d.json"
    path.write_text(text)
    out = tmp_path / "mc"
    assert main(["montecarlo", "--n", "2", "--dist", str(path), "--out", str(out)]) == 2
    _err(capsys)
    assert not out.exists()


@pytest.mark.parametrize("text", ['{"spec": [1, 2', '{"spec": 5}', "[" * 100_000])
def test_damaged_run_json_on_resume_one_line(text, tmp_path, capsys):
    out = tmp_path / "mc"
    out.mkdir()
    (out / "run.json").write_text(text)
    assert main(["montecarlo", "--n", "2", "--resume", "--out", str(out)]) == 2
    assert "damaged" in _err(capsys)


@pytest.mark.parametrize("text", ["{", '{"step": "x"}', "[]"])
def test_damaged_tuner_checkpoint_one_line(text, tmp_path):
    from tuning.loop import CHECKPOINT, SIDECAR, load_checkpoint
    from tuning.problem import UsageError

    (tmp_path / CHECKPOINT).write_bytes(b"\x00garbage")
    (tmp_path / SIDECAR).write_text(text)
    with pytest.raises(UsageError, match="damaged") as e:
        load_checkpoint(tmp_path, None, None)
    assert "\n" not in str(e.value)


@settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
# keys that would break the one line if shown as written (found by this test)
@example({"\n": 2**63})
@example({"a\nb": "x"})
@example({"": {"\r": -(2**64)}})
@given(
    st.recursive(
        st.one_of(
            st.integers(min_value=-(10**500), max_value=10**500),
            st.floats(),
            st.booleans(),
            st.text(max_size=3),
            st.none(),
        ),
        lambda c: st.one_of(
            st.lists(c, max_size=3), st.dictionaries(st.text(max_size=3), c, max_size=3)
        ),
        max_leaves=8,
    )
)
def test_any_gains_json_is_read_or_one_line(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("g") / "g.json"
    path.write_text(json.dumps(data, allow_nan=True))
    from smibjax.cli.options import build_from_args

    class A:  # the parsed options of `simulate --gains path`
        gains, controller, adaptation, preset, phi_layer = (
            str(path),
            None,
            None,
            None,
            None,
        )
        set = []

    try:
        build_from_args(A())
    except (ParameterError, Exception) as e:  # noqa: BLE001 - checked below
        from smibjax.cli.options import CLIError

        assert isinstance(e, (ParameterError, CLIError)), repr(e)
        assert "\n" not in str(e)


# 13. Unclear messages.
@pytest.mark.parametrize(
    "argv, needle",
    [
        (["simulate", "--out", ""], "--out: '' is not allowed"),
        (["simulate", "--plot", " "], "--plot"),
        (["montecarlo", "--workers", str(10**6)], "the CPU count"),
        (["montecarlo", "--seed", "1.5"], "must be an integer"),
        (["simulate", "--fault-time", "nan"], "t_fault = nan is not allowed"),
        (["simulate", "--t-end", "true"], "must be a number"),
    ],
)
def test_unclear_flags_are_one_clear_line(argv, needle, capsys):
    assert main(argv) == 2
    assert needle in _err(capsys)


def test_out_under_a_file_refused_before_the_run(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["simulate", "--out", str(blocker / "x.npz")]) == 2
    assert "is a file, not a folder" in _err(capsys)


def test_gains_file_value_named_by_its_key_not_the_flag(tmp_path, capsys):
    gains = {
        "schema": "smibjax.gains/1",
        "controller": "aftsc",
        "adaptation": "oracle",
        "plant": {"preset": "paper"},
        "options": {"phi_layer": float("nan")},
        "gains": {"beta1": 50.0},
    }
    path = tmp_path / "g.json"
    path.write_text(json.dumps(gains))
    assert main(["simulate", "--gains", str(path)]) == 2
    line = _err(capsys)
    assert "--phi-layer" not in line and "phi_layer" in line, line


@pytest.mark.parametrize("v", [True, False, "1", None, [1]])
def test_bools_and_strings_are_not_numbers(v):
    from smibjax._validate import require_integer, require_real

    with pytest.raises(ParameterError):
        require_real("x", v)
    with pytest.raises(ParameterError):
        require_integer("n", v)


@pytest.mark.parametrize("v", [1.5, 2.0, 10**10, -1])
def test_counts_are_integers_in_range(v):
    from smibjax._validate import require_integer

    with pytest.raises(ParameterError):
        require_integer("n", v, 1, 10**9)


def test_grad_through_nan_gains_refused_before_solving():
    g = eqx.tree_at(lambda g: g.beta1, sj.Gains(), jnp.nan)

    def loss(g):
        return sj.simulate(g, save=sj.SaveOptions(2.0, 0.1)).delta[-1]

    with pytest.raises(ParameterError, match="beta1 = nan"):
        jax.grad(loss)(g)


def test_cache_folder_that_is_a_file_said_on_the_phase_line(tmp_path, capsys):
    """A cache folder that is a file: nothing printed when the cache is set up (a
    refused input after it stays one line, issue 49 class 10); the phase line before
    the first compile says the cache is off and why."""
    import jax

    from smibjax import _process
    from smibjax._commandline import say_compiling

    f = tmp_path / "cache"
    f.write_text("x")
    before = jax.config.jax_compilation_cache_dir
    try:
        jax.config.update("jax_compilation_cache_dir", None)
        assert _process.enable_compilation_cache(str(f)) is None
        assert capsys.readouterr().err == ""
        say_compiling("the simulation")
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(
            "compiling the simulation (cache: off: "
        )
        assert f"{str(f)!r} is not a writable folder" in err
    finally:
        _process.CACHE_PROBLEM = None
        jax.config.update("jax_compilation_cache_dir", before)


def test_read_data_deep_toml_is_one_line(tmp_path):
    p = tmp_path / "x.toml"
    p.write_text("a = " + "[" * 3000 + "]" * 3000)
    with pytest.raises(ParameterError, match="nested deeper|not valid"):
        read_data(p)
    assert tomllib  # the reader the files use


def test_progress_bar_closed_before_an_error_line(capsys):
    import sys

    from smibjax.cli.cct import progress_bar

    update = progress_bar("cct")
    update(1, 5)  # the work stops here, on an error
    update.close()
    print("smibjax: error: boom", file=sys.stderr)
    err = capsys.readouterr().err
    assert "\nsmibjax: error: boom" in err  # on a line of its own
    update(5, 5)  # nothing more is drawn after the close
    assert "cct" not in capsys.readouterr().err


@pytest.mark.parametrize(
    "label, want", [("..", "gains"), (".", "gains"), ("a/b", "a_b"), ("ok-1", "ok-1")]
)
def test_compare_set_labels_stay_inside_out(label, want, tmp_path):
    from smibjax.cli.compare import safe_label

    got = safe_label(label)
    assert got == want
    assert (tmp_path / "out" / got).resolve().parent == (tmp_path / "out").resolve()


def test_compare_set_of_a_gain_a_builtin_set_lacks_warns(capsys):
    from smibjax.cli.compare import _warn_dropped_sets, resolve_gain_set_context

    for spec in ("avr-pss", "none", "paper"):
        label, _, ctx, _ = resolve_gain_set_context(spec, {"beta1": 3.0})
        _warn_dropped_sets(label, ctx, {"beta1": 3.0})
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2  # avr-pss and none drop it; paper takes it
    assert all("--set beta1 does not apply" in ln for ln in err)


# 4. Extreme finite plant values: metrics defined for every way a run ends.
def test_extreme_plants_give_defined_metrics():
    """32 plants with every value drawn log-uniformly over 1e-3..1e3 x its paper value
    (valid ones only), one batched run each: a run that reached t_end has finite
    metrics (settling times may be inf: not settled); a run that lost synchronism
    has inf settling times and no NaN; only a spent step budget gives NaN."""
    rng = np.random.default_rng(34)
    names = ("H", "D", "T0", "V", "Xd", "XT", "XL", "Tr", "Pm", "f")
    base = sj.Plant()
    rows = []
    while len(rows) < 32:
        kw = {n: float(getattr(base, n)) * 10 ** rng.uniform(-3, 3) for n in names}
        try:
            sj.Plant(**kw)  # (B0 = 0: the start is inside the domain)
        except ParameterError:
            continue
        rows.append(kw)
    plants = jax.tree_util.tree_map(
        lambda *xs: jnp.stack(xs), *[sj.Plant(**r) for r in rows]
    )

    @eqx.filter_jit
    @eqx.filter_vmap
    def run(plant):
        tr = sj.simulate(
            sj.Gains(),
            plant=plant,
            solver=sj.SolverOptions(max_steps=4000),
            save=sj.SaveOptions(2.0, 0.05),
        )
        return tr.lost_sync, tr.budget_exhausted, metrics(tr)

    lost, spent, m = run(plants)
    lost, spent = np.asarray(lost), np.asarray(spent)
    vals = {k: np.asarray(v, dtype=float) for k, v in m._asdict().items()}
    settling = ("settling_delta", "settling_Vt", "settling_omega")
    for k, v in vals.items():
        assert not np.isnan(v[~spent]).any(), k
        if k not in settling and k != "overshoot":
            assert np.isfinite(v[~spent & ~lost]).all(), k
        if k in settling:
            assert np.isinf(v[lost]).all(), k
    assert lost.any() and (~lost & ~spent).any()  # both ends are exercised


# 13. Error lines mixed into progress bars: every command's bars are closed (by the
# shared `progress_bars`) before the error line is printed.
def _error_on_its_own_line(err: str) -> str:
    line = next(ln for ln in err.split("\n") if "smibjax: error: boom" in ln)
    assert line == "smibjax: error: boom", repr(err)  # no '\r' bar text before it
    return line


def test_progress_bars_closes_every_bar_on_an_error(capsys):
    import sys

    from smibjax._commandline import progress_bars

    with pytest.raises(RuntimeError), progress_bars() as make:
        make(total=5, desc="first").update(1)
        make(total=5, desc="second").update(2)
        raise RuntimeError("boom")
    print("smibjax: error: boom", file=sys.stderr)
    err = capsys.readouterr().err
    assert "first:" in err and "second:" in err
    _error_on_its_own_line(err)


def test_case_montecarlo_failing_mid_run_prints_the_error_on_its_own_line(
    monkeypatch, capsys, tmp_path
):
    """`montecarlo --case`: the first chunk fails after the bar is drawn."""
    import types

    import smibjax.cli.grid as grid
    import smibjax.grid.montecarlo as gmc
    from smibjax.cli.options import CLIError
    from smibjax.grid.scenarios import FaultDistribution

    def fail(k):
        raise CLIError("boom")

    monkeypatch.chdir(tmp_path)  # the default run folder runs/montecarlo-<time>
    case = types.SimpleNamespace(system=None, name="kundur")
    monkeypatch.setattr(grid, "load", lambda a: (case, "op", "pf"))
    dist = FaultDistribution()
    monkeypatch.setattr(grid, "_grid_distribution", lambda c, a: (dist, 4, 2))
    monkeypatch.setattr(grid, "_describe", lambda c, pf: "a case")
    monkeypatch.setattr(gmc, "chunk_runner", lambda *a, **k: fail)
    assert main(["montecarlo", "--case", "kundur", "--n", "4"]) == 2
    err = capsys.readouterr().err
    assert "scenarios:" in err  # the bar was drawn
    _error_on_its_own_line(err)


# 13. A read-only --out is refused before the run, also for root: /proc refuses the
# creation of a file to every user, root included, where os.access("/proc", W_OK)
# is true for root (the former check).
@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc")
@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--out", "/proc/x.npz"],
        ["simulate", "--plot", "/proc/x.png"],
        ["cct", "--out", "/proc/x.json"],
        ["montecarlo", "--n", "2", "--out", "/proc/smibjax-mc"],
        ["montecarlo", "--case", "smib-gencls", "--n", "2"]
        + ["--out", "/proc/smibjax-mc"],
        ["compare", "--out", "/proc/smibjax-cmp"],
        ["compare", "--case", "smib-gencls", "--variant", "heavy:GENCLS.H=12"]
        + ["--out", "/proc/smibjax-cmp"],
        ["reproduce", "--out", "/proc/smibjax-rep"],
        ["modes", "--case", "smib-gencls", "--csv", "/proc/x.csv"],
    ],
)
def test_unwritable_out_refused_before_the_run_also_for_root(argv, capsys):
    assert main(argv) == 2
    line = _err(capsys)
    assert "is not allowed: the folder '/proc' is not writable" in line, line


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc")
def test_tuner_unwritable_out_refused_before_config_json(capsys):
    from tuning.optimize import main as tune

    assert tune(["--out", "/proc/smibjax-tune", "--steps", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "'/proc' is not writable" in err, err


# 13. --workers has no upper bound: every command that takes it (the parser's
# bound) and the library's dask_runner refuse more workers than CPUs.
@pytest.mark.parametrize(
    "argv",
    [
        ["montecarlo", "--n", "2"],
        ["montecarlo", "--case", "smib-gencls", "--n", "2"],
        ["compare"],
        ["compare", "--case", "smib-gencls", "--variant", "heavy:GENCLS.H=12"],
    ],
)
def test_workers_bounded_by_the_cpu_count_in_every_command(argv, capsys):
    cpus = os.cpu_count() or 1
    assert main([*argv, "--workers", str(cpus + 1)]) == 2
    line = _err(capsys)
    assert f"--workers {cpus + 1} is not allowed" in line and "CPU count" in line


def test_dask_runner_workers_bounded_by_the_cpu_count(monkeypatch):
    import types

    from smibjax.cli import cluster

    def started(*a, **k):
        raise AssertionError("a cluster was started")

    fake = types.SimpleNamespace(LocalCluster=started, Client=started)
    monkeypatch.setattr(cluster, "_distributed", lambda: fake)
    cpus = os.cpu_count() or 1
    with (
        pytest.raises(ParameterError, match=r"at most \d+ \(the CPU count"),
        cluster.dask_runner(workers=cpus + 1),
    ):
        pass


def test_tuner_failing_mid_run_prints_the_error_on_its_own_line(
    monkeypatch, capsys, tmp_path
):
    """The tuner's bar (tuning/loop.py): a training step fails after the bar is
    drawn; the error line printed next stands on its own line."""
    import sys
    import types

    from tuning import loop

    def fail(*a):
        raise RuntimeError("boom")

    space = types.SimpleNamespace(to_raw=lambda init: 0.0)
    opt = types.SimpleNamespace(init=lambda raw: None)
    summary = {"stable_fraction": 1.0, "settling_delta_mean": 1.0}
    setup = types.SimpleNamespace(plant=None)
    monkeypatch.setattr(loop, "build", lambda cfg: (None, space, setup, None, opt))
    monkeypatch.setattr(loop.problem_module, "engine", lambda cfg, s: (None, None))
    monkeypatch.setattr(loop, "make_step", lambda *a: fail)
    monkeypatch.setattr(loop, "make_validation", lambda *a: lambda r: (summary, 0))
    monkeypatch.setattr(loop, "_search", lambda cfg, sp, se, d, raw0, q: (raw0, []))
    monkeypatch.setattr(loop, "draw_scenarios", lambda *a: None)
    monkeypatch.setattr(loop, "continuation_scale", lambda cfg, step: 1.0)
    cfg = {"validation": {"every": 1}, "steps": 3, "batch": 1, "seed": 0}
    try:
        loop.run(cfg, tmp_path)
    except RuntimeError:
        print("smibjax: error: boom", file=sys.stderr)  # as the entry point does
    err = capsys.readouterr().err
    assert "tuning:" in err  # the bar was drawn
    _error_on_its_own_line(err)


def test_compare_set_of_an_avr_pss_parameter_is_honoured(capsys):
    """Issue 49, class 5: `compare --gains avr-pss --set K_A=0.0001` ran the
    AVR-PSS at its own K_A (only the paper's law's gains were passed on). Each set
    takes the --set values that are its controller's parameters; the paper's law
    has no K_A and says so in one warning."""
    from smibjax.cli.compare import _warn_dropped_sets, resolve_gain_set_context

    sets = {"K_A": 1e-4, "k1": 2.0}
    _, avr, ctx_avr, _ = resolve_gain_set_context("avr-pss", sets)
    _, law, ctx_law, _ = resolve_gain_set_context("paper", sets)
    assert float(avr.K_A) == 1e-4 and float(law.k1) == 2.0
    _warn_dropped_sets("paper", ctx_law, sets)
    _warn_dropped_sets("avr-pss", ctx_avr, sets)
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2
    assert "--set K_A does not apply to set 'paper'" in err[0]
    assert "--set k1 does not apply to set 'avr-pss'" in err[1]
