"""The sparse power flow (smibjax.grid.powerflow_sparse) against the dense Newton of
`powerflow`, and its implicit gradients against central differences."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smibjax.grid.case import load_case
from smibjax.grid.powerflow import power_flow, scale_operating_point
from smibjax.grid.powerflow_sparse import power_flow_sparse

pytestmark = pytest.mark.xdist_group("grid")

FIELDS = ("vm", "va", "p_gen", "q_gen", "p_slack")


@pytest.mark.parametrize("name", ["kundur", "ieee39", "smib"])
@pytest.mark.parametrize("start", ["case", "flat"])
def test_the_sparse_solution_equals_the_dense_one(name, start):
    """Both starts of every built-in network: the same solution to 1e-9 (pu, rad)."""
    system = load_case(name).system
    dense = power_flow(system, start=start)
    sparse = power_flow_sparse(system, start=start)
    assert bool(sparse.converged) and bool(dense.converged)
    for f in FIELDS:
        err = float(jnp.max(jnp.abs(getattr(sparse, f) - getattr(dense, f))))
        assert err < 1e-9, f
    assert float(jnp.max(jnp.abs(sparse.dp))) < 1e-10


def _objective(system, load, p):
    s2 = eqx.tree_at(
        lambda s: s.loads.p, system, jnp.asarray(system.loads.p).at[load].set(p)
    )
    r = power_flow_sparse(s2)
    return r.va[10] + 2 * r.vm[5] + r.q_gen[2] + r.p_slack


def test_the_gradient_wrt_a_load_equals_central_differences():
    """d(va + 2 vm + q_gen + p_slack)/d(load p) by the implicit function theorem
    equals central differences of the solver itself to 1e-6 relative."""
    system = load_case("ieee39").system
    p0 = float(system.loads.p[3])
    g = jax.grad(lambda p: _objective(system, 3, p))(p0)
    h = 1e-5
    fd = (_objective(system, 3, p0 + h) - _objective(system, 3, p0 - h)) / (2 * h)
    assert float(g) == pytest.approx(float(fd), rel=1e-6)
    assert abs(float(g)) > 1e-3  # not a trivially zero derivative


def test_vmap_over_load_factors_equals_the_loop():
    system = load_case("kundur").system
    factors = jnp.array([0.9, 1.0, 1.1])
    batch = jax.vmap(
        lambda f: power_flow_sparse(scale_operating_point(system, f, f)).vm
    )(factors)
    for k, f in enumerate(np.asarray(factors)):
        one = power_flow_sparse(scale_operating_point(system, float(f), float(f)))
        assert float(jnp.max(jnp.abs(batch[k] - one.vm))) < 1e-12
