"""The coordinated tuner on a multi-machine case (`python -m tuning.optimize` with a
`[case]` table; tuning/grid_*.py).

One tiny case keeps the tests cheap: the paper's SMIB network (smib.raw) with its
machine given an SEXS exciter and an IEEEST stabilizer and no mechanical damping
(tests/data/grid_tuning/smib_pss.dyr, 15 states), 2 s horizons, batches of 2. The
runs share one compiled program (`grid_run._compiled`, keyed by the config)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from tuning.grid_config import check_grid_config, load_grid_config
from tuning.optimize import main

# one worker runs the module: its runs share one compiled program in-process
# (`grid_run._compiled`); on the other worker the resume and gradient tests traced and
# lowered it again (33 s and 30 s of the suite on the CI machine, 8 s and 1 s here)
pytestmark = pytest.mark.xdist_group("tuning_grid")

ROOT = Path(__file__).resolve().parent.parent
RAW = ROOT / "src/smibjax/grid/cases/smib.raw"
DYR = ROOT / "tests/data/grid_tuning/smib_pss.dyr"

TINY = f"""
steps = 2
batch = 2
seed = 3

[case]
raw = "{RAW.as_posix()}"
dyr = "{DYR.as_posix()}"

[gains]
names = ["IEEEST.KS", "IEEEST.T1", "IEEEST.T3"]

[gains.bounds]
"IEEEST.KS" = [0.5, 50.0]

[scenarios]
kind = "bus"
buses = [2]
t_fault = [0.2, 0.2]
clear_after = [0.05, 0.08]
load_factor = [0.9, 1.1]

[train]
t_end = 2.0
dt_save = 0.02
rtol = 1e-9
atol = 1e-11

[loss]
target_damping = 0.3
damping_load_factors = [0.9, 1.1]

[optimizer]
learning_rate = 0.1

[validation]
n = 3
every = 1
t_end = 2.0
load_factors = [1.0]

[report]
fault_bus = 2
t_end = 2.0
"""


def _config(tmp_path, text=TINY, name="tiny.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


@pytest.fixture(scope="session")  # made once per worker, whatever runs between
def tiny_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("grid_tune")
    cfg = _config(tmp)
    out = tmp / "run"
    rc = main(["--config", str(cfg), "--out", str(out), "--quiet"])
    return rc, out, cfg


def test_tiny_run_writes_its_files(tiny_run):
    """End to end: exit 0; gains.json is a flat table of device parameters by name
    whose values, set on the case, give the modes the summary reports; the report
    has the modes before and after, the physics and the plot."""
    rc, out, _ = tiny_run
    assert rc == 0
    for f in (
        "gains.json",
        "report.md",
        "summary.json",
        "history.csv",
        "trajectories.png",
        "config.json",
        "checkpoint.eqx",
        "checkpoint.json",
    ):
        assert (out / f).is_file(), f
    gains = json.loads((out / "gains.json").read_text())
    assert set(gains) == {"IEEEST[1:1].KS", "IEEEST[1:1].T1", "IEEEST[1:1].T3"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 2
    assert summary["start"]["stable_fraction"] == 1.0
    # the start is the dyr file's KS = 5 (log transform: exp(log 5))
    assert summary["modes_before"][0]["modes"]
    from smibjax.grid.case import load_case
    from smibjax.grid.modes import linearize, modes
    from smibjax.grid.operating import operating_point
    from smibjax.grid.params import set_params

    case = set_params(load_case(RAW, DYR), gains)
    op, _ = operating_point(case, 1.0, 1.0)
    em = [
        m
        for m in modes(case, linearize(case, op, inputs=(), outputs=()))
        if m.kind == "electromechanical"
    ]
    after = summary["modes_after"][0]["modes"]
    assert len(em) == len(after) == 1
    assert em[0].damping == pytest.approx(after[0]["damping"], abs=1e-9)
    assert summary["tuned"]["worst_damping"] == pytest.approx(em[0].damping, abs=1e-9)
    assert summary["modes_before"][0]["modes"][0]["damping"] == pytest.approx(
        0.0812042, abs=1e-6
    )  # KS = 5 of the dyr file (`smibjax modes` on it: 8.120%)
    side = json.loads((out / "checkpoint.json").read_text())
    assert [v["step"] for v in side["validation"]] == [0, 1, 2]
    best = side["validation"][side["best_step"]]
    for key in ("stable_fraction", "worst_damping", "settling_angle_mean"):
        got = summary["tuned"][key]  # JSON has no inf: summary.json writes null
        # (the 2 s horizon leaves no second in band after the fault: not settled)
        assert (float("inf") if got is None else got) == best[key]
    report = (out / "report.md").read_text()
    assert "Electromechanical modes before and after" in report
    assert "Efd peak" in report and "IEEEST[1:1].KS" in report
    rows = (out / "history.csv").read_text().strip().splitlines()
    assert len(rows) == 3  # header + 2 steps


def test_tuned_dyr_round_trips(tiny_run, tmp_path):
    """tuned.dyr is the case's dyr file with the tuned numbers written in: read back,
    its IEEEST record has gains.json's values exactly and every other record the
    case file's, lines without a tuned number are the case file's bytes, and
    report.md has the old -> new table. The tiny run's best is its start (its
    validation cannot tell the steps apart), so the round trip to the simulation is
    also checked on gains moved off the start, written by the tuner's own
    `tuned_dyr`: the case loaded from that file (`simulate --case RAW --dyr
    tuned.dyr`'s library path) is the case with the gains set by `set_params`,
    leaf for leaf, and runs the same trajectory (1e-12)."""
    from types import SimpleNamespace

    from smibjax.grid.case import load_case
    from smibjax.grid.events import BusFault
    from smibjax.grid.operating import operating_point
    from smibjax.grid.params import set_params
    from smibjax.grid.psse import read_dyr
    from smibjax.grid.simulate import simulate_case
    from tuning.grid_run import tuned_dyr

    rc, out, cfg_path = tiny_run
    assert rc == 0
    gains = json.loads((out / "gains.json").read_text())

    def check_file(tuned, gains):
        new, old = read_dyr(tuned), read_dyr(DYR)
        assert [(r.model, r.bus, r.line) for r in new] == [
            (r.model, r.bus, r.line) for r in old
        ]
        for a, b in zip(old, new, strict=True):
            for p, v in a.params.items():
                want = gains.get(f"{a.model}[{a.bus}:{a.ident}].{p}", v)
                assert b.params[p] == want, (a.model, p)
        la = DYR.read_bytes().splitlines(keepends=True)
        lb = tuned.read_bytes().splitlines(keepends=True)
        assert len(la) == len(lb)
        diff = [k for k, (x, y) in enumerate(zip(la, lb, strict=True)) if x != y]
        assert diff == [3, 4]  # IEEEST's T1 ... T6 line and its KS line (0-based)
        assert lb[4].endswith(
            b"/ PSS on speed: KS = 5, two lead-lags 0.2/0.05, washout 3 s\n"
        )

    check_file(out / "tuned.dyr", gains)
    report = (out / "report.md").read_text()
    assert "## tuned.dyr: old -> new per device and parameter" in report
    row = next(x for x in report.splitlines() if x.startswith("| IEEEST[1:1] | KS |"))
    assert row.split("|")[3:5] == [" 3 ", " 5 "]  # the record's line, the old value
    assert float(row.split("|")[5]) == pytest.approx(gains["IEEEST[1:1].KS"], rel=1e-5)

    base = load_case(RAW, DYR)
    moved = {k: v * math.sqrt(3.0) for k, v in gains.items()}  # 17-digit values
    cfg = load_grid_config(cfg_path)
    text = tuned_dyr(cfg, SimpleNamespace(case=base), moved).text
    (tmp_path / "tuned.dyr").write_text(text, encoding="utf-8")
    check_file(tmp_path / "tuned.dyr", moved)
    from_dyr = load_case(RAW, tmp_path / "tuned.dyr")
    by_set = set_params(base, moved)
    la, lb = jax.tree_util.tree_leaves(from_dyr), jax.tree_util.tree_leaves(by_set)
    assert len(la) == len(lb)
    assert all(np.array_equal(x, y) for x, y in zip(la, lb, strict=True))
    fault = BusFault(bus=base.system.bus_index(2), t_on=0.2, t_off=0.27)
    sim = jax.jit(lambda c, o: simulate_case(c, o, [fault], t_end=1.5, dt_save=0.05))
    runs = [sim(c, operating_point(c, 1.0, 1.0)[0]) for c in (from_dyr, by_set, base)]
    assert bool(runs[0].stable)
    for f in ("delta", "omega", "efd", "vs"):
        a, b = np.asarray(getattr(runs[0], f)), np.asarray(getattr(runs[1], f))
        assert np.max(np.abs(a - b)) <= 1e-12, f
    # the case file's settings run another trajectory: the comparison can tell
    assert np.max(np.abs(np.asarray(runs[2].vs) - np.asarray(runs[0].vs))) > 1e-4


@pytest.mark.parametrize(
    "config", ["kundur_pss.toml", "ieee39_pss.toml", "wecc179_pss.toml"]
)
def test_shipped_configs_tuned_dyr_round_trips(config, tmp_path):
    """The shipped configs' tuned.dyr (the tuner's `_gains` and `tuned_dyr` on
    values moved off the start, no run): the built-in case's dyr file with every
    trained value, tie (Kundur's T5 = T6) and `case.set` value (Kundur's TGOV1.VMAX
    = 1.1 on every governor) written in; the case read from it equals the tuner's
    case with those values set, leaf for leaf."""
    from types import SimpleNamespace

    from smibjax.grid.case import case_files, load_case
    from smibjax.grid.params import set_params
    from smibjax.grid.psse import read_dyr
    from tuning.grid_problem import load_case_from, make_space
    from tuning.grid_run import _gains, case_dyr, tuned_dyr

    cfg = load_grid_config(ROOT / "tuning/configs" / config)
    case = load_case_from(cfg)
    space = make_space(case, cfg["gains"])
    problem = SimpleNamespace(case=case, space=space)
    moved = space.to_raw(
        space.start * (1 + 0.1 * np.sqrt(np.arange(1, len(space.names) + 1)))
        + 0.01 * (space.start == 0)  # WECC's switched-off stabilizers (K1 = 0)
    )
    gains = _gains(cfg, problem, moved)
    ties = {f for f, _ in space.tie}
    assert set(gains) == {*space.names, *ties, *cfg["case"]["set"]}
    p = tmp_path / "tuned.dyr"
    p.write_text(tuned_dyr(cfg, problem, gains).text, encoding="utf-8")
    old, new = read_dyr(case_dyr(cfg)), read_dyr(p)
    n_changed = 0
    for a, b in zip(old, new, strict=True):
        for q, v in a.params.items():
            name = f"{a.model}[{a.bus}:{a.ident}].{q}"
            want = gains.get(name, gains.get(f"{a.model}.{q}", v))
            assert b.params[q] == want, name
            n_changed += b.params[q] != v
    assert n_changed >= len(space.names)
    from_dyr = load_case(case_files(cfg["case"]["name"])[0], p)
    by_set = set_params(case, gains)
    la, lb = jax.tree_util.tree_leaves(from_dyr), jax.tree_util.tree_leaves(by_set)
    assert len(la) == len(lb)
    assert all(np.array_equal(x, y) for x, y in zip(la, lb, strict=True))


def test_gradient_matches_central_differences(tmp_path):
    """d loss / d log KS (the stabilizer gain, through the power flows, the adaptive
    solver of both scenarios and the eigenvalues) against central differences; the
    damping term is active (target 0.3 > zeta 0.08) and contributes. (The loss and
    gradient are the runs' own compiled program.)"""
    from tuning.grid_problem import reference
    from tuning.grid_run import compiled_grad

    cfg = load_grid_config(_config(tmp_path))
    check_grid_config(cfg)
    problem, grad = compiled_grad(cfg)
    raw0 = problem.space.to_raw(problem.space.start)
    refs = reference(problem, raw0)
    events, lfs = problem.batch(0)
    name = "IEEEST[1:1].KS"
    (_, info), g = grad(raw0, events, lfs, refs)
    assert float(info["damping"]) > 1e-3  # the hinge is on
    h = 1e-4

    def at(dx):
        r = dict(raw0)
        r[name] = raw0[name] + dx
        return float(grad(r, events, lfs, refs)[0][0])

    fd = (at(h) - at(-h)) / (2 * h)
    assert abs(float(g[name])) > 1e-3
    assert float(g[name]) == pytest.approx(fd, rel=2e-3)


def test_resume_equals_uninterrupted(tmp_path):
    """A run stopped after 1 of 2 steps and resumed from its checkpoint ends with the
    same parameters, optimizer state and history as an uninterrupted run."""
    from tuning.grid_run import run_grid

    cfg = load_grid_config(_config(tmp_path))
    check_grid_config(cfg)
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    _, whole = run_grid(cfg, a, quiet=True)
    _, first = run_grid(cfg, b, quiet=True, stop_after=1)
    assert first.step == 1
    _, rest = run_grid(cfg, b, resume=True, quiet=True)
    assert rest.step == whole.step == 2
    for k in whole.raw:
        assert float(rest.raw[k]) == float(whole.raw[k])
    la = jax.tree_util.tree_leaves(whole.opt_state)
    lb = jax.tree_util.tree_leaves(rest.opt_state)
    assert all(np.array_equal(x, y) for x, y in zip(la, lb, strict=True))
    assert [r["loss"] for r in rest.history] == [r["loss"] for r in whole.history]
    assert rest.best.step == whole.best.step


BAD = [
    (
        ('names = ["IEEEST.KS", "IEEEST.T1", "IEEEST.T3"]', 'names = ["IEEEST.KQ"]'),
        "IEEEST has no parameter 'KQ'",
    ),
    (
        ('names = ["IEEEST.KS", "IEEEST.T1", "IEEEST.T3"]', 'names = ["TGOV1.R"]'),
        "the case has no TGOV1",
    ),
    # a parameter that is not a dyr parameter (from the raw file): tuned.dyr could
    # not hold it (issue 48)
    (
        (
            'names = ["IEEEST.KS", "IEEEST.T1", "IEEEST.T3"]',
            'names = ["IEEEST.KS", "GENTRA.ra"]',
        ),
        "tuned.dyr: GENTRA[1:1].ra: GENTRA.ra is not a parameter of the GENTRA dyr",
    ),
    (
        ('"IEEEST.KS" = [0.5, 50.0]', '"IEEEST.KS" = [10.0, 50.0]'),
        "excludes the start value IEEEST[1:1].KS = 5",
    ),
    (
        ("load_factor = [0.9, 1.1]", "load_factor = [0.9, 20.0]"),
        "power flow does not converge at load factor 20",
    ),
    (("buses = [2]", "buses = [2, 99]"), "bus 99 is not in the system"),
    (
        (
            f'dyr = "{DYR.as_posix()}"',
            f'dyr = "{DYR.as_posix()}"\nskip_unsupported = 1',
        ),
        "case.skip_unsupported = 1 is not allowed: must be true or false",
    ),
    # horizons beyond a million samples and step budgets beyond 1e8 (before: an
    # OverflowError traceback after the output folder was written)
    (
        ("[train]\nt_end = 2.0", "[train]\nt_end = 1e306"),
        "train.t_end = 1e+306 is not allowed: must be <= 20000 s (at most 1e+06 "
        "samples of train.dt_save = 0.02 s a run)",
    ),
    (
        ("every = 1\nt_end = 2.0", "every = 1\nt_end = 4e5"),
        "validation.t_end = 400000.0 is not allowed: must be <= 20000 s",
    ),
    (
        ("fault_bus = 2\nt_end = 2.0", "fault_bus = 2\nt_end = 1e300"),
        "report.t_end = 1e+300 is not allowed",
    ),
    (
        ("atol = 1e-11", "atol = 1e-11\nmax_steps = 1000000000000"),
        "train.max_steps = 1000000000000 is not allowed: must be an integer in "
        "[1, 1e+08]",
    ),
    # issue 48: bounds outside the parameter's meaning, a tie across models
    (
        ('"IEEEST.KS" = [0.5, 50.0]', '"IEEEST.KS" = [-0.5, 50.0]'),
        "IEEEST[1:1].KS is a gain on the speed deviation, which damps only >= 0",
    ),
    (
        (
            'names = ["IEEEST.KS", "IEEEST.T1", "IEEEST.T3"]',
            'names = ["IEEEST.KS"]\ngroups = { g = ["IEEEST[1:1].T1", "SEXS[1:1].K"] }',
        ),
        "a tie across models or parameters",
    ),
]


@pytest.mark.parametrize("edit,message", BAD, ids=[m for _, m in BAD])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, edit, message):
    """A parameter the case lacks, a bound excluding the start value, a load range
    whose power flow fails at an end (naming the factor), a fault on a bus that does
    not exist: one line, exit 2, no output folder."""
    old, new = edit
    assert old in TINY
    cfg = _config(tmp_path, TINY.replace(old, new))
    out = tmp_path / "out"
    rc = main(["--config", str(cfg), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert message in err
    assert not out.exists()


def test_space_transforms_and_ties():
    """log raw values round-trip; projection clips into the bounds; a tie copies
    the leader's per-device value."""
    from smibjax.grid.case import load_case
    from tuning.grid_problem import make_space

    case = load_case("kundur")
    space = make_space(
        case,
        {
            "names": ["IEEEST.KS", "IEEEST.T6"],
            "per_device": True,
            "bounds": {"IEEEST.KS": [1.0, 40.0]},
            "transform": {},
            "tie": {"IEEEST.T5": "IEEEST.T6"},
        },
    )
    assert len(space.names) == 8 and space.names[0] == "IEEEST[1:1].KS"
    raw = space.to_raw(space.start)
    assert float(raw["IEEEST[1:1].KS"]) == pytest.approx(math.log(20.0))
    raw = {**raw, "IEEEST[2:1].KS": jnp.asarray(10.0), "IEEEST[3:1].T6": jnp.log(7.0)}
    raw = space.project(raw)
    vals = space.values(raw)
    assert float(vals["IEEEST[2:1].KS"]) == pytest.approx(40.0)
    assert float(vals["IEEEST[3:1].T5"]) == pytest.approx(7.0)
    assert float(vals["IEEEST[1:1].T5"]) == pytest.approx(10.0)


@pytest.mark.parametrize("factor", [0.8, 1.2])
def test_scaled_operating_point_is_an_equilibrium(factor):
    """Loads and generation scaled by a factor: every state derivative at rest is
    below 1e-8 (the loads' constant impedances come from the scaled P + jQ; with the
    raw file's they were not, and dEfd/dt was ~700/s at 0.8), concretely and traced."""
    from smibjax.grid.case import load_case
    from smibjax.grid.modes import check_equilibrium
    from smibjax.grid.operating import operating_point, operating_point_traced
    from smibjax.grid.params import set_params

    case = set_params(load_case("kundur"), {"TGOV1.VMAX": 1.1})
    op, _ = operating_point(case, factor, factor)
    check_equilibrium(case, op, tol=1e-8)
    op_t, _ = jax.jit(lambda f: operating_point_traced(case, f, f))(factor)
    assert np.max(np.abs(np.asarray(op_t.y0) - np.asarray(op.y0))) < 1e-9
    check_equilibrium(case, op_t, tol=1e-8)


def test_smib_only_flags_are_refused_with_a_case(tmp_path, capsys):
    """--init/--controller are the SMIB tuner's: with a [case] config, one line,
    exit 2, nothing written."""
    cfg = _config(tmp_path)
    out = tmp_path / "out"
    rc = main(["--config", str(cfg), "--out", str(out), "--init", "paper"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "--init is not allowed with a [case] config" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "path, value", [("seed", -1), ("validation.seed", "x"), ("validation.seed", 1.5)]
)
def test_seeds_are_checked_with_the_config(tmp_path, path, value):
    """Issue 49: seed = -1 and validation.seed = "x" were a traceback after the output
    folder was written, validation.seed = 1.5 was taken."""
    from smibjax import ParameterError

    cfg = load_grid_config(_config(tmp_path))
    *head, last = path.split(".")
    table = cfg
    for k in head:
        table = table[k]
    table[last] = value
    with pytest.raises(ParameterError, match=rf"^{path} = .* is not allowed: must be"):
        check_grid_config(cfg)


# issue 48: every stabilizer model tunable, bounds from the model's meaning, groups,
# the modal-only loss, the WECC 179 config


def _space(case, names, bounds=None, **kw):
    from tuning.grid_problem import make_space

    return make_space(
        case,
        {
            "names": names,
            "per_device": kw.get("per_device", True),
            "bounds": bounds or {},
            "transform": kw.get("transform", {}),
            "tie": kw.get("tie", {}),
            "groups": kw.get("groups", {}),
        },
    )


MEANING_BAD = [
    # (names, bounds, groups, message)
    (["ST2CUT.K1"], {"ST2CUT.K1": [-1.0, 30.0]}, {}, "gain on the speed deviation"),
    # switched off in the case (K1 = 0): the speed input alone fixes the side
    (
        ["ST2CUT[10:1].K1"],
        {"ST2CUT[10:1].K1": [-5.0, 0.0]},
        {},
        "ST2CUT[10:1].K1 is a gain on the speed deviation",
    ),
    # switched off and on electrical power: either side, but not across 0
    (
        ["ST2CUT[42:1].K1"],
        {"ST2CUT[42:1].K1": [-5.0, 5.0]},
        {},
        "its bounds must be on one side of 0",
    ),
    (
        ["IEEEST.KS"],
        {"IEEEST.KS": [-5.0, 5.0]},
        {},
        "gain of sign fixed by the case (start -2): its bounds must be <= 0",
    ),
    (
        ["ST2CUT.T6"],
        {"ST2CUT.T6": [0.0, 15.0]},
        {},
        "is a time constant (s): lower bound > 0",
    ),
    (["ST2CUT.ICS1"], {}, {}, "is an input code, remote bus or filter order"),
    (["IEEEST.LSMIN"], {"IEEEST.LSMIN": [-1.0, 1.0]}, {}, "(a lower limit) must be"),
    (["ST2CUT[5:1].T7"], {}, {}, "ST2CUT[5:1].T7 = 0 in the case: the time constant"),
    (["EXST1.VIMAX"], {}, {}, "is not a tunable parameter of EXST1"),
    (
        ["IEEEST.T4"],
        {},
        {"g": ["ST2CUT[5:1].K1", "IEEEST[3:1].KS"]},
        "a tie across models or parameters",
    ),
    (
        ["ST2CUT.K1"],
        {"ST2CUT.K1": [0.0, 30.0]},
        {"g": ["ST2CUT[5:1].K1", "ST2CUT[8:1].K1"]},
        "ST2CUT[5:1].K1 is also trained on its own",
    ),
    (["IEEEST.KQ"], {}, {}, "IEEEST has no parameter 'KQ'"),
    (["PSS2A.KS1"], {}, {}, "the case has no PSS2A"),
]


@pytest.mark.parametrize(
    "names,bounds,groups,message", MEANING_BAD, ids=[m[3] for m in MEANING_BAD]
)
def test_bounds_outside_the_meaning_are_refused(names, bounds, groups, message):
    """On WECC 179 (speed-input ST2CUTs, power-input IEEEST with KS = -2): a speed
    gain allowed below 0, a gain's bounds across 0 against the case's sign, a time
    constant allowed to reach 0, an input code, a lower limit above 0, a time
    constant the case has at 0 (its block is absent), a limit that is not a gain or
    time constant, a group across models, a group member also trained alone, a
    parameter the model lacks, a model the case lacks: one line each."""
    from smibjax import ParameterError
    from smibjax.grid.case import load_case

    case = load_case("wecc179")
    with pytest.raises(ParameterError) as e:
        _space(case, names, bounds, groups=groups)
    assert message in str(e.value)
    assert len(str(e.value).splitlines()) == 1


def test_every_stabilizer_model_has_a_meaning_for_every_parameter():
    """Each stabilizer model's dyr parameters (PSS/E CONs and ICONs) all have a kind
    in `grid_bounds.MEANING` (none falls to 'not tunable' by omission), and the SVC's
    gain and time constants too."""
    from smibjax.grid.case import STABILIZERS
    from smibjax.grid.psse import DYR_MODELS
    from tuning.grid_bounds import MEANING, kind_of

    for model in STABILIZERS:
        assert set(MEANING[model]) == set(DYR_MODELS[model]), model
    assert kind_of("CSVGN1", "K") == ("gain", "positive")
    assert kind_of("CSVGN1", "T5") == ("time", None)
    assert kind_of("SEXS", "K") == ("gain", None)
    assert kind_of("TGOV1", "R") is None  # no meaning table: the plain checks


def test_groups_signed_log_and_skipped_blocks():
    """WECC 179: a group of three ST2CUT gains is one trained value the others
    follow; a negative gain (IEEEST's KS = -2 on power) takes a signed log
    transform that round-trips and projects into its bounds; a group name skips
    the devices whose time constant is 0 (ST2CUT T9 exists at 10 of 25)."""
    from smibjax.grid.case import load_case
    from smibjax.grid.params import get_param, set_params

    case = load_case("wecc179")
    sp = _space(
        case,
        ["IEEEST.KS", "ST2CUT.T9"],
        {"IEEEST.KS": [-20.0, -0.1]},
        groups={"g": ["ST2CUT[8:1].K1", "ST2CUT[12:1].K1", "ST2CUT[14:1].K1"]},
    )
    assert len([n for n in sp.names if n.endswith(".T9")]) == 10
    assert len([n for n in sp.skipped if n.endswith(".T9")]) == 15
    assert sp.names[-1] == "ST2CUT[8:1].K1"
    assert dict(sp.tie) == {
        "ST2CUT[12:1].K1": "ST2CUT[8:1].K1",
        "ST2CUT[14:1].K1": "ST2CUT[8:1].K1",
    }
    k = sp.names.index("IEEEST[3:1].KS")
    assert sp.transforms[k] == "log" and sp.signs[k] == -1
    raw = sp.to_raw(sp.start)
    assert float(raw["IEEEST[3:1].KS"]) == pytest.approx(math.log(2.0))
    raw = {**raw, "IEEEST[3:1].KS": jnp.asarray(5.0), "ST2CUT[8:1].K1": jnp.log(4.0)}
    vals = sp.values(sp.project(raw))
    assert float(vals["IEEEST[3:1].KS"]) == pytest.approx(-20.0)  # clipped to -20
    tuned = set_params(case, {n: float(v) for n, v in vals.items()})

    def k1(g):
        return float(get_param(tuned, f"ST2CUT[{g}:1].K1")[0])

    assert [k1(8), k1(12), k1(14)] == pytest.approx([4.0, 4.0, 4.0])
    assert (k1(5), k1(10), k1(35)) == (5.5, 0.0, 10.0)  # the others untouched


MODAL = (
    TINY.replace("[loss]\n", "[loss]\nsettling = 0.0\nitae = 0.0\novershoot = 0.0\n")
    .replace("[loss]\n", "[loss]\neffort = 0.0\nunstable = 0.0\n")
    .replace(
        "damping_load_factors = [0.9, 1.1]",
        'damping_load_factors = [0.9, 1.1]\ndamping_reduce = "mean"',
    )
)


def test_modal_only_loss_and_its_gradient(tmp_path):
    """Every time-domain weight 0: the loss is 100 x the mean over the load factors
    of the squared hinge sum over the electromechanical modes, equal to the hinge
    computed from `smibjax modes`' concrete classification (NumPy eigenvalues), and
    no fault is simulated (stable is NaN); its gradient with respect to log KS and
    log T1 (through the power flow, the Jacobian and the eigenvalues, both load
    factors in one vmapped program) against central differences."""
    from smibjax.grid.modes import linearize, modes
    from smibjax.grid.operating import operating_point
    from tuning.grid_problem import reference
    from tuning.grid_run import compiled_grad

    cfg = load_grid_config(_config(tmp_path, MODAL))
    check_grid_config(cfg)
    problem, grad = compiled_grad(cfg)
    raw0 = problem.space.to_raw(problem.space.start)
    refs = reference(problem, raw0)
    events, lfs = problem.batch(0)
    (val, info), g = grad(raw0, events, lfs, refs)
    assert math.isnan(float(info["stable"]))
    hinge = []
    for lf in (0.9, 1.1):
        op, _ = operating_point(problem.case, lf, lf)
        ms = modes(problem.case, linearize(problem.case, op, inputs=(), outputs=()))
        z = [m.damping for m in ms if m.kind == "electromechanical"]
        assert z
        hinge.append(sum(max(0.0, 0.3 - x) ** 2 for x in z))
    assert float(val) == pytest.approx(100 * np.mean(hinge), rel=1e-9)
    assert float(val) > 0.1
    h = 1e-4
    for name in ("IEEEST[1:1].KS", "IEEEST[1:1].T1"):

        def at(dx, name=name):
            r = dict(raw0)
            r[name] = raw0[name] + dx
            return float(grad(r, events, lfs, refs)[0][0])

        fd = (at(h) - at(-h)) / (2 * h)
        assert abs(float(g[name])) > 1e-3, name
        assert float(g[name]) == pytest.approx(fd, rel=1e-4), name


def test_wecc179_config_validates():
    """tuning/configs/wecc179_pss.toml: the schema and every gain's bounds against
    its meaning on WECC 179; all 29 stabilizers' gains trained, the 7 negative ones
    (power input) with the signed log."""
    from tuning.grid_problem import load_case_from, make_space

    cfg = load_grid_config(ROOT / "tuning/configs/wecc179_pss.toml")
    check_grid_config(cfg)
    case = load_case_from(cfg)
    space = make_space(case, cfg["gains"])
    assert len(space.names) == 29
    assert all(n.endswith((".KS", ".K1")) for n in space.names)
    pairs = zip(space.transforms, space.signs, strict=True)
    assert sum(t == "log" and s < 0 for t, s in pairs) == 7
    assert not any(cfg["loss"][k] for k in ("settling", "itae", "overshoot"))
    assert cfg["loss"]["damping_load_factors"] == [0.9, 1.0, 1.1]


def test_exciter_gains_are_tunable_within_their_meaning_svc_refused():
    """The tiny case's SEXS: K (50) and TE take the log transform; its limit EMAX is
    not tunable; the SVC (CSVGN1, a shunt device at a bus) is refused in one line
    (parameter names address a generator's devices only)."""
    from smibjax import ParameterError
    from smibjax.grid.case import load_case

    case = load_case(RAW, DYR)
    sp = _space(case, ["SEXS.K", "SEXS.TE"])
    assert sp.transforms == ("log", "log")
    with pytest.raises(ParameterError, match="EMAX is not a tunable parameter"):
        _space(case, ["SEXS.EMAX"])
    with pytest.raises(ParameterError, match="CSVGN1 is a shunt device at a bus"):
        _space(case, ["CSVGN1.K"])
