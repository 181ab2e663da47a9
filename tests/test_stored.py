"""Stored programs (`smibjax._stored`): the warm start both models' command lines
use. A stored program computes what the traced program computes, bit for bit; it is
reused for other numbers of the same structure and not for another structure."""

import jax.numpy as jnp
import numpy as np
import pytest

from smibjax import _stored


def _f(x, idx, *, scale):
    """A program with a floating input, an index array and a static keyword."""
    return {"y": jnp.sin(x[idx]) * scale, "s": jnp.sum(x)}


def _fresh():
    _stored._LOADED.clear()


@pytest.fixture
def stored(monkeypatch):
    monkeypatch.delenv("SMIBJAX_EXPORTED", raising=False)
    assert _stored.folder() is not None  # the suite's compilation cache
    _fresh()
    yield
    _fresh()


def test_a_stored_program_is_reused_for_other_numbers_not_other_structure(stored):
    f = _stored.stored_jit(_f, "test.f")
    rng = np.random.default_rng(7)
    # a fresh structure every session of the suite would be exported again: use the
    # sizes to make this test's first call exported only once per cache
    x = rng.normal(size=5)
    idx = np.array([0, 3, 4])
    out = f(x, idx, scale=2.0)
    first = _stored.LAST_PATH["test.f"]
    assert first in ("exported", "stored")
    np.testing.assert_array_equal(out["y"], np.sin(x[idx]) * 2.0)
    assert float(out["s"]) == float(jnp.sum(jnp.asarray(x)))
    # other numbers, same structure: read from disk, not traced
    _fresh()
    x2 = rng.normal(size=5)
    out2 = f(x2, idx, scale=2.0)
    assert _stored.LAST_PATH["test.f"] == "stored"
    np.testing.assert_array_equal(out2["y"], np.sin(x2[idx]) * 2.0)
    # other index values or another static keyword: another program (the old one
    # would compute with the old indices)
    _fresh()
    idx2 = np.array([1, 2, 2 + int(rng.integers(1, 3))])
    out3 = f(x2, idx2, scale=2.0)
    np.testing.assert_array_equal(out3["y"], np.sin(x2[idx2]) * 2.0)
    out4 = f(x2, idx, scale=3.0)
    np.testing.assert_array_equal(out4["y"], np.sin(x2[idx]) * 3.0)


def test_without_the_store_the_traced_program_gives_the_same_bits(stored, monkeypatch):
    f = _stored.stored_jit(_f, "test.f2")
    x = np.linspace(0.1, 0.9, 5)
    idx = np.array([4, 1])
    a = f(x, idx, scale=1.5)
    monkeypatch.setenv("SMIBJAX_EXPORTED", "0")
    b = f(x, idx, scale=1.5)
    assert _stored.LAST_PATH["test.f2"] == "traced"
    for k in a:
        np.testing.assert_array_equal(np.asarray(a[k]), np.asarray(b[k]))


def test_the_host_power_flow_is_the_sparse_newtons_bit_for_bit(stored):
    from smibjax.grid.case import load_case
    from smibjax.grid.powerflow_sparse import power_flow_host, power_flow_sparse

    system = load_case("ieee14", skip_unsupported=False).system
    for start in ("case", "flat"):
        a = power_flow_host(system, start=start)
        b = power_flow_sparse(system, start=start)
        assert bool(a.converged)
        for f in a.__dataclass_fields__:
            x, y = np.asarray(getattr(a, f)), np.asarray(getattr(b, f))
            assert x.dtype == y.dtype, f
            np.testing.assert_array_equal(x, y, err_msg=f)


def test_the_grids_stored_run_is_the_librarys_run(stored):
    """`simulate --case`'s stored program against the library's jitted run and
    metrics: the same numbers; another clearing time reuses the program and gives
    another run."""
    from smibjax.cli._exported import run_grid
    from smibjax.grid.case import load_case
    from smibjax.grid.events import BusFault
    from smibjax.grid.metrics import grid_metrics
    from smibjax.grid.operating import operating_point, scaled_power_flow
    from smibjax.grid.simulate import simulate_jit

    case = load_case("kundur-gencls")
    scaled, pf = scaled_power_flow(case)
    ev = (BusFault(bus=6, t_on=0.5, t_off=0.6),)
    opts = dict(t_end=1.5, dt_save=0.05)
    tr, m, dy0 = run_grid(scaled, pf, ev, 0.5, **opts)
    assert float(jnp.max(jnp.abs(dy0))) < 1e-8  # Kundur starts at rest
    assert _stored.LAST_PATH["grid.simulate"] in ("exported", "stored")
    op, _ = operating_point(case)
    ref = simulate_jit(case, op, ev, **opts)
    ref_m = grid_metrics(case, ref, jnp.asarray(0.5))
    for f in ("delta", "omega", "v_bus", "pe", "stable", "t_unstable"):
        np.testing.assert_allclose(
            np.asarray(getattr(tr, f)), np.asarray(getattr(ref, f)), rtol=0, atol=1e-12
        )
    for f in m.FIELDS:
        np.testing.assert_allclose(
            np.asarray(getattr(m, f)), np.asarray(getattr(ref_m, f)), rtol=0, atol=1e-12
        )
    # the fault is in the run (not a run at rest)
    assert float(jnp.max(jnp.abs(tr.delta[-1] - tr.delta[0]))) > 1e-3
    # a later clearing time: the same program from disk, a larger swing
    _fresh()
    later = (BusFault(bus=6, t_on=0.5, t_off=0.65),)
    tr2, _, _ = run_grid(scaled, pf, later, 0.5, **opts)
    assert _stored.LAST_PATH["grid.simulate"] == "stored"
    swing = lambda t: float(jnp.max(jnp.abs(t.delta - t.delta[0])))  # noqa: E731
    assert swing(tr2) > swing(tr) + 1e-3
