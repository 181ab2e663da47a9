"""Device parameters written back into a PSS/E dyr file (issue 48, part 1).

`rewrite_dyr` returns the text of a dyr file with the numbers of named records
replaced and everything else kept character for character: comments (after `/`, and
`@!` lines), the order of the records, the spacing of every untouched line, records
of models smibjax does not read, ANDES's records. Only the tokens of the replaced
parameters change; a new value is written as Python's `repr` of the float64 (the
shortest text that reads back as the same float64; right-aligned in the old
number's width when shorter, so the columns stay), so reading the new file with
`psse.read_dyr` gives exactly the values given.

`dyr_updates` turns parameter values by name (`smibjax.grid.params`: `IEEEST.KS`,
`IEEEST[1:1].KS`) into the records' parameters by their dyr names (a machine's
device field `xd` is the dyr record's `Xd`, `Tdop` its `Tdo_p`, ...).

The core reads the file and returns text; writing it is the caller's (the tuner
writes `tuned.dyr` atomically).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .psse import DYR_MODELS, PsseError, _number, _split

__all__ = ["DyrChange", "DyrRewrite", "rewrite_dyr", "dyr_updates", "dyr_name"]

# a machine's device field -> its dyr parameter name (the machines' `from_params`)
_MACHINE_FIELDS = {
    "Tdop": "Tdo_p",
    "Tdopp": "Tdo_pp",
    "Tqop": "Tqo_p",
    "Tqopp": "Tqo_pp",
    "xd": "Xd",
    "xq": "Xq",
    "xdp": "Xd_p",
    "xqp": "Xq_p",
    "xdpp": "Xd_pp",
    "xl": "Xl",
}

# PSS/E ICONs (integers) among the dyr parameters: written without a decimal point
_ICONS = {"IEEEST": ("ICS", "IB")}

Key = tuple[str, int, str]  # (MODEL, BUS, ID)


@dataclasses.dataclass(frozen=True)
class DyrChange:
    """One replaced number: the record (`model`, `bus`, `ident`, its first `line`
    in `file`), the parameter's dyr name, the value read (`old`) and written
    (`new`), and the text written for it."""

    model: str
    bus: int
    ident: str
    param: str
    old: float
    new: float
    text: str
    file: str
    line: int

    @property
    def device(self) -> str:
        """`MODEL[BUS:ID]`, as in the parameter names of `smibjax.grid.params`."""
        return f"{self.model}[{self.bus}:{self.ident}]"


@dataclasses.dataclass(frozen=True)
class DyrRewrite:
    """The new text of a dyr file and what changed in it (file order)."""

    text: str
    changes: tuple[DyrChange, ...]


def _spans(text: str) -> list[tuple[int, int, bool]]:
    """(start, end, quoted) of each field of one line, in `psse._split`'s reading
    (the same fields, in order; an empty field of ",," has start == end; a quoted
    field's span is its content inside the quotes). Stops at a `/` outside quotes."""
    out: list[tuple[int, int, bool]] = []
    pending: tuple[int, int, bool] | None = None
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == "'" or c == '"':
            j = text.find(c, i + 1)
            if j < 0:
                return out  # _split refuses the line; it never gets here
            if pending is not None:
                out.append(pending)
            a, b = i + 1, j
            while a < b and text[a].isspace():
                a += 1
            while b > a and text[b - 1].isspace():
                b -= 1
            pending = (a, b, True)
            i = j + 1
        elif c == "/":
            break
        elif c == ",":
            out.append(pending if pending is not None else (i, i, False))
            pending = None
            i += 1
        elif c.isspace():
            i += 1
        else:
            j = i
            while j < n and not (text[j].isspace() or text[j] in ",/'\""):
                j += 1
            if pending is not None:
                out.append(pending)
            pending = (i, j, False)
            i = j
    if pending is not None:
        out.append(pending)
    return out


def _format(model: str, param: str, value: float, where: str) -> str:
    v = float(value)
    if not math.isfinite(v):
        raise PsseError(f"{where}: {model} field {param}: {v!r} is not a finite number")
    if param in _ICONS.get(model, ()) and v == int(v):
        return str(int(v))
    return repr(v)


def rewrite_dyr(
    path: str | Path, updates: Mapping[Key, Mapping[str, float]]
) -> DyrRewrite:
    """The text of the dyr file at `path` with, for each `(MODEL, BUS, ID)` of
    `updates`, that record's parameters (by their names in `DYR_MODELS[MODEL]`)
    replaced by the given values; every other character as read (the file is read
    as UTF-8, other bytes kept as they are with `surrogateescape`: encode the text
    the same way to write it back byte for byte).

    Raises `PsseError` (one line) for a model `DYR_MODELS` lacks, a parameter the
    model's record lacks (naming the record's parameters), a record not in the
    file or in it twice, a non-finite value, or a record of the wrong parameter
    count (as `read_dyr`)."""
    name = str(path)
    want: dict[Key, dict[str, float]] = {}
    for (model, bus, ident), params in updates.items():
        model = str(model).upper()
        if model not in DYR_MODELS:
            raise PsseError(
                f"{name}: dyr model {model!r} is not one smibjax reads "
                f"({', '.join(DYR_MODELS)}); its parameters cannot be written"
            )
        names = DYR_MODELS[model]
        for p in params:
            if p not in names:
                raise PsseError(
                    f"{name}: {model} record has no parameter {p!r} (it has "
                    f"{' '.join(names)})"
                )
        key = (model, int(bus), str(ident).strip())
        want.setdefault(key, {}).update({p: float(v) for p, v in params.items()})
    with open(path, "rb") as fh:
        text = fh.read().decode("utf-8", errors="surrogateescape")
    lines = text.splitlines(keepends=True)
    edits: dict[int, list[tuple[int, int, str]]] = {}  # line index -> replacements
    changes: list[DyrChange] = []
    seen: dict[Key, int] = {}
    toks: list[tuple[int, int, int, bool]] = []  # (line index, start, end, quoted)
    start = 0
    for k, line in enumerate(lines):
        body = line.rstrip("\r\n")
        if body.lstrip().startswith("@!"):
            continue
        fields, _, slash = _split(body, f"{name}:{k + 1}")
        spans = _spans(body)
        got = [body[a:b] if (q or b > a) else None for a, b, q in spans]
        if got != fields:  # a guard: this module and the reader disagree
            raise PsseError(f"{name}:{k + 1}: cannot locate the fields of this line")
        if spans and not toks:
            start = k
        toks += [(k, a, b, q) for a, b, q in spans]
        if not slash:
            continue
        real = [t for t in toks if t[2] > t[1] or t[3]]  # ",," fields dropped
        toks = []
        if len(real) < 3:
            continue
        word = lambda t: lines[t[0]][t[1] : t[2]]  # noqa: E731
        model = word(real[1]).strip().upper()
        if model not in DYR_MODELS or not any(m == model for m, _, _ in want):
            continue
        where = f"{name}:{start + 1}"
        try:
            bus = _number(word(real[0]), "i")
        except ValueError:
            raise PsseError(
                f"{where}: {model} field BUS: {word(real[0])!r} is not a bus number"
            ) from None
        key = (model, int(bus), word(real[2]).strip())
        if key not in want:
            continue
        if key in seen:
            raise PsseError(
                f"{where}: a second {model} record for generator {key[2]!r} at bus "
                f"{key[1]} (the first on line {seen[key]}); which to write is ambiguous"
            )
        seen[key] = start + 1
        names = DYR_MODELS[model]
        values = real[3:]
        if len(values) != len(names):
            raise PsseError(
                f"{where}: {model} record has {len(values)} parameters, expected "
                f"{len(names)} ({' '.join(names)})"
            )
        for p in (p for p in names if p in want[key]):  # the record's order
            new = want[key][p]
            li, a, b, _ = values[names.index(p)]
            try:
                old = float(_number(lines[li][a:b], "f"))
            except ValueError:
                raise PsseError(
                    f"{where}: {model} field {p}: {lines[li][a:b]!r} is not a number"
                ) from None
            s = _format(model, p, new, where)
            edits_text = s.rjust(b - a)  # a shorter number keeps the columns
            edits.setdefault(li, []).append((a, b, edits_text))
            changes.append(
                DyrChange(model, key[1], key[2], p, old, new, s, name, start + 1)
            )
    missing = [k for k in want if k not in seen]
    if missing:
        m, b, i = missing[0]
        raise PsseError(
            f"{name}: no {m} record for generator {i!r} at bus {b} (the file has "
            f"{len(seen)} of the {len(want)} records to write)"
        )
    for li, reps in edits.items():
        line = lines[li]
        for a, b, s in sorted(reps, reverse=True):
            line = line[:a] + s + line[b:]
        lines[li] = line
    return DyrRewrite(text="".join(lines), changes=tuple(changes))


def dyr_name(model: str, field: str) -> str | None:
    """The dyr parameter name of device field `field` of `model` (None when the
    field is not a dyr parameter: it comes from the raw file or is derived)."""
    names = DYR_MODELS.get(model, ())
    if field in names:
        return field
    alias = _MACHINE_FIELDS.get(field)
    return alias if alias in names else None


def dyr_updates(case, values: Mapping[str, float]) -> dict[Key, dict[str, float]]:
    """`{(MODEL, BUS, ID): {dyr parameter: value}}` of parameter values by name
    (`smibjax.grid.params`: `MODEL.PARAM` sets every device of the model,
    `MODEL[BUS:ID].PARAM` one; a value is a scalar or one per device), in the
    order given (a later name overrides an earlier one, as `set_params`). Raises
    `ParamError` (one line) for a name the case lacks or a device field that is
    not a dyr parameter."""
    from .loop import gen_names
    from .params import ParamError, _locate

    names = gen_names(case)
    lay = case.layout
    out: dict[Key, dict[str, float]] = {}
    for name, value in values.items():
        (kind, k), group, par, idx = _locate(case, name)
        model = type(group).__name__
        dyr = dyr_name(model, par)
        if dyr is None:
            have = ", ".join(DYR_MODELS.get(model, ()))
            raise ParamError(
                f"{name}: {model}.{par} is not a parameter of the {model} dyr record "
                f"(it has {have}); it comes from the raw file or is derived, and "
                "cannot be written to a dyr file"
            )
        pos = (lay.machine_gen if kind == "machines" else lay.controller_gen)[k]
        vals = np.broadcast_to(np.asarray(value, dtype=np.float64), (len(idx),))
        for i, v in zip(idx, vals, strict=True):
            bus, ident = names[int(pos[int(i)])].split(":", 1)
            out.setdefault((model, int(bus), ident), {})[dyr] = float(v)
    return out
