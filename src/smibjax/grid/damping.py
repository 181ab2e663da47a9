"""Damping as a tuning goal: a differentiable loss on the damping ratios of the
electromechanical modes, at one or several operating points.

    loss = reduce over operating points p of  sum over selected modes m of
           max(0, target - zeta_pm)^2,     zeta = -Re(lambda) / |lambda|

with lambda the eigenvalues of the exact state matrix `state_matrix(case, op_p)`
(`jnp.linalg.eigvals`), op_p = `operating_point_traced(case, load_factor_p)`, so the
equilibrium follows the parameters (`set_params(case, {"IEEEST.KS": k})` with k
traced) and the gradient flows through the power flow (implicit function theorem),
the initialization, the Jacobian (forward mode) and the eigenvalues.

**Which eigenvalues.** The electromechanical modes are chosen once, at a reference
point (`reference_modes`: the concrete classification of `modes.modes`, the
eigenvalues with omega > 0 whose rotor angles and speeds hold most of the
participation, 0.05 to 5 Hz). In the traced loss, each reference eigenvalue picks the
nearest eigenvalue of the traced A (`argmin |lambda - lambda_ref|`: an integer, no
gradient; the gradient flows through the picked eigenvalue). The selection is a
piecewise-constant function of the parameters, so the loss is differentiable
wherever the picks do not change, which is everywhere near the reference point; a
tuner that moves far should refresh `reference` (call `reference_modes` again at its
current parameters) every few steps. This is simpler and sharper than a smooth weight
on participation and frequency band, which would need eigenvector derivatives and
lets exciter modes in the same band leak in.

**Crossings and repeats.** The derivative of a simple eigenvalue is l' dA r / (l' r);
at a repeated eigenvalue it is undefined (a Jordan block's eigenvalues move like the
square root of the perturbation), and `jnp.linalg.eigvals`'s derivative there is
inf/NaN. How the loss stays well defined:
- a hinge term is identically zero (with zero gradient) for every mode with
  zeta >= target, whatever its eigenvalue does, so crossings among well-damped modes
  never reach the loss;
- the loss is a sum over the selected set, a symmetric function of its eigenvalues:
  when two selected modes cross (swap order) the sum is continuous and its gradient
  is the sum of the two branches' gradients, which is continuous through a crossing
  of distinct (non-defective) eigenvalues; only at the exact coincidence of two
  eigenvalues with a defective (Jordan) structure is the gradient unbounded, a set
  of measure zero in parameter space;
- a selected mode crossing an unselected one can swap the pick (the nearest
  eigenvalue changes): the loss is then continuous only if both have the same
  damping, and its gradient jumps. `pick_gap` returns the distance ratio of the
  nearest to the second-nearest eigenvalue per reference mode so that a caller can
  see a swap coming (ratio near 1). Two reference modes can pick the same
  eigenvalue only when they are closer to it than to their own; refresh the
  reference before the modes move that far.
The squared hinge has a continuous first derivative at zeta = target (both sides
give 0), so the loss is C^1 in zeta.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from .loop import Case, Operating
from .modes import damping_ratios, linearize, modes, state_matrix
from .operating import operating_point_traced

__all__ = ["reference_modes", "damping_loss", "mode_damping", "pick_gap"]


def reference_modes(
    case: Case, load_factors=(1.0,), ops: tuple[Operating, ...] | None = None
) -> tuple[np.ndarray, ...]:
    """Per operating point, the electromechanical eigenvalues (omega > 0, complex,
    1/s) of the concrete `case` (`modes.modes` classification): the reference that
    `damping_loss` tracks."""
    if ops is None:
        op_at = jax.jit(lambda lf: operating_point_traced(case, lf)[0])
        ops = tuple(op_at(jnp.float64(lf)) for lf in load_factors)
    out = []
    for op in ops:
        ms = modes(case, linearize(case, op, inputs=(), outputs=()))
        lam = [m.eigenvalue for m in ms if m.kind == "electromechanical"]
        out.append(np.asarray(lam, dtype=np.complex128))
    return tuple(out)


def _pick(lam, ref):
    """The eigenvalues of `lam` nearest each of `ref` (indices carry no gradient)."""
    if ref.size == 0:
        return jnp.zeros(0, dtype=lam.dtype)
    dist = jnp.abs(jax.lax.stop_gradient(lam)[None, :] - jnp.asarray(ref)[:, None])
    return lam[jnp.argmin(dist, axis=1)]


def mode_damping(case: Case, op: Operating, ref) -> jnp.ndarray:
    """Damping ratios of the eigenvalues of `state_matrix(case, op)` nearest the
    reference eigenvalues `ref` (traced; differentiable, see the module docstring)."""
    lam = jnp.linalg.eigvals(state_matrix(case, op))
    return damping_ratios(_pick(lam, np.asarray(ref)))


def pick_gap(case: Case, op: Operating, ref) -> np.ndarray:
    """Per reference eigenvalue: |nearest - ref| / |second nearest - ref| (concrete).
    Near 1, the pick is about to swap to another eigenvalue."""
    lam = np.linalg.eigvals(np.asarray(state_matrix(case, op)))
    out = []
    for r in np.asarray(ref):
        d = np.sort(np.abs(lam - r))
        out.append(d[0] / d[1] if len(d) > 1 and d[1] > 0 else 0.0)
    return np.asarray(out)


def damping_loss(
    case: Case,
    op: Operating | None = None,
    target: float = 0.1,
    load_factors=(1.0,),
    reference=None,
    reduce: str = "mean",
):
    """The damping loss (dimensionless, 0 when every selected mode has zeta >= target)
    of `case` at the operating points `load_factors` (or at the one given `op`).

    `reference`: per operating point, the electromechanical eigenvalues to track
    (`reference_modes`); computed from `case` when None (then `case` must be
    concrete: compute it once outside `jax.grad`). `reduce`: "mean" or "max" over the
    operating points (max: the gradient of the worst point)."""
    if reduce not in ("mean", "max"):
        raise ParameterError(f"reduce = {reduce!r} is not allowed: use 'mean' or 'max'")
    ops = (op,) if op is not None else None
    if reference is None:
        reference = reference_modes(case, load_factors, ops)
    if ops is None:
        ops = tuple(operating_point_traced(case, lf)[0] for lf in load_factors)
    if len(reference) != len(ops):
        raise ParameterError(
            f"reference has {len(reference)} operating points, not {len(ops)}"
        )
    terms = []
    for op_p, ref in zip(ops, reference, strict=True):
        zeta = mode_damping(case, op_p, ref)
        terms.append(jnp.sum(jnp.maximum(target - zeta, 0.0) ** 2))
    terms = jnp.stack(terms)
    return jnp.mean(terms) if reduce == "mean" else jnp.max(terms)
