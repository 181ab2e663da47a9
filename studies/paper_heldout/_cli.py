"""The study scripts' command lines: gains files and a few flags, checked before any
work (one line and exit 2 on a bad argument, nothing written)."""

from __future__ import annotations

import sys
from pathlib import Path


def gains_args(argv: list[str], doc: str, flags: tuple[str, ...] = ()):
    """(gains files, flags given) from `argv`; `--help` prints `doc` and exits 0."""
    script = Path(sys.argv[0]).name
    if any(a in ("-h", "--help") for a in argv):
        print(doc.strip())
        raise SystemExit(0)
    files, given = [], set()
    for a in argv:
        if a.startswith("-"):
            if a not in flags:
                allowed = ", ".join((*flags, "--help"))
                _refuse(f"{script}: option {a!r} is not allowed: use {allowed}")
            given.add(a)
        elif not Path(a).is_file():
            _refuse(f"{script}: {a!r} is not allowed: must be an existing gains file")
        else:
            files.append(Path(a))
    return files, given


def _refuse(line: str):
    print(line, file=sys.stderr)
    raise SystemExit(2)
