"""Seeded fault-scenario distributions (for tuning batches and Monte Carlo).

Times are sampled as fault inception, clearing duration and reclosing delay, so that
t_fault < t_clear <= t_reclose holds by construction.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import jax

from ._parameters import Fault, ParameterError
from ._validate import MAX_MAGNITUDE

__all__ = [
    "FaultDistribution",
    "ScenarioDistribution",
    "sample_faults",
    "sample_scenarios",
]


def _require_finite_range(name: str, lo: float, hi: float, bound=None) -> None:
    """A range [lo, hi] of finite numbers (within +-bound): an infinite end would
    draw inf or NaN scenarios."""
    ok = math.isfinite(lo) and math.isfinite(hi)
    if ok and bound is not None:
        ok = max(abs(lo), abs(hi)) <= bound
    if not ok:
        within = "" if bound is None else f" with |value| <= {bound:g}"
        raise ParameterError(
            f"{name} = [{lo:g}, {hi:g}] is not allowed: must be finite{within}"
        )


@dataclasses.dataclass(frozen=True)
class FaultDistribution:
    """Independent uniform ranges [lo, hi] of each scenario variable (s, s, s, -, pu).

    Defaults: t_fault in [0.2, 1.0] s, clearing duration in [0.05, 0.25] s, reclosing
    1.0-2.5 s after clearing, location in [0.1, 0.9], fault reactance in [0, 0.05].
    """

    t_fault: tuple[float, float] = (0.2, 1.0)
    clear_duration: tuple[float, float] = (0.05, 0.25)
    reclose_delay: tuple[float, float] = (1.0, 2.5)
    fault_location: tuple[float, float] = (0.1, 0.9)
    fault_reactance: tuple[float, float] = (0.0, 0.05)

    def __post_init__(self):
        allowed = {
            "t_fault": (0.0, float("inf"), "within [0, inf)"),
            "clear_duration": (0.0, float("inf"), "> 0 (clearing after the fault)"),
            "reclose_delay": (0.0, float("inf"), ">= 0"),
            "fault_location": (0.0, 1.0, "within (0, 1)"),
            "fault_reactance": (0.0, float("inf"), ">= 0"),
        }
        for f in dataclasses.fields(self):
            r = getattr(self, f.name)
            lo_ok, hi_ok, what = allowed[f.name]
            try:
                lo, hi = (float(r[0]), float(r[1])) if len(r) == 2 else (None, None)
            except (TypeError, ValueError, KeyError, IndexError):  # a table, ...
                lo = hi = None
            if lo is None:
                raise ParameterError(
                    f"{f.name} = {r!r} is not allowed: must be a range [lo, hi]"
                )
            _require_finite_range(f.name, lo, hi)
            if not lo <= hi:
                raise ParameterError(
                    f"{f.name} = [{lo:g}, {hi:g}] is not allowed: empty range (lo > hi)"
                )
            strict = f.name in ("clear_duration", "fault_location")
            bad_lo = lo <= lo_ok if strict else lo < lo_ok
            bad_hi = hi >= hi_ok if f.name == "fault_location" else hi > hi_ok
            if bad_lo or bad_hi:
                raise ParameterError(
                    f"{f.name} = [{lo:g}, {hi:g}] is not allowed: must be {what}"
                )
            object.__setattr__(self, f.name, (lo, hi))

    @classmethod
    def from_dict(cls, d: dict) -> FaultDistribution:
        """From a table of name -> [lo, hi]; unknown names are an error."""
        names = [f.name for f in dataclasses.fields(cls)]
        for k in d:
            if k not in names:
                raise ParameterError(
                    f"unknown scenario key {k!r}: allowed are {', '.join(names)}"
                )
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


def sample_faults(key: jax.Array, n: int, dist: FaultDistribution) -> Fault:
    """`n` scenarios as one batched `Fault` (leading axis n), reproducible from `key`."""
    if n <= 0:
        raise ParameterError(f"n = {n} is not allowed: must be >= 1")
    ks = jax.random.split(key, 5)

    def u(k, r):
        return jax.random.uniform(k, (n,), minval=r[0], maxval=r[1], dtype=float)

    tf = u(ks[0], dist.t_fault)
    tc = tf + u(ks[1], dist.clear_duration)
    tr = tc + u(ks[2], dist.reclose_delay)
    return Fault(
        t_fault=tf,
        t_clear=tc,
        t_reclose=tr,
        lam=u(ks[3], dist.fault_location),
        Xf=u(ks[4], dist.fault_reactance),
    )


PLANT_SCENARIO_NAMES = ("D", "Pm")


@dataclasses.dataclass(frozen=True)
class ScenarioDistribution:
    """A fault distribution, optionally with the plant's true damping D and mechanical
    power Pm (pu) drawn too (uniform in [lo, hi]; `None`: the plant's own value).

    The controller's operating point (delta_e, Pm_ref) stays nominal: the adaptation
    law is what must cope with a true D and Pm that differ from it.
    """

    faults: FaultDistribution = FaultDistribution()
    D: tuple[float, float] | None = None
    Pm: tuple[float, float] | None = None

    def __post_init__(self):
        for name, lo_ok, what in (("D", 0.0, ">= 0"), ("Pm", 0.0, "> 0")):
            r = getattr(self, name)
            if r is None:
                continue
            try:
                lo, hi = float(r[0]), float(r[1])
                if len(r) != 2:
                    raise ValueError
            except (TypeError, ValueError, IndexError):
                raise ParameterError(
                    f"{name} = {r!r} is not allowed: must be a range [lo, hi]"
                ) from None
            _require_finite_range(name, lo, hi, MAX_MAGNITUDE)
            if not lo <= hi:
                raise ParameterError(
                    f"{name} = [{lo:g}, {hi:g}] is not allowed: empty range (lo > hi)"
                )
            bad = lo < lo_ok if name == "D" else lo <= lo_ok
            if bad:
                raise ParameterError(
                    f"{name} = [{lo:g}, {hi:g}] is not allowed: must be {what}"
                )
            object.__setattr__(self, name, (lo, hi))

    @classmethod
    def from_dict(cls, d: dict) -> ScenarioDistribution:
        """From a table of name -> [lo, hi]: the five fault names of
        `FaultDistribution`, plus optionally D and Pm. Unknown names are an error."""
        names = [f.name for f in dataclasses.fields(FaultDistribution)]
        allowed = names + list(PLANT_SCENARIO_NAMES)
        for k in d:
            if k not in allowed:
                raise ParameterError(
                    f"unknown scenario key {k!r}: allowed are {', '.join(allowed)}"
                )
        faults = FaultDistribution.from_dict({k: d[k] for k in names if k in d})
        return cls(faults=faults, **{k: d[k] for k in PLANT_SCENARIO_NAMES if k in d})

    def to_dict(self) -> dict:
        """The inverse of `from_dict` (every fault range; D and Pm if drawn)."""
        out = {k: list(v) for k, v in dataclasses.asdict(self.faults).items()}
        for k in PLANT_SCENARIO_NAMES:
            if getattr(self, k) is not None:
                out[k] = list(getattr(self, k))
        return out


def sample_scenarios(
    seed: int, start: int, stop: int, dist: ScenarioDistribution, plant
) -> tuple[Fault, jax.Array, jax.Array]:
    """Scenarios `start` to `stop - 1` of the sequence defined by `seed`: a batched
    `Fault` and the true D and Pm of each (the plant's values where not drawn).

    Scenario i depends on (seed, i) only (its key is `fold_in(PRNGKey(seed), i)`), so
    any chunking of the sequence, in any order and on any machine, gives the same rows.
    """
    if not 0 <= start < stop:
        raise ParameterError(
            f"scenario range [{start}, {stop}) is not allowed: need 0 <= start < stop"
        )
    fd = dist.faults
    d_rng = dist.D if dist.D is not None else (float(plant.D),) * 2
    p_rng = dist.Pm if dist.Pm is not None else (float(plant.Pm),) * 2
    ranges = (fd.t_fault, fd.clear_duration, fd.reclose_delay, fd.fault_location)
    ranges += (fd.fault_reactance, tuple(d_rng), tuple(p_rng))
    draw = _sampler(tuple(tuple(float(x) for x in r) for r in ranges), stop - start)
    tf, tc, tr, lam, xf, D, Pm = draw(
        jax.numpy.asarray(seed, dtype=jax.numpy.uint32),
        jax.numpy.asarray(start),
    )
    return Fault(t_fault=tf, t_clear=tc, t_reclose=tr, lam=lam, Xf=xf), D, Pm


@functools.lru_cache(maxsize=16)
def _sampler(ranges: tuple, count: int):
    """Jitted draw of `count` consecutive scenarios (compiled once per ranges and
    count: a Monte Carlo chunk costs no per-op dispatch)."""

    @jax.jit
    def draw(seed, start):
        base = jax.random.PRNGKey(seed)

        def one(i):
            ks = jax.random.split(jax.random.fold_in(base, i), 7)

            def u(k, r):
                return jax.random.uniform(k, (), minval=r[0], maxval=r[1], dtype=float)

            tf = u(ks[0], ranges[0])
            tc = tf + u(ks[1], ranges[1])
            tr = tc + u(ks[2], ranges[2])
            return (tf, tc, tr, *(u(ks[j], ranges[j]) for j in range(3, 7)))

        return jax.vmap(one)(start + jax.numpy.arange(count))

    return draw
