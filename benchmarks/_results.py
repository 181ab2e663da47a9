"""Shared by the benchmark scripts: machine metadata and the results file."""

from __future__ import annotations

import datetime
import json
import os
import platform
from pathlib import Path

import jax

import smibjax as sj
from smibjax._files import write_text


def write_results(out: str | Path, name: str, config: dict, payload: dict) -> Path:
    """Write `out/name.json` with date, machine, versions and `config` beside `payload`."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {
        "date": datetime.date.today().isoformat(),
        "machine": platform.machine(),
        "processor": platform.processor(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "smibjax": sj.__version__,
        "config": config,
    }
    path = out / f"{name}.json"
    return write_text(path, json.dumps({**meta, **payload}, indent=1))
