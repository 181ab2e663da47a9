"""The AC power flow of `powerflow` solved sparsely: the same equations, unknowns and
result (`PowerFlowResult`), Newton-Raphson with the analytic Jacobian (MATPOWER's
dS/dVa, dS/dVm) assembled as a SciPy sparse matrix and solved by a sparse LU
(SuperLU) on the host, called from JAX through `jax.pure_callback`, so it works
under jit and (one scenario after another) under vmap.

Derivatives: the solution x* = (va, vm) of F(x, theta) = 0 is a `jax.custom_vjp`
whose backward pass is the implicit-function theorem, d/dtheta = -(dF/dx)^-T applied
to the cotangent (one sparse solve with the transposed Jacobian), then the
vector-Jacobian product of F in theta (the loads, generation, set points, branch and
shunt parameters), evaluated in JAX from the branch list (no dense Y). Reverse mode
only (`jax.grad`, `jax.vjp`); `powerflow.power_flow` (dense, optimistix) also has
forward mode.

Cost: O(branches) per Jacobian and one sparse LU per Newton step; the 2,224-bus GB
network solves in a fraction of a second where the dense Newton (a Jacobian by
forward-mode autodiff over 4,448 unknowns and a dense LU) took 37 CPU-s (issue 46).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._errors import ParameterError
from .powerflow import PowerFlowResult, Start, _schedule, _start, result_of
from .system import System
from .ybus import branch_admittances

__all__ = ["power_flow_sparse", "power_flow_host"]


def _network(system: System):
    """(fr, to, y_ff, y_ft, y_tf, y_tt, diag): the branch list and each bus's fixed
    shunt (pu), as JAX arrays."""
    br, sh = system.branches, system.shunts
    y_ff, y_ft, y_tf, y_tt = branch_admittances(system)
    diag = (
        jnp.zeros(system.n_bus, dtype=jnp.complex128)
        .at[jnp.asarray(sh.bus)]
        .add(jnp.asarray(sh.g) + 1j * jnp.asarray(sh.b))
    )
    return jnp.asarray(br.fr), jnp.asarray(br.to), y_ff, y_ft, y_tf, y_tt, diag


def _current(net, v):
    """The network's bus currents Y v (pu) from the branch list."""
    fr, to, y_ff, y_ft, y_tf, y_tt, diag = net
    i = diag * v
    i = i.at[fr].add(y_ff * v[fr] + y_ft * v[to])
    return i.at[to].add(y_tf * v[fr] + y_tt * v[to])


def _residual(x, net, s):
    """F(x): the power-flow equations of `powerflow` (2 n)."""
    n = s.slack.shape[0]
    va, vm = x[:n], x[n:]
    v = vm * jnp.exp(1j * va)
    inj = v * jnp.conj(_current(net, v))
    r_p = jnp.where(s.slack, va - s.va_set, jnp.real(inj) - s.p_sched)
    r_q = jnp.where(s.fixed_v, vm - s.v_set, jnp.imag(inj) - s.q_sched)
    return jnp.concatenate([r_p, r_q])


# ---- host side (NumPy / SciPy) ----


def _ybus_host(fr, to, y_ff, y_ft, y_tf, y_tt, diag):
    n = diag.shape[0]
    rows = np.concatenate([fr, fr, to, to, np.arange(n)])
    cols = np.concatenate([fr, to, fr, to, np.arange(n)])
    vals = np.concatenate([y_ff, y_ft, y_tf, y_tt, diag])
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


def _jacobian_host(Y, x, slack, fixed_v):
    """dF/dx (2n x 2n, CSC) at x: MATPOWER's dSbus/dV with the set-point rows as
    identity rows."""
    n = Y.shape[0]
    va, vm = x[:n], x[n:]
    v = vm * np.exp(1j * va)
    i = Y @ v
    dv = sp.diags(v)
    dvn = sp.diags(v / np.abs(vm))
    ds_dvm = dv @ np.conj(Y @ dvn) + sp.diags(np.conj(i)) @ dvn
    ds_dva = 1j * dv @ np.conj(sp.diags(i) - Y @ dv)
    J = sp.bmat([[ds_dva.real, ds_dvm.real], [ds_dva.imag, ds_dvm.imag]], format="csr")
    held = np.concatenate([slack, fixed_v])
    keep = sp.diags((~held).astype(np.float64))
    return (keep @ J + sp.diags(held.astype(np.float64))).tocsc()


def _residual_host(Y, x, s):
    n = Y.shape[0]
    slack, fixed_v, va_set, v_set, p_sched, q_sched = s
    va, vm = x[:n], x[n:]
    v = vm * np.exp(1j * va)
    inj = v * np.conj(Y @ v)
    r_p = np.where(slack, va - va_set, inj.real - p_sched)
    r_q = np.where(fixed_v, vm - v_set, inj.imag - q_sched)
    return np.concatenate([r_p, r_q])


def _newton_host(x0, tol, max_iter, *args):
    """Newton from x0 on the host: (x, steps taken, converged)."""
    *net, slack, fixed_v, va_set, v_set, p_sched, q_sched = (
        np.asarray(a) for a in args
    )
    Y = _ybus_host(*net)
    s = (slack, fixed_v, va_set, v_set, p_sched, q_sched)
    x = np.array(x0, dtype=np.float64)
    ok = False
    k = 0
    for k in range(1, int(max_iter) + 1):
        f = _residual_host(Y, x, s)
        if not np.all(np.isfinite(f)):
            k -= 1
            break
        try:
            dx = spla.splu(_jacobian_host(Y, x, slack, fixed_v)).solve(f)
        except RuntimeError:  # singular Jacobian
            k -= 1
            break
        x = x - dx
        if not np.all(np.isfinite(x)):
            break
        step = np.max(np.abs(dx)) if dx.size else 0.0
        if step <= tol + tol * np.max(np.abs(x)):
            f = _residual_host(Y, x, s)
            if np.max(np.abs(f), initial=0.0) <= tol:
                ok = True
                break
    return x, np.int32(k), np.bool_(ok)


def _transpose_solve_host(x, g, *args):
    """(dF/dx)^-T g at x on the host."""
    *net, slack, fixed_v, _va, _v, _p, _q = (np.asarray(a) for a in args)
    Y = _ybus_host(*net)
    J = _jacobian_host(Y, np.asarray(x), slack, fixed_v)
    return spla.splu(J.T.tocsc()).solve(np.asarray(g, dtype=np.float64))


def _host_args(net, s):
    return (*net, s.slack, s.fixed_v, s.va_set, s.v_set, s.p_sched, s.q_sched)


@eqx.filter_custom_vjp
def _solve(theta, x0, tol, max_iter):
    net, s = theta
    n2 = x0.shape[0]
    shapes = (
        jax.ShapeDtypeStruct((n2,), jnp.float64),
        jax.ShapeDtypeStruct((), jnp.int32),
        jax.ShapeDtypeStruct((), jnp.bool_),
    )
    return jax.pure_callback(
        lambda x0, *a: _newton_host(x0, tol, max_iter, *a),
        shapes,
        x0,
        *_host_args(net, s),
        vmap_method="sequential",
    )


@_solve.def_fwd
def _solve_fwd(perturbed, theta, x0, tol, max_iter):
    out = _solve(theta, x0, tol, max_iter)
    return out, out[0]


@_solve.def_bwd
def _solve_bwd(x, g_out, perturbed, theta, x0, tol, max_iter):
    net, s = theta
    g = g_out[0]
    lam = jax.pure_callback(
        _transpose_solve_host,
        jax.ShapeDtypeStruct(x.shape, jnp.float64),
        x,
        g,
        *_host_args(net, s),
        vmap_method="sequential",
    )
    _, vjp = eqx.filter_vjp(lambda th: _residual(x, *th), theta)
    (d_theta,) = vjp(-lam)
    return d_theta


def power_flow_sparse(
    system: System,
    *,
    start: Start = "case",
    tol: float = 1e-10,
    max_iter: int = 30,
) -> PowerFlowResult:
    """Solve the AC power flow of `system` (the equations and result of
    `powerflow.power_flow`) by Newton with the analytic sparse Jacobian and a sparse
    LU. Never raises on non-convergence (`converged = False`); jittable; vmappable
    (scenarios one after another); reverse-mode differentiable (implicit function
    theorem) in the loads, generation, set points and network parameters."""
    if start not in ("case", "flat"):
        raise ParameterError(f"power flow: start {start!r} is not 'case' or 'flat'")
    system = jax.tree.map(jnp.asarray, system)
    return _power_flow_sparse(system, jnp.asarray(start == "flat"), tol, max_iter)


@eqx.filter_jit
def _power_flow_sparse(system, flat, tol, max_iter) -> PowerFlowResult:
    s = _schedule(system)
    net = _network(system)
    x0 = _start(system, s, flat)
    x, steps, done = _solve((net, s), x0, tol, max_iter)
    n = system.n_bus
    va, vm = x[:n], x[n:]
    v = vm * jnp.exp(1j * va)
    inj = v * jnp.conj(_current(net, v))
    return result_of(system, s, va, vm, inj, steps, done, tol)


# ---- the host entry: two stored programs around the host Newton ----


def _prepare(system, flat):
    """Newton's inputs: the start x0 and the host arguments (branch list, schedule)."""
    s = _schedule(system)
    net = _network(system)
    out = dict(zip(_HOST_ARGS, _host_args(net, s), strict=True))
    return out | {"x0": _start(system, s, flat)}


def _finish(system, x, steps, done, tol):
    """The `PowerFlowResult` fields of Newton's iterate x."""
    s = _schedule(system)
    net = _network(system)
    n = system.n_bus
    va, vm = x[:n], x[n:]
    v = vm * jnp.exp(1j * va)
    inj = v * jnp.conj(_current(net, v))
    # the step count and flag arrive as floats: arguments, not constants of the program
    res = result_of(system, s, va, vm, inj, steps.astype(jnp.int32), done > 0.5, tol)
    return {f: getattr(res, f) for f in PowerFlowResult.__dataclass_fields__}


def _stored():
    from .._stored import stored_jit

    return stored_jit(_prepare, "powerflow.prepare"), stored_jit(
        _finish, "powerflow.finish"
    )


_HOST_ARGS = ("fr", "to", "y_ff", "y_ft", "y_tf", "y_tt", "diag")
_HOST_ARGS += ("slack", "fixed_v", "va_set", "v_set", "p_sched", "q_sched")
_PREPARE = _FINISH = None


def power_flow_host(
    system: System,
    *,
    start: Start = "case",
    tol: float = 1e-10,
    max_iter: int = 30,
) -> PowerFlowResult:
    """`power_flow_sparse` for the host (not jittable, not differentiable): the same
    Newton iterates and result, with the set-up and the result as stored programs
    (`smibjax._stored`) around the host Newton, so that a later process with a case
    of the same structure neither traces nor compiles them."""
    global _PREPARE, _FINISH
    if _PREPARE is None:
        _PREPARE, _FINISH = _stored()
    if start not in ("case", "flat"):
        raise ParameterError(f"power flow: start {start!r} is not 'case' or 'flat'")
    flat = np.asarray(start == "flat", dtype=np.float64)
    prep = _PREPARE(system, flat)
    x, steps, done = _newton_host(
        np.asarray(prep["x0"]), tol, max_iter, *(prep[k] for k in _HOST_ARGS)
    )
    fields = _FINISH(
        system, x, np.asarray(steps, np.float64), np.asarray(done, np.float64), tol
    )
    return PowerFlowResult(**fields)
