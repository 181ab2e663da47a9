"""The command line's warm start: `simulate`'s program and its summary's program
stored with `jax.export` (StableHLO), so that a second identical `python -m smibjax
simulate` neither traces them nor loads the solver (diffrax, optimistix, lineax).

`run` checks its inputs as `simulate` does (`simulate_inputs`), then looks for a
stored pair of programs under a key made of everything that determines them: the
controller's and parameter sets' structure (the static fields included) and their
arrays' shapes and dtypes, the horizon, sampling interval and solver options, the
versions of JAX, jaxlib, equinox, diffrax, lineax and optimistix, equinox's error
mode and a hash of smibjax's source files. On a hit it calls the stored programs
(the compiled executables come from JAX's persistent compilation cache, whose
folder holds the stored programs too, under `smibjax-exported/`). On a miss it
traces and exports them, stores them atomically for next time and calls them; on
any error (an unreadable file, a program JAX cannot export) it runs the library's
traced path, silently. The two paths compute the same programs: their results are
equal bit for bit (tests/test_startup.py).

Set SMIBJAX_EXPORTED=0 to always take the traced path.
"""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path
from types import SimpleNamespace

from .. import _stored

__all__ = ["run", "observe", "run_grid", "LAST_PATH"]

LAST_PATH: str | None = None
"""How the last `run` in this process computed: "stored" (a stored program),
"exported" (traced, exported and stored now), "traced" (the library's path)."""


def observe(traj):
    """(metrics, arrays) of a trajectory: `metrics` and the npz/plot arrays
    (`trajectory_arrays`), as JAX values: the summary's program, traced in one
    jitted function (run eagerly, its ~100 small operations compiled one kernel
    each: 1.1 s of CPU per `simulate`)."""
    from .._metrics import metrics
    from .plotting import trajectory_arrays

    return metrics(traj), trajectory_arrays(traj, numpy=False)


def run(gains, fault, plant, op, init, solver, save):
    """One `simulate` run with the library's defaults for the rest (adaptation as
    the controller has it, delta band, hard input limits) and its summary's
    program: (trajectory, metrics, arrays). `trajectory` has the attributes of a
    `Trajectory` (a `Trajectory` on the traced path), `metrics` those of a
    `Metrics` with NumPy values, `arrays` the npz layout as NumPy arrays. Bad
    input raises `ParameterError` before anything is computed, as `simulate` does."""
    global LAST_PATH
    from .._inputs import simulate_inputs

    inputs = simulate_inputs(gains, fault, plant, op, init, None, solver, save)
    folder = _stored.folder()
    if folder is not None:
        try:
            out = _run_stored(folder, inputs)
        except Exception:  # any failure: the traced path answers
            out = None
        if out is not None:
            return out
    LAST_PATH = "traced"
    return _traced(inputs)


def _traced(inputs):
    """The library's path: `simulate` (traced, compiled or loaded from the
    persistent cache) and the summary's program, jitted."""
    import jax
    import numpy as np

    from .._simulate import _simulate

    controller, fault, plant, op, init, solver, save = inputs
    traj = _simulate(controller, fault, plant, op, init, **_statics(solver, save))
    m, arrays = jax.jit(observe)(traj)
    m = jax.tree_util.tree_map(jax.device_get, m)
    return traj, m, {k: np.asarray(v) for k, v in arrays.items()}


def _statics(solver, save) -> dict:
    """`_simulate`'s static keywords, as `simulate` passes them for the command
    line (the default delta band, hard input limits)."""
    from .._inputs import DEFAULT_DELTA_BAND

    return {
        "t_end": float(save.t_end),
        "dt_save": float(save.dt_save),
        "solver": solver,
        "delta_band": float(DEFAULT_DELTA_BAND),
        "input_smoothing": 0.0,
    }


def _split(inputs):
    """(dynamic leaves, their treedef, the static part, key text) of a run's
    inputs: the arrays `eqx.filter_jit` would pass to the program, and the text
    of everything else that determines it."""
    import equinox as eqx
    import jax

    controller, fault, plant, op, init, solver, save = inputs
    args = (controller, fault, plant, op, init)
    dynamic, static = eqx.partition(args, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    static_leaves, static_def = jax.tree_util.tree_flatten(static)
    statics = _statics(solver, save)
    text = "\n".join(
        [
            str(treedef),
            str(static_def),
            repr(static_leaves),
            repr([(tuple(x.shape), str(x.dtype), _stored.weak(x)) for x in leaves]),
            repr(sorted((k, repr(v)) for k, v in statics.items())),
            *_stored.environment(),
        ]
    )
    return leaves, treedef, static, text


def _run_stored(folder: Path, inputs):
    """The run from the stored programs of these inputs (exported and stored
    first when there are none); None where JAX cannot export them."""
    global LAST_PATH
    import jax
    import numpy as np

    leaves, treedef, static, text = _split(inputs)
    key = hashlib.sha256(text.encode()).hexdigest()
    path = folder / f"{key}.bin"
    stored = _stored.read(path, key, 2)
    if stored is None:
        stored = _export(inputs, leaves, treedef, static, key)
        _stored.write(path, stored)
        LAST_PATH = "exported"
    else:
        LAST_PATH = "stored"
    header, sim_blob, obs_blob = stored
    from jax import export

    with _stored.no_lapack(not header["lapack"]):
        sim = export.deserialize(bytearray(sim_blob))
        outs = sim.call(*leaves)
        obs = export.deserialize(bytearray(obs_blob))
        m_out, a_out = obs.call(*outs)
    traj = SimpleNamespace(**dict(zip(header["trajectory"], outs, strict=True)))
    m = _metrics_like(header["metrics"], [jax.device_get(x) for x in m_out])
    arrays = {k: np.asarray(v) for k, v in zip(header["arrays"], a_out, strict=True)}
    return traj, m, arrays


def _metrics_like(names, values):
    """A `Metrics`-like named tuple of `values` (the class itself lives beside
    the solver)."""
    from collections import namedtuple

    return namedtuple("Metrics", names)(*values)


def _export(inputs, leaves, treedef, static, key):
    """(header, simulate's program, the summary's program) of these inputs,
    exported (traced now)."""
    import equinox as eqx
    import jax
    from jax import export

    from .._metrics import Metrics
    from .._simulate import Trajectory, _simulate

    controller, fault, plant, op, init, solver, save = inputs
    statics = _statics(solver, save)
    simulate_fn = _simulate.__wrapped__
    names = [f.name for f in dataclasses.fields(Trajectory)]

    def sim(*dynamic):
        args = eqx.combine(jax.tree_util.tree_unflatten(treedef, dynamic), static)
        traj = simulate_fn(*args, **statics)
        return tuple(getattr(traj, k) for k in names)

    sim_exp = export.export(jax.jit(sim), platforms=["cpu"])(*map(_stored.spec, leaves))
    array_names: list[str] = []

    def obs(*outs):
        traj = SimpleNamespace(**dict(zip(names, outs, strict=True)))
        m, arrays = observe(traj)
        array_names[:] = sorted(arrays)  # (a jitted function's dict: sorted keys)
        return tuple(m), tuple(arrays[k] for k in array_names)

    obs_exp = export.export(jax.jit(obs), platforms=["cpu"])(*sim_exp.out_avals)
    sim_blob, obs_blob = bytes(sim_exp.serialize()), bytes(obs_exp.serialize())
    header = {
        "key": key,
        "trajectory": names,
        "metrics": list(Metrics._fields),
        "arrays": array_names,
        # the programs call no LAPACK routine: calling them needs no LAPACK set-up
        # (jaxlib's loads SciPy: 0.2-0.4 s)
        "lapack": b"lapack" in sim_blob or b"lapack" in obs_blob,
    }
    return header, sim_blob, obs_blob


# ---- the grid's `simulate --case` ----


def _grid_program(case, vm, va, p_gen, q_gen, events, t_first, **options):
    """From a case's power flow to its run's trajectory and metrics: every device
    at its equilibrium (`initialize`), the run (`simulate_case`), the metrics
    (`grid_metrics`), as one flat dict ("traj.NAME", "metrics.NAME")."""
    from ..grid.loop import initialize
    from ..grid.metrics import grid_metrics
    from ..grid.operating import rest_residual
    from ..grid.simulate import simulate_case

    op = initialize(case, vm, va, p_gen, q_gen)
    tr = simulate_case(case, op, events, **options)
    m = grid_metrics(case, tr, t_first)
    out = {f"traj.{k}": getattr(tr, k) for k in tr.__dataclass_fields__ if k != "ibr"}
    out |= {f"ibr.{k}": v for k, v in tr.ibr.items()}  # the renewables' signals
    fields = [k for k in m.__dataclass_fields__ if getattr(m, k) is not None]
    out |= {f"metrics.{k}": getattr(m, k) for k in fields}
    return out | {"rest.dy0": rest_residual(case, op)}


_GRID = None


def run_grid(case, pf, events, t_first: float, before_trace=None, **options):
    """`simulate --case`'s run from the power flow `pf` of `case` (already scaled):
    (GridTrajectory, GridMetrics, dy/dt at the state at rest before the events
    (`grid.operating.rest_residual`)), from a stored program when one of this
    structure exists (`smibjax._stored`); `before_trace()` is called first when the
    program must be traced (the phase line). Concrete events are checked first."""
    import jax.numpy as jnp

    from ..grid.events import check_events
    from ..grid.metrics import GridMetrics
    from ..grid.trajectory import GridTrajectory

    global _GRID
    if _GRID is None:
        _GRID = _stored.stored_jit(_grid_program, "grid.simulate")
    check_events(case, events)
    # (the events' times and impedances are arrays: arguments of the program, so a
    # run with other times reuses it; their positions are part of its structure)
    out = _GRID(
        case,
        pf.vm,
        pf.va,
        pf.p_gen,
        pf.q_gen,
        events,
        jnp.asarray(t_first, dtype=jnp.float64),
        before_trace=before_trace,
        **options,
    )
    part = lambda tag: {  # noqa: E731
        k.split(".", 1)[1]: v for k, v in out.items() if k.startswith(tag)
    }
    traj = GridTrajectory(**part("traj."), ibr=part("ibr."))
    metrics = GridMetrics(**part("metrics."))
    return traj, metrics, out["rest.dy0"]
