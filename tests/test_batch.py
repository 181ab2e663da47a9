"""The batch engine (`smibjax._batch`): every batched caller's runs equal one
`simulate` + `metrics` per scenario, lanes carry their own parameter values, and the
compiled-in structure (projection box) is part of the program's identity."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smibjax as sj
from smibjax._batch import Engine, Scenarios
from smibjax.controllers import EstimateBox, Synergetic, make_controller

T_END = 2.0
# tight tolerances: batched and single runs are different programs (other rounding,
# constants folded), and the saturating loop amplifies rounding at loose ones
TIGHT = sj.SolverOptions(rtol=1e-10, atol=1e-12)
TOL = dict(solver=TIGHT)
SAVE = sj.SaveOptions(t_end=T_END)


def faults(n=3):
    """n short faults, all cleared and reclosed inside T_END."""
    tf = jnp.linspace(0.2, 0.4, n)
    return sj.Fault(
        t_fault=tf,
        t_clear=tf + jnp.linspace(0.05, 0.15, n),
        t_reclose=jnp.full(n, 1.5),
        lam=jnp.linspace(0.2, 0.8, n),
        Xf=jnp.zeros(n),
    )


def row(tree, i):
    return jax.tree_util.tree_map(lambda a: a[i], tree)


def one_by_one(ctrl, f, plant, d=None):
    """The reference: one `simulate` per scenario, its `metrics` and step count."""
    out = []
    for i in range(jax.tree_util.tree_leaves(f)[0].shape[0]):
        p = plant if d is None else sj.Plant(**{**_fields(plant), "D": float(d[i])})
        tr = sj.simulate(ctrl, row(f, i), p, solver=TIGHT, save=SAVE)
        out.append((sj.metrics(tr), int(tr.num_steps), bool(tr.lost_sync)))
    return out


def _fields(plant):
    return {k: float(getattr(plant, k)) for k in sj.PLANT_NAMES}


def assert_matches(out, ref):
    """Batched against single runs: XLA compiles a batch to another program than a
    single run (other rounding, constants folded), so the adaptive solver takes a few
    different steps (within 5%); the verdicts are equal and the metrics agree to the
    solver's tolerance (settling times to one 10 ms sample)."""
    for i, (m, steps, lost) in enumerate(ref):
        assert int(out.num_steps[i]) == pytest.approx(steps, rel=0.05)
        assert bool(out.lost_sync[i]) == lost
        assert bool(out.metrics.stable[i]) == bool(m.stable)
        a, b = float(out.metrics.settling_delta[i]), float(m.settling_delta)
        assert a == pytest.approx(b, abs=0.0101), (i, "settling_delta")
        for name in ("overshoot", "effort_uf", "peak_uf_cmd", "E_min", "Vt_max"):
            a, b = float(getattr(out.metrics, name)[i]), float(getattr(m, name))
            assert a == pytest.approx(b, rel=1e-6, abs=1e-9), (i, name)


@pytest.mark.parametrize("alpha", [5 / 7, 1.0], ids=["aftsc", "asc"])
def test_engine_equals_one_simulate_per_scenario(alpha):
    """The paper's law (ASC with alpha = 1 compiled in) with D drawn per scenario."""
    g = sj.Gains.paper("aftsc", beta1=-1.0, beta2=-1.0, alpha=alpha)
    plant = sj.Plant.preset("realistic")
    f, d = faults(), jnp.asarray([0.1, 0.25, 0.4])
    out = Engine(plant, t_end=T_END, **TOL).run(g, Scenarios(f, D=d))
    assert_matches(out, one_by_one(g, f, plant, d))
    # D really reaches the plant: the three runs differ
    assert len(set(np.asarray(out.metrics.overshoot).round(12))) == 3


def test_lanes_run_their_own_parameter_values():
    """Per-lane values (CCT lanes, a search population): lane i runs its own gains."""
    gains = [sj.Gains.paper("aftsc", beta1=b, beta2=-1.0) for b in (-1.0, -2.0, -0.5)]
    lanes = jax.tree_util.tree_map(lambda *x: jnp.stack(x), *gains)
    f = faults()
    out = Engine(t_end=T_END, **TOL).run(gains[0], Scenarios(f), lanes=lanes)
    for i, g in enumerate(gains):
        ref = one_by_one(g, row_batch(f, i), sj.Plant())
        assert_matches(take(out, i), ref)


def row_batch(f, i):
    return jax.tree_util.tree_map(lambda a: a[i : i + 1], f)


def take(out, i):
    return jax.tree_util.tree_map(lambda a: a[i : i + 1], out)


def test_structure_is_part_of_the_program():
    """Two projection boxes, one engine: the second call must not reuse the first
    box compiled into the first program (the controller's structure is in the
    cache key)."""
    g = sj.Gains.paper("aftsc", beta1=-1.0, beta2=-1.0, gamma1=5.0, gamma2=5.0)
    plant = sj.Plant.preset("realistic")
    f = faults(2)
    engine = Engine(plant, t_end=T_END, **TOL)
    results = []
    for box in (
        EstimateBox([-1.0, 0.0], [0.0, 2.0]),
        EstimateBox([-0.6, 0.0], [0.0, 1.1]),
    ):
        ctrl = Synergetic(g, oracle=False, projection=box)
        out = engine.run(ctrl, Scenarios(f))
        assert_matches(out, one_by_one(ctrl, f, plant))
        results.append(np.asarray(out.metrics.effort_uf))
    assert not np.array_equal(results[0], results[1])


def test_other_controllers_and_the_synchronism_flag():
    """avr-pss through the engine equals its runs; `synchronous` is no loss of
    synchronism and no spent budget."""
    ctrl = make_controller("avr-pss")
    plant = sj.Plant.preset("realistic")
    f = faults(2)
    out = Engine(plant, t_end=T_END, **TOL).run(ctrl, Scenarios(f))
    assert_matches(out, one_by_one(ctrl, f, plant))
    np.testing.assert_array_equal(
        np.asarray(out.synchronous),
        ~(np.asarray(out.lost_sync) | np.asarray(out.budget_exhausted)),
    )


def test_bad_engine_settings_are_one_clear_error():
    with pytest.raises(sj.ParameterError, match="t_end = 0 is not allowed"):
        Engine(t_end=0.0)
    with pytest.raises(sj.ParameterError, match="solver = 1e-06 is not allowed"):
        Engine(solver=1e-6)
    with (
        pytest.warns(DeprecationWarning),
        pytest.raises(sj.ParameterError, match="max_steps = 0 is not allowed"),
    ):
        Engine(max_steps=0)
    with pytest.raises(sj.ParameterError, match="must be a controller"):
        Engine(t_end=T_END, **TOL).run("aftsc", Scenarios(faults(2)))


def test_the_old_engine_keywords_are_a_deprecated_shim_for_the_solver_options():
    """Engine(rtol=, atol=, max_steps=) of 0.1 builds the same `SolverOptions` (and
    so the same compiled program) as solver=, with a DeprecationWarning; both at
    once is refused."""
    with pytest.warns(DeprecationWarning, match=r"Engine\(atol=, rtol=\)"):
        old = Engine(t_end=T_END, rtol=1e-10, atol=1e-12)
    assert old.solver == TIGHT and old.key() == Engine(t_end=T_END, **TOL).key()
    with pytest.warns(DeprecationWarning, match="max_steps="):
        assert Engine(max_steps=7).solver == sj.SolverOptions(max_steps=7)
    with pytest.raises(TypeError, match="not both"):
        Engine(solver=TIGHT, rtol=1e-6)
