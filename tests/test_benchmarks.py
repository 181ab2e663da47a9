"""The benchmark scripts of benchmarks/ (and the study studies/stiff_solvers/) run end
to end on tiny configurations, so that they cannot rot. No wall-clock assertions:
exit status 0, the JSON's keys, finite positive numbers, and the accuracy figures the
scripts check.

The scripts run one after another in two background chains (`bench_chain`): under
pytest-xdist in the controller process from the start of the session, beside the
tests; otherwise from this module's first test. Each uses the suite's persistent
compilation cache, so a later script finds what an earlier one compiled.
"""

import json
import math
import os

import pytest

from bench_chain import ENV, TINY, start, wait
from helpers import ROOT

# collected last (conftest.py): by then the chain has mostly run
pytestmark = pytest.mark.xdist_group("benchmarks")


@pytest.fixture(scope="module")
def started(request, tmp_path_factory):
    """The folder the chain writes to: the controller's (xdist), or a chain of this
    module's selected scripts started here."""
    if os.environ.get(ENV):
        yield os.environ[ENV]
        return
    wanted = [
        name
        for name in TINY
        if any(
            item.module is request.module and item.name == f"test_{name}_tiny"
            for item in request.session.items
        )
    ]
    folder = tmp_path_factory.mktemp("benchmarks")
    chains = start(folder, wanted)
    yield folder
    for chain in chains:
        chain.stop()


def finish(started, name, stem=None):
    """Wait for the script; its JSON results `stem`.json (default: the script's
    name; the output is printed on failure)."""
    stem = stem or name
    rc, out = wait(started, name)
    text = (out / "log.txt").read_text()
    print(text)
    assert rc == 0, f"{name}.py exited with {rc}:\n{text[-4000:]}"
    assert (out / f"{stem}.png").is_file()
    res = json.loads((out / f"{stem}.json").read_text())
    for key in ("date", "machine", "cpus", "python", "jax", "smibjax", "config"):
        assert key in res
    return res


def positive(*values):
    for v in values:
        assert isinstance(v, (int, float)) and math.isfinite(v) and v > 0, v


def test_throughput_tiny(started):
    res = finish(started, "throughput")
    rows = res["rows"]
    assert {(r["controller"], r["devices"], r["batch"]) for r in rows} == {
        (c, 2, 4) for c in ("aftsc", "asc")
    }
    for r in rows:
        positive(
            r["scenarios_per_s"],
            r["seconds"],
            r["first_call_s"],
            r["mean_steps"],
            r["max_steps"],
            r["us_per_scenario_step"],
        )
        assert 0 <= r["stable_fraction"] <= 1
        assert r["status"] == "-"  # targets are judged at batch >= 1024 only
    for ctrl in ("aftsc", "asc"):
        err = res["accuracy"][ctrl]["max_abs_delta_error_rad"]
        assert math.isfinite(err) and 0 <= err < 1e-5


def test_vs_scipy_tiny(started):
    res = finish(started, "vs_scipy")
    rows, agreement = res["rows"], res["agreement"]
    for ctrl in ("aftsc", "asc"):
        positive(
            rows[f"{ctrl} smibjax"]["scenarios_per_s"],
            rows[f"{ctrl} smibjax"]["ratio_vs_fastest_scipy"],
        )
        assert rows[f"{ctrl} smibjax"]["status"] in ("met", "MISSED")
        for method in ("LSODA", "Radau"):
            r = rows[f"{ctrl} {method}"]
            positive(r["scenarios_per_s"], r["seconds"], r["smibjax_ratio"])
            assert r["stopped_or_failed"] == 0
            a = agreement[ctrl][method]
            assert a["compared_scenarios"] == 1
            # same model, same tolerance, two integrators: close agreement
            assert 0 <= a["scipy_vs_smibjax_rad"] < 1e-4
            assert 0 <= a["scipy_vs_reference_rad"] < 1e-4
        assert 0 <= agreement[ctrl]["smibjax_vs_reference_rad"] < 1e-5


def test_gradients_tiny(started):
    res = finish(started, "gradients")
    positive(
        res["forward_s"],
        res["value_and_grad_s"],
        res["ratio"],
        res["forward_first_call_s"],
        res["value_and_grad_first_call_s"],
        res["grad_norm"],
    )
    assert res["loss"] == pytest.approx(res["loss_from_value_and_grad"], rel=1e-9)
    assert res["dropped_scenarios"] == 0
    mem = res["memory_mb"]
    positive(mem["baseline_peak_rss"], mem["forward_peak_rss"], mem["grad_peak_rss"])
    assert mem["grad_peak_rss"] > mem["baseline_peak_rss"]
    assert set(res["finite_differences"]) == {"T2", "gamma2"}
    for r in res["finite_differences"].values():
        positive(abs(r["autodiff"]), abs(r["finite_difference"]))
        assert r["relative_error"] < 1e-2


def test_compile_tiny(started):
    res = finish(started, "compile")
    rows = res["rows"]
    assert set(rows) == {"simulate cold", "simulate warm"}
    for r in rows.values():
        positive(
            r["to_result_s"],
            r["process_wall_s"],
            r["in_python_s"],
            r["import_s"],
            r["first_result_s"],
        )
        # spawn <= first import < result < exit
        assert r["in_python_s"] <= r["to_result_s"] <= r["process_wall_s"]
        assert r["status"] in ("met", "MISSED")


def test_montecarlo_tiny(started):
    res = finish(started, "montecarlo")
    positive(
        res["scenarios_per_s"],
        res["wall_s"],
        res["first_chunk_s"],
        res["warm_chunk_s"],
        res["steps_mean"],
        res["steps_max"],
    )
    assert res["config"]["n"] == 8 and res["config"]["chunk"] == 4
    assert isinstance(res["met"], bool) and 0 <= res["stable_fraction"] <= 1


def test_cluster_scaling_tiny(started):
    res = finish(started, "cluster_scaling")
    rows = res["rows"]
    assert len(rows) >= 3  # in-process on 1 and on all devices, Dask with 1 worker
    for r in rows.values():
        positive(r["warm_scenarios_per_s"], r["cold_scenarios_per_s"])
        assert r["same_rows"] is True


def test_stiff_solvers_tiny(started):
    res = finish(started, "stiff_solvers")
    for ctrl in ("aftsc", "asc"):
        for method in ("RK45", "Radau"):
            r = res["rows"][ctrl][method]
            assert r["steps"] > 0 and r["nfev"] > r["steps"]
            assert (r["njev"] > 0) == (method == "Radau")
        # two integrators of one model at one tolerance: the same end state
        assert 0 <= res["delta_end_spread_rad"][ctrl] < 1e-4


def _tiny_case(params):
    """The tiny tuning case (tests/data/grid_tuning/tiny.toml) with `params` set."""
    from smibjax.grid.case import load_case
    from smibjax.grid.params import set_params

    data = ROOT / "tests/data/grid_tuning"
    case = load_case(ROOT / "src/smibjax/grid/cases/smib.raw", data / "smib_pss.dyr")
    return set_params(case, params) if params else case


def _worst_em_damping(params, load_factors):
    """The smallest damping ratio of the tiny case's electromechanical modes with
    `params` set, over `load_factors` (load and generation scaled together)."""
    from smibjax.grid.modes import linearize, modes
    from smibjax.grid.operating import operating_point

    case = _tiny_case(params)
    zetas = []
    for lf in load_factors:
        op, _ = operating_point(case, load_factor=lf, gen_factor=lf)
        ms = modes(case, linearize(case, op, inputs=(), outputs=()))
        zetas += [float(m.damping) for m in ms if m.kind == "electromechanical"]
    return min(zetas)


def test_tuning_grid_tiny(started):
    """benchmarks/tuning_grid.py on the tuner tests' tiny case (the paper's SMIB network,
    its machine with SEXS + IEEEST, tests/data/grid_tuning/tiny.toml)."""
    res = finish(started, "tuning_grid", "tuning_grid_smib")
    rows, timing = res["rows"], res["timing"]
    assert set(rows) == {
        "textbook PSS",
        "gradient (tuned)",
        "CMA-ES (mean)",
        "CMA-ES (best sample)",
        "single-scenario fixed-step",
        "no PSS (KS = 0)",
    }
    # equal simulation budgets: steps x batch = 4 training simulations each
    for k in ("gradient", "cma_es", "single_scenario"):
        assert timing[k]["scenario_simulations"] == 4
    assert timing["single_scenario"]["solver"] == "explicit Euler"
    buses = res["config"]["cct_buses"]
    assert buses == [2]  # the config's one fault bus
    for r in rows.values():
        # faults cleared within 0.08 s, below every CCT: all stable
        assert r["stable_fraction"] == 1.0
        assert set(r["cct"]) == {"2"}
        assert 0.08 < r["cct"]["2"] <= 1.0
    # the worst damping ratios are the modes' (independent of the benchmark's
    # plumbing): the textbook set, the no-PSS set, and a tuned set from its gains
    checks = {
        "textbook PSS": {},
        "no PSS (KS = 0)": {"IEEEST.KS": 0.0},
        "single-scenario fixed-step": res["gains"]["single-scenario fixed-step"],
    }
    for label, params in checks.items():
        assert rows[label]["worst_damping"] == pytest.approx(
            _worst_em_damping(params, (1.0,)), abs=1e-9
        ), label
    # without the stabilizer the swing mode is negatively damped (-2.9%); with the
    # dyr file's KS = 5 its damping ratio is 8.12% (`smibjax modes`)
    assert rows["no PSS (KS = 0)"]["worst_damping"] < 0
    assert rows["textbook PSS"]["worst_damping"] == pytest.approx(0.0812042, abs=1e-6)
    # the CCT bracket, simulated again: stable at the CCT, unstable 10 ms later
    import jax.numpy as jnp

    from smibjax.grid.events import BusFault
    from smibjax.grid.operating import operating_point
    from smibjax.grid.simulate import simulate_batch

    case = _tiny_case({})
    op, _ = operating_point(case, load_factor=1.0, gen_factor=1.0)
    cct = rows["textbook PSS"]["cct"]["2"]
    ev = (
        BusFault(
            bus=jnp.full(2, case.system.bus_index(2)),
            t_on=jnp.full(2, 0.5),
            t_off=0.5 + jnp.asarray([cct, cct + 0.01]),
        ),
    )
    tr = simulate_batch(case, op, ev, t_end=5.0, dt_save=0.05, rtol=1e-7, atol=1e-9)
    assert [bool(s) for s in tr.stable] == [True, False]
