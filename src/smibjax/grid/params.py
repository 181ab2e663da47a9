"""Device parameters by name: `MODEL.PARAM` (every device of a model) or
`MODEL[BUS:ID].PARAM` (one device: PSS/E bus number and machine id), e.g.
`IEEEST.KS` or `SEXS[1:1].K`. The names are the PSS/E dyr parameter names of
`smibjax.grid.psse.DYR_MODELS`, which are the device groups' field names.

`set_params` returns a new case (the values may be traced: differentiate or vmap
through them); concrete values meet the same checks as a dyr file's (the device
group's `__check_init__`: `ParameterError`, one line). Re-run the operating point
afterwards, since references and states at
rest depend on the parameters.
"""

from __future__ import annotations

import re

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from .loop import Case, gen_names

__all__ = ["ParamError", "parse_name", "get_param", "set_params", "tunable_names"]

_NAME = re.compile(r"^([A-Z0-9_]+)(?:\[([^\]]+)\])?\.([A-Za-z0-9_]+)$")


class ParamError(ParameterError):
    """A parameter name that does not exist in the case (one line)."""


def parse_name(name: str) -> tuple[str, str | None, str]:
    m = _NAME.match(name.strip())
    if not m:
        raise ParamError(
            f"parameter {name!r} is not MODEL.PARAM or MODEL[BUS:ID].PARAM "
            "(e.g. IEEEST.KS, SEXS[1:1].K)"
        )
    return m.group(1), m.group(2), m.group(3)


def _groups(case: Case):
    lay = case.layout
    for k, m in enumerate(case.machines):
        yield ("machines", k), m, lay.machine_gen[k]
    for k, c in enumerate(case.controllers):
        yield ("controllers", k), c, lay.controller_gen[k]
    # issue 47: a renewable's models (REGCA1, REECB1, REPCA1) by their PSS/E names,
    # each a sub-module of the plant's injector group (`Renewable.parts`)
    for k, d in enumerate(case.injectors):
        for attr in getattr(d, "parts", {}).values():
            yield ("injectors", k, attr), getattr(d, attr), tuple(int(i) for i in d.gen)


def _locate(case: Case, name: str):
    model, dev, par = parse_name(name)
    names = gen_names(case)
    hits = [(w, g, pos) for w, g, pos in _groups(case) if type(g).__name__ == model]
    if not hits:
        have = sorted({type(g).__name__ for _, g, _ in _groups(case)})
        raise ParamError(f"{name}: the case has no {model} (it has {', '.join(have)})")
    where, group, pos = hits[0]
    fields = _param_fields(group)
    if par not in fields:
        raise ParamError(
            f"{name}: {model} has no parameter {par!r} (it has {', '.join(fields)})"
        )
    if dev is None:
        idx = np.arange(len(pos))
    else:
        dev = dev if ":" in dev else f"{dev}:1"
        labels = [names[i] for i in pos]
        if dev not in labels:
            raise ParamError(
                f"{name}: no {model} at generator {dev} (it has {', '.join(labels)})"
            )
        idx = np.array([labels.index(dev)])
    return where, group, par, idx


def get_param(case: Case, name: str):
    """The values of parameter `name` (an array over the devices it names)."""
    _, group, par, idx = _locate(case, name)
    return jnp.asarray(getattr(group, par))[idx]


def set_params(case: Case, values: dict) -> Case:
    """`case` with parameters set by name (value: a scalar, or one per device)."""
    for name, value in values.items():
        where, group, par, idx = _locate(case, name)
        old = jnp.asarray(getattr(group, par), dtype=jnp.float64)
        new = old.at[idx].set(jnp.asarray(value, dtype=jnp.float64))
        group2 = eqx.tree_at(lambda g, p=par: getattr(g, p), group, new)
        check = getattr(group2, "__check_init__", None)
        if check is not None:  # the checks a dyr file's values meet (concrete only)
            check()
        kind, k, *sub = where
        groups = list(getattr(case, kind))
        if sub:  # issue 47: a sub-module of an injector group
            group2 = eqx.tree_at(lambda d, a=sub[0]: getattr(d, a), groups[k], group2)
        groups[k] = group2
        case = eqx.tree_at(lambda c, kd=kind: getattr(c, kd), case, tuple(groups))
    return case


def tunable_names(case: Case, model: str) -> list[str]:
    """The parameter names of `model`'s group in the case."""
    for _, g, _ in _groups(case):
        if type(g).__name__ == model:
            return _param_fields(g)
    return []


def _param_fields(group) -> list[str]:
    """A group's numeric parameters with a device axis (not its positions, bases or
    names)."""
    out = []
    for f in group.__dataclass_fields__:
        a = getattr(group, f, None)
        if f in ("gen", "bus", "mbase") or np.ndim(a) != 1:
            continue
        kind = a.dtype.kind if hasattr(a, "dtype") else np.asarray(a).dtype.kind
        if isinstance(a, list | tuple) or kind not in "fiu":
            continue
        out.append(f)
    return out
