"""Magnetic saturation of synchronous machines, PSS/E style: a saturation factor
Se(psi) of a flux (voltage) magnitude psi (pu), fitted through the two data points of
the dyr record, S10 = Se(1.0) and S12 = Se(1.2). The machine adds Se(psi) psi to the
field current (d axis; GENROU also a share on the q axis), so Se = 0 is no saturation.

Two fits:

- "quadratic" (PSS/E GENROU, GENSAL; ANDES `ExcQuadSat`):

      Se(psi) = B (psi - A)^2 / psi  for psi > A,  0 otherwise,
      a = sqrt(S10 / (1.2 S12)),  A = 1.2 - 0.2 / (1 - a),  B = 1.2 S12 (1 - a)^2 / 0.04

  (A is where saturation starts; Se and its slope are continuous there).
- "exponential" (PSS/E GENROE, GENSAE):

      Se(psi) = S10 psi^n,  n = ln(S12 / S10) / ln(1.2).

The exponential fit reads a flux above `PSI_MAX` (10 pu; a machine's data end at
1.2 pu) as `PSI_MAX`: an explicit solver's trial step far outside the physical range
(states of 1e30 after a switch, rejected by the error control) then cannot overflow
psi^n (n up to about 20) into inf, whose inf - inf is a NaN that poisons the step
control and the gradients of the whole run.

S10 = 0 is no saturation at all in both fits, whatever S12 (PSS/E's convention; also
ANDES's `ExcQuadSat` and OpenIPSL's `SE`). With S10 > 0 the quadratic fit needs
S10 < 1.2 S12 (else the parabola through the two points opens on the wrong side) and
the exponential fit needs S12 > 0.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..._validate import ParameterError, is_concrete

__all__ = [
    "SATURATION_KINDS",
    "quadratic_fit",
    "exponential_fit",
    "saturation_factor",
    "check_saturation",
]

SATURATION_KINDS = ("quadratic", "exponential")
PSI_MAX = 10.0  # pu: the exponential fit's flux is read as at most this


def quadratic_fit(s10, s12):
    """(A, B) of Se(psi) = B (psi - A)^2 / psi through Se(1.0) = s10 and Se(1.2) = s12
    (pu). No saturation (s10 = 0, PSS/E's convention, whatever s12) gives B = 0."""
    s10, s12 = jnp.asarray(s10, float), jnp.asarray(s12, float)
    on = (s10 > 0) & (s12 > 0)
    # the inner where keeps sqrt away from 0 where off (a finite gradient in S10)
    a = jnp.where(
        on, jnp.sqrt(jnp.where(on, s10 / (1.2 * jnp.where(on, s12, 1.0)), 1.0)), 0.0
    )
    big_a = 1.2 - 0.2 / (1.0 - a)
    big_b = jnp.where(on, 1.2 * s12 * (1.0 - a) ** 2 / 0.04, 0.0)
    return big_a, big_b


def exponential_fit(s10, s12):
    """(k, n) of Se(psi) = k psi^n through Se(1.0) = s10 and Se(1.2) = s12 (pu):
    k = s10, n = ln(s12 / s10) / ln(1.2). No saturation (s10 = 0) gives k = n = 0."""
    s10, s12 = jnp.asarray(s10, float), jnp.asarray(s12, float)
    on = (s10 > 0) & (s12 > 0)
    n = jnp.where(
        on, jnp.log(jnp.where(on, s12 / jnp.where(on, s10, 1.0), 1.0)), 0.0
    ) / np.log(1.2)
    return jnp.where(on, s10, 0.0), n


def saturation_factor(psi, s10, s12, kind: str = "quadratic"):
    """Se(psi): the saturation factor (pu/pu) at flux magnitude psi (pu) of the fit
    `kind` ("quadratic" or "exponential") through Se(1.0) = s10, Se(1.2) = s12."""
    psi = jnp.abs(psi)
    if kind == "quadratic":
        big_a, big_b = quadratic_fit(s10, s12)
        on = psi > big_a
        safe = jnp.where(on & (psi > 0), psi, 1.0)
        return jnp.where(on, big_b * (safe - big_a) ** 2 / safe, 0.0)
    if kind == "exponential":
        k, n = exponential_fit(s10, s12)
        safe = jnp.where(psi > 0, jnp.minimum(psi, PSI_MAX), 1.0)
        return jnp.where(psi > 0, k * safe**n, 0.0)
    raise ParameterError(
        f"saturation = {kind!r} is not allowed: must be one of {SATURATION_KINDS}"
    )


def check_saturation(owner: str, kind: str, s10, s12) -> None:
    """Raise `ParameterError` (one line naming the value) unless the fit `kind` exists
    for (s10, s12); skipped for traced values."""
    if kind not in SATURATION_KINDS:
        raise ParameterError(
            f"{owner}.saturation = {kind!r} is not allowed: "
            f"must be one of {SATURATION_KINDS}"
        )
    if not is_concrete(s10, s12):
        return
    s10, s12 = np.asarray(s10, float), np.asarray(s12, float)
    for name, v in (("S10", s10), ("S12", s12)):
        bad = ~(np.isfinite(v) & (v >= 0))
        if np.any(bad):
            raise ParameterError(
                f"{owner}.{name} = {_fmt(v)} is not allowed: must be finite and >= 0"
            )
    off = s10 == 0  # no saturation (PSS/E), whatever S12
    if kind == "quadratic":
        ok = off | (s10 < 1.2 * s12)
        allowed = "the quadratic fit needs S10 < 1.2 S12 (or S10 = 0: none)"
    else:
        ok = off | (s12 > 0)
        allowed = "the exponential fit needs S12 > 0 where S10 > 0 (S10 = 0: none)"
    if not np.all(ok):
        raise ParameterError(
            f"{owner}.S10, S12 = {_fmt(s10)}, {_fmt(s12)} are not allowed: {allowed}"
        )


def _fmt(x) -> str:
    a = np.asarray(x)
    if a.ndim == 0:
        return f"{float(a):g}"
    return np.array2string(a, precision=6, threshold=6)
