"""The one error family (issue 44): every refusal of user input is a ParameterError."""

from __future__ import annotations

import subprocess
import sys

import pytest

import smibjax as sj
from smibjax.grid.case import CaseError, load_case
from smibjax.grid.params import ParamError
from smibjax.grid.powerflow import PowerFlowError
from smibjax.grid.psse import PsseError


@pytest.mark.parametrize("cls", [CaseError, ParamError, PowerFlowError, PsseError])
def test_every_grid_refusal_is_a_parameter_error(cls):
    assert issubclass(cls, sj.ParameterError)
    assert issubclass(cls, ValueError)


def test_refusals_from_the_grid_entries_are_parameter_errors(tmp_path):
    with pytest.raises(sj.ParameterError, match="not built in"):
        load_case("no-such-case")
    bad = tmp_path / "x.dyr"
    bad.write_text("1 'GENCLS' 1 3.0 /\n")  # one parameter short
    from smibjax.grid.psse import read_dyr

    with pytest.raises(sj.ParameterError, match="x.dyr:1: GENCLS record has 1"):
        read_dyr(bad)


def test_the_error_family_loads_without_jax():
    code = (
        "import sys; from smibjax._errors import ParameterError; "
        "print('jax' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "False"
