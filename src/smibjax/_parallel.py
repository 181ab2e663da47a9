"""Run a batch function over all CPU devices.

XLA's CPU backend runs a vmapped batch on one core. With several host devices
(`--xla_force_host_platform_device_count=N`, set by the entry points:
`smibjax.configure`) the batch is
split along its leading axis over the devices, so N cores work at once. Two ways:

- `device_map`: each slice is committed to its own device and the same jitted function
  runs on all of them from a thread pool (the computations release the GIL). XLA
  compiles one executable per device: N compiles, side by side.
- `shard_batch`: one `jax.shard_map` program over a mesh of the devices, compiled once
  (the tuner's value-and-grad: 5 s instead of two side-by-side compiles of 10-13 s).
  The reverse pass of diffrax's Runge-Kutta step needs `smibjax._compat`'s guarded
  work-around of an equinox bug under `shard_map`.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache, partial

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from ._compat import shard_map_closure_fix

__all__ = ["device_map", "shard_batch", "split_batch"]


@lru_cache(maxsize=8)
def _pool(n: int) -> ThreadPoolExecutor:
    return ThreadPoolExecutor(max_workers=n, thread_name_prefix="smibjax-device")


def _slices(size: int, devices: list) -> int:
    """Devices to split a batch of `size` over: slices of at least 2, since a batch of
    one compiles to a different program (other rounding), and results would depend on
    how a batch happens to be split."""
    return max(1, min(len(devices), size // 2))


def _pad(tree, n: int):
    """Pad the leading axis of every leaf to a multiple of n by repeating the final
    element. Returns (padded, original length)."""
    size = jax.tree_util.tree_leaves(tree)[0].shape[0]
    pad = -(-size // n) * n - size

    def padded(a):
        return jnp.concatenate([a, jnp.repeat(a[-1:], pad, axis=0)]) if pad else a

    return jax.tree_util.tree_map(padded, tree), size


def split_batch(tree, n: int):
    """Split the leading axis of every leaf into `n` nearly equal slices (the last
    slices are padded by repeating the final element so all have one shape). Returns
    (slices, original length)."""
    full, size = _pad(tree, n)
    per = jax.tree_util.tree_leaves(full)[0].shape[0] // n
    return [
        jax.tree_util.tree_map(lambda a, i=i: a[i * per : (i + 1) * per], full)
        for i in range(n)
    ], size


def device_map(fn, replicated, batched, devices=None):
    """`fn(replicated, batched)` evaluated slice-wise on every device in parallel;
    outputs (leading batch axis) are concatenated and trimmed to the input length."""
    devices = list(jax.devices() if devices is None else devices)
    size = jax.tree_util.tree_leaves(batched)[0].shape[0]
    n = _slices(size, devices)
    if n == 1:
        # committed to the first device like every other call's inputs: an executable
        # is compiled per input placement, and a later call with committed inputs
        # (e.g. the output of an earlier one) would compile the program again
        d = devices[0]
        return fn(jax.device_put(replicated, d), jax.device_put(batched, d))
    slices, size = split_batch(batched, n)

    def run(i):
        d = devices[i]
        out = fn(jax.device_put(replicated, d), jax.device_put(slices[i], d))
        return jax.block_until_ready(out)

    outs = list(_pool(n).map(run, range(n)))
    outs = [jax.device_put(o, devices[0]) for o in outs]
    return _gather(outs, size)


@partial(jax.jit, static_argnums=1)
def _gather(outs: list, size: int):
    """The slices' outputs concatenated along the batch axis and trimmed to `size`:
    one compiled call (op by op it was two dispatches per output leaf, about 4% of a
    Monte Carlo chunk of 256)."""
    return jax.tree_util.tree_map(lambda *xs: jnp.concatenate(xs)[:size], *outs)


def shard_batch(fn, devices=None):
    """`fn(replicated, batched)` (a pure, traceable function of one slice, e.g. a
    vmapped one) as one program over a mesh of `devices` (default: all): the leading
    axis of `batched` is split into equal slices (padded by repeating its final
    element, at least 2 per device) and every output, batched along its leading axis,
    is gathered on the first device and trimmed to the input length. Every leaf of
    `replicated` and `batched` must be an array. Compiled once per mesh size and input
    shapes, where `device_map` compiles once per device."""
    devices = list(jax.devices() if devices is None else devices)
    programs: dict[int, tuple] = {}
    single = jax.jit(fn)

    def program(n: int):
        if n not in programs:
            mesh = Mesh(np.asarray(devices[:n]), ("batch",))
            body = jax.shard_map(
                fn,
                mesh=mesh,
                in_specs=(P(), P("batch")),
                out_specs=P("batch"),
                check_vma=False,
            )
            programs[n] = (
                jax.jit(body),
                NamedSharding(mesh, P()),
                NamedSharding(mesh, P("batch")),
            )
        return programs[n]

    def call(replicated, batched):
        size = jax.tree_util.tree_leaves(batched)[0].shape[0]
        n = _slices(size, devices)
        if n == 1:
            # committed, always: the tuner's first step gets fresh (uncommitted)
            # parameters and every later step the previous step's (committed)
            # output, and jit compiles one executable per placement (measured: a
            # one-slice tuning run's second step compiled the whole program again,
            # 20 s)
            d = devices[0]
            out = single(jax.device_put(replicated, d), jax.device_put(batched, d))
        else:
            jitted, whole, split = program(n)
            padded, _ = _pad(batched, n)
            with shard_map_closure_fix():
                out = jitted(
                    jax.device_put(replicated, whole), jax.device_put(padded, split)
                )
            if size % n:
                out = jax.tree_util.tree_map(lambda a: a[:size], out)
        return jax.device_put(out, devices[0])

    return call
