"""tests/identity.py's comparison within tolerance (issue 44): two captures agree when
verdicts are identical, times within 1e-6 s and angles within 1e-9 rad."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tests.identity import compare


def _capture(root, delta=0.0, t_shift=0.0, stable=True, gain=1.5):
    (root / "tune").mkdir(parents=True)
    np.savez(
        root / "mc_a_0.npz",
        max_delta=np.array([1.2 + delta, 0.7]),
        settling_delta=np.array([3.25 + t_shift, np.inf]),
        stable=np.array([stable, True]),
    )
    (root / "cct.json").write_text(json.dumps({"cct": {"a": [0.21 + t_shift]}}))
    for name in ("gains.json", "gains_last.json"):
        (root / "tune" / name).write_text(json.dumps({"gains": {"k": gain}}))
    (root / "tune" / "history.csv").write_text(
        f"step,loss,seconds\n0,{0.5 + delta},1.0\n"
    )
    return root


@pytest.mark.parametrize(
    ("change", "same"),
    [
        ({}, True),
        ({"delta": 5e-10}, True),  # within 1e-9 rad
        ({"delta": 5e-9}, False),
        ({"t_shift": 5e-7}, True),  # within 1e-6 s
        ({"t_shift": 5e-6}, False),
        ({"stable": False}, False),  # a verdict flips
        ({"gain": 1.5 + 1e-8}, False),
    ],
)
def test_compare_within_tolerance(tmp_path, capsys, change, same):
    a = _capture(tmp_path / "a")
    b = _capture(tmp_path / "b", **change)
    assert compare(a, b) == (0 if same else 1)
    out = capsys.readouterr().out
    assert ("identical within tolerance" in out) == same
