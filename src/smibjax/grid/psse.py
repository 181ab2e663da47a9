"""PSS/E files: the power-flow raw file (versions 32 and 33) and the dynamics (dyr) file.

`read_raw` parses a raw file into `RawData`, one list of records per data category,
each record a dict of PSS/E field names with PSS/E's documented defaults filled in;
`to_system` converts it to a `System` (per unit on SBASE, angles in rad, the
transformers as an off-nominal tap on the from side with a phase shift). `read_dyr`
parses a dyr file into `DyrRecord`s, the parameters named by `DYR_MODELS`;
`check_dynamics` checks the records against a `System`. Every refusal is a
`PsseError` with one line naming the file, the line and the field.

References: PSS/E 33 Program Operation Manual (POM), chapter 5 (power-flow raw data
format) and the PSS/E 33 Model Library (the CON/ICON lists of the dynamic models).
The conventions are given in docs/psse.md; the deviations from ANDES's reader are
listed there too.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._errors import ParameterError
from .system import Branches, Buses, Generators, Loads, Shunts, System

__all__ = [
    "DYR_KINDS",
    "DYR_MODELS",
    "DyrRecord",
    "PsseError",
    "RawData",
    "check_dynamics",
    "read_dyr",
    "read_raw",
    "unsupported_models",
    "to_system",
]

ZERO_Z = 1e-4  # pu: the impedance of a tie (a star leg of zero impedance)


class PsseError(ParameterError):
    """A PSS/E file this reader refuses; the message is one line,
    `file:line: record field NAME: what is wrong`."""


# --------------------------------------------------------------------------- lexing


def _split(text: str, where: str) -> tuple[list[str | None], list[bool], bool]:
    """Split one line of PSS/E data into fields: comma or blank separated, single
    quotes around strings (which may hold commas, blanks and slashes), a `/` outside
    quotes ends the data (the rest is a comment). Two commas with nothing between
    give an empty field (None: the PSS/E default). Returns the fields, whether each
    was quoted, and whether a `/` was met."""
    fields: list[str | None] = []
    quoted: list[bool] = []
    pending: str | None = None
    pending_q = False
    have = False
    i, n = 0, len(text)
    slash = False
    while i < n:
        c = text[i]
        if c == "'" or c == '"':
            j = text.find(c, i + 1)
            if j < 0:
                raise PsseError(
                    f"{where}: unterminated quoted string {text[i:].strip()!r}"
                )
            if have:
                fields.append(pending)
                quoted.append(pending_q)
            pending, pending_q, have = text[i + 1 : j].strip(), True, True
            i = j + 1
        elif c == "/":
            slash = True
            break
        elif c == ",":
            fields.append(pending if have else None)
            quoted.append(pending_q if have else False)
            pending, pending_q, have = None, False, False
            i += 1
        elif c.isspace():
            i += 1
        else:
            j = i
            while j < n and not (text[j].isspace() or text[j] in ",/'\""):
                j += 1
            if have:
                fields.append(pending)
                quoted.append(pending_q)
            pending, pending_q, have = text[i:j], False, True
            i = j
    if have:
        fields.append(pending)
        quoted.append(pending_q)
    return fields, quoted, slash


# ---------------------------------------------------------------- record layouts

_REQ = object()  # no default: the field must be given

# (name, type, default); type "i" int, "f" float, "s" string. None as a default means
# "filled in later from other data" (bus area, SBASE, winding voltage).
_BUS = [
    ("I", "i", _REQ),
    ("NAME", "s", ""),
    ("BASKV", "f", 0.0),
    ("IDE", "i", 1),
    ("AREA", "i", 1),
    ("ZONE", "i", 1),
    ("OWNER", "i", 1),
    ("VM", "f", 1.0),
    ("VA", "f", 0.0),
]
_LOAD = [
    ("I", "i", _REQ),
    ("ID", "s", "1"),
    ("STATUS", "i", 1),
    ("AREA", "i", None),
    ("ZONE", "i", None),
    ("PL", "f", 0.0),
    ("QL", "f", 0.0),
    ("IP", "f", 0.0),
    ("IQ", "f", 0.0),
    ("YP", "f", 0.0),
    ("YQ", "f", 0.0),
    ("OWNER", "i", None),
    ("SCALE", "f", 1.0),
]
_FSHUNT = [
    ("I", "i", _REQ),
    ("ID", "s", "1"),
    ("STATUS", "i", 1),
    ("GL", "f", 0.0),
    ("BL", "f", 0.0),
]
_GEN = [
    ("I", "i", _REQ),
    ("ID", "s", "1"),
    ("PG", "f", 0.0),
    ("QG", "f", 0.0),
    ("QT", "f", 9999.0),
    ("QB", "f", -9999.0),
    ("VS", "f", 1.0),
    ("IREG", "i", 0),
    ("MBASE", "f", None),
    ("ZR", "f", 0.0),
    ("ZX", "f", 1.0),
    ("RT", "f", 0.0),
    ("XT", "f", 0.0),
    ("GTAP", "f", 1.0),
    ("STAT", "i", 1),
    ("RMPCT", "f", 100.0),
    ("PT", "f", 9999.0),
    ("PB", "f", -9999.0),
]
_BRANCH = [
    ("I", "i", _REQ),
    ("J", "i", _REQ),
    ("CKT", "s", "1"),
    ("R", "f", 0.0),
    ("X", "f", _REQ),
    ("B", "f", 0.0),
    ("RATEA", "f", 0.0),
    ("RATEB", "f", 0.0),
    ("RATEC", "f", 0.0),
    ("GI", "f", 0.0),
    ("BI", "f", 0.0),
    ("GJ", "f", 0.0),
    ("BJ", "f", 0.0),
    ("ST", "i", 1),
    ("MET", "i", 1),
    ("LEN", "f", 0.0),
]
_XF1 = [
    ("I", "i", _REQ),
    ("J", "i", _REQ),
    ("K", "i", 0),
    ("CKT", "s", "1"),
    ("CW", "i", 1),
    ("CZ", "i", 1),
    ("CM", "i", 1),
    ("MAG1", "f", 0.0),
    ("MAG2", "f", 0.0),
    ("NMETR", "i", 2),
    ("NAME", "s", ""),
    ("STAT", "i", 1),
]
_XF2 = [("R1-2", "f", 0.0), ("X1-2", "f", _REQ), ("SBASE1-2", "f", None)]
_XF2_3W = [
    ("R1-2", "f", 0.0),
    ("X1-2", "f", _REQ),
    ("SBASE1-2", "f", None),
    ("R2-3", "f", 0.0),
    ("X2-3", "f", _REQ),
    ("SBASE2-3", "f", None),
    ("R3-1", "f", 0.0),
    ("X3-1", "f", _REQ),
    ("SBASE3-1", "f", None),
    ("VMSTAR", "f", 1.0),
    ("ANSTAR", "f", 0.0),
]


def _winding(w: str) -> list:
    """The winding record of winding `w` (a transformer's lines 3, 4, 5)."""
    return [
        ("WINDV" + w, "f", None),
        ("NOMV" + w, "f", 0.0),
        ("ANG" + w, "f", 0.0),
        ("RATA" + w, "f", 0.0),
        ("RATB" + w, "f", 0.0),
        ("RATC" + w, "f", 0.0),
        ("COD" + w, "i", 0),
        ("CONT" + w, "i", 0),
        ("RMA" + w, "f", 1.1),
        ("RMI" + w, "f", 0.9),
        ("VMA" + w, "f", 1.1),
        ("VMI" + w, "f", 0.9),
        ("NTP" + w, "i", 33),
        ("TAB" + w, "i", 0),
        ("CR" + w, "f", 0.0),
        ("CX" + w, "f", 0.0),
    ]


# the records after line 1 of a two- and of a three-winding transformer
_XF_LINES = {
    2: (_XF2, _winding("1"), [("WINDV2", "f", None), ("NOMV2", "f", 0.0)]),
    3: (_XF2_3W, _winding("1"), _winding("2"), _winding("3")),
}
_SWSHUNT = [
    ("I", "i", _REQ),
    ("MODSW", "i", 1),
    ("ADJM", "i", 0),
    ("STAT", "i", 1),
    ("VSWHI", "f", 1.0),
    ("VSWLO", "f", 1.0),
    ("SWREM", "i", 0),
    ("RMPCT", "f", 100.0),
    ("RMIDNT", "s", ""),
    ("BINIT", "f", 0.0),
]

# The data categories of a v32/v33 raw file after the case identification, in file
# order, each ended by a record whose first field is 0. Reading stops after the
# switched shunts (GNE and induction machine data follow; they are not read).
_BLOCKS = (
    "bus",
    "load",
    "fixed shunt",
    "generator",
    "branch",
    "transformer",
    "area",
    "two-terminal dc",
    "vsc dc",
    "impedance correction",
    "multi-terminal dc",
    "multi-section line",
    "zone",
    "inter-area transfer",
    "owner",
    "facts",
    "switched shunt",
)
_LAYOUT = {
    "bus": _BUS,
    "load": _LOAD,
    "fixed shunt": _FSHUNT,
    "generator": _GEN,
    "branch": _BRANCH,
    "switched shunt": _SWSHUNT,
}
_VERSIONS = (32, 33, 34, 35)

# -- versions 34 and 35 (PSS/E 34 and 35 POM, checked against files PSS/E wrote:
# tests/data/psse/README.md). What differs from 33 in the records read here: a
# system-wide data section after the titles (GENERAL, GAUSS, NEWTON, ADJUST, TYSL,
# SOLVER, RATING records, ended by a 0 record), header lines `@!` anywhere, a branch
# NAME and 12 ratings, the system switching devices after the branches, 12 ratings
# per transformer winding, and in 35 the generator's NREG, the winding's NOD and the
# switched shunt's ID, SWREG and NREG.
_SYSTEM_WIDE = ("GENERAL", "GAUSS", "NEWTON", "ADJUST", "TYSL", "SOLVER", "RATING")
_RATES = [(f"RATE{k}", "f", 0.0) for k in range(1, 13)]
_BRANCH_34 = _BRANCH[:6] + [("NAME", "s", "")] + _RATES + _BRANCH[9:]
_SWITCH = (
    [("I", "i", _REQ), ("J", "i", _REQ), ("CKT", "s", "1"), ("X", "f", _REQ)]
    + _RATES
    + [("STAT", "i", 1), ("NSTAT", "i", 1), ("MET", "i", 1), ("STYPE", "i", 1)]
    + [("NAME", "s", "")]
)
_GEN_35 = _GEN[:8] + [("NREG", "i", 0)] + _GEN[8:]
_SWSHUNT_35 = [
    ("I", "i", _REQ),
    ("ID", "s", "1"),
    ("MODSW", "i", 1),
    ("ADJM", "i", 0),
    ("STAT", "i", 1),
    ("VSWHI", "f", 1.0),
    ("VSWLO", "f", 1.0),
    ("SWREG", "i", 0),
    ("NREG", "i", 0),
    ("RMPCT", "f", 100.0),
    ("RMIDNT", "s", ""),
    ("BINIT", "f", 0.0),
]


def _winding_34(w: str, nod: bool) -> list:
    """Winding w's record in versions 34 (nod False) and 35 (with NODw)."""
    old = _winding(w)  # WINDV NOMV ANG RATA RATB RATC COD CONT RMA ... CX
    rates = [(f"RATE{w}-{k}", "f", 0.0) for k in range(1, 13)]
    return old[:3] + rates + old[6:8] + ([("NOD" + w, "i", 0)] if nod else []) + old[8:]


def _layouts(version: int):
    """(blocks, record layouts, transformer lines) of a raw file version."""
    if version <= 33:
        return _BLOCKS, _LAYOUT, _XF_LINES
    nod = version >= 35
    blocks = _BLOCKS[:5] + ("switching device",) + _BLOCKS[5:]
    layout = dict(_LAYOUT, branch=_BRANCH_34)
    layout["switching device"] = _SWITCH
    if version >= 35:
        layout["generator"] = _GEN_35
        layout["switched shunt"] = _SWSHUNT_35
    xf = {
        2: (
            _XF2,
            _winding_34("1", nod),
            [("WINDV2", "f", None), ("NOMV2", "f", 0.0)],
        ),
        3: (_XF2_3W, *(_winding_34(w, nod) for w in "123")),
    }
    return blocks, layout, xf


def _number(tok: str, kind: str) -> float | int:
    v = float(tok)
    if not math.isfinite(v):  # nan, inf: refused like any other non-number
        raise ValueError
    if kind == "f":
        return v
    if v != int(v):
        raise ValueError
    return int(v)


def _record(fields, quoted, layout, where, what):
    rec: dict = {}
    for k, (name, kind, default) in enumerate(layout):
        tok = fields[k] if k < len(fields) else None
        if tok is None or (tok == "" and not quoted[k]):
            if default is _REQ:
                raise PsseError(
                    f"{where}: {what} field {name}: missing (it has no default)"
                )
            rec[name] = default
        elif kind == "s":
            rec[name] = tok
        else:
            try:
                if quoted[k]:
                    raise ValueError
                rec[name] = _number(tok, kind)
            except ValueError:
                noun = "a number" if kind == "f" else "an integer"
                raise PsseError(
                    f"{where}: {what} field {name}: {tok!r} is not {noun}"
                ) from None
    return rec


# --------------------------------------------------------------------- raw reader


def _refuse_foreign(path, what: str) -> None:
    """Raise `PsseError` if `path` is another program's format (MATPOWER, JSON, a
    spreadsheet) by its name or its first bytes; a missing file is left to `open`."""
    suffix = Path(str(path)).suffix.lower()
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return
    text = head.decode("utf-8", errors="replace").lstrip()
    fmt = None
    if head[:4] in (b"PK\x03\x04", b"\xd0\xcf\x11\xe0") or suffix in _SHEETS:
        fmt = "a spreadsheet (xlsx, xls)"
    elif suffix == ".json" or text[:1] in ("{", "["):
        fmt = "a JSON file"
    elif suffix == ".m" or _MATPOWER.search(text):
        fmt = "a MATPOWER case (.m)"
    if fmt:
        raise PsseError(
            f"{path}:1: this is {fmt}, not a PSS/E {what} file: smibjax reads PSS/E "
            "v32-v35 raw + dyr files"
        )


_SHEETS = (".xlsx", ".xls", ".xlsm", ".ods")
_MATPOWER = re.compile(
    r"^\s*function\s+mpc\s*=|^\s*mpc\.(baseMVA|bus|gen|branch)\b", re.M
)


@dataclass
class RawData:
    """The records of a PSS/E raw file as read (PSS/E units: MW, Mvar, kV, degrees;
    PSS/E's defaults filled in for blank trailing fields). Each record is a dict of
    PSS/E field names (upper case, as in the POM) plus `_line`, its line number in
    the file (the first line of a transformer record)."""

    path: str
    version: int
    sbase: float
    basfrq: float
    title: tuple[str, str]
    buses: list[dict] = field(default_factory=list)
    loads: list[dict] = field(default_factory=list)
    fixed_shunts: list[dict] = field(default_factory=list)
    generators: list[dict] = field(default_factory=list)
    branches: list[dict] = field(default_factory=list)
    transformers: list[dict] = field(default_factory=list)
    switched_shunts: list[dict] = field(default_factory=list)


_ATTR = {
    "bus": "buses",
    "load": "loads",
    "fixed shunt": "fixed_shunts",
    "generator": "generators",
    "branch": "branches",
    "transformer": "transformers",
    "switched shunt": "switched_shunts",
}


def read_raw(path) -> RawData:
    """Read a PSS/E raw file of version 32, 33, 34 or 35 (the records read here have
    the same fields in 32 and 33; 34 and 35: `_layouts`): case identification
    (SBASE, BASFRQ, two title lines), buses, loads, fixed shunts, generators,
    non-transformer branches, system switching devices (34, 35: read as branches of
    reactance X, j ZERO_Z where X = 0), two- and three-winding transformers (K != 0)
    and switched shunts. The system-wide data (34, 35), areas, dc lines, impedance
    corrections, multi-section lines, zones, transfers, owners and FACTS devices are
    skipped, and so are `@!` header lines; reading stops at the end of the switched
    shunt data or at `Q`. Another version, another program's format (MATPOWER,
    JSON, a spreadsheet), a malformed field or a record naming an unknown bus raises
    `PsseError`."""
    name = str(path)
    _refuse_foreign(path, "raw")
    with open(path, encoding="utf-8", errors="replace") as fh:
        lines = fh.read().splitlines()
    first = 0  # the case identification: the first line that is not a `@!` header
    while first < len(lines) and lines[first].lstrip().startswith("@!"):
        first += 1
    if first >= len(lines):
        raise PsseError(f"{name}:1: case identification: the file is empty")
    where = f"{name}:{first + 1}"
    f, q, _ = _split(lines[first], where)
    head = _record(
        f,
        q,
        [
            ("IC", "i", 0),
            ("SBASE", "f", 100.0),
            ("REV", "i", 33),
            ("XFRRAT", "f", 0.0),
            ("NXFRAT", "f", 0.0),
            ("BASFRQ", "f", 60.0),
        ],
        where,
        "case identification",
    )
    if head["REV"] not in _VERSIONS:
        raise PsseError(
            f"{where}: case identification field REV: version {head['REV']:.6g} is not "
            "supported (this reader reads PSS/E 32, 33, 34 and 35 raw files)"
        )
    if not (0 < head["SBASE"] < math.inf):
        what = "is not positive" if not head["SBASE"] > 0 else "is not finite"
        raise PsseError(
            f"{where}: case identification field SBASE: {head['SBASE']!r} {what}"
        )
    if not (0 <= head["BASFRQ"] < math.inf):
        what = "is not positive" if not head["BASFRQ"] > 0 else "is not finite"
        raise PsseError(
            f"{where}: case identification field BASFRQ: {head['BASFRQ']!r} {what} "
            "(0: the default, 60 Hz)"
        )
    title = tuple(
        (lines[k].rstrip() if k < len(lines) else "") for k in (first + 1, first + 2)
    )
    raw = RawData(
        path=name,
        version=head["REV"],
        sbase=float(head["SBASE"]),
        basfrq=float(head["BASFRQ"]) or 60.0,
        title=title,
    )
    blocks, layouts, xf_lines = _layouts(raw.version)

    block = 0
    k = first + 3
    system_wide = raw.version >= 34  # until its 0 record (or the first bus record)
    while k < len(lines) and block < len(blocks):
        lineno = k + 1
        where = f"{name}:{lineno}"
        text = lines[k]
        k += 1
        if text.lstrip().startswith("@!"):
            continue  # a header line (34, 35)
        f, q, _ = _split(text, where)
        if not f or (len(f) == 1 and f[0] is None):
            continue  # blank or comment-only line
        if system_wide:
            if not q[0] and str(f[0]).upper() in _SYSTEM_WIDE:
                continue
            system_wide = False
            if f[0] == "0" and not q[0]:
                continue  # the end of the system-wide data
        if f[0] == "Q" and not q[0]:
            break
        if f[0] == "0" and not q[0]:
            block += 1
            continue
        kind = blocks[block]
        if kind == "transformer":
            rec = _record(f, q, _XF1, where, "transformer")
            rest = xf_lines[2 if rec["K"] == 0 else 3]
            if k + len(rest) > len(lines):
                n = 2 if rec["K"] == 0 else 3
                raise PsseError(
                    f"{where}: transformer record ends early (a {n}-winding record has "
                    f"{len(rest) + 1} lines)"
                )
            for layout in rest:
                w = f"{name}:{k + 1}"
                f2, q2, _ = _split(lines[k], w)
                rec.update(_record(f2, q2, layout, w, "transformer"))
                k += 1
        elif kind == "switching device":
            sw = _record(f, q, layouts[kind], where, "switching device")
            # a branch of reactance X, no resistance or charging (a tie where X = 0)
            rec = {n: d for n, _, d in _BRANCH if d is not _REQ}
            rec.update(I=sw["I"], J=sw["J"], CKT=sw["CKT"], ST=sw["STAT"])
            rec.update(X=sw["X"] if sw["X"] != 0.0 else ZERO_Z, R=0.0)
            rec["_switch"] = True
            kind = "branch"
        elif kind in layouts:
            rec = _record(f, q, layouts[kind], where, kind)
        else:
            continue  # a category this reader skips
        rec["_line"] = lineno
        getattr(raw, _ATTR[kind]).append(rec)
    _fill_and_check(raw)
    return raw


MAX_BUS = 999_999
"""The largest bus number (PSS/E's is 999,997)."""


def _short(x) -> str:
    """A number as written in a one-line message: at most 12 significant digits."""
    return f"{x:.12g}" if abs(x) >= 1e12 else str(x)


def _fill_and_check(raw: RawData) -> None:
    """Fill the defaults that depend on other data and check the bus references."""
    name = raw.path
    buses = {}
    for b in raw.buses:
        if not 1 <= b["I"] <= MAX_BUS:
            raise PsseError(
                f"{name}:{b['_line']}: bus field I: {_short(b['I'])} is not a bus "
                f"number (1 to {MAX_BUS})"
            )
        if b["I"] in buses:
            raise PsseError(
                f"{name}:{b['_line']}: bus field I: bus {b['I']} is already defined "
                f"on line {buses[b['I']]['_line']}"
            )
        buses[b["I"]] = b

    def known(rec, what, fld):
        n = abs(rec[fld])
        if n not in buses:
            raise PsseError(
                f"{name}:{rec['_line']}: {what} field {fld}: bus {rec[fld]} is not in "
                "the bus data"
            )
        return n

    for r in raw.loads:
        bus = buses[known(r, "load", "I")]
        for fld in ("AREA", "ZONE", "OWNER"):
            if r[fld] is None:
                r[fld] = bus[fld]
    for r in raw.fixed_shunts:
        known(r, "fixed shunt", "I")
    for r in raw.switched_shunts:
        known(r, "switched shunt", "I")
    for r in raw.generators:
        known(r, "generator", "I")
        if r["MBASE"] is None:
            r["MBASE"] = raw.sbase
        if not 0 < r["MBASE"] < math.inf:
            raise PsseError(
                f"{name}:{r['_line']}: generator field MBASE: {r['MBASE']!r} is not positive"
            )
        if not 0 < r["VS"] < math.inf:  # a power flow from 0 V has no solution
            raise PsseError(
                f"{name}:{r['_line']}: generator field VS: {r['VS']!r} is not a "
                "positive voltage set point (pu)"
            )
    for r in raw.branches:
        known(r, "branch", "I")
        r["J"] = known(r, "branch", "J")  # a negative J marks the metered end
        if r["R"] == 0.0 and r["X"] == 0.0:
            raise PsseError(
                f"{name}:{r['_line']}: branch field X: zero impedance (R = X = 0) is "
                "not supported"
            )
    for r in raw.transformers:
        line = r["_line"]
        three = r["K"] != 0
        windings = [("1", "I", 2), ("2", "J", 3)] + ([("3", "K", 4)] if three else [])
        for _, fld, _ in windings:
            r[fld] = known(
                r, "transformer", fld
            )  # a negative bus marks the metered end
        for fld, hi in (("CW", 3), ("CZ", 3), ("CM", 2)):
            if r[fld] not in range(1, hi + 1):
                raise PsseError(
                    f"{name}:{line}: transformer field {fld}: {r[fld]} is not one of "
                    f"{', '.join(str(v) for v in range(1, hi + 1))}"
                )
        stats = (0, 1, 2, 3, 4) if three else (0, 1)
        if r["STAT"] not in stats:
            raise PsseError(
                f"{name}:{line}: transformer field STAT: {r['STAT']} is not one of "
                f"{', '.join(str(v) for v in stats)}"
            )
        for pair in ("1-2", "2-3", "3-1") if three else ("1-2",):
            if r["SBASE" + pair] is None:
                r["SBASE" + pair] = raw.sbase
            if r["SBASE" + pair] <= 0:
                raise PsseError(
                    f"{name}:{line + 1}: transformer field SBASE{pair}: "
                    f"{r['SBASE' + pair]!r} is not positive"
                )
        for w, fld, off in windings:
            bus_no = r[fld]
            if r["CW"] != 1 or (r["CM"] == 2 and w == "1"):
                if buses[bus_no]["BASKV"] <= 0:
                    raise PsseError(
                        f"{name}:{line}: transformer field CW: CW = {r['CW']}, CM = "
                        f"{r['CM']} need the base kV of bus {bus_no}, which is "
                        f"{buses[bus_no]['BASKV']}"
                    )
            if r["WINDV" + w] is None:  # POM: 1.0 for CW = 1, 3; NOMV for CW = 2
                nomv = r["NOMV" + w] or buses[bus_no]["BASKV"]
                r["WINDV" + w] = nomv if r["CW"] == 2 else 1.0
            if r["WINDV" + w] == 0.0:
                raise PsseError(
                    f"{name}:{line + off}: transformer field WINDV{w}: 0 is not a "
                    "winding ratio"
                )


# --------------------------------------------------------------------- to System


def _ratio(r: dict, w: str, vb: float) -> float:
    """Winding w's off-nominal ratio t_w in pu of its bus base voltage `vb` (kV)."""
    windv = r["WINDV" + w]
    if r["CW"] == 1:  # off-nominal ratio in pu of the bus base voltage
        return windv
    if r["CW"] == 2:  # winding voltage in kV
        return windv / vb
    return windv * (r["NOMV" + w] or vb) / vb  # pu of NOMV; NOMV = 0: the bus base kV


def _impedance(r: dict, pair: str, sbase: float, where: str) -> complex:
    """The impedance between windings `pair` ("1-2", ...) in pu on the system base."""
    s_w = r["SBASE" + pair]
    rr, xx = r["R" + pair], r["X" + pair]
    if r["CZ"] == 2:  # pu on the winding MVA base SBASEi-j
        rr, xx = rr * sbase / s_w, xx * sbase / s_w
    elif r["CZ"] == 3:  # load loss in W and |Z| in pu on SBASEi-j
        rw = rr / (1e6 * s_w)
        if abs(xx) < rw:
            raise PsseError(
                f"{where}: transformer field X{pair}: |Z| = {xx!r} is below R = {rw!r} "
                "from the load loss (CZ = 3)"
            )
        xw = math.copysign(math.sqrt(xx * xx - rw * rw), xx)
        rr, xx = rw * sbase / s_w, xw * sbase / s_w
    return complex(rr, xx)


def _magnetizing(r: dict, vb1: float, sbase: float, where: str) -> complex:
    """The magnetizing admittance G + jB at bus I in pu on the system base."""
    if r["CM"] == 1:  # pu on the system base and bus I's base voltage
        return complex(r["MAG1"], r["MAG2"])
    # CM = 2: no-load loss in W, exciting current in pu on SBASE1-2 and NOMV1
    k = (vb1 / (r["NOMV1"] or vb1)) ** 2
    g = r["MAG1"] / (1e6 * sbase) * k
    y = abs(r["MAG2"]) * r["SBASE1-2"] / sbase * k
    if y < g:
        raise PsseError(
            f"{where}: transformer field MAG2: exciting current {r['MAG2']!r} is "
            "below the no-load loss's conductance (CM = 2)"
        )
    return complex(g, -math.sqrt(y * y - g * g))


def _transformer(r: dict, vb1: float, vb2: float, sbase: float, where: str):
    """A two-winding transformer as (r, x, tap, shift, y_m) on the system base.

    PSS/E's model (POM 33, two-winding transformer data): bus I, the magnetizing
    admittance y_m = G + jB at bus I, an ideal transformer t1 e^{j ANG1} : 1, the
    impedance R + jX, an ideal 1 : t2, bus J; t1, t2 in pu of the bus base voltages.
    Moving t2 to the from side gives the branch tap t1/t2, shift ANG1 and impedance
    (R + jX) t2^2.
    """
    t1, t2 = _ratio(r, "1", vb1), _ratio(r, "2", vb2)
    z = _impedance(r, "1-2", sbase, where) * t2 * t2
    if z == 0:
        raise PsseError(
            f"{where}: transformer field X1-2: zero impedance (R = X = 0) is not supported"
        )
    y_m = _magnetizing(r, vb1, sbase, where)
    return z.real, z.imag, t1 / t2, math.radians(r["ANG1"]), y_m


def _three_winding(r: dict, vb: tuple, sbase: float, where: str):
    """A three-winding transformer as three branches from its buses to a star point:
    [(r, x, tap, shift) of windings 1, 2, 3] and the magnetizing admittance at bus I.

    PSS/E's model (POM 33, three-winding transformer data): winding w is bus w, an
    ideal transformer t_w e^{j ANGw} : 1, the star impedance Z_w, the star point;
    Z_1 = (Z12 + Z31 - Z23) / 2, Z_2 = (Z12 + Z23 - Z31) / 2,
    Z_3 = (Z23 + Z31 - Z12) / 2, each Z_ij on the system base; a zero Z_w (|Z_w| <
    1e-12 pu) is a tie of j ZERO_Z.
    """
    z12, z23, z31 = (_impedance(r, p, sbase, where) for p in ("1-2", "2-3", "3-1"))
    zs = ((z12 + z31 - z23) / 2, (z12 + z23 - z31) / 2, (z23 + z31 - z12) / 2)
    legs = []
    for w, z in zip("123", zs, strict=True):
        if abs(z) < 1e-12:  # zero up to the rounding of the three pair impedances
            z = complex(0.0, ZERO_Z)  # a tie
        legs.append(
            (z.real, z.imag, _ratio(r, w, vb[int(w) - 1]), math.radians(r["ANG" + w]))
        )
    return legs, _magnetizing(r, vb[0], sbase, where)


def to_system(raw: RawData, *, var_limited: bool = False) -> System:
    """Convert `RawData` to a `System`: per unit on SBASE, angles in rad, bus positions
    for bus numbers. Conventions (docs/psse.md):

    - branches and generators out of service are kept with status 0; out-of-service
      loads, fixed shunts and switched shunts are dropped (the System has no status
      for them);
    - loads: constant power PL + j QL (+ IP, IQ times the raw file's VM, with a
      warning: constant-current loads are converted to constant power at the case's
      voltage); the constant-admittance part YP + j YQ becomes a shunt
      g + j b = (YP + j YQ) / SBASE (YQ < 0 inductive);
    - fixed shunts (GL + j BL) / SBASE, switched shunts j BINIT / SBASE;
    - line-end shunts GI + j BI, GJ + j BJ of in-service branches become shunts at
      their buses; a transformer's magnetizing admittance becomes a shunt at bus I;
    - a three-winding transformer's star leg of zero impedance (Z12 + Z23 = Z31 and
      its rotations) is a tie of impedance j ZERO_Z = 1e-4 pu (PSS/E's zero-impedance
      threshold THRSHZ; PSS/E merges the two buses, ANDES adds 1e-8 to r and x); a
      branch record with R = X = 0 is refused;
    - two-winding transformers: one branch (`_transformer`); three-winding
      transformers: a star point bus (number: one above the largest bus number, in
      file order; type 1, or 4 when the transformer is out of service; VMSTAR,
      ANSTAR; base kV NOMV1 or bus I's) and three branches from the winding buses to
      it (`_three_winding`), a winding out of service (STAT 2, 3, 4) as status 0;
    - `var_limited` (a raw file that holds PSS/E's solved case, as ACTIVSg2000's
      does; issue 45): a generator bus (type 2) whose in-service generators all sit
      at a reactive limit (QG = QT or QB, to 1e-3 Mvar) and whose voltage VM is not
      their set point VS (by more than 1e-4 pu) is a PQ bus (type 1) holding their
      QG: PSS/E's var-limited generator, so that the power flow returns the file's
      own solution (`_var_limited`). Off by default: a raw file that is not a
      solution (ANDES's IEEE 14 has QG = QT with VM far from VS) keeps its types.
    """
    sb = raw.sbase
    bus_rec = list(raw.buses)
    if var_limited:
        bus_rec = _var_limited(raw)
    star_numbers = {}
    top = max((b["I"] for b in raw.buses), default=0)
    by_number = {b["I"]: b for b in raw.buses}
    for r in raw.transformers:
        if r["K"] == 0:
            continue
        top += 1
        star_numbers[id(r)] = top
        bus_rec.append(
            {
                "I": top,
                "NAME": f"STAR {r['I']}-{r['J']}-{r['K']} {r['CKT']}",
                "BASKV": r["NOMV1"] or by_number[r["I"]]["BASKV"],
                "IDE": 4 if r["STAT"] == 0 else 1,
                "AREA": by_number[r["I"]]["AREA"],
                "VM": r["VMSTAR"],
                "VA": r["ANSTAR"],
            }
        )
    number = np.array([b["I"] for b in bus_rec], dtype=np.int64)
    pos = {int(n): k for k, n in enumerate(number)}
    kv = {b["I"]: b["BASKV"] for b in bus_rec}
    vm = {b["I"]: b["VM"] for b in bus_rec}
    buses = Buses(
        number=number,
        kind=[b["IDE"] for b in bus_rec],
        vm=[b["VM"] for b in bus_rec],
        va=[math.radians(b["VA"]) for b in bus_rec],
        base_kv=[b["BASKV"] for b in bus_rec],
        area=[b["AREA"] for b in bus_rec],
        name=tuple(b["NAME"] for b in bus_rec),
    )

    sh_bus, sh_g, sh_b = [], [], []

    def shunt(bus, g, b, keep_zero=False):
        if keep_zero or g != 0.0 or b != 0.0:
            sh_bus.append(pos[bus])
            sh_g.append(g)
            sh_b.append(b)

    br = {
        k: []
        for k in ("fr", "to", "r", "x", "b", "tap", "shift", "status", "xf", "ckt")
    }

    def branch(fr, to, r, x, b, tap, shift, status, xf, ckt):
        for key, v in zip(
            br, (pos[fr], pos[to], r, x, b, tap, shift, status, xf, ckt), strict=True
        ):
            br[key].append(v)

    for r in raw.branches:
        on = 1.0 if r["ST"] != 0 else 0.0
        branch(r["I"], r["J"], r["R"], r["X"], r["B"], 1.0, 0.0, on, 0, r["CKT"])
        if on:
            shunt(r["I"], r["GI"], r["BI"])
            shunt(r["J"], r["GJ"], r["BJ"])
    for r in raw.transformers:
        where = f"{raw.path}:{r['_line'] + 1}"
        if r["K"] == 0:
            rr, xx, tap, shift, y_m = _transformer(r, kv[r["I"]], kv[r["J"]], sb, where)
            on = 1.0 if r["STAT"] != 0 else 0.0
            branch(r["I"], r["J"], rr, xx, 0.0, tap, shift, on, 1, r["CKT"])
        else:
            vb = (kv[r["I"]], kv[r["J"]], kv[r["K"]])
            legs, y_m = _three_winding(r, vb, sb, where)
            star = star_numbers[id(r)]
            # STAT: 0 all windings out, 1 all in, 2 winding 2 out, 3 winding 3 out,
            # 4 winding 1 out
            out = {0: "123", 1: "", 2: "2", 3: "3", 4: "1"}[r["STAT"]]
            for w, fld, (rr, xx, tap, shift) in zip("123", "IJK", legs, strict=True):
                on = 0.0 if w in out else 1.0
                branch(r[fld], star, rr, xx, 0.0, tap, shift, on, 1, r["CKT"])
            on = 0.0 if "1" in out else 1.0
        if on:
            shunt(r["I"], y_m.real, y_m.imag)

    ld_bus, ld_p, ld_q, ld_id, ld_pi, ld_qi = [], [], [], [], [], []
    current = []
    for r in raw.loads:
        if r["STATUS"] == 0:
            continue
        v = vm[r["I"]]
        if r["IP"] != 0.0 or r["IQ"] != 0.0:
            current.append(r)
        ld_bus.append(pos[r["I"]])
        ld_p.append((r["PL"] + r["IP"] * v) / sb)
        ld_q.append((r["QL"] + r["IQ"] * v) / sb)
        ld_id.append(r["ID"])
        ld_pi.append(r["IP"] * v / sb)
        ld_qi.append(r["IQ"] * v / sb)
        shunt(r["I"], r["YP"] / sb, r["YQ"] / sb)
    if current:
        first = current[0]
        warnings.warn(
            f"{raw.path}:{first['_line']}: {len(current)} load(s) with a constant-current "
            "part (IP, IQ) converted to constant power at the raw file's bus voltage VM "
            "in the power flow (kept as constant current under a load model)",
            stacklevel=2,
        )
    for r in raw.fixed_shunts:
        if r["STATUS"] != 0:
            shunt(r["I"], r["GL"] / sb, r["BL"] / sb, keep_zero=True)
    for r in raw.switched_shunts:
        if r["STAT"] != 0:
            shunt(r["I"], 0.0, r["BINIT"] / sb, keep_zero=True)

    gens = raw.generators
    remote = [g for g in gens if g["IREG"] not in (0, g["I"])]
    if remote:
        warnings.warn(
            f"{raw.path}:{remote[0]['_line']}: {len(remote)} generator(s) regulate a "
            "remote bus (IREG); the System holds VS as the set point of the "
            "generator's own bus",
            stacklevel=2,
        )
    system = System(
        buses=buses,
        branches=Branches(
            fr=np.array(br["fr"], dtype=np.int64),
            to=np.array(br["to"], dtype=np.int64),
            r=br["r"],
            x=br["x"],
            b=br["b"],
            tap=br["tap"],
            shift=br["shift"],
            status=br["status"],
            is_transformer=np.array(br["xf"], dtype=np.int64),
            ckt=tuple(br["ckt"]),
        ),
        shunts=Shunts(bus=np.array(sh_bus, dtype=np.int64), g=sh_g, b=sh_b),
        loads=Loads(
            bus=np.array(ld_bus, dtype=np.int64),
            p=ld_p,
            q=ld_q,
            ident=tuple(ld_id),
            p_i=ld_pi,
            q_i=ld_qi,
        ),
        generators=Generators(
            bus=np.array([pos[g["I"]] for g in gens], dtype=np.int64),
            p=[g["PG"] / sb for g in gens],
            q=[g["QG"] / sb for g in gens],
            v_set=[g["VS"] for g in gens],
            qmin=[g["QB"] / sb for g in gens],
            qmax=[g["QT"] / sb for g in gens],
            mbase=[g["MBASE"] for g in gens],
            status=[1.0 if g["STAT"] != 0 else 0.0 for g in gens],
            ident=tuple(g["ID"] for g in gens),
            zsource=[complex(g["ZR"], g["ZX"]) for g in gens],
        ),
        s_base=sb,
        f_base=raw.basfrq,
        name=" / ".join(t.strip() for t in raw.title if t.strip()),
    )
    return system


def _var_limited(raw: RawData) -> list[dict]:
    """The raw file's bus records, the generator buses at a reactive limit in the
    file's solution turned into PQ buses (`to_system`'s `var_limited`)."""
    gens: dict[int, list[dict]] = {}
    for g in raw.generators:
        if g["STAT"] != 0:
            gens.setdefault(g["I"], []).append(g)
    out = []
    for b in raw.buses:
        on = gens.get(b["I"], [])
        limited = (
            b["IDE"] == 2
            and on
            and all(
                min(abs(g["QG"] - g["QT"]), abs(g["QG"] - g["QB"])) <= 1e-3 for g in on
            )
            and all(abs(b["VM"] - g["VS"]) > 1e-4 for g in on)
        )
        out.append({**b, "IDE": 1} if limited else b)
    return out


# ---------------------------------------------------------------------- dyr reader

_DC_EXCITER = (
    "TR",
    "KA",
    "TA",
    "TB",
    "TC",
    "VRMAX",
    "VRMIN",
    "KE",
    "TE",
    "KF",
    "TF1",
    "SWITCH",
    "E1",
    "SE1",
    "E2",
    "SE2",
)

# GENSAL's and GENSAE's CONs (PSS/E Model Library): no q-axis transient circuit
_SALIENT = (
    "Tdo_p",
    "Tdo_pp",
    "Tqo_pp",
    "H",
    "D",
    "Xd",
    "Xq",
    "Xd_p",
    "Xd_pp",
    "Xl",
    "S10",
    "S12",
)

DYR_MODELS: dict[str, tuple[str, ...]] = {
    "GENCLS": ("H", "D"),
    "GENTRA": ("Tdo_p", "H", "D", "Xd", "Xq", "Xd_p", "S10", "S12"),
    "GENROU": (
        "Tdo_p",
        "Tdo_pp",
        "Tqo_p",
        "Tqo_pp",
        "H",
        "D",
        "Xd",
        "Xq",
        "Xd_p",
        "Xq_p",
        "Xd_pp",
        "Xl",
        "S10",
        "S12",
    ),
    # machines of issue 45
    "GENROE": (
        "Tdo_p",
        "Tdo_pp",
        "Tqo_p",
        "Tqo_pp",
        "H",
        "D",
        "Xd",
        "Xq",
        "Xd_p",
        "Xq_p",
        "Xd_pp",
        "Xl",
        "S10",
        "S12",
    ),
    "GENSAL": _SALIENT,
    "GENSAE": _SALIENT,
    "SEXS": ("TA_TB", "TB", "K", "TE", "EMIN", "EMAX"),
    "IEEEX1": _DC_EXCITER,
    "EXDC2": _DC_EXCITER,
    "EXST1": (
        "TR",
        "VIMAX",
        "VIMIN",
        "TC",
        "TB",
        "KA",
        "TA",
        "VRMAX",
        "VRMIN",
        "KC",
        "KF",
        "TF",
    ),
    "IEEEST": (
        "ICS",
        "IB",
        "A1",
        "A2",
        "A3",
        "A4",
        "A5",
        "A6",
        "T1",
        "T2",
        "T3",
        "T4",
        "T5",
        "T6",
        "KS",
        "LSMAX",
        "LSMIN",
        "VCU",
        "VCL",
    ),
    "STAB1": ("K_T", "T", "T1_T3", "T3", "T2_T4", "T4", "HLIM"),
    "TGOV1": ("R", "T1", "VMAX", "VMIN", "T2", "T3", "Dt"),
    "CSVGN1": ("K", "T1", "T2", "T3", "T4", "T5", "RMIN", "VMAX", "VMIN", "CBASE"),
    # --- exciters and the compensator IEEEVC (issue 45; devices/esst3a.py,
    # esdc2a.py, scrx.py, ieeet2.py, ieeevc.py). Source: PSS/E Model Library; the
    # same order as ANDES 2.0's psse-dyr.yaml and OpenIPSL's PSSE library
    "ESST3A": (
        "TR",
        "VIMAX",
        "VIMIN",
        "KM",
        "TC",
        "TB",
        "KA",
        "TA",
        "VRMAX",
        "VRMIN",
        "KG",
        "KP",
        "KI",
        "VBMAX",
        "KC",
        "XL",
        "VGMAX",
        "THETAP",
        "TM",
        "VMMAX",
        "VMMIN",
    ),
    "ESDC2A": _DC_EXCITER,
    "SCRX": ("TA_TB", "TB", "K", "TE", "EMIN", "EMAX", "CSWITCH", "rc_rfd"),
    "IEEET2": (
        "TR",
        "KA",
        "TA",
        "VRMAX",
        "VRMIN",
        "KE",
        "TE",
        "KF",
        "TF1",
        "TF2",
        "E1",
        "SE1",
        "E2",
        "SE2",
    ),
    "IEEEVC": ("RC", "XC"),
    "ESDC1A": _DC_EXCITER,
    "IEEET1": (
        "TR",
        "KA",
        "TA",
        "VRMAX",
        "VRMIN",
        "KE",
        "TE",
        "KF",
        "TF",
        "SWITCH",
        "E1",
        "SE1",
        "E2",
        "SE2",
    ),
    # --- end of the issue-45 exciters
    # --- issue-45 exciters, part 2 (devices/esst4b.py, esst1a.py, exac1.py,
    # exac2.py). PSS/E Model Library CON order, as the ACTIVSg2000 and Australian
    # 14-generator records fit it (ANDES 2.0's psse-dyr.yaml lists ESST1A's and
    # ESAC1A's in other orders, which those records do not fit); ESST1A's two
    # ICONs first, as PSS/E writes them
    "ESST4B": (
        "TR",
        "KPR",
        "KIR",
        "VRMAX",
        "VRMIN",
        "TA",
        "KPM",
        "KIM",
        "VMMAX",
        "VMMIN",
        "KG",
        "KP",
        "KI",
        "VBMAX",
        "KC",
        "XL",
        "THETAP",
    ),
    "ESST1A": (
        "UEL",
        "VOS",
        "TR",
        "VIMAX",
        "VIMIN",
        "TC",
        "TB",
        "TC1",
        "TB1",
        "KA",
        "TA",
        "VAMAX",
        "VAMIN",
        "VRMAX",
        "VRMIN",
        "KC",
        "KF",
        "TF",
        "KLR",
        "ILR",
    ),
    "EXAC1": (
        "TR",
        "TB",
        "TC",
        "KA",
        "TA",
        "VRMAX",
        "VRMIN",
        "TE",
        "KF",
        "TF",
        "KC",
        "KD",
        "KE",
        "E1",
        "SE1",
        "E2",
        "SE2",
    ),
    "ESAC1A": (
        "TR",
        "TB",
        "TC",
        "KA",
        "TA",
        "VAMAX",
        "VAMIN",
        "TE",
        "KF",
        "TF",
        "KC",
        "KD",
        "KE",
        "E1",
        "SE1",
        "E2",
        "SE2",
        "VRMAX",
        "VRMIN",
    ),
    "EXAC2": (
        "TR",
        "TB",
        "TC",
        "KA",
        "TA",
        "VAMAX",
        "VAMIN",
        "KB",
        "VRMAX",
        "VRMIN",
        "TE",
        "KL",
        "KH",
        "KF",
        "TF",
        "KC",
        "KD",
        "KE",
        "VLR",
        "E1",
        "SE1",
        "E2",
        "SE2",
    ),
    "EXPIC1": (
        "TR",
        "KA",
        "TA1",
        "VR1",
        "VR2",
        "TA2",
        "TA3",
        "TA4",
        "VRMAX",
        "VRMIN",
        "KF",
        "TF1",
        "TF2",
        "EFDMAX",
        "EFDMIN",
        "KE",
        "TE",
        "E1",
        "SE1",
        "E2",
        "SE2",
        "KP",
        "KI",
        "KC",
    ),
    "ESAC6A": (
        "TR",
        "KA",
        "TA",
        "TK",
        "TB",
        "TC",
        "VAMAX",
        "VAMIN",
        "VRMAX",
        "VRMIN",
        "TE",
        "VFELIM",
        "KH",
        "VHMAX",
        "TH",
        "TJ",
        "KC",
        "KD",
        "KE",
        "E1",
        "SE1",
        "E2",
        "SE2",
    ),
    "DC4B": (
        "UEL",
        "OEL",
        "TR",
        "KP",
        "KI",
        "KD",
        "TD",
        "VRMAX",
        "VRMIN",
        "KA",
        "TA",
        "KE",
        "TE",
        "KF",
        "TF",
        "VEMIN",
        "E1",
        "SE1",
        "E2",
        "SE2",
    ),
    # --- end of the issue-45 exciters, part 2
    # smibjax-specific, not a PSS/E model: the paper's synergetic excitation law on
    # a local SMIB equivalent (devices/synex.py)
    "SYNEX": (
        "XE",
        "XD",
        "XDP",
        "TDOP",
        "H",
        "D",
        "BETA",
        "T1",
        "ALPHA",
        "C",
        "EMIN",
        "EMAX",
    ),
    # governors and stabilizers of issue 45 (PSS/E 33 Model Library CON order; the
    # ICONs first, as PSS/E writes them: IEEEG1's JBUS, M; ST2CUT's ICS1, IB1, ICS2,
    # IB2; PSS2A/B's ICS1, IB1, ICS2, IB2, M, N)
    "IEEEG1": (
        "JBUS",
        "M",
        "K",
        "T1",
        "T2",
        "T3",
        "UO",
        "UC",
        "PMAX",
        "PMIN",
        "T4",
        "K1",
        "K2",
        "T5",
        "K3",
        "K4",
        "T6",
        "K5",
        "K6",
        "T7",
        "K7",
        "K8",
    ),
    "HYGOV": (
        "R",
        "r",
        "Tr",
        "Tf",
        "Tg",
        "VELM",
        "GMAX",
        "GMIN",
        "TW",
        "At",
        "Dturb",
        "qNL",
    ),
    "IEESGO": (
        "T1",
        "T2",
        "T3",
        "T4",
        "T5",
        "T6",
        "K1",
        "K2",
        "K3",
        "PMAX",
        "PMIN",
    ),
    "ST2CUT": (
        "ICS1",
        "IB1",
        "ICS2",
        "IB2",
        "K1",
        "K2",
        "T1",
        "T2",
        "T3",
        "T4",
        "T5",
        "T6",
        "T7",
        "T8",
        "T9",
        "T10",
        "LSMAX",
        "LSMIN",
        "VCU",
        "VCL",
    ),
    "STAB2A": ("K2", "T2", "K3", "T3", "K4", "K5", "T5", "HLIM"),
    "GAST": ("R", "T1", "T2", "T3", "AT", "KT", "VMAX", "VMIN", "Dturb"),
    "PSS2A": (
        "ICS1",
        "IB1",
        "ICS2",
        "IB2",
        "M",
        "N",
        "TW1",
        "TW2",
        "T6",
        "TW3",
        "TW4",
        "T7",
        "KS2",
        "KS3",
        "T8",
        "T9",
        "KS1",
        "T1",
        "T2",
        "T3",
        "T4",
        "VSTMAX",
        "VSTMIN",
    ),
    "PSS2B": (
        "ICS1",
        "IB1",
        "ICS2",
        "IB2",
        "M",
        "N",
        "TW1",
        "TW2",
        "T6",
        "TW3",
        "TW4",
        "T7",
        "KS2",
        "KS3",
        "T8",
        "T9",
        "KS1",
        "T1",
        "T2",
        "T3",
        "T4",
        "T10",
        "T11",
        "VS1MAX",
        "VS1MIN",
        "VS2MAX",
        "VS2MIN",
        "VSTMAX",
        "VSTMIN",
    ),
    # issue 45 (GGOV1, devices/ggov1.py): PSS/E Model Library CON order, the ICONs
    # Rselect and Flag first, as PSS/E writes them
    "GGOV1": (
        "Rselect",
        "Flag",
        "R",
        "Tpelec",
        "maxerr",
        "minerr",
        "Kpgov",
        "Kigov",
        "Kdgov",
        "Tdgov",
        "Vmax",
        "Vmin",
        "Tact",
        "Kturb",
        "Wfnl",
        "Tb",
        "Tc",
        "Teng",
        "Tfload",
        "Kpload",
        "Kiload",
        "Ldref",
        "Dm",
        "Ropen",
        "Rclose",
        "Kimw",
        "Aset",
        "Ka",
        "Ta",
        "Trate",
        "db",
        "Tsa",
        "Tsb",
        "Rup",
        "Rdown",
    ),
    # --- issue 47: inverter-based resources (WECC second-generation renewable
    # models, PSS/E 33 Model Library; the ICONs first, as PSS/E writes them, in the
    # order of ANDES 2.0's andes/io/psse-dyr.yaml)
    "REGCA1": (
        "LVPLSW",
        "Tg",
        "Rrpwr",
        "Brkpt",
        "Zerox",
        "Lvpl1",
        "Volim",
        "Lvpnt1",
        "Lvpnt0",
        "Iolim",
        "Tfltr",
        "Khv",
        "Iqrmax",
        "Iqrmin",
        "Accel",
    ),
    "REECB1": (
        "BUSR",
        "PFFLAG",
        "VFLAG",
        "QFLAG",
        "PQFLAG",
        "Vdip",
        "Vup",
        "Trv",
        "dbd1",
        "dbd2",
        "Kqv",
        "Iqh1",
        "Iql1",
        "Vref0",
        "Tp",
        "Qmax",
        "Qmin",
        "Vmax",
        "Vmin",
        "Kqp",
        "Kqi",
        "Kvp",
        "Kvi",
        "Tiq",
        "dPmax",
        "dPmin",
        "Pmax",
        "Pmin",
        "Imax",
        "Tpord",
    ),
    "REPCA1": (
        "IREG",
        "BRCH_FROM",
        "BRCH_TO",
        "CKT",
        "VCFlag",
        "RefFlag",
        "Fflag",
        "Tfltr",
        "Kp",
        "Ki",
        "Tft",
        "Tfv",
        "Vfrz",
        "Rc",
        "Xc",
        "Kc",
        "emax",
        "emin",
        "dbd1",
        "dbd2",
        "Qmax",
        "Qmin",
        "Kpg",
        "Kig",
        "Tp",
        "fdbd1",
        "fdbd2",
        "femax",
        "femin",
        "Pmax",
        "Pmin",
        "Tlag",
        "Ddn",
        "Dup",
    ),
    # --- end of issue 47's inverter-based resources
}
"""The dyr models read, each with its parameter names in the order of the dyr record
(the PSS/E CON order; IEEEST's two ICONs, the input signal code ICS and the remote bus
IB, come first, as PSS/E writes them). Source: PSS/E 33 Model Library (GENCLS, GENTRA,
GENROU, SEXS, IEEEX1, EXDC2, EXST1, IEEEST, STAB1, TGOV1, CSVGN1), checked against
ANDES 2.0's andes/io/psse-dyr.yaml, which has the same order for every model it reads
(it has no GENTRA, STAB1 or CSVGN1). GENROE has GENROU's CONs; GENSAL and GENSAE
(not in ANDES) PSS/E's 12 CONs, as in ANDES's nordic44/N44_BC.dyr. SYNEX is
smibjax's own record (no PSS/E or ANDES model): the paper's synergetic excitation
law as a decentralized exciter (`devices.synex`). Names: `_p` a prime (Xd_p = X'd, Tdo_p = T'do),
`_pp` a double prime, `A_B` a ratio A/B; S10, S12 the saturation S(1.0), S(1.2)."""

DYR_KINDS: dict[str, str] = {
    "GENCLS": "machine",
    "GENTRA": "machine",
    "GENROU": "machine",
    # issue 45
    "GENROE": "machine",
    "GENSAL": "machine",
    "GENSAE": "machine",
    "CSVGN1": "machine",  # PSS/E models an SVC as a machine on a generator record
    "SEXS": "exciter",
    "IEEEX1": "exciter",
    "EXDC2": "exciter",
    "EXST1": "exciter",
    "SYNEX": "exciter",
    "IEEEST": "pss",
    "STAB1": "pss",
    "TGOV1": "governor",
    # --- issue-45 exciters and the compensator
    "ESST3A": "exciter",
    "ESDC2A": "exciter",
    "SCRX": "exciter",
    "IEEET2": "exciter",
    "IEEEVC": "compensator",  # in front of the exciter: changes what it regulates
    "ESDC1A": "exciter",
    "IEEET1": "exciter",
    # --- end of the issue-45 exciters
    # --- issue-45 exciters, part 2
    "ESST4B": "exciter",
    "ESST1A": "exciter",
    "EXAC1": "exciter",
    "ESAC1A": "exciter",
    "EXAC2": "exciter",
    "EXPIC1": "exciter",
    "ESAC6A": "exciter",
    "DC4B": "exciter",
    # --- end of the issue-45 exciters, part 2
    # governors and stabilizers of issue 45
    "IEEEG1": "governor",
    "HYGOV": "governor",
    "IEESGO": "governor",
    "ST2CUT": "pss",
    "STAB2A": "pss",
    "GAST": "governor",
    "PSS2A": "pss",
    "PSS2B": "pss",
    # issue 45 (GGOV1)
    "GGOV1": "governor",
    # --- issue 47: inverter-based resources. REGCA1 is the generator's machine
    # record (the converter); the electrical and plant controllers sit on it
    "REGCA1": "machine",
    "REECB1": "renewable electrical control",
    "REPCA1": "plant controller",
    # --- end of issue 47's inverter-based resources
}
"""What each dyr model is to its generator: a machine (one per generator in service),
or an exciter, a load compensator, a stabilizer (pss) or a governor (at most one
each, with a machine)."""


@dataclass(frozen=True)
class DyrRecord:
    """One dyr record: `bus` (PSS/E number), `model`, the generator `ident` (ID),
    `params` by the names of `DYR_MODELS[model]`, and where it was read."""

    bus: int
    model: str
    ident: str
    params: dict[str, float]
    file: str
    line: int


def read_dyr(path, skip_unsupported: bool = False) -> list[DyrRecord]:
    """Read a PSS/E dyr file: records `BUS 'MODEL' ID p1 p2 ... /`, a record possibly
    spanning lines and ended by `/` (text after it on that line is a comment).

    Only the models of `DYR_MODELS` are read. Records of other models are refused
    with one `PsseError` naming every unsupported model of the file (with its number
    of records and its first line) and how to skip them, or, with
    `skip_unsupported`, skipped with one warning naming them. ANDES's `Toggle`
    record (`Line 'Toggle' Line_8 2.0 /`: a switching event in ANDES's own dyr
    extension, not PSS/E data) is skipped with one warning either way; give the
    event to the simulation instead. A wrong parameter count or a field that is not
    a number raises `PsseError` (file:line: MODEL field NAME: ...); so does another
    program's format (MATPOWER, JSON, a spreadsheet)."""
    name = str(path)
    out, unsupported, toggles = _scan_dyr(path)
    if toggles:
        warnings.warn(
            f"{name}:{toggles[0]}: {_count(toggles, 'ANDES Toggle record')} skipped "
            "(ANDES's switching event, not PSS/E data; give the event to the "
            "simulation: --trip-line, --fault-line)",
            stacklevel=2,
        )
    if unsupported:
        first = min(v[0] for v in unsupported.values())
        several = len(unsupported) > 1
        names = ", ".join(repr(m) for m in unsupported)
        what = f"dyr models {names} are" if several else f"dyr model {names} is"
        where = "; ".join(
            f"{m!r}: {_count(v, 'record')} from line {v[0]}"
            for m, v in unsupported.items()
        )
        if skip_unsupported:
            warnings.warn(
                f"{name}:{first}: {what} not supported; their records are skipped "
                f"({where})",
                stacklevel=2,
            )
        else:
            raise PsseError(
                f"{name}:{first}: {what} not supported (supported: "
                f"{', '.join(DYR_MODELS)}); {where}; --skip-unsupported "
                "(skip_unsupported=True) skips their records, which leaves a skipped "
                "exciter's field voltage and a skipped governor's mechanical power "
                "constant"
            )
    return out


def _scan_dyr(path):
    """(records, {unsupported model as written: its lines}, Toggle lines)."""
    name = str(path)
    _refuse_foreign(path, "dyr")
    with open(path, encoding="utf-8", errors="replace") as fh:
        lines = fh.read().splitlines()
    out: list[DyrRecord] = []
    unsupported: dict[str, list[int]] = {}  # model as written -> its lines
    toggles: list[int] = []
    toks: list[str | None] = []
    quoted: list[bool] = []
    start = 0
    for k, text in enumerate(lines, start=1):
        if text.lstrip().startswith("@!"):
            continue
        f, q, slash = _split(text, f"{name}:{k}")
        if f and not toks:
            start = k
        toks += f
        quoted += q
        if not slash:
            continue
        if toks:
            rec = _dyr_record(toks, quoted, name, start)
            if isinstance(rec, DyrRecord):
                out.append(rec)
            elif rec == "TOGGLE":
                toggles.append(start)
            elif rec is not None:
                unsupported.setdefault(rec, []).append(start)
        toks, quoted = [], []
    if any(t is not None for t in toks):
        raise PsseError(f"{name}:{start}: dyr record is not ended by '/'")
    return out, unsupported, toggles


def unsupported_models(path) -> list[str]:
    """The model names (upper case) of a dyr file that `DYR_MODELS` lacks, in file
    order (ANDES's Toggle records not counted)."""
    return [m.upper() for m in _scan_dyr(path)[1]]


def _count(lines: list, noun: str) -> str:
    return f"{len(lines)} {noun}{'s' if len(lines) != 1 else ''}"


# issue 47: dyr fields that are text, not numbers (REPCA1's branch circuit id)
_TEXT_FIELDS = {("REPCA1", "CKT")}


def _dyr_record(toks, quoted, name, line):
    """The DyrRecord of one record's tokens, or the model name as written (an
    unsupported model), or "TOGGLE" (ANDES's Toggle record)."""
    where = f"{name}:{line}"
    toks = [
        t for t in toks if t is not None
    ]  # empty fields (",,") have no meaning here
    if len(toks) < 3:
        raise PsseError(
            f"{where}: dyr record field ID: missing (a record is BUS 'MODEL' ID ...)"
        )
    written = toks[1].strip()
    model = written.upper()
    if model == "TOGGLE":
        return "TOGGLE"
    if model not in DYR_MODELS:
        return written
    try:
        bus = _number(toks[0], "i")
    except ValueError:
        raise PsseError(
            f"{where}: {model} field BUS: {toks[0]!r} is not a bus number"
        ) from None
    names = DYR_MODELS[model]
    values = toks[3:]
    if len(values) != len(names):
        raise PsseError(
            f"{where}: {model} record has {len(values)} parameters, expected {len(names)} "
            f"({' '.join(names)})"
        )
    params = {}
    for n, v in zip(names, values, strict=True):
        if (model, n) in _TEXT_FIELDS:  # issue 47: a circuit id is text
            params[n] = str(v).strip()
            continue
        try:
            params[n] = _number(v, "f")
        except ValueError:
            raise PsseError(
                f"{where}: {model} field {n}: {v!r} is not a number"
            ) from None
    return DyrRecord(
        bus=bus, model=model, ident=toks[2].strip(), params=params, file=name, line=line
    )


def check_dynamics(
    system: System, records: list[DyrRecord]
) -> dict[int, dict[str, DyrRecord]]:
    """Check dyr records against a System and return them by generator position:
    `{gen: {"machine": rec, "exciter": rec, "pss": rec, "governor": rec}}` (the keys
    present). Raises `PsseError` for a record naming a bus not in the raw file or a
    generator (bus, ID) that is not there, a second machine (or exciter, stabilizer,
    governor) for one generator, a controller without its generator's machine, and a
    generator in service without a machine record."""
    numbers = np.asarray(system.buses.number)
    gens = system.generators
    gen_bus = (
        numbers[np.asarray(gens.bus, dtype=np.int64)]
        if len(gens.ident)
        else numbers[:0]
    )
    index = {
        (int(b), str(i).strip()): k
        for k, (b, i) in enumerate(zip(gen_bus, gens.ident, strict=True))
    }
    known = {int(n) for n in numbers}
    by_gen: dict[int, dict[str, DyrRecord]] = {}
    for rec in records:
        where = f"{rec.file}:{rec.line}"
        if rec.bus not in known:
            raise PsseError(
                f"{where}: {rec.model} field BUS: bus {rec.bus} is not in the raw file"
            )
        g = index.get((rec.bus, rec.ident))
        if g is None:
            raise PsseError(
                f"{where}: {rec.model} field ID: no generator {rec.ident!r} at bus "
                f"{rec.bus} in the raw file"
            )
        kind = DYR_KINDS[rec.model]
        have = by_gen.setdefault(g, {})
        if kind in have:
            first = have[kind]
            raise PsseError(
                f"{where}: {rec.model} is a second {kind} record for generator "
                f"{rec.ident!r} at bus {rec.bus} (the first: {first.model} on line "
                f"{first.line})"
            )
        have[kind] = rec
    machines = ", ".join(m for m, k in DYR_KINDS.items() if k == "machine")
    for have in by_gen.values():
        if "machine" not in have:
            rec = min(have.values(), key=lambda r: r.line)
            raise PsseError(
                f"{rec.file}:{rec.line}: {rec.model} for generator {rec.ident!r} at bus "
                f"{rec.bus} has no machine record ({machines})"
            )
    dyr = records[0].file if records else "dyr"
    for g in range(len(gens.ident)):
        if float(np.asarray(gens.status)[g]) != 0.0 and "machine" not in by_gen.get(
            g, {}
        ):
            raise PsseError(
                f"{dyr}: generator {gens.ident[g]!r} at bus {int(gen_bus[g])} is in "
                f"service but has no machine record ({machines})"
            )
    return by_gen
