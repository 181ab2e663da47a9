"""Transfer-function blocks shared by the controller models, vectorized over the
device axis: each returns (output, state derivative) for the block's input and state.

Every block keeps its state even where a time constant is zero (a group has one
state count): a zero lag time constant makes the block algebraic (output = its
input, through the gain and the limits), and its state a placeholder whose
derivative is exactly zero, left at the value `init` gave it. Division is guarded
(`_safe`) so gradients stay finite in both branches of every `jnp.where`.

Limits come in the two kinds of the PSS/E block diagrams:

- non-windup (PSS/E's limits drawn on a lag block, ANDES `LagAntiWindup`): the
  state is held at a limit while its input pushes it outwards, and leaves it as
  soon as the input reverses;
- windup (a separate limiter after a block, ANDES `HardLimiter`/`Limiter`): the
  block's output is clipped, its states are not.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..._validate import ParameterError, is_concrete, require

__all__ = [
    "nonwindup",
    "lag",
    "lag_nonwindup",
    "sweeping",
    "leadlag",
    "washout",
    "second_order_lag",
    "second_order_leadlag",
    "build_group",
    "check",
    "regulated",
    "fex",
]


def _safe(T):
    """T where T > 0, else 1 (a divisor for the branch that is not taken)."""
    return jnp.where(T > 0, T, 1.0)


def nonwindup(x, dx, lo, hi):
    """dx/dt of a state held within [lo, hi]: zero while at (or past) a limit and
    pushed outwards (infinite limits: no limit)."""
    pinned = ((x >= hi) & (dx > 0)) | ((x <= lo) & (dx < 0))
    return jnp.where(pinned, 0.0, dx)


def lag(x, u, K, T):
    """K / (1 + s T): y = x, T dx/dt = K u - x; T = 0: y = K u."""
    on = T > 0
    return jnp.where(on, x, K * u), jnp.where(on, (K * u - x) / _safe(T), 0.0)


# Moving limits: the state is drawn onto a limit it has crossed with the time
# constant T / SWEEP (see `sweeping`).
SWEEP = 30.0


def sweeping(x, dx, lo, hi, T):
    """dx/dt (units of x per s) of a state kept within limits [lo(t), hi(t)] that
    move: the lag's own dx/dt, bounded to [(lo - x)/tau, (hi - x)/tau] with tau =
    T / SWEEP (s). Continuous in x, lo and hi (no switching surface to chatter on):

    - inside, farther than tau |dx| from both limits: dx unchanged;
    - pushed onto a limit: x approaches it as a first-order lag of time constant
      tau, and rides it, lagging a limit that moves at rate r by tau r;
    - past a limit that has moved across it (a falling ceiling, x above hi): x is
      drawn back to the limit at rate (hi - x)/tau, or faster if its own dx says so,
      so it is swept along with the limit, and leaves it as soon as the input
      reverses (PSS/E's integrate-then-clamp, ANDES `AntiWindup`'s reset, to within
      tau times the limit's rate).
    """
    tau = _safe(T) / SWEEP
    return jnp.minimum(jnp.maximum(dx, (lo - x) / tau), (hi - x) / tau)


def lag_nonwindup(x, u, K, T, lo, hi, moving=False):
    """K / (1 + s T) with non-windup limits [lo, hi] on its state; returns (y,
    dx/dt), y = clip(x, lo, hi) in the units of K u. T = 0: y = clip(K u, lo, hi).

    Constant limits (`moving` False): dx/dt = (K u - x)/T, zeroed while x is at (or
    past) a limit and K u pushes outwards. Limits that move (`moving` True, or an
    array selecting devices): `sweeping` bounds dx/dt, so that the state follows a
    falling limit down instead of staying where the limit left it (a stale state
    above the ceiling would hold the output at the limit after the input reverses,
    until the state had decayed to it)."""
    on = T > 0
    f = (K * u - x) / _safe(T)
    dx = nonwindup(x, f, lo, hi)
    if moving is not False:
        dx = jnp.where(moving, sweeping(x, f, lo, hi, T), dx)
    y = jnp.where(on, jnp.clip(x, lo, hi), jnp.clip(K * u, lo, hi))
    return y, jnp.where(on, dx, 0.0)


def leadlag(x, u, T_lead, T_lag):
    """(1 + s T_lead) / (1 + s T_lag): T_lag dx/dt = u - x, y = x + (T_lead /
    T_lag)(u - x); T_lag = 0 (then T_lead = 0): y = u."""
    on = T_lag > 0
    y = jnp.where(on, x + T_lead / _safe(T_lag) * (u - x), u)
    return y, jnp.where(on, (u - x) / _safe(T_lag), 0.0)


def washout(x, u, K, T):
    """s K / (1 + s T): T dx/dt = u - x, y = (K / T)(u - x); T = 0 (then K = 0):
    y = 0."""
    on = T > 0
    y = jnp.where(on, K / _safe(T) * (u - x), 0.0)
    return y, jnp.where(on, (u - x) / _safe(T), 0.0)


def second_order_lag(x1, x2, u, a1, a2):
    """1 / (1 + a1 s + a2 s^2), states (x1, x2) = (y, dy/dt) when a2 > 0; a2 = 0,
    a1 > 0: the first-order lag 1 / (1 + a1 s) in x1 (x2 a placeholder at 0);
    a1 = a2 = 0: y = u. Returns (y, dx1, dx2)."""
    second, first = a2 > 0, (a2 <= 0) & (a1 > 0)
    y = jnp.where(second | first, x1, u)
    dx1 = jnp.where(second, x2, jnp.where(first, (u - x1) / _safe(a1), 0.0))
    dx2 = jnp.where(second, (u - x1 - a1 * x2) / _safe(a2), 0.0)
    return y, dx1, dx2


def second_order_leadlag(x1, x2, u, a3, a4, a5, a6):
    """(1 + a5 s + a6 s^2) / (1 + a3 s + a4 s^2) in controllable form: with a4 > 0,
    dx1/dt = x2, a4 dx2/dt = u - x1 - a3 x2, y = x1 + a5 x2 + a6 dx2/dt; a4 = 0
    (then a6 = 0), a3 > 0: (1 + a5 s) / (1 + a3 s) in x1; a3 = a4 = 0 (then a5 =
    a6 = 0): y = u. Returns (y, dx1, dx2)."""
    second, first = a4 > 0, (a4 <= 0) & (a3 > 0)
    ddx = (u - x1 - a3 * x2) / _safe(a4)
    dfirst = (u - x1) / _safe(a3)
    y = jnp.where(
        second,
        x1 + a5 * x2 + a6 * ddx,
        jnp.where(first, x1 + a5 * dfirst, u),
    )
    dx1 = jnp.where(second, x2, jnp.where(first, dfirst, 0.0))
    dx2 = jnp.where(second, ddx, 0.0)
    return y, dx1, dx2


def regulated(meas):
    """The voltage an exciter regulates (pu): the compensated voltage "Vc" of a
    load/line-drop compensator (IEEEVC) where the closed loop provides one, else
    the terminal voltage "Vt"."""
    return meas["Vc"] if "Vc" in meas else meas["Vt"]


def fex(i_n):
    """FEX(IN): the rectifier regulation function of IEEE 421.5 (PSS/E's AC and
    ST3A/ST4B exciters), the ratio of a rectifier's output voltage to its open-
    circuit voltage for the commutating load IN = KC Ifd / VE (pu/pu):

        IN <= 0: 1;  IN <= 0.433: 1 - 0.577 IN;  IN <= 0.75: sqrt(0.75 - IN^2);
        IN <= 1: 1.732 (1 - IN);  IN > 1: 0.

    Continuous in IN; the square root's argument is guarded for the gradient."""
    mid = jnp.sqrt(jnp.maximum(0.75 - jnp.clip(i_n, 0.433, 0.75) ** 2, 1e-12))
    return jnp.where(
        i_n <= 0.0,
        1.0,
        jnp.where(
            i_n <= 0.433,
            1.0 - 0.577 * i_n,
            jnp.where(
                i_n <= 0.75, mid, jnp.where(i_n <= 1.0, 1.732 * (1.0 - i_n), 0.0)
            ),
        ),
    )


def check(obj, rules) -> None:
    """Validate concrete parameters of `obj`: `rules` is a list of (name, ok-function
    of the NumPy values of `obj`, what is allowed). Skipped under tracing (any field
    traced: a rule may read fields other than the one it names, and `set_params`
    runs these checks on a group whose values may be traced)."""
    if not is_concrete(*jax.tree_util.tree_leaves(obj)):
        return
    for name, ok, allowed in rules:
        require(ok(obj), type(obj).__name__, name, getattr(obj, name), allowed)


def v(obj, name):
    """The NumPy value of field `name` of `obj` (for `check` rules)."""
    return np.asarray(getattr(obj, name), dtype=float)


def proper(lead: str, lag_: str):
    """A `check` rule: the lead-lag (1 + s lead)/(1 + s lag) is proper (lag > 0, or
    lag = lead = 0), with both time constants >= 0."""
    return (
        lag_,
        lambda o: (
            (v(o, lag_) >= 0)
            & (v(o, lead) >= 0)
            & ((v(o, lag_) > 0) | (v(o, lead) == 0))
        ),
        f"must be >= 0, and > 0 where {lead} != 0 (the block would be improper)",
    )


def nonneg(*names):
    return [(n, lambda o, n=n: v(o, n) >= 0, "must be >= 0") for n in names]


def positive(*names):
    return [(n, lambda o, n=n: v(o, n) > 0, "must be > 0") for n in names]


def ordered(lo: str, hi: str):
    return (hi, lambda o: v(o, hi) >= v(o, lo), f"must be >= {lo}")


def require_at_rest(ok, owner: str, name: str, value, allowed: str) -> None:
    """At `init`: refuse (one line) an operating point the device cannot hold, when
    the values are concrete."""
    if is_concrete(ok, value):
        require(np.asarray(ok), owner, name, np.asarray(value), allowed)


def build_group(cls, positions, records, names, pos_field="gen", **extra):
    """Build the group `cls` from PSS/E dyr records: `records[i]` maps CON names to
    floats for the device at `positions[i]`. Extra keys are ignored; a missing one
    is refused in one line naming the model, the record and the name."""
    positions = np.asarray(positions, dtype=np.int64).reshape(-1)
    records = list(records)
    if len(records) != positions.size:
        raise ParameterError(
            f"{cls.__name__}.from_params: {positions.size} positions but "
            f"{len(records)} records"
        )
    cols = {}
    for n in names:
        col = []
        for i, rec in enumerate(records):
            if n not in rec:
                raise ParameterError(
                    f"{cls.__name__} record {i} (position {positions[i]}) has no {n}"
                )
            try:
                col.append(float(rec[n]))
            except (TypeError, ValueError):
                raise ParameterError(
                    f"{cls.__name__} record {i}: {n} = {rec[n]!r} is not a number"
                ) from None
        cols[n] = np.asarray(col, dtype=np.float64)
    return cls(**{pos_field: positions}, **cols, **extra)
