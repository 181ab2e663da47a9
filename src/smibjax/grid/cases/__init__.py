"""The built-in cases as PSS/E v33 files: Kundur's two-area system (`kundur.raw` with
`kundur.dyr`, `kundur_nopss.dyr`, `kundur_gencls.dyr`, `kundur_synex.dyr`), the IEEE
39-bus New England system (`ieee39.raw` with `ieee39.dyr`, `ieee39_pss.dyr`,
`ieee39_gencls.dyr`) and the paper's SMIB with SVC (`smib.raw` with `smib.dyr`,
`smib_gencls.dyr`); and ANDES 2.0's public IEEE 14, WECC 179, NPCC and Nordic 44
files (`ieee14.*`, `wecc179.*`, `npcc.*`, `nordic44.*`). Sources, licences, chosen
values and unit conversions: README.md beside these files."""

from __future__ import annotations

from pathlib import Path

from ..._errors import ParameterError

__all__ = ["CASES_DIR", "case_file", "case_files"]

CASES_DIR = Path(__file__).resolve().parent
"""The folder holding the case files (installed as package data)."""


def case_files() -> list[str]:
    """The names of the case files (raw and dyr), sorted."""
    return sorted(p.name for p in CASES_DIR.iterdir() if p.suffix in (".raw", ".dyr"))


def case_file(name: str) -> Path:
    """The path of the built-in case file `name` (e.g. "kundur.raw"); an unknown name
    raises ValueError naming it and the known ones."""
    if name not in case_files():
        raise ParameterError(
            f"case file {name!r} is not built in: must be one of {case_files()}"
        )
    return CASES_DIR / name
