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
*electromechanical* when the rotor angles and speeds hold most of its participation
(> 0.5) and it oscillates (0.05 to 5 Hz); it is *inter-area* when the machines that
take part (speed mode shape at least 20% of the largest) swing in two opposing groups
whose areas (the raw file's bus areas) are disjoint, or, in a one-area system, when
each opposing group has at least two machines; *local* otherwise. Zero modes (|lambda|
< 1e-6 1/s... see `zero_tol`) of a system without an infinite bus, the absolute
angle and, without governors or damping, the common speed, are reported as
`kind = "zero"`, not as instabilities.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from .loop import Case, Operating, evaluate, gen_names, state_labels
from .network import stage_configs, stage_matrices

__all__ = ["Linearization", "Mode", "linearize", "modes", "damping_ratios"]

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


def linearize(
    case: Case, op: Operating, inputs=INPUTS, outputs=OUTPUTS
) -> Linearization:
    """The state-space model at the operating point (see the module docstring)."""
    mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
    n_gen = case.n_gen
    u0 = jnp.zeros(len(inputs) * n_gen)

    def fm(y, u):
        return _f_and_m(case, op, mats, y, u, inputs, outputs)

    (A, C) = jax.jacfwd(fm, argnums=0)(op.y0, u0)
    (B, D) = jax.jacfwd(fm, argnums=1)(op.y0, u0)
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
    mag = jnp.abs(eigenvalues)
    return jnp.where(mag > 0, -jnp.real(eigenvalues) / jnp.where(mag > 0, mag, 1), 1.0)


def participation(R, L):
    """p_ki = |r_ki l_ik|, each column (mode) normalized to sum 1."""
    p = np.abs(R * L.T)
    return p / np.maximum(p.sum(axis=0, keepdims=True), 1e-300)


def modes(case: Case, lin: Linearization, zero_tol: float = 1e-5) -> list[Mode]:
    """Every mode of `lin.A` (one per conjugate pair: the one with omega >= 0)."""
    lam, R = np.linalg.eig(lin.A)
    L = np.linalg.inv(R)
    P = participation(R, L)
    labels = lin.states
    names = gen_names(case)
    areas = np.asarray(case.system.buses.area)[np.asarray(case.layout.gen_bus)]
    speed_rows = {lab[1]: k for k, lab in enumerate(labels) if lab[2] == "omega"}
    mech = np.array([lab[2] in ("delta", "omega") for lab in labels])
    scale = max(1.0, float(np.max(np.abs(lam))))
    out = []
    for k in range(len(lam)):
        if lam[k].imag < -1e-9 * scale:
            continue
        f = abs(lam[k].imag) / (2 * np.pi)
        zeta = float(damping_ratios(jnp.asarray(lam[k])))
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
        if abs(lam[k]) < zero_tol:
            kind = "zero"
        elif em_share > 0.5 and 0.05 <= f <= 5.0:
            kind = "electromechanical"
        else:
            kind = "other"
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
    out.sort(key=lambda m: (m.kind != "electromechanical", m.damping))
    return out


def _scope(shape: dict, names, areas) -> str:
    """'inter-area' or 'local' from the speed mode shape (see the module docstring)."""
    if not shape:
        return ""
    area_of = dict(zip(names, areas, strict=True))
    sig = {g: v for g, v in shape.items() if abs(v) >= 0.2}
    pos = [g for g, v in sig.items() if v.real >= 0]
    neg = [g for g, v in sig.items() if v.real < 0]
    if not pos or not neg:
        return "local"
    a_pos, a_neg = {area_of[g] for g in pos}, {area_of[g] for g in neg}
    if len(set(areas)) > 1:
        return "inter-area" if not (a_pos & a_neg) else "local"
    return "inter-area" if min(len(pos), len(neg)) >= 2 else "local"
