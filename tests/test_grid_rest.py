"""A device that does not start at rest is named (PSS/E's suspect initial
conditions): `grid.operating.rest_residual` and `not_at_rest`."""

import jax
import numpy as np

from smibjax.grid.case import load_case
from smibjax.grid.operating import not_at_rest, operating_point, rest_residual
from smibjax.grid.params import set_params


def test_a_field_limit_below_the_operating_points_field_voltage_is_named():
    case = load_case("kundur")
    op, _ = operating_point(case)
    assert float(np.max(np.abs(rest_residual(case, op)))) < 1e-8
    assert not_at_rest(case, rest_residual(case, op)) == []
    # generator 2's exciter can no longer deliver the field voltage it needs
    efd0 = float(op.held[0]["Efd"][1])
    low = set_params(case, {"SEXS[2:1].EMAX": 0.5 * efd0})
    op2, _ = operating_point(low)
    dy = jax.jit(lambda: rest_residual(low, op2))()
    rows = not_at_rest(low, dy)
    assert [(m, g) for m, g, _, _ in rows] == [("GENROU", "2:1")]
    model, gen, state, v = rows[0]
    assert state == "e1q" and v < -1e-3  # the flux decays toward the lower field
