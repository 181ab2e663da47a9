"""Load models for dynamic simulation (issue 47): how each load's power-flow power
is split into constant power, constant current and constant impedance, PSS/E's way.

PSS/E's raw file gives each load as PL + j QL (constant power), IP + j IQ (constant
current: MW and MVAr at 1 pu voltage) and YP + j YQ (constant admittance: MW and
MVAr at 1 pu). Before a dynamic run PSS/E's CONL activity converts a share of the
constant-power part of every load to constant current and a share to constant
admittance (the rest stays constant power); the raw file's constant-current and
constant-admittance parts stay as they are. A `LoadModel` is that conversion:
`p` = (share kept as constant power, share to constant current, share to constant
impedance) of the constant-power P, `q` the same for Q (each triple sums to 1),
with PSS/E's low-voltage treatment (`pqbrak`: constant power below it turns
impedance-like; `ibrak`: constant current likewise; see `devices.zipload`).

`with_load_model(case, model)` adds a `ZIPLoad` injector for every load that is not
all impedance; without a load model (None, the default), or when every part is an
impedance, the case stays the linear network of before: every load a constant
impedance at its power-flow voltage (the raw file's IP, IQ included).

The command line's form (`parse_load_model`): "p=P,I,Z q=P,I,Z" with optional
"pqbrak=0.7" and "ibrak=0.5", e.g. "p=0,0,1 q=0,0,1" or "p=1,0,0 q=1,0,0 pqbrak=0";
the names "impedance", "current", "power" for all-Z, all-I and all-P with PSS/E's
default breaks.
"""

from __future__ import annotations

import math

import equinox as eqx
import numpy as np

from .._errors import ParameterError
from .devices.zipload import ZIPLoad
from .loop import Case, with_injectors

__all__ = ["LoadModel", "with_load_model", "parse_load_model", "load_shares"]

PQBRAK = 0.7  # PSS/E's default constant-power break (pu voltage)
IBRAK = 0.5  # the constant-current break (pu voltage)


class LoadModel(eqx.Module):
    """The conversion of loads for dynamics: `p` and `q` the shares of the raw
    file's constant-power part kept as constant power, converted to constant current
    and to constant impedance (each triple sums to 1, each share in [0, 1]);
    `pqbrak`, `ibrak` (pu voltage, in [0, 1]; 0 turns the treatment off) where the
    constant power and constant current parts start to turn impedance-like.
    ANDES's PQ in time domain: `LoadModel(p=..., q=..., pqbrak=0, ibrak=0)`."""

    p: tuple[float, float, float] = eqx.field(static=True, default=(0.0, 0.0, 1.0))
    q: tuple[float, float, float] = eqx.field(static=True, default=(0.0, 0.0, 1.0))
    pqbrak: float = eqx.field(static=True, default=PQBRAK)
    ibrak: float = eqx.field(static=True, default=IBRAK)

    def __check_init__(self):
        for name in ("p", "q"):
            v = getattr(self, name)
            text = ",".join(f"{x:g}" for x in v) if len(v) == 3 else str(v)
            if len(v) != 3 or not all(math.isfinite(x) and 0 <= x <= 1 for x in v):
                raise ParameterError(
                    f"LoadModel.{name} = {text} is not allowed: three shares "
                    "(constant power, current, impedance), each in [0, 1]"
                )
            if abs(sum(v) - 1.0) > 1e-9:
                raise ParameterError(
                    f"LoadModel.{name} = {text} is not allowed: the shares of "
                    f"constant power, current and impedance must add up to 1 (they "
                    f"add up to {sum(v):g})"
                )
        for name in ("pqbrak", "ibrak"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 <= v <= 1):
                raise ParameterError(
                    f"LoadModel.{name} = {v:g} is not allowed: a voltage in [0, 1] pu "
                    "(0: no low-voltage treatment)"
                )


def load_shares(case: Case, model: LoadModel) -> np.ndarray:
    """(6, n_load) shares of each load's power-flow P and Q: rows constant power,
    current, impedance of P, then of Q, from the raw file's constant-current parts
    (`Loads.p_i`, `q_i`: kept as current) and `model`'s conversion of the rest."""
    ld = case.system.loads
    p = np.asarray(ld.p, dtype=float)
    q = np.asarray(ld.q, dtype=float)
    pi, qi = (np.asarray(x, dtype=float) for x in ld.current_parts())
    rows = []
    for tot, cur, (a, b, c) in ((p, pi, model.p), (q, qi, model.q)):
        safe = np.where(tot != 0, tot, 1.0)
        f_i = np.where(tot != 0, cur / safe, 0.0)  # the raw file's current share
        rest = 1.0 - f_i
        rows += [a * rest, b * rest + f_i, c * rest]
    return np.stack(rows)


def with_load_model(case: Case, model: LoadModel | None) -> Case:
    """`case` with its loads as `model` says: a `ZIPLoad` injector for the loads
    with a constant power or constant current part; `case` itself when there is
    none (None, or every part an impedance)."""
    others = tuple(d for d in case.injectors if not isinstance(d, ZIPLoad))
    if model is None:
        return (
            case if len(others) == len(case.injectors) else with_injectors(case, others)
        )
    sh = load_shares(case, model)
    nonlinear = np.flatnonzero(
        np.any(np.abs(sh[[0, 1, 3, 4]]) > 0, axis=0)
        & (
            (np.asarray(case.system.loads.p) != 0)
            | (np.asarray(case.system.loads.q) != 0)
        )
    )
    if nonlinear.size == 0:
        return with_injectors(case, others) if others != case.injectors else case
    k = nonlinear.size
    zip_ = ZIPLoad(
        bus=np.asarray(case.system.loads.bus)[nonlinear],
        load=nonlinear,
        share=sh[:, nonlinear],
        pqbrak=np.full(k, model.pqbrak),
        ibrak=np.full(k, model.ibrak),
    )
    return with_injectors(case, (*others, zip_))


_NAMED = {
    "impedance": ((0.0, 0.0, 1.0), (0.0, 0.0, 1.0)),
    "current": ((0.0, 1.0, 0.0), (0.0, 1.0, 0.0)),
    "power": ((1.0, 0.0, 0.0), (1.0, 0.0, 0.0)),
}


def parse_load_model(text: str) -> LoadModel:
    """A `LoadModel` from "p=P,I,Z q=P,I,Z [pqbrak=B] [ibrak=C]" (spaces or
    semicolons between the parts; a missing p or q is all impedance) or one of
    "impedance", "current", "power"; `ParameterError` (one line) otherwise."""
    t = text.strip()
    if t in _NAMED:
        p, q = _NAMED[t]
        return LoadModel(p=p, q=q)
    kw: dict = {}
    for part in t.replace(";", " ").split():
        key, eq, val = part.partition("=")
        key = key.strip().lower()
        if not eq or key not in ("p", "q", "pqbrak", "ibrak") or key in kw:
            raise ParameterError(
                f"--load-model {text!r} is not allowed: write 'p=P,I,Z q=P,I,Z "
                "[pqbrak=V] [ibrak=V]' (shares of constant power, current, impedance)"
                " or one of impedance, current, power"
            )
        try:
            nums = tuple(float(x) for x in val.split(","))
        except ValueError:
            raise ParameterError(
                f"--load-model {key}={val} is not allowed: numbers separated by commas"
            ) from None
        if key in ("p", "q"):
            if len(nums) != 3:
                raise ParameterError(
                    f"--load-model {key}={val} is not allowed: three shares "
                    "(constant power, current, impedance)"
                )
            kw[key] = nums
        else:
            if len(nums) != 1:
                raise ParameterError(
                    f"--load-model {key}={val} is not allowed: one voltage (pu)"
                )
            kw[key] = nums[0]
    if not kw:
        raise ParameterError(f"--load-model {text!r} is not allowed: it is empty")
    return LoadModel(**kw)
