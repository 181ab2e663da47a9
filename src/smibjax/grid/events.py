"""Events as data: faults, branch trips and reclosures, generator trips, load steps
and trips, controller reference steps.

Each event is an equinox Module whose fields may be traced (times, locations, fault
impedances, even the faulted bus or branch position), so a batch of scenarios is a
vmap over events of one structure. An event contributes one or two *switch times*
(`switches`); the network is piecewise constant between them and the solver restarts
at each (`jump_ts`), so the switch times stay differentiable.

The switch times of a scenario are applied in the order the events list them
(`BusFault` lists its on and off times in turn): stage j of the run is the network
after the first j switches. With concrete times `check_order` refuses a list that is
out of time order; under `jit` the order is trusted (draw times in order).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from .._errors import ParameterError
from .._validate import is_concrete, require

if TYPE_CHECKING:
    from .loop import Case

__all__ = [
    "BusFault",
    "LineFault",
    "BranchTrip",
    "BranchClose",
    "GenTrip",
    "LoadStep",
    "RefStep",
    "REF_SIGNALS",
    "Event",
    "switch_times",
    "check_order",
    "check_events",
    "check_steps",
    "check_positions",
]

Scalar = Float[Array, ""]


def _f(x):
    return jnp.asarray(x, dtype=jnp.float64)


def _i(x):
    return jnp.asarray(x, dtype=jnp.int32)


def _check(ev, position: str, times=(), impedance=False) -> None:
    """`ParameterError` (one line) for concrete fields out of range: a negative
    position, a time that is not finite and >= 0, times out of order (`times` in
    their order), a fault impedance that is not finite and >= 0."""
    name = type(ev).__name__
    fields = [position, *times] + (["r", "x"] if impedance else [])
    vals = [getattr(ev, f) for f in fields]
    if not is_concrete(*vals):
        return
    v = {f: np.asarray(a) for f, a in zip(fields, vals, strict=True)}
    require(v[position] >= 0, name, position, v[position], "must be >= 0 (a position)")
    for f in times:
        require(np.isfinite(v[f]) & (v[f] >= 0), name, f, v[f], "must be finite, >= 0")
    for a, b in zip(times, times[1:], strict=False):
        require(v[b] >= v[a], name, b, v[b], f"must be >= {a} = {{}}", v[a])
    if impedance:
        for f in ("r", "x"):
            require(
                np.isfinite(v[f]) & (v[f] >= 0), name, f, v[f], "must be finite, >= 0"
            )


class BusFault(eqx.Module):
    """A three-phase fault at bus position `bus` from `t_on` to `t_off` (s) through
    the impedance r + j x (pu, system base); r = x = 0 is a bolted fault (the bus
    voltage is held at exactly zero)."""

    bus: Int[Array, ""] = eqx.field(converter=_i)
    t_on: Scalar = eqx.field(converter=_f)
    t_off: Scalar = eqx.field(converter=_f)
    r: Scalar = eqx.field(converter=_f, default=0.0)
    x: Scalar = eqx.field(converter=_f, default=0.0)

    def __check_init__(self):
        _check(self, "bus", ("t_on", "t_off"), impedance=True)

    def switches(self):
        return (self.t_on, self.t_off)


class LineFault(eqx.Module):
    """A three-phase fault on branch position `branch` at fraction `frac` in (0, 1) of
    its length from its from-bus, from `t_on` to `t_off` (s), through r + j x (pu).
    The branch is split at the fault point (series impedance and charging in
    proportion; a transformer's tap stays at the from side); at `t_off` the fault
    is removed and the branch is whole again (to clear by opening the branch, add a
    `BranchTrip` at the same time)."""

    branch: Int[Array, ""] = eqx.field(converter=_i)
    frac: Scalar = eqx.field(converter=_f)
    t_on: Scalar = eqx.field(converter=_f)
    t_off: Scalar = eqx.field(converter=_f)
    r: Scalar = eqx.field(converter=_f, default=0.0)
    x: Scalar = eqx.field(converter=_f, default=0.0)

    def __check_init__(self):
        _check(self, "branch", ("t_on", "t_off"), impedance=True)
        if is_concrete(self.frac):
            f = np.asarray(self.frac)
            require((f > 0) & (f < 1), "LineFault", "frac", f, "must lie in (0, 1)")

    def switches(self):
        return (self.t_on, self.t_off)


class BranchTrip(eqx.Module):
    """Branch position `branch` opens at `t` (s)."""

    branch: Int[Array, ""] = eqx.field(converter=_i)
    t: Scalar = eqx.field(converter=_f)

    def __check_init__(self):
        _check(self, "branch", ("t",))

    def switches(self):
        return (self.t,)


class BranchClose(eqx.Module):
    """Branch position `branch` closes (recloses) at `t` (s)."""

    branch: Int[Array, ""] = eqx.field(converter=_i)
    t: Scalar = eqx.field(converter=_f)

    def __check_init__(self):
        _check(self, "branch", ("t",))

    def switches(self):
        return (self.t,)


class GenTrip(eqx.Module):
    """Generator position `gen` trips at `t` (s): it stops injecting current, its
    states are frozen and it leaves the centre of inertia."""

    gen: Int[Array, ""] = eqx.field(converter=_i)
    t: Scalar = eqx.field(converter=_f)

    def __check_init__(self):
        _check(self, "gen", ("t",))

    def switches(self):
        return (self.t,)


# issue 47, part 3: load steps and trips, reference steps


class LoadStep(eqx.Module):
    """The load at position `load` of `System.loads` changes by `delta` times its
    power-flow power at `t` (s): +0.1 is a 10 % step up, -1 trips it. Every part of
    the load (constant impedance, and with a load model constant power and constant
    current) scales alike; the impedance part is a shunt change at its bus (an
    exact low-rank update of the network, like a fault's)."""

    load: Int[Array, ""] = eqx.field(converter=_i)
    delta: Scalar = eqx.field(converter=_f)
    t: Scalar = eqx.field(converter=_f)

    def __check_init__(self):
        _check(self, "load", ("t",))
        if is_concrete(self.delta):
            d = np.asarray(self.delta)
            require(
                np.isfinite(d) & (d >= -1),
                "LoadStep",
                "delta",
                d,
                "must be finite and >= -1 (a relative change; -1 trips the load)",
            )

    def switches(self):
        return (self.t,)


REF_SIGNALS = ("Vref", "Pref")


class RefStep(eqx.Module):
    """A step of `delta` at `t` (s) in a reference of the controller at generator
    position `gen`: `signal` "Vref" (the exciter's voltage reference, pu: the step
    enters the exciter's summing junction where Vref and the stabilizer's signal
    VOTHSG enter, so it is a step of Vref for every PSS/E exciter) or "Pref" (the
    governor's reference, in that model's own reference units: PSS/E's PREF or
    speed reference, the `ref` its `init` returns; e.g. TGOV1's R Pm0, IEEEG1's
    P0)."""

    gen: Int[Array, ""] = eqx.field(converter=_i)
    delta: Scalar = eqx.field(converter=_f)
    t: Scalar = eqx.field(converter=_f)
    signal: str = eqx.field(static=True, default="Vref")

    def __check_init__(self):
        _check(self, "gen", ("t",))
        if self.signal not in REF_SIGNALS:
            raise ParameterError(
                f"RefStep.signal = {self.signal!r} is not allowed: one of "
                f"{', '.join(REF_SIGNALS)}"
            )
        if is_concrete(self.delta):
            d = np.asarray(self.delta)
            require(np.isfinite(d), "RefStep", "delta", d, "must be finite")

    def switches(self):
        return (self.t,)


Event = BusFault | LineFault | BranchTrip | BranchClose | GenTrip | LoadStep | RefStep


def switch_times(events) -> Float[Array, " n_switch"]:
    """Every switch time of `events`, in their order (s)."""
    ts = [t for e in events for t in e.switches()]
    if not ts:
        return jnp.zeros((0,))
    return jnp.stack([jnp.asarray(t, dtype=jnp.float64) for t in ts])


def check_order(events) -> None:
    """ValueError (one line) if concrete switch times are out of order or negative
    (for a batch of scenarios, in any scenario)."""
    try:
        ts = np.asarray(switch_times(events))
    except Exception:  # traced: nothing to check
        return
    # (n_switch,) or, for a batch of scenarios, (n_switch, batch)
    if ts.size and (
        np.any(np.diff(ts, axis=0) < 0)
        or np.any(ts[0] < 0)
        or not np.all(np.isfinite(ts))
    ):
        raise ParameterError(
            f"event times {ts.tolist()} must be finite, >= 0 and in the order the "
            "events are listed"
        )


def check_positions(
    events, n_bus: int, n_branch: int, n_gen: int, n_load: int | None = None
) -> None:
    """`ParameterError` (one line) if a concrete position is past the case's buses,
    branches or generators (positions are 0-based; the command line takes PSS/E
    numbers)."""
    for e in events:
        for field, n, what in (
            ("bus", n_bus, "buses"),
            ("branch", n_branch, "branches"),
            ("gen", n_gen, "generators"),
            ("load", n_load, "loads"),
        ):
            if not hasattr(e, field) or n is None:
                continue
            p = getattr(e, field)
            if is_concrete(p):
                require(
                    np.asarray(p) < n,
                    type(e).__name__,
                    field,
                    np.asarray(p),
                    f"must be a position < {n} (the case has {n} {what})",
                )


def check_events(case: Case, events) -> None:
    """`ParameterError`/`ValueError` (one line) for concrete events that do not fit
    the case (a position past its buses, branches or generators) or are out of time
    order; traced events are trusted. Run before tracing: under `jit` the events'
    values are not known."""
    check_order(events)
    sys_ = case.system
    n_load = jnp.shape(sys_.loads.bus)[0]
    check_positions(events, sys_.n_bus, len(sys_.branches.r), case.n_gen, n_load)
    check_steps(case, events)


def check_steps(case: Case, events) -> None:
    """`ParameterError` (one line) for a concrete `RefStep` on a generator without
    that reference: "Vref" needs an exciter that reads the stabilizer's signal Vs
    (where the step enters), "Pref" a governor whose reference is one number per
    device."""
    from .events import RefStep

    for e in events:
        if not isinstance(e, RefStep):
            continue
        try:
            g = int(e.gen)
        except (TypeError, jax.errors.ConcretizationTypeError):
            continue  # traced: trusted
        out = "Efd" if e.signal == "Vref" else "Pm"
        ok = False
        for c, gens in zip(case.controllers, case.layout.controller_gen, strict=True):
            if c.output != out or g not in gens:
                continue
            ok = "Vs" in c.inputs if out == "Efd" else True
        if not ok:
            from .loop import gen_names

            what = "exciter that reads Vs" if out == "Efd" else "governor"
            raise ParameterError(
                f"RefStep {e.signal} on generator {gen_names(case)[g]} is not allowed: "
                f"the generator has no {what} (no {e.signal} to step)"
            )
