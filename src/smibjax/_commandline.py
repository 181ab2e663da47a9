"""What a command line of smibjax needs, shared by `python -m smibjax` and `python -m
tuning.optimize`: a parser with one-line errors, the error it raises, the one line a
library error becomes (naming the flag of the value), and a fresh run folder."""

from __future__ import annotations

import argparse
import contextlib
import datetime
import os
import re
import sys
from pathlib import Path

__all__ = [
    "CLIError",
    "Parser",
    "DefaultsFormatter",
    "one_line",
    "given",
    "fresh_out",
    "out_path",
    "OUTPUT_ROOT",
    "UNNAMED",
    "progress_bars",
    "say_compiling",
    "announce_compile",
    "xla_alarms_explained",
    "explain_xla_alarm",
]


class CLIError(Exception):
    """A user error to report on one line."""


class DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """argparse's help with each option's default appended ("(default: 10.0)"),
    except where there is none to show (None, False, an empty list) or the help
    already states it."""

    def _get_help_string(self, action):
        text = action.help or ""
        d = action.default
        if (
            d is None
            or d is False
            or d == []
            or d is argparse.SUPPRESS
            or "default" in text
            or "%(default)" in text
        ):
            return text
        return super()._get_help_string(action) if text else "(default: %(default)s)"


class Parser(argparse.ArgumentParser):
    """argparse's parser with one-line errors (no usage dump), arguments left over
    reported with the help of the (sub)command they were given to, and the set of
    its long flags (`flags`, for `one_line`)."""

    def __init__(self, *args, **kw):
        self.flags: set[str] = set()  # before argparse adds -h/--help
        kw.setdefault("formatter_class", DefaultsFormatter)
        super().__init__(*args, **kw)

    def add_argument(self, *names, **kw):
        self.flags.update(n for n in names if n.startswith("--"))
        flag = next((n for n in names if n.startswith("--")), None)
        if flag is not None and kw.get("action") in (None, "store", "append"):
            kind = kw.get("type")
            if kind is int:
                kw["type"] = integer(flag, *INT_BOUNDS.get(flag, (-MAX_INT, MAX_INT)))
            elif kind is None and flag in PATH_FLAGS:
                kw["type"] = path_text(flag)
        return super().add_argument(*names, **kw)

    def error(self, message):
        raise CLIError(f"{message} (see `{self.prog} --help`)")

    def parse_args(self, args=None, namespace=None):
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            command = getattr(ns, "command", None)
            prog = f"{self.prog} {command}" if command else self.prog
            raise CLIError(
                f"unrecognized arguments: {' '.join(extras)} (see `{prog} --help`)"
            )
        return ns


MAX_INT = 10**9  # the largest |integer| of a flag without its own bounds


def _cpus() -> int:
    return os.cpu_count() or 1


INT_BOUNDS = {
    # flag: (lo, hi); hi may be a function (evaluated when the flag is parsed)
    "--max-steps": (1, 10**8),  # smibjax._validate.MAX_STEPS
    "--n": (1, 10**9),
    "--chunk": (1, 10**9),
    "--batch": (1, 10**9),
    "--steps": (0, 10**9),
    "--seed": (0, 2**32 - 1),
    "--workers": (1, _cpus),
}
"""The bounds of the integer flags (any command): every other `type=int` flag is
bounded by +-`MAX_INT`."""

PATH_FLAGS = {"--out", "--plot", "--csv", "--gains", "--dist", "--config", "--init"}
"""Flags naming a file or folder: an empty name is refused (`--out ''` would
otherwise be the same as no --out)."""


def given(args, flag: str) -> bool:
    """Whether `flag` was written on the command line (`args.argv`, kept by
    `cli.main`; argparse's unique prefixes count), whatever its value: a flag
    given at its default value is still given."""
    flags = getattr(args, "flags", set())
    for token in getattr(args, "argv", ()):
        if token == "--":
            break
        name = token.split("=", 1)[0]
        if not name.startswith("--"):
            continue
        if name == flag or (
            name not in flags and len(name) > 2 and flag.startswith(name)
        ):
            return True
    return False


def integer(flag: str, lo: int, hi):
    """An argparse type: an integer (decimal digits, no fraction, no exponent, not
    longer than 30 characters) within [lo, hi] (`hi` may be a function). A refusal
    is a `CLIError` naming the flag as the user wrote it (`--n 0 is not allowed`)."""

    def parse(text: str) -> int:
        t = text.strip()
        top = hi() if callable(hi) else hi
        if len(t) > 30 or not t.lstrip("+-").isdigit():
            raise CLIError(
                f"{flag} {text[:40]!r} is not allowed: must be an integer in "
                f"[{lo}, {top}]"
            )
        v = int(t)
        if not lo <= v <= top:
            raise CLIError(
                f"{flag} {v} is not allowed: must be an integer in [{lo}, {top}]"
                + (" (the CPU count)" if callable(hi) else "")
            )
        return v

    parse.__name__ = "integer"
    return parse


def path_text(flag: str):
    """An argparse type: a file or folder name, not empty."""

    def parse(text: str) -> str:
        if text is UNNAMED:  # the flag alone (argparse passes `const` through here)
            return text
        if not text.strip():
            raise argparse.ArgumentTypeError(
                f"{text!r} is not allowed: must be a file or folder name (empty)"
            )
        return text

    parse.__name__ = "path"
    return parse


def one_line(error: Exception, flags: set[str] = frozenset()) -> str:
    """The message of a library error with the values the command takes as flags
    named as the user writes them: the refused one (`t_end = 1.5 s is not allowed`
    -> `--t-end 1.5 s is not allowed`) and those the reason refers to (`must be
    after reclose_time = 2 s` -> `must be after --reclose-time 2 s`)."""

    def flag(m: re.Match) -> str:
        f = "--" + m.group(1).replace("_", "-")
        return f"{f} {m.group(2)}" if f in flags else m.group(0)

    name = r"(?<![\w.-])([a-z][a-z0-9_]*) = "
    text = str(error)
    head, sep, reason = text.partition(" is not allowed")
    head = re.sub(name + r"(\S+(?: s)?)$", flag, head)
    reason = re.sub(name + r"(\S+)", flag, reason)
    return head + sep + reason


OUTPUT_ROOT = Path("runs")
"""The one folder (relative to the working directory) under which every command's
default output goes, as `<command>-<YYYYmmdd-HHMMSS>` (`fresh_out`)."""


class _Unnamed(str):
    """The value of an output flag given without a name (`--out` alone)."""


UNNAMED = _Unnamed("")
"""`const` of the file flags that take an optional name (`simulate --out`, `cct
--out`): the command picks a new name under `OUTPUT_ROOT` (`out_path`)."""


def fresh_out(kind: str, suffix: str = "") -> Path:
    """A new output under `OUTPUT_ROOT` named by the command and the time
    (`runs/montecarlo-20261202-072700`, + `suffix`), with `-2`, `-3`, ... appended
    while that name is taken."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    path, i = OUTPUT_ROOT / f"{kind}-{stamp}{suffix}", 2
    while path.exists():
        path, i = OUTPUT_ROOT / f"{kind}-{stamp}-{i}{suffix}", i + 1
    return path


def out_path(given, command: str, suffix: str = "", default: bool = True):
    """The output a command writes: `given` as is when named; a new name under
    `OUTPUT_ROOT` (`fresh_out(command, suffix)`) when the flag came without a name
    (`UNNAMED`), or was not given and the command writes by `default`; else None
    (nothing written)."""
    if given is UNNAMED or (given is None and default):
        return fresh_out(command, suffix)
    return None if given is None else Path(given)


@contextlib.contextmanager
def progress_bars():
    """A factory of tqdm progress bars (on stderr unless `file=` says otherwise) for
    one command: `with progress_bars() as bar: b = bar(total=n, desc=...)`. Every bar
    it made is closed when the block ends, also when an error ends it, so the error
    (or warning) line printed next starts on a line of its own instead of after the
    bar's last '\\r' drawing. Used by every command that draws a bar (montecarlo,
    cct, compare, the `--case` commands, the tuner)."""
    made = []

    def bar(**kw):
        from tqdm.auto import tqdm

        kw.setdefault("file", sys.stderr)
        made.append(tqdm(**kw))
        return made[-1]

    try:
        yield bar
    finally:
        for b in made:
            b.close()  # a second close (the bar's own) does nothing


def say_compiling(what: str, *programs: str, file=None) -> None:
    """Print 'compiling WHAT (cache: warm|cold|off)' on stderr: the line a long
    command prints before its first compiled step, so that no wait is silent."""
    from ._process import cache_state

    print(
        f"compiling {what} (cache: {cache_state(*programs)})",
        file=file or sys.stderr,
        flush=True,
    )


@contextlib.contextmanager
def announce_compile(what: str, *programs: str, file=None):
    """Within the block, print `say_compiling`'s line when JAX has traced the
    first sizeable program (a trace of >= 0.05 s: after the inputs were checked,
    so that a refused input stays one line, and before the compile or the cache
    load). The cache state is read on entry."""
    import jax.monitoring

    from ._process import cache_state

    state = cache_state(*programs)
    said = []

    def listener(event: str, duration: float, **kwargs) -> None:
        if not said and event.endswith("jaxpr_trace_duration") and duration >= 0.05:
            said.append(True)
            print(
                f"compiling {what} (cache: {state})",
                file=file or sys.stderr,
                flush=True,
            )

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


_ALARM = b"Very slow compile?"


def explain_xla_alarm(chunk: bytes) -> bytes:
    """`chunk` (bytes written to stderr) with XLA's slow-compile alarm (its log
    line, the `*` banner around it and "[Compiling module M] Very slow compile? If
    you want to file a bug, ...", which reads like a crash) replaced, where it
    stood, by one line of ours naming the program; any other byte is passed through
    unchanged."""
    if _ALARM not in chunk:
        return chunk
    import re

    keep = []
    for line in chunk.split(b"\n"):
        text = line.strip()
        if _ALARM in line:
            m = re.search(rb"\[Compiling module ([^\]]+)\]", line)
            module = m.group(1).decode(errors="replace") if m else "a program"
            keep.append(
                f"smibjax: still compiling {module} (XLA notes a slow compile: not "
                "an error; a large case's first compile takes minutes on a small CPU, "
                "then it is cached)".encode()
            )
        elif b"slow_operation_alarm" in line or (text and set(text) == {ord("*")}):
            continue
        else:
            keep.append(line)
    return b"\n".join(keep)


@contextlib.contextmanager
def xla_alarms_explained():
    """Within the block, everything written to file descriptor 2 (stderr: Python's,
    XLA's C++ log, child processes') passes through `explain_xla_alarm` on a thread
    (each write forwarded at once: progress bars' '\\r' drawing is not held back).
    Restored, with every byte forwarded, when the block ends. Does nothing where
    stderr has no file descriptor (a captured stream)."""
    import threading

    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    r, w = os.pipe()
    os.dup2(w, fd)
    os.close(w)

    def pump():
        while True:
            chunk = os.read(r, 65536)
            if not chunk:
                break
            data = explain_xla_alarm(chunk)
            while data:
                data = data[os.write(saved, data) :]

    t = threading.Thread(target=pump, name="smibjax-stderr", daemon=True)
    t.start()
    try:
        yield
    finally:
        try:
            sys.stderr.flush()
        except (OSError, ValueError):
            pass
        os.dup2(saved, fd)  # the pipe's last write end closes: the pump drains, ends
        t.join(timeout=5)  # (a child process still holding the pipe keeps it open)
        if not t.is_alive():
            os.close(r)
        os.close(saved)
