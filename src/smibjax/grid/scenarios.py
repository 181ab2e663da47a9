"""Fault scenarios for multi-machine cases, drawn reproducibly.

A `FaultDistribution` describes a family of scenarios of one structure, so that a
batch is one vmapped run:
- kind "bus": a three-phase fault at a bus drawn from `buses` (PSS/E numbers; empty =
  every bus), on at t_fault, cleared (removed) after a clearing time;
- kind "line": a fault at a fraction drawn in `location` along a branch drawn from
  `branches` ((from, to, ckt) triples or positions; empty = every line in service),
  cleared by opening the branch; reclosed `reclose` seconds later when `reclose` is
  given (a range; None = no reclosure).
Times in s; `fault_r`, `fault_x`: fault impedance range (pu).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from .events import BranchClose, BranchTrip, BusFault, LineFault
from .system import System

__all__ = ["FaultDistribution", "sample_events", "bus_positions", "branch_positions"]


@dataclasses.dataclass(frozen=True)
class FaultDistribution:
    kind: str = "bus"
    buses: tuple[int, ...] = ()
    branches: tuple = ()
    t_fault: tuple[float, float] = (0.5, 1.0)
    clear_after: tuple[float, float] = (0.05, 0.1)
    location: tuple[float, float] = (0.1, 0.9)
    reclose: tuple[float, float] | None = None
    fault_x: tuple[float, float] = (0.0, 0.0)
    fault_r: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self):
        if self.kind not in ("bus", "line"):
            raise ParameterError(
                f"fault kind {self.kind!r} is not allowed: 'bus' or 'line'"
            )
        for name in ("t_fault", "clear_after", "location", "fault_x", "fault_r"):
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                raise ParameterError(f"{name} = {[lo, hi]} must be a range lo <= hi")
        if self.t_fault[0] < 0 or self.clear_after[0] <= 0:
            raise ParameterError(
                f"t_fault = {list(self.t_fault)} must be >= 0 and clear_after = "
                f"{list(self.clear_after)} > 0"
            )
        if not (0 < self.location[0] and self.location[1] < 1):
            raise ParameterError(f"location = {list(self.location)} must lie in (0, 1)")

    def t_last(self) -> float:
        """The latest switch time the distribution can draw (s)."""
        t = self.t_fault[1] + self.clear_after[1]
        return t + (self.reclose[1] if self.reclose else 0.0)


def bus_positions(system: System, numbers) -> np.ndarray:
    """Positions of PSS/E bus numbers (all buses if empty); ValueError naming a
    number that is not in the system."""
    if not len(numbers):
        return np.arange(system.n_bus)
    return np.array([system.bus_index(b) for b in numbers], dtype=np.int64)


def branch_positions(system: System, branches) -> np.ndarray:
    """Positions of branches given as positions or (from, to[, ckt]) bus numbers (all
    lines in service if empty); ValueError naming one that does not exist."""
    br = system.branches
    if not len(branches):
        keep = (np.asarray(br.status) > 0) & (np.asarray(br.is_transformer) == 0)
        return np.flatnonzero(keep)
    num = np.asarray(system.buses.number)
    fr, to = num[np.asarray(br.fr)], num[np.asarray(br.to)]
    out = []
    for b in branches:
        if isinstance(b, int | np.integer):
            if not 0 <= b < len(fr):
                raise ParameterError(
                    f"branch position {b} does not exist (0..{len(fr) - 1})"
                )
            out.append(int(b))
            continue
        a, c = int(b[0]), int(b[1])
        ckt = str(b[2]).strip() if len(b) > 2 else None
        hit = [
            k
            for k in range(len(fr))
            if {int(fr[k]), int(to[k])} == {a, c}
            and (ckt is None or not br.ckt or br.ckt[k].strip() == ckt)
        ]
        if not hit:
            raise ParameterError(
                f"branch {a}-{c}{' ' + ckt if ckt else ''} does not exist"
            )
        out.append(hit[0])
    return np.array(out, dtype=np.int64)


def sample_events(system: System, dist: FaultDistribution, n: int, seed: int):
    """n scenarios as a tuple of events with a leading batch axis (numpy RNG
    `default_rng(seed)`: the same seed gives the same scenarios)."""
    rng = np.random.default_rng(seed)
    t_on = rng.uniform(*dist.t_fault, n)
    t_off = t_on + rng.uniform(*dist.clear_after, n)
    fx = rng.uniform(*dist.fault_x, n)
    fr = rng.uniform(*dist.fault_r, n)
    if dist.kind == "bus":
        pos = bus_positions(system, dist.buses)
        bus = pos[rng.integers(0, len(pos), n)]
        return (BusFault(bus=jnp.asarray(bus), t_on=t_on, t_off=t_off, r=fr, x=fx),)
    pos = branch_positions(system, dist.branches)
    br = pos[rng.integers(0, len(pos), n)]
    lam = rng.uniform(*dist.location, n)
    ev = [
        LineFault(branch=jnp.asarray(br), frac=lam, t_on=t_on, t_off=t_off, r=fr, x=fx),
        BranchTrip(branch=jnp.asarray(br), t=t_off),
    ]
    if dist.reclose is not None:
        ev.append(
            BranchClose(branch=jnp.asarray(br), t=t_off + rng.uniform(*dist.reclose, n))
        )
    return tuple(ev)
