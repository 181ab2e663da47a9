"""What a command line of smibjax needs, shared by `python -m smibjax` and `python -m
tuning.optimize`: a parser with one-line errors, the error it raises, the one line a
library error becomes (naming the flag of the value), and a fresh run folder."""

from __future__ import annotations

import argparse
import datetime
import re
from pathlib import Path

__all__ = ["CLIError", "Parser", "DefaultsFormatter", "one_line", "fresh_out"]


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


def fresh_out(kind: str) -> Path:
    """A new run folder under runs/, named by kind and time."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{kind}-{stamp}"
