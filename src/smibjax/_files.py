"""Files: gain tables and gains files in, atomic writes out (the command line and the
tuner read and write through here). Nothing here is used by the numerical core."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from ._gainsfile import GainsFile, check_complete, is_schema_table, legacy, validate
from ._parameters import ParameterError
from ._validate import MAX_DEPTH, check_tree, require_real, show_key, show_value
from .controllers.synergetic import GAIN_NAMES

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "read_data",
    "read_utf8",
    "read_table",
    "read_gains",
    "atomic_write",
    "write_text",
    "write_json",
    "write_npz",
    "file_mode",
    "check_new_file",
    "check_writable",
    "check_out_folder",
    "read_gains_file",
    "write_gains_file",
]


def read_utf8(path: str | os.PathLike) -> str:
    """The text of a UTF-8 file; any other encoding is a one-line `ParameterError`."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ParameterError(
            f"file {str(path)!r} is not allowed: must be UTF-8 text (byte "
            f"0x{e.object[e.start]:02x} at offset {e.start} is not)"
        ) from None


def read_data(path: str | os.PathLike):
    """The parsed content of a `.toml` file, or of a JSON file (any other suffix)."""
    p = Path(path)
    if not p.is_file():
        raise ParameterError(f"file {str(p)!r} does not exist or is not a file")
    text = read_utf8(p)
    kind = "toml" if p.suffix.lower() == ".toml" else "json"
    try:
        data = tomllib.loads(text) if kind == "toml" else json.loads(text)
    except (ValueError, tomllib.TOMLDecodeError) as e:
        reason = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ParameterError(f"file {str(p)!r} is not valid {kind}: {reason}") from None
    except RecursionError:
        raise ParameterError(
            f"file {str(p)!r} is not allowed: nested deeper than {MAX_DEPTH} levels"
        ) from None
    return check_tree(data, f"file {str(p)!r}")


def read_table(path: str | os.PathLike) -> dict[str, float]:
    """A flat table of name -> number from a `.json` or `.toml` file."""
    p = Path(path)
    data = read_data(p)
    if not isinstance(data, dict):
        raise ParameterError(f"file {str(p)!r} must hold a flat table of name = value")
    out = {}
    for k, v in data.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ParameterError(
                f"{show_key(k)} = {show_value(v)} in {str(p)!r} is not allowed: "
                "must be a number"
            )
        out[str(k)] = (
            require_real(f"{show_key(k)} in {str(p)!r}", v) if isinstance(v, int) else v
        )
    return out


def read_gains(path: str | os.PathLike, complete: bool = False) -> dict[str, float]:
    """Gain values from a flat JSON/TOML table whose keys are gain names; with
    `complete`, all nine gains must be there (a gain set for batch studies). A gains
    file with context (schema `smibjax.gains/1`, `gainsfile.py`) gives its gains."""
    if is_schema_table(read_data(path)):
        return read_gains_file(path, complete=complete).gains
    table = read_table(path)
    unknown = sorted(set(table) - set(GAIN_NAMES))
    if unknown:
        raise ParameterError(
            f"unknown gain {unknown[0]!r} in {str(path)!r}: allowed are "
            f"{', '.join(GAIN_NAMES)}"
        )
    # c1, c2 (weighted macro-variables) are optional: 1 is the paper's form
    required = [g for g in GAIN_NAMES if g not in ("c1", "c2")]
    missing = [g for g in required if g not in table]
    if complete and missing:
        raise ParameterError(
            f"gain {missing[0]!r} is missing from {str(path)!r}: a gain set needs "
            f"all of {', '.join(required)}"
        )
    return table


_MUST_BE_NEW: set[str] = set()
"""The user-named outputs that `check_new_file` found absent (without --force):
`atomic_write` puts them in place without replacing a file that another process
created meanwhile."""


def _key(p: Path) -> str:
    return os.path.abspath(p)


def atomic_write(
    path: str | os.PathLike, write: Callable[[str], None], new: bool | None = None
) -> Path:
    """Call `write(tmp_path)` and move the result onto `path` in one rename, so a reader
    never sees a half-written file and an existing file survives a crash. With `new`
    (default: when `check_new_file` checked `path` without force) the file is put in
    place with a hard link, which fails if `path` exists by then: a file created by
    another process while this one worked is never replaced (one-line error, the
    finished output is removed)."""
    p = Path(path)
    if new is None:
        new = _key(p) in _MUST_BE_NEW
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=p.suffix, dir=p.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, file_mode())  # mkstemp creates 0600: honour the user's umask
        if new:
            _link_new(tmp, p)
        else:
            os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return p


def _link_new(tmp: str, p: Path) -> None:
    """Move `tmp` onto `p` unless `p` exists (atomically: link, then unlink)."""
    try:
        os.link(tmp, p)
    except FileExistsError:
        raise ParameterError(
            f"output {str(p)!r} is not allowed: it was created by another process "
            "while this run worked, and is kept (choose another name, or add --force)"
        ) from None
    except OSError:  # a file system without hard links: O_EXCL, then a copy
        try:
            fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, file_mode())
        except FileExistsError:
            raise ParameterError(
                f"output {str(p)!r} is not allowed: it was created by another "
                "process while this run worked, and is kept (choose another name, "
                "or add --force)"
            ) from None
        with open(tmp, "rb") as src, os.fdopen(fd, "wb") as dst:
            dst.write(src.read())
    os.unlink(tmp)


def file_mode() -> int:
    """The mode a new file gets from open(): 0o666 without the process's umask."""
    mask = os.umask(0o022)  # reading the umask means setting it: put it back at once
    os.umask(mask)
    return 0o666 & ~mask


def check_new_file(
    path: str | os.PathLike, force: bool = False, option: str = "--out"
) -> Path:
    """`path`, unless it names a folder, or an existing file and not `force` (a
    user-named output file is never replaced silently)."""
    p = Path(path)
    if not str(path).strip():
        raise ParameterError(f"{option} = '' is not allowed: must be a file name")
    if p.is_dir():
        raise ParameterError(
            f"{option} = {str(p)!r} is not allowed: must be a file name (it is a folder)"
        )
    if p.exists() and not force:
        raise ParameterError(
            f"{option} = {str(p)!r} is not allowed: must be a new file (it exists; "
            "add --force to replace it)"
        )
    check_writable(p.parent, option, str(p))
    if not force:
        _MUST_BE_NEW.add(_key(p))
    return p


def check_writable(folder: Path, option: str, name: str) -> None:
    """Raise `ParameterError` unless files can be created in `folder` (or in the
    nearest existing folder above it, where it is still to be made): checked before
    the run, not after it, by creating and removing a probe file there (permission
    bits say nothing for root, and a read-only mount or a pseudo file system such
    as /proc refuses what `os.access` allows)."""
    here = Path(folder) if str(folder) else Path(".")
    while not here.exists() and here != here.parent:
        here = here.parent
    if here.exists() and not here.is_dir():
        raise ParameterError(
            f"{option} = {name!r} is not allowed: {str(here)!r} is a file, not a folder"
        )
    try:
        with tempfile.NamedTemporaryFile(dir=here, prefix=".smibjax-probe-"):
            pass  # removed on close
    except OSError as e:
        raise ParameterError(
            f"{option} = {name!r} is not allowed: the folder {str(here)!r} is not "
            f"writable ({e.strerror or e})"
        ) from None


def check_out_folder(path: str | os.PathLike, option: str = "--out") -> Path:
    """`path` as an output folder: it is a folder or can be made as one, and files
    can be created there (`check_writable`); checked before any work."""
    p = Path(path)
    check_writable(p, option, str(p))
    return p


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Atomically write a text file."""

    def _w(tmp):
        with open(tmp, "w") as fh:
            fh.write(text)

    return atomic_write(path, _w)


def write_json(path: str | os.PathLike, obj) -> Path:
    """Atomically write JSON (inf/nan written as null)."""

    def clean(o):
        if isinstance(o, float) and (o != o or o in (float("inf"), float("-inf"))):
            return None
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        return o

    return write_text(path, json.dumps(clean(obj), indent=2) + "\n")


def write_npz(path: str | os.PathLike, arrays: dict) -> Path:
    """Atomically write an uncompressed `.npz` of named arrays."""
    import numpy as np

    def _w(tmp):
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)

    return atomic_write(path, _w)


def read_gains_file(path: str | os.PathLike, complete: bool = False) -> GainsFile:
    """A gains file (`smibjax._gainsfile`): schema, or a flat table of gains (`legacy`,
    with the paper's context). With `complete`, the paper's law needs every gain but
    c1, c2 (a gain set for batch studies)."""
    p = Path(path)
    data = read_data(p)
    gf = validate(data, p) if is_schema_table(data) else legacy(read_gains(p))
    if complete:
        check_complete(gf, p)
    return gf


def write_gains_file(path: str | os.PathLike, gf: GainsFile) -> Path:
    """Write `gf` as schema JSON (atomically), after validating it."""
    data = gf.to_dict()
    validate(data, path)
    return write_json(path, data)
