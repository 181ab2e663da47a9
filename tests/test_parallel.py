"""Batches over the host devices: `shard_batch` (one shard_map program) against
`device_map` (one program per device) and against one device, through diffrax's reverse
pass (which needs smibjax._compat's work-around under shard_map)."""

import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import smibjax as sj
from smibjax._compat import shard_map_closure_fix
from smibjax._fixed import solve_fixed
from smibjax._parallel import device_map, shard_batch


def _swing(t, y, loop):
    """A one-machine swing equation (rad, rad/s) whose fault stage, between the
    fault's time and its clearing, scales the synchronizing power by (1 - lam)."""
    gains, fault = loop
    on = (t > fault.t_fault) & (t < fault.t_clear)
    sync = gains["K"] * jnp.where(on, 1.0 - fault.lam, 1.0)
    return jnp.stack([y[1], 0.8 - sync * jnp.sin(y[0]) - gains["D"] * y[1]])


def _value_and_grad():
    """Per-fault value and gradient (with respect to the gains) of a short run of the
    fixed-step training solver (`smibjax._fixed.solve_fixed`, Tsit5 on a grid with
    the fault's switch times) on a two-state swing equation: the reverse pass goes
    through diffrax's stage loop, as the simulator's does, at a small fraction of the
    simulator's compile (the check's child: 25 CPU-s with `sj.simulate`)."""
    ts = np.linspace(0.0, 0.3, 31)

    def one(g, f):
        sol = solve_fixed(
            _swing,
            (g, f),
            jnp.stack([jnp.arcsin(0.8 / g["K"]), 0.0]),
            jnp.stack([f.t_fault, f.t_clear, f.t_reclose]),
            lambda t, y, loop: jnp.abs(y[0]) < 3.0,
            t_end=0.3,
            dt=2e-3,
            ts=ts,
        )
        return jnp.sum(sol.samples**2)

    return jax.vmap(jax.value_and_grad(one), in_axes=(None, 0))


def _gains():
    return {"K": jnp.asarray(1.6), "D": jnp.asarray(0.4)}


def _faults(n):
    t = jnp.linspace(0.02, 0.1, n)
    return sj.Fault(
        t_fault=t,
        t_clear=t + 0.1,
        t_reclose=t + 0.15,
        lam=jnp.linspace(0.2, 0.8, n),
        Xf=jnp.zeros(n),
    )


def test_shard_batch_matches_device_map_and_one_device():
    # This process has one host device (the suite's); the check runs in a child with
    # two, as the command-line tools and the tuner use them.
    here = Path(__file__).resolve().parent
    code = (
        "from smibjax import configure\n"
        f"configure(cache_dir={str(here.parent / '.jax_cache')!r})\n"
        "import jax\n"
        "assert len(jax.devices()) == 2, jax.devices()\n"
        "import test_parallel\n"
        "test_parallel.check_two_devices()\n"
        "print('CHECKED')\n"
    )
    env = {
        **os.environ,
        "XLA_FLAGS": "--xla_force_host_platform_device_count=2",
        "PYTHONPATH": os.pathsep.join([str(here), os.environ.get("PYTHONPATH", "")]),
    }
    p = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env
    )
    assert p.returncode == 0 and "CHECKED" in p.stdout, p.stderr[-3000:]


def check_two_devices():
    """shard_batch against device_map and one device, on 2 host devices."""
    fn = _value_and_grad()
    jitted = jax.jit(fn)
    g = _gains()
    faults = _faults(5)  # 5 over 2 devices: padded to 6, trimmed back
    # the single-device references first: slices of 3 (device_map's slice shape),
    # committed to the first device as device_map commits its first slice, so that
    # device_map runs the same executable there (uncommitted inputs compiled the
    # whole program a third time: 2 compiles fewer)
    first = jax.devices()[0]
    singles = {
        i: jitted(
            *jax.device_put(
                (g, jax.tree_util.tree_map(lambda a, i=i: a[i : i + 3], faults)),
                first,
            )
        )
        for i in (1, 2)
    }
    sharded = shard_batch(fn)(g, faults)
    mapped = device_map(jitted, g, faults)
    (v, dg), (v2, dg2) = sharded, mapped
    assert v.shape == (5,)
    assert np.all(np.isfinite(v)) and np.all(v > 0)
    np.testing.assert_allclose(v, v2, rtol=1e-12, atol=0)
    leaves = zip(
        jax.tree_util.tree_leaves(dg), jax.tree_util.tree_leaves(dg2), strict=True
    )
    for a, b in leaves:
        assert a.shape[0] == 5
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-14)
    # and against other slices of 3 run one by one on a single device
    for i, (v1, _) in singles.items():
        np.testing.assert_allclose(v[i : i + 3], v1, rtol=1e-12)
    # outputs are gathered on the first device, like device_map's
    assert v.devices() == {jax.devices()[0]}


def test_shard_batch_of_one_slice_runs_on_one_device():
    fn = jax.vmap(lambda a, x: a * jnp.sin(x), in_axes=(None, 0))
    x = jnp.array([0.3, 0.7])  # 2 scenarios: one slice, no mesh
    out = shard_batch(fn)(jnp.asarray(2.0), x)
    np.testing.assert_allclose(out, 2.0 * np.sin([0.3, 0.7]), rtol=1e-15)


def test_the_equinox_work_around_is_scoped():
    from equinox import _ad

    original = _ad._strip_weak_dtype
    with shard_map_closure_fix():
        patched = _ad._strip_weak_dtype
        assert patched is not original
        s = jax.ShapeDtypeStruct((2,), jnp.float64)
        assert patched({"a": s}) == {"a": jax.ShapeDtypeStruct((2,), jnp.float64)}
    assert _ad._strip_weak_dtype is original


def test_a_one_slice_batch_compiles_once_wherever_its_inputs_live():
    """Fresh (uncommitted) inputs and the committed output of an earlier call run the
    same executable: a one-slice batch is committed to the first device. (Before: a
    one-slice tuning run's second step, fed the first step's output, compiled its
    whole program again, 20 s.)"""
    import jax.monitoring

    d = jax.devices()[0]
    a, x = jnp.asarray(0.5), jnp.array([0.1, 0.2])  # uncommitted
    a_on, x_on = jax.device_put(a, d), jax.device_put(x, d)  # committed
    compiles = []

    def listen(event, duration, **kw):
        if event.endswith("backend_compile_duration"):
            compiles.append(duration)

    for wrap in (shard_batch, lambda f: lambda r, b: device_map(jax.jit(f), r, b)):
        fn = wrap(jax.vmap(lambda a, x: a * jnp.cos(x) + 0.123, in_axes=(None, 0)))
        compiles.clear()
        jax.monitoring.register_event_duration_secs_listener(listen)
        try:
            first = fn(a, x)
            again = fn(a_on, x_on)
        finally:
            jax.monitoring.unregister_event_duration_listener(listen)
        np.testing.assert_array_equal(first, again)
        assert len(compiles) == 1, compiles
