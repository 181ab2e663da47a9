"""How a tuning run in `--out DIR` starts, and its wall time over sessions.

`--resume` continues the run whose options are saved in `DIR/config.json`, so the
options of the resuming command must be the same (like `smibjax montecarlo --resume`):
a different `--batch`, `--seed`, `--steps`, `--controller`, `--preset`, `--init` or any
config key would make the resumed run silently differ from the one it claims to
finish, and is refused with the first key that differs. A run killed before its first
checkpoint leaves only `config.json`: `--resume` then starts it from scratch (and says
so on stderr). A fresh start refuses a folder that already holds files.

`sessions.json` records when each session started and how long it ran; a session that
was killed is counted up to its last write in the folder. The report states the sum.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from smibjax import ParameterError
from smibjax._files import write_json

__all__ = [
    "start_mode",
    "first_difference",
    "SessionClock",
    "SESSIONS",
    "OLD_CHECKPOINT",
]

CONFIG = "config.json"
OLD_CHECKPOINT = "checkpoint.pkl"  # the older tuner's pickle: not read
SESSIONS = "sessions.json"


def first_difference(saved, new, path: str = ""):
    """The first dotted key where the tables differ, with both values, or None."""
    if isinstance(saved, dict) and isinstance(new, dict):
        for k in [*new, *(k for k in saved if k not in new)]:
            here = f"{path}.{k}" if path else str(k)
            if k not in saved or k not in new:
                return here, saved.get(k, "(absent)"), new.get(k, "(absent)")
            d = first_difference(saved[k], new[k], here)
            if d is not None:
                return d
        return None
    if isinstance(saved, (list, tuple)) and isinstance(new, (list, tuple)):
        if len(saved) == len(new) and all(
            first_difference(a, b) is None for a, b in zip(saved, new, strict=True)
        ):
            return None
        return path, list(saved), list(new)
    same = saved == new and type(saved) is type(new)
    numbers = (int, float)
    if isinstance(saved, bool) or isinstance(new, bool):  # true == 1, but not alike
        same = saved is new
    elif isinstance(saved, numbers) and isinstance(new, numbers):
        same = float(saved) == float(new)
    return None if same else (path, saved, new)


def start_mode(out: Path, cfg: dict, resume: bool, checkpoint: str) -> bool:
    """True: continue the run in `out` from its checkpoint; False: start afresh.

    Raises `ParameterError` (one line) for a fresh start into a folder that holds
    files, a `--resume` of a folder without a tuning run, and a `--resume` whose
    options differ from the run's `config.json`."""
    out = Path(out)
    if not resume:
        if out.exists() and (not out.is_dir() or any(out.iterdir())):
            raise ParameterError(
                f"--out {str(out)!r} already holds files: use --resume to continue "
                "it or choose another folder"
            )
        return False
    saved_path = out / CONFIG
    if not saved_path.is_file():
        raise ParameterError(
            f"--resume: no checkpoint in {str(out)!r} (no tuning run there: "
            f"{CONFIG} is missing)"
        )
    try:
        saved = json.loads(saved_path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as e:
        raise ParameterError(
            f"--resume: {str(saved_path)!r} is not a tuning run's configuration ({e})"
        ) from None
    train = saved.get("train") if isinstance(saved, dict) else None
    if isinstance(train, dict) and "phi_layer" not in train:
        train["phi_layer"] = 0.0  # a run from before the key: trained without it
    diff = first_difference(saved, json.loads(json.dumps(cfg)))
    if diff is not None:
        key, old, new = diff
        raise ParameterError(
            f"--resume: {key} = {new!r} differs from the run in {str(out)!r} "
            f"({key} = {old!r}); repeat its options"
        )
    if not (out / checkpoint).is_file() and (out / OLD_CHECKPOINT).is_file():
        raise ParameterError(
            f"--resume: {str(out / OLD_CHECKPOINT)!r} is a checkpoint of an older "
            "tuner (pickle), which this one does not read: start the run afresh in "
            "a new folder"
        )
    if not (out / checkpoint).is_file():
        print(
            f"tuning.optimize: note: {str(out)!r} has no checkpoint yet (the run "
            "stopped before its first one): starting it from scratch",
            file=sys.stderr,
        )
        return False
    return True


class SessionClock:
    """Wall time of a run over all its sessions (`sessions.json` in `out`)."""

    def __init__(self, out: Path, resume: bool):
        self.path = Path(out) / SESSIONS
        self.sessions = self._previous(Path(out)) if resume else []
        self.sessions.append({"started": time.time()})
        write_json(self.path, self.sessions)

    def _previous(self, out: Path) -> list[dict]:
        try:
            sessions = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return []
        if not isinstance(sessions, list):
            return []
        last_write = max(
            (p.stat().st_mtime for p in out.iterdir() if p.name != SESSIONS),
            default=0.0,
        )
        out_list = []
        for s in sessions:
            if not isinstance(s, dict) or "started" not in s:
                continue
            if s.get("seconds") is None:  # killed: count it up to its last write
                s = {**s, "seconds": max(0.0, last_write - float(s["started"]))}
                s["interrupted"] = True
            out_list.append(s)
        return out_list

    def finish(self, seconds: float) -> tuple[float, int]:
        """Record this session's `seconds`; returns (total seconds, sessions)."""
        self.sessions[-1]["seconds"] = float(seconds)
        write_json(self.path, self.sessions)
        return sum(float(s["seconds"]) for s in self.sessions), len(self.sessions)
