"""Small-signal analysis: the exact linearization of a case's closed loop at its
operating point, its modes, damping ratios and participation factors.

The closed loop (machines, the algebraic network eliminated exactly by the
network solution of `network`, every controller) is one JAX function
dy/dt = f(y, u); `linearize` differentiates it with `jax.jacfwd` at the operating
point: A = df/dy, B = df/du for named inputs, C = dm/dy and D = dm/du for named
measurements, so that the transfer function from input j to output i is
C_i (sI - A)^-1 B_j + D_ij.

Modes (`modes`): eigenvalues lambda = sigma + j omega of A, frequency omega/(2 pi)
(Hz), damping ratio zeta = -sigma/|lambda|, right eigenvectors r (columns) and left
eigenvectors l (rows of inv(R)), participation factors p_ki = |r_ki l_ik| normalized
so that each mode's participations sum to 1 (Kundur section 12.2). A mode is
*electromechanical* when the rotor angles and speeds hold most of its participation (>
0.5) and it oscillates (0.05 to 5 Hz); it is *inter-area* when the machines that take
part (speed mode shape at least 20% of the largest) swing in two opposing groups whose
main areas (the raw file's bus area holding most of each group's mode shape) differ,
or, in a one-area system, when each opposing group has at least two machines, or, in
any system, when many machines take part (`SPREAD`: at least 6 and a quarter of them;
a 0.22 Hz NPCC mode of 24 machines in overlapping areas); *common* when two or more
machines take part all in phase (no opposing group: the whole system swinging against
its controllers, e.g. a slow speed-governor or washout mode); *local* otherwise. Zero
modes (|lambda| < 1e-6 1/s... see `zero_tol`) of a system without an infinite bus, the
absolute angle and, without governors or damping, the common speed, are reported as
`kind = "zero"`, not as instabilities; each zero eigenvalue is its own mode (a double
zero of an undamped system without an infinite bus is two modes: its numerical pair,
~1e-8 apart, is not a conjugate pair). A zero mode whose participation sits on a state
that never moves (its row of A is identically zero: a disabled filter stage, an
infinite bus's angle) has `kind = "frozen"`.
The damping ratio of a zero or frozen mode is reported as NaN (undefined).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from .loop import Case, Operating, evaluate, gen_names, state_labels
from .network import stage_configs, stage_matrices

__all__ = [
    "Linearization",
    "Mode",
    "linearize",
    "modes",
    "state_matrix",
    "damping_ratios",
    "participation",
    "transfer_function",
    "dominant_machines",
    "dominant_text",
    "check_equilibrium",
    "active_limits",
    "LIMIT_CONVENTION",
]

INPUTS = ("Efd", "Pm", "Vs")
OUTPUTS = ("delta", "omega", "Pe", "Vt", "Efd")


@dataclasses.dataclass(frozen=True)
class Linearization:
    """dy/dt = A y + B u, m = C y + D u around the operating point, with the labels
    of the states ((model, device, state) per row of A), the inputs and the outputs
    ((name, generator) per column of B / row of C)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: tuple
    inputs: tuple
    outputs: tuple


def _f_and_m(case: Case, op: Operating, mats, y, u_vec, inputs, outputs):
    n_gen = case.n_gen
    u = {name: u_vec[i * n_gen : (i + 1) * n_gen] for i, name in enumerate(inputs)}
    dy, meas, _ = evaluate(case, op, mats, 0, y, u)
    m = jnp.concatenate([meas[name] for name in outputs]) if outputs else jnp.zeros(0)
    return dy, m


def state_matrix(case: Case, op: Operating):
    """A = df/dy at the operating point (pre-event network), as a JAX array:
    differentiable with respect to everything in `case` and `op`."""
    mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
    return jax.jacfwd(lambda y: evaluate(case, op, mats, 0, y)[0])(op.y0)


@functools.partial(jax.jit, static_argnums=(2, 3))
def _jacobians(case: Case, op: Operating, inputs, outputs):
    mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
    u0 = jnp.zeros(len(inputs) * case.n_gen)

    def fm(y, u):
        return _f_and_m(case, op, mats, y, u, inputs, outputs)

    A, C = jax.jacfwd(fm, argnums=0)(op.y0, u0)
    B, D = jax.jacfwd(fm, argnums=1)(op.y0, u0)
    return A, B, C, D


def linearize(
    case: Case, op: Operating, inputs=INPUTS, outputs=OUTPUTS
) -> Linearization:
    """The state-space model at the operating point (see the module docstring)."""
    A, B, C, D = _jacobians(case, op, tuple(inputs), tuple(outputs))
    names = gen_names(case)
    return Linearization(
        A=np.asarray(A),
        B=np.asarray(B),
        C=np.asarray(C),
        D=np.asarray(D),
        states=state_labels(case),
        inputs=tuple((i, g) for i in inputs for g in names),
        outputs=tuple((o, g) for o in outputs for g in names),
    )


@dataclasses.dataclass(frozen=True)
class Mode:
    """One eigenvalue of A with what it means: index into the eigenvalues, the
    eigenvalue (1/s), frequency (Hz), damping ratio, kind ("electromechanical",
    "zero", "other"), scope ("local", "inter-area" or ""), the dominant states
    ((label, participation) sorted, largest first) and the speed mode shape per
    machine (complex, largest = 1)."""

    index: int
    eigenvalue: complex
    frequency: float
    damping: float
    kind: str
    scope: str
    dominant: tuple
    shape: dict


def damping_ratios(eigenvalues):
    """zeta = -Re(lambda) / |lambda| (works on JAX arrays; 1 for lambda = 0)."""
    eigenvalues = jnp.asarray(eigenvalues)
    mag = jnp.abs(eigenvalues)
    return jnp.where(mag > 0, -jnp.real(eigenvalues) / jnp.where(mag > 0, mag, 1), 1.0)


def participation(R, L):
    """p_ki = |r_ki l_ik|, each column (mode) normalized to sum 1."""
    p = np.abs(R * L.T)
    return p / np.maximum(p.sum(axis=0, keepdims=True), 1e-300)


def modes(case: Case, lin: Linearization, zero_tol: float = 1e-5) -> list[Mode]:
    """Every mode of `lin.A`: one per conjugate pair (the one with omega > 0), and
    every real eigenvalue, zero ones included (see the module docstring). Sorted:
    electromechanical modes first, least damped first; then the others by
    damping; zero and frozen modes last. `zero_tol`: |lambda| (1/s) below which an
    eigenvalue is a zero mode."""
    lam, R = np.linalg.eig(lin.A)
    L = np.linalg.inv(R)
    P = participation(R, L)
    labels = lin.states
    names = gen_names(case)
    areas = np.asarray(case.system.buses.area)[np.asarray(case.layout.gen_bus)]
    speed_rows = {lab[1]: k for k, lab in enumerate(labels) if lab[2] == "omega"}
    mech = np.array([lab[2] in ("delta", "omega") for lab in labels])
    still = ~np.any(lin.A != 0, axis=1)  # states whose derivative is identically 0
    out = []
    for k in range(len(lam)):
        zero = abs(lam[k]) < zero_tol
        if not zero and lam[k].imag < 0:
            continue
        f = 0.0 if zero else abs(lam[k].imag) / (2 * np.pi)
        em_share = float(P[mech, k].sum())
        shape = {}
        if speed_rows:
            vec = np.array(
                [R[speed_rows[g], k] if g in speed_rows else 0 for g in names]
            )
            big = np.max(np.abs(vec))
            if big > 0:
                vec = vec / vec[np.argmax(np.abs(vec))]
            shape = {
                g: complex(v)
                for g, v in zip(names, vec, strict=True)
                if g in speed_rows
            }
        if zero:
            kind = "frozen" if float(P[still, k].sum()) > 0.5 else "zero"
        elif em_share > 0.5 and 0.05 <= f <= 5.0:
            kind = "electromechanical"
        else:
            kind = "other"
        zeta = float("nan") if zero else float(damping_ratios(lam[k]))
        scope = _scope(shape, names, areas) if kind == "electromechanical" else ""
        order = np.argsort(-P[:, k])[:5]
        dominant = tuple(
            (f"{labels[i][1]} {labels[i][2]} ({labels[i][0]})", float(P[i, k]))
            for i in order
            if P[i, k] > 0.05
        )
        out.append(
            Mode(
                index=k,
                eigenvalue=complex(lam[k]),
                frequency=f,
                damping=zeta,
                kind=kind,
                scope=scope,
                dominant=dominant,
                shape=shape,
            )
        )
    rank = {"electromechanical": 0, "other": 1, "zero": 2, "frozen": 3}
    out.sort(key=lambda m: (rank[m.kind], np.nan_to_num(m.damping, nan=2.0)))
    return out


def dominant_machines(mode: Mode, share: float = 0.2) -> tuple[str, ...]:
    """The machines ('bus:id') whose speed mode shape is at least `share` of the
    largest, largest first."""
    items = sorted(mode.shape.items(), key=lambda kv: -abs(kv[1]))
    return tuple(g for g, v in items if abs(v) >= share)


def dominant_text(mode: Mode, top: int = 5, share: float = 0.2) -> str:
    """The dominant machines (`dominant_machines`) for a line of text: the first
    `top`, then how many more ("23:2, 36:1, 24:1, 25:1, 23:1 and 19 more")."""
    names = dominant_machines(mode, share)
    text = ", ".join(names[:top])
    return text + (f" and {len(names) - top} more" if len(names) > top else "")


def transfer_function(lin: Linearization, s, output, input) -> complex:
    """G(s) = C_i (sI - A)^-1 B_j + D_ij for the output ('Vt', '1:1') and the input
    ('Efd', '1:1') named as in `lin.outputs` / `lin.inputs`; `s` in 1/s (j omega
    for the frequency response, 0 for the DC gain)."""
    i = lin.outputs.index(tuple(output))
    j = lin.inputs.index(tuple(input))
    n = lin.A.shape[0]
    x = np.linalg.solve(s * np.eye(n) - lin.A, lin.B[:, j])
    return complex(lin.C[i] @ x + lin.D[i, j])


SPREAD = (6, 0.25)
"""A mode whose speed mode shape has at least max(6, 25% of the machines) taking
part, in two opposing groups, is inter-area whatever the areas say (`_scope`)."""


def _scope(shape: dict, names, areas) -> str:
    """'inter-area', 'local' or 'common' from the speed mode shape (see the module
    docstring): the machines taking part (|shape| >= 0.2 of the largest) split by
    the sign of their real part into two opposing groups; inter-area when the two
    groups' main areas (the area holding most of a group's |shape|) differ, in a
    one-area system when each group has two machines or more, and in any system
    when the machines taking part are many (`SPREAD`); local otherwise."""
    if not shape:
        return ""
    area_of = dict(zip(names, areas, strict=True))
    sig = {g: v for g, v in shape.items() if abs(v) >= 0.2}
    pos = [g for g, v in sig.items() if v.real >= 0]
    neg = [g for g, v in sig.items() if v.real < 0]
    if not pos or not neg:
        return "common" if len(sig) >= 2 else "local"
    least, share = SPREAD
    if len(sig) >= max(least, share * len(shape)):
        return "inter-area"

    def main_area(group):
        weight: dict = {}
        for g in group:
            weight[area_of[g]] = weight.get(area_of[g], 0.0) + abs(sig[g])
        return max(weight, key=weight.get)

    if len(set(areas)) > 1:
        return "inter-area" if main_area(pos) != main_area(neg) else "local"
    return "inter-area" if min(len(pos), len(neg)) >= 2 else "local"


def check_equilibrium(case: Case, op: Operating, tol: float = 1e-6) -> None:
    """ValueError (one line, naming the state) when the largest |dy/dt| at the
    operating point exceeds `tol` (state units per s): the linearization of a point
    that is not an equilibrium describes no small-signal behaviour."""
    mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
    dy = np.abs(
        np.asarray(jax.jit(evaluate, static_argnums=(3,))(case, op, mats, 0, op.y0)[0])
    )
    if dy.size and dy.max() > tol:
        k = int(np.argmax(dy))
        model, dev, st = state_labels(case)[k]
        raise ParameterError(
            f"the operating point is not an equilibrium: d{st}/dt = {dy[k]:.3g} at "
            f"{model} {dev} (more than {tol:g})"
        )


LIMIT_CONVENTION = (
    "the linearization takes JAX's derivative at the limit: a non-windup state "
    "exactly on its limit is free (its derivative is not held at 0), the output "
    "clipped there moves at half its free gain (neither binding nor free)"
)
"""How `linearize` treats a limiter whose signal sits exactly on its limit at the
operating point (jnp.clip's derivative at a tie is 1/2; `_blocks.nonwindup` holds a
state only while it is pushed outwards, and at rest nothing pushes). Another
program may treat the limit as binding (derivative 0) or free (1)."""


LIMITED_STATES = {
    ("TGOV1", "x_v"): ("VMIN", "VMAX"),
    ("SEXS", "Efd"): ("EMIN", "EMAX"),
}
"""The states held by constant non-windup limits, by (model, state): the limits
`active_limits` checks. Not checked: exciter limits that move with the terminal
voltage (IEEEX1, EXDC2, EXST1) and algebraic output limiters (IEEEST, STAB1,
CSVGN1)."""


def active_limits(case: Case, op: Operating, tol: float = 1e-9) -> list[tuple]:
    """The limiters on which the operating point sits: (model, device 'bus:id',
    state, limit name, value) for each state of `LIMITED_STATES` within `tol`
    (relative, absolute below 1) of its device's limit, in the order of the flat
    state."""
    from .loop import state_labels

    labels = state_labels(case)
    y0 = np.asarray(op.y0, dtype=float)
    lay = case.layout
    groups = [(m, len(lay.machine_gen[k])) for k, m in enumerate(case.machines)]
    groups += [(c, len(lay.controller_gen[k])) for k, c in enumerate(case.controllers)]
    groups += [(sv, len(lay.svc_bus[k])) for k, sv in enumerate(case.svcs)]
    out, at = [], 0
    for dev, n in groups:
        model = type(dev).__name__
        for st in dev.state_names:
            x = y0[at : at + n]
            for name in LIMITED_STATES.get((model, st), ()):
                lim = np.broadcast_to(np.asarray(getattr(dev, name), dtype=float), (n,))
                near = np.abs(x - lim) <= tol * np.maximum(1.0, np.abs(lim))
                for i in np.flatnonzero(np.isfinite(lim) & near):
                    _, device, state = labels[at + i]
                    out.append((model, device, state, name, float(lim[i])))
            at += n
    return out
