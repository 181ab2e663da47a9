"""The tuning problem on a multi-machine case: which device parameters are trained and
how (`GridSpace`), the scenarios, the loss and its gradient, the validation.

**Parameters.** Each trained parameter is a device parameter by name
(`smibjax.grid.params`), e.g. `IEEEST[1:1].KS`. The optimizer works on raw values:
`log(value)` for a `log` transform (positive constants: gains, time constants), the
value itself for `linear`; after every step the raw values are projected into the
bounds (`[log lo, log hi]` for log). A bound that excludes the case's value, or a
log transform of a value <= 0, is refused.

**Scenarios.** Training batch k is drawn with NumPy's `default_rng([seed, k])`: the
faults (`sample_events`) and one load factor per scenario, uniform in
`scenarios.load_factor`. Loads and the non-slack generation are scaled by the same
factor (the slack balances the losses) and the power flow is re-solved inside the
traced loss for every scenario (`operating_point_traced`, differentiable through the
implicit function theorem), so the gradient sees the operating point move with the
parameters and the factor. A scenario whose power flow fails to converge is dropped
from the batch (counted in `dropped`).

**Loss** (per scenario, averaged over the batch), with rel(t) the COI-referred
angles, rel_f their value at the horizon, w(t) the speed deviations (pu), t0 the
fault time, T the horizon, e(t) = max over machines of max(|rel - rel_f| /
band_angle, |w - w_coi| / band_speed) (`coi_speeds`: the common frequency excursion,
which the governors set, is not the stabilizers' to damp):
- `settling`: the time (s) after t0 with e(t) > 1, smoothed: sum of
  sigmoid(2 log e(t)) dt, a differentiable stand-in for the settling time;
- `itae`: (1/T) sum (t - t0) log(1 + e(t)) dt (s), a global pull towards fast decay;
- `overshoot`: the largest |rel - rel_f| after t0 (rad);
- `effort`: the mean square stabilizer output Vs (pu^2) after t0;
- `unstable`: 1 for a run that loses synchronism (its time-domain terms are then
  dropped; no gradient);
- `damping`: the squared hinge max(0, target - zeta)^2 summed over the
  electromechanical modes, worst over `loss.damping_load_factors` (the modal term of
  `smibjax.grid.damping`, with the reference modes refreshed at every validation
  and every `loss.reference_every` steps).

With every time-domain weight 0 the loss is the modal term alone and the training
batch is not simulated (a large case: WECC 179's 650 states); the held-out faults
still judge every validation.
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from smibjax import ParameterError

__all__ = ["GridSpace", "GridProblem", "build_grid", "load_case_from"]

TERMS = ("settling", "itae", "overshoot", "effort", "unstable", "damping")


@dataclasses.dataclass(frozen=True)
class GridSpace:
    """The trained parameters: names (one per trained value), transforms, bounds
    (value space), start values; `tie`: (follower, leader) name pairs (a tie within
    a device, or the members of a group after its first); `signs`: per name, -1 for
    a log transform of a negative value (value = -exp(raw)), else +1; `skipped`:
    the device parameters of a group name left untrained (a time constant the case
    has at 0, a block it does not have)."""

    names: tuple[str, ...]
    transforms: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    start: np.ndarray
    tie: tuple[tuple[str, str], ...] = ()
    signs: tuple[int, ...] = ()
    skipped: tuple[str, ...] = ()

    def _sign(self, k: int) -> int:
        return self.signs[k] if self.signs else 1

    def to_raw(self, values) -> dict:
        return {
            n: jnp.asarray(
                math.log(self._sign(k) * v) if t == "log" else v, dtype=jnp.float64
            )
            for k, (n, t, v) in enumerate(
                zip(self.names, self.transforms, values, strict=True)
            )
        }

    def values(self, raw: dict) -> dict:
        """{name: value} (traced or concrete) of raw parameters, ties included."""
        out = {
            n: (self._sign(k) * jnp.exp(raw[n]) if t == "log" else raw[n])
            for k, (n, t) in enumerate(zip(self.names, self.transforms, strict=True))
        }
        for follower, leader in self.tie:
            out[follower] = out[leader]
        return out

    def raw_bounds(self):
        lo, hi = [], []
        for k, (a, b, t) in enumerate(
            zip(self.lower, self.upper, self.transforms, strict=True)
        ):
            if t == "log":
                s = self._sign(k)
                a, b = sorted((math.log(s * a), math.log(s * b)))
            lo.append(a)
            hi.append(b)
        return np.asarray(lo), np.asarray(hi)

    def project(self, raw: dict) -> dict:
        lo, hi = self.raw_bounds()
        return {n: jnp.clip(raw[n], lo[k], hi[k]) for k, n in enumerate(self.names)}


def load_case_from(cfg: dict):
    """The case of the `[case]` table (one-line `ParameterError` if it cannot be
    loaded)."""
    from smibjax.cli.grid import load_case_reporting
    from smibjax.grid.case import CaseError
    from smibjax.grid.params import ParamError, set_params

    c = cfg["case"]
    try:
        case = load_case_reporting(
            c["name"] or c["raw"], c["dyr"] or None, c["skip_unsupported"]
        )
    except (CaseError, OSError, ValueError) as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ParameterError(f"case: {msg}") from None
    try:
        return set_params(case, {k: float(v) for k, v in c["set"].items()})
    except ParamError as e:
        raise ParameterError(f"case.set: {e}") from None


def _expand(case, name: str, per_device: bool) -> list[str]:
    from smibjax.grid.loop import gen_names
    from smibjax.grid.params import ParamError, _locate, parse_name

    model, dev, par = parse_name(name)
    if model in {type(s).__name__ for s in case.svcs}:
        raise ParamError(
            f"{name}: {model} is a shunt device at a bus, which parameter names "
            "(MODEL[BUS:ID].PARAM of a generator's devices) do not address yet: "
            "not tunable"
        )
    _locate(case, name)  # raises ParamError for a name the case lacks
    if dev is not None or not per_device:
        return [name]
    _, _, _, idx = _locate(case, name)
    for g in (*case.machines, *case.controllers):
        if type(g).__name__ == model:
            gens = np.asarray(g.gen)
            break
    names = gen_names(case)
    return [f"{model}[{names[int(gens[i])]}].{par}" for i in idx]


def _base_name(name: str) -> str:
    from smibjax.grid.params import parse_name

    model, _, par = parse_name(name)
    return f"{model}.{par}"


def _start(case, name: str) -> float:
    """The start value of a trained name (its first device's)."""
    from smibjax.grid.params import get_param

    return float(np.asarray(get_param(case, name))[0])


def _groups(case, gcfg: dict):
    """[(label, [device parameter names])] of `gains.groups`: each group one
    trained value, its members one model and one parameter."""
    from smibjax.grid.params import ParamError, parse_name

    out = []
    for label, members in gcfg.get("groups", {}).items():
        names = []
        for m in members:
            names += _expand(case, m, True)
        kinds = {_base_name(n) for n in names}
        if len(kinds) > 1:
            raise ParamError(
                f"gains.groups.{label}: a group ties one parameter of one model, not "
                f"{', '.join(sorted(kinds))} (a tie across models or parameters)"
            )
        if len(names) < 2:
            raise ParamError(f"gains.groups.{label}: a group needs two devices or more")
        parse_name(names[0])
        out.append((label, names))
    return out


def make_space(case, gcfg: dict) -> GridSpace:
    """The `GridSpace` of the `[gains]` table on `case` (one-line errors): the
    names (a group name expanded per device when `per_device`, skipping a time
    constant the case has at 0), the groups (one value per group, the members tied
    to the first), the ties, bounds checked against the parameters' meaning
    (`tuning.grid_bounds`)."""
    from smibjax.grid.params import ParamError, get_param, parse_name

    from .grid_bounds import absent, check_bounds, default_bounds, kind_of

    try:
        names, skipped = [], []
        for n in gcfg["names"]:
            expanded = _expand(case, n, gcfg["per_device"])
            for e in expanded:
                if e in names:
                    raise ParamError(f"gains.names: {e} is named twice")
                if (
                    len(expanded) > 1
                    and parse_name(n)[1] is None
                    and absent(case, e, float(np.asarray(get_param(case, e))[0]))
                ):
                    skipped.append(e)
                    continue
                names.append(e)
        if gcfg["names"] and not names:
            raise ParamError(
                f"gains.names: every device has {', '.join(gcfg['names'])} = 0 (the "
                "block is absent)"
            )
        tie = []
        for label, members in _groups(case, gcfg):
            for m in members:
                if m in names or _base_name(m) in gcfg["names"] and m not in skipped:
                    raise ParamError(
                        f"gains.groups.{label}: {m} is also trained on its own "
                        "(gains.names)"
                    )
                if any(m == f for f, _ in tie):
                    raise ParamError(f"gains.groups.{label}: {m} is in two groups")
            names.append(members[0])
            tie += [(m, members[0]) for m in members[1:]]
        for follower, leader in gcfg["tie"].items():
            get_param(case, follower)
            lm, ld, lp = parse_name(leader)
            fm, fd, fp = parse_name(follower)
            hits = [n for n in names if _base_name(n) == f"{lm}.{lp}" or n == leader]
            if not hits:
                raise ParamError(
                    f"gains.tie.{follower} = {leader!r}: {leader} is not trained"
                )
            if fm != lm:
                raise ParamError(
                    f"gains.tie.{follower} = {leader!r}: a parameter follows one of "
                    "its own model"
                )
            for n in hits:
                tie.append((n[: -len(lp)] + fp, n))
        start = [_start(case, n) for n in names]
    except ParamError as e:
        raise ParameterError(f"gains: {e}") from None
    groups = dict(_groups(case, gcfg))
    known = (
        set(names)
        | {_base_name(n) for n in names}
        | set(gcfg["names"])
        | {m for ms in groups.values() for m in ms}
    )
    for key in (*gcfg["bounds"], *gcfg["transform"]):
        if key not in known:
            raise ParameterError(
                f"gains: {key} has a bound or transform but is not trained "
                f"(gains.names = {gcfg['names']})"
            )
    transforms, lower, upper, signs = [], [], [], []
    for n, v in zip(names, start, strict=True):
        b = gcfg["bounds"].get(n, gcfg["bounds"].get(_base_name(n)))
        t = gcfg["transform"].get(n, gcfg["transform"].get(_base_name(n)))
        meaning = kind_of(*parse_name(n)[::2])
        signed = meaning is not None and meaning[0] == "gain"
        if t is None:
            pos = v > 0 and (b is None or b[0] > 0)
            neg = signed and v < 0 and (b is None or b[1] < 0)
            t = "log" if pos or neg else "linear"
        if t == "log" and not (v > 0 or signed and v < 0):
            raise ParameterError(
                f"gains.transform.{_base_name(n)} = 'log' is not allowed: {n} "
                f"starts at {v:g} (log needs a value > 0"
                + (", or < 0 for a gain)" if signed else ")")
            )
        s = -1 if t == "log" and v < 0 else 1
        lo, hi = b if b is not None else default_bounds(case, n, v, t)
        if t == "log" and not (s * lo > 0 and s * hi > 0):
            raise ParameterError(
                f"gains.bounds.{_base_name(n)} = [{lo:g}, {hi:g}] is not allowed: a "
                "log transform needs bounds of the start value's sign, not 0"
            )
        if not lo <= v <= hi:
            raise ParameterError(
                f"gains.bounds.{_base_name(n)} = [{lo:g}, {hi:g}] is not allowed: it "
                f"excludes the start value {n} = {v:g}"
            )
        check_bounds(case, n, lo, hi, v)
        transforms.append(t)
        lower.append(float(lo))
        upper.append(float(hi))
        signs.append(s)
    return GridSpace(
        names=tuple(names),
        transforms=tuple(transforms),
        lower=np.asarray(lower),
        upper=np.asarray(upper),
        start=np.asarray(start),
        tie=tuple(tie),
        signs=tuple(signs),
        skipped=tuple(skipped),
    )


def fault_distribution(case, scfg: dict):
    """The `FaultDistribution` of `[scenarios]`, its buses/branches checked against
    the case (one line naming what does not exist)."""
    from smibjax.grid.scenarios import (
        FaultDistribution,
        branch_positions,
        bus_positions,
    )

    try:
        dist = FaultDistribution(
            kind=scfg["kind"],
            buses=tuple(int(b) for b in scfg["buses"]),
            branches=tuple(
                tuple(b) if isinstance(b, list) else int(b) for b in scfg["branches"]
            ),
            t_fault=tuple(scfg["t_fault"]),
            clear_after=tuple(scfg["clear_after"]),
            location=tuple(scfg["location"]),
            reclose=tuple(scfg["reclose"]) if scfg["reclose"] else None,
            fault_r=tuple(scfg["fault_r"]),
            fault_x=tuple(scfg["fault_x"]),
        )
        if dist.kind == "bus":
            bus_positions(case.system, dist.buses)
        else:
            branch_positions(case.system, dist.branches)
    except ValueError as e:
        key = "buses" if scfg["kind"] == "bus" else "branches"
        have = [int(b) for b in np.asarray(case.system.buses.number)]
        raise ParameterError(
            f"scenarios.{key} = {scfg[key]!r}: {e} (buses: {have})"
        ) from None
    return dist


def check_power_flows(case, cfg: dict) -> None:
    """Every operating point the run will use converges: both ends of
    `scenarios.load_factor` and the listed load factors (one line naming the first
    factor that does not)."""
    from smibjax.grid.operating import operating_point
    from smibjax.grid.powerflow import PowerFlowError

    lo, hi = cfg["scenarios"]["load_factor"]
    checks = [("scenarios.load_factor", lf) for lf in (lo, hi)]
    checks += [
        ("loss.damping_load_factors", lf) for lf in cfg["loss"]["damping_load_factors"]
    ]
    checks += [
        ("validation.load_factors", lf) for lf in cfg["validation"]["load_factors"]
    ]
    checks.append(("report.load_factor", cfg["report"]["load_factor"]))
    seen = set()
    for key, lf in checks:
        if lf in seen:
            continue
        seen.add(lf)
        try:
            _, pf = operating_point(case, load_factor=lf, gen_factor=lf)
        except PowerFlowError as e:
            raise ParameterError(
                f"{key}: the power flow does not converge at load factor {lf:g} "
                f"({str(e).splitlines()[0]})"
            ) from None
        except ValueError as e:
            raise ParameterError(
                f"{key}: no operating point at load factor {lf:g} "
                f"({str(e).splitlines()[0]})"
            ) from None
        if not np.all(np.isfinite(np.asarray(pf.vm))):
            raise ParameterError(
                f"{key}: the power flow does not converge at load factor {lf:g}"
            )


def draw(case, dist, n: int, seed: int, k: int, lf_range):
    """Batch k of seed `seed`: (events with a leading axis of n, load factors (n,))."""
    from smibjax.grid.scenarios import sample_events

    rng = np.random.default_rng([seed, k])
    ev = sample_events(case.system, dist, n, int(rng.integers(2**31)))
    lf = rng.uniform(lf_range[0], lf_range[1], n)
    return ev, jnp.asarray(lf)


def reference_fault(case, rcfg: dict, dist):
    """The reference fault of the report: a bolted fault at `report.fault_bus` (0: the
    distribution's first bus, else the case's first non-generator bus) at 0.5 s,
    cleared after `report.clear_after` s."""
    from smibjax.grid.events import BusFault

    bus = int(rcfg["fault_bus"]) or (dist.buses[0] if dist.buses else 0)
    if not bus:
        bus = int(np.asarray(case.system.buses.number)[-1])
    try:
        pos = case.system.bus_index(bus)
    except ValueError as e:
        raise ParameterError(f"report.fault_bus = {bus}: {e}") from None
    return bus, (BusFault(bus=pos, t_on=0.5, t_off=0.5 + rcfg["clear_after"]),)


def _machine_mask(case):
    mask = np.zeros(case.n_gen, dtype=bool)
    for gt in case.layout.machine_gen:
        mask[list(gt)] = True
    return mask


def coi_speeds(case, omega):
    """Speed deviations referred to the centre of inertia (pu): omega minus the
    inertia-weighted mean speed of the machines (the synchronous frame's where the
    case has an infinite bus). The common frequency excursion, which the governors
    and not the stabilizers set, is removed."""
    from smibjax.grid.simulate import coi_weights

    mask = jnp.asarray(_machine_mask(case))
    if len(case.sources):
        return omega
    w = coi_weights(case, mask * 1.0)
    return omega - jnp.sum(w * omega, axis=-1, keepdims=True) / jnp.sum(w)


def scenario_terms(case, tr, t0, band_angle, band_speed):
    """The per-scenario loss terms (see the module docstring) of a trajectory."""
    from smibjax.grid.simulate import coi_angles

    mask = jnp.asarray(_machine_mask(case))
    ts = tr.ts
    dt = ts[1] - ts[0]
    ok = tr.stable
    rel = coi_angles(case, jnp.nan_to_num(tr.delta), mask * 1.0)
    dev = jnp.abs(rel - rel[-1]) / band_angle
    spd = jnp.abs(coi_speeds(case, jnp.nan_to_num(tr.omega))) / band_speed
    e = jnp.max(jnp.where(mask, jnp.maximum(dev, spd), 0.0), axis=-1)
    after = (ts >= t0).astype(ts.dtype)
    le = jnp.log(e + 1e-12)
    settle = jnp.sum(after * jax.nn.sigmoid(2.0 * le)) * dt
    itae = jnp.sum(after * (ts - t0) * jnp.log1p(e)) * dt / ts[-1]
    over = jnp.max(after[:, None] * jnp.where(mask, jnp.abs(rel - rel[-1]), 0.0))
    vs = jnp.nan_to_num(tr.vs)
    effort = jnp.sum(after[:, None] * jnp.where(mask, vs**2, 0.0)) / (
        jnp.sum(after) * jnp.maximum(jnp.sum(mask), 1)
    )
    z = jnp.zeros(())
    return {
        "settling": jnp.where(ok, settle, z),
        "itae": jnp.where(ok, itae, z),
        "overshoot": jnp.where(ok, over, z),
        "effort": jnp.where(ok, effort, z),
        "unstable": jnp.where(ok, z, 1.0),
    }


def em_damping(case, op, ref, mask):
    """Damping ratios of the eigenvalues of the state matrix nearest the reference
    eigenvalues `ref` (a traced complex array; the picks carry no gradient); slots
    with mask 0 (padding) get a harmless stand-in eigenvalue -1 + 1j."""
    from smibjax.grid.modes import damping_ratios, state_matrix

    lam = jnp.linalg.eigvals(state_matrix(case, op))
    dist = jnp.abs(jax.lax.stop_gradient(lam)[None, :] - ref[:, None])
    picked = jnp.where(mask > 0, lam[jnp.argmin(dist, axis=1)], -1.0 + 1.0j)
    return damping_ratios(picked)


class GridProblem(eqx.Module):
    """Everything a run needs, built and checked once (`build_grid`)."""

    cfg: dict = eqx.field(static=True)
    case: object
    space: GridSpace = eqx.field(static=True)
    dist: object = eqx.field(static=True)
    opt: object = eqx.field(static=True)

    def case_at(self, raw: dict):
        from smibjax.grid.params import set_params

        return set_params(self.case, self.space.values(raw))

    def options(self, t_end):
        t = self.cfg["train"]
        return dict(
            t_end=float(t_end),
            dt_save=float(t["dt_save"]),
            rtol=float(t["rtol"]),
            atol=float(t["atol"]),
            max_steps=int(t["max_steps"]),
        )

    def batch(self, k: int, n: int | None = None, seed: int | None = None):
        return draw(
            self.case,
            self.dist,
            int(n or self.cfg["batch"]),
            int(self.cfg["seed"] if seed is None else seed),
            k,
            self.cfg["scenarios"]["load_factor"],
        )


def build_grid(cfg: dict) -> GridProblem:
    """The problem of a grid config: the case, the trained parameters, the fault
    distribution, every power flow checked; one-line `ParameterError`s."""
    from .grid_config import check_grid_config

    check_grid_config(cfg)
    case = load_case_from(cfg)
    space = make_space(case, cfg["gains"])
    dist = fault_distribution(case, cfg["scenarios"])
    reference_fault(case, cfg["report"], dist)
    check_power_flows(case, cfg)
    o = cfg["optimizer"]
    opt = optax.chain(
        optax.clip_by_global_norm(float(o["clip"])), optax.adam(o["learning_rate"])
    )
    return GridProblem(cfg=cfg, case=case, space=space, dist=dist, opt=opt)


def simulate_scenarios(problem: GridProblem, raw, events, lfs, t_end):
    """Trajectories and power-flow verdicts of a batch (vmapped; the power flow
    re-solved per scenario at its load factor)."""
    from smibjax.grid.operating import operating_point_traced
    from smibjax.grid.simulate import simulate_case

    case = problem.case_at(raw)
    opts = problem.options(t_end)

    def one(ev, lf):
        op, pf = operating_point_traced(case, lf, lf)
        return simulate_case(case, op, ev, **opts), pf.converged

    axes = jax.tree_util.tree_map(lambda x: 0 if jnp.ndim(x) else None, events)
    return jax.vmap(one, in_axes=(axes, 0))(events, lfs)


def damping_term(problem: GridProblem, raw, refs):
    """The worst (`loss.damping_reduce` = "max") or mean ("mean") over the damping
    load factors of the squared-hinge damping loss, and the smallest picked damping
    ratio. `refs` = (eigenvalues (n_lf, M), mask (n_lf, M)):
    the reference electromechanical modes per load factor, padded to a fixed M so
    that a refresh with another count of modes does not recompile."""
    from smibjax.grid.operating import operating_point_traced

    case = problem.case_at(raw)
    target = problem.cfg["loss"]["target_damping"]
    lfs = problem.cfg["loss"]["damping_load_factors"]
    lam_ref, mask = refs

    def one(lf, ref, m):  # one load factor; vmapped: one program for all of them
        op, _ = operating_point_traced(case, lf, lf)
        z = em_damping(case, op, ref, m)
        return (
            jnp.sum(m * jnp.maximum(target - z, 0.0) ** 2),
            jnp.min(jnp.where(m > 0, z, jnp.inf)),
        )

    terms, zmin = jax.vmap(one)(jnp.asarray(lfs, dtype=jnp.float64), lam_ref, mask)
    reduce = problem.cfg["loss"].get("damping_reduce", "max")
    red = jnp.mean if reduce == "mean" else jnp.max
    return red(terms), jnp.min(zmin)


REF_SLOTS = 12  # reference modes per load factor (padding; more are an error)


def reference(problem: GridProblem, raw) -> tuple:
    """The electromechanical eigenvalues at each damping load factor (concrete),
    padded to `REF_SLOTS`: (eigenvalues (n_lf, REF_SLOTS), mask)."""
    from smibjax.grid.damping import reference_modes
    from smibjax.grid.operating import operating_point

    case = problem.case_at(raw)
    ops = tuple(
        operating_point(case, load_factor=lf, gen_factor=lf)[0]
        for lf in problem.cfg["loss"]["damping_load_factors"]
    )
    refs = reference_modes(case, ops=ops)
    m = max(REF_SLOTS, *(len(r) for r in refs))
    lam = np.full((len(refs), m), 1e6 + 0j)
    mask = np.zeros((len(refs), m))
    for k, r in enumerate(refs):
        lam[k, : len(r)] = r
        mask[k, : len(r)] = 1.0
    return jnp.asarray(lam), jnp.asarray(mask)


def make_loss(problem: GridProblem):
    """loss(raw, events, lfs, refs) -> (scalar, info): the weighted loss of a batch."""
    lc = problem.cfg["loss"]
    t_end = problem.cfg["train"]["t_end"]

    modal_only = not any(lc[k] for k in TERMS if k != "damping")

    def loss(raw, events, lfs, refs):
        from smibjax.grid.events import switch_times

        if modal_only:
            # every time-domain weight 0: the modal term carries the tuning and the
            # batch is not simulated (the faults judge the parameters at validation)
            d, zmin = damping_term(problem, raw, refs)
            nan = jnp.full((), jnp.nan)
            info = {k: (d if k == "damping" else nan) for k in TERMS}
            info |= {"stable": nan, "dropped": jnp.zeros(()), "zeta_min": zmin}
            return lc["damping"] * d, info
        trs, conv = simulate_scenarios(problem, raw, events, lfs, t_end)
        axes = jax.tree_util.tree_map(lambda x: 0 if jnp.ndim(x) else None, events)
        t0 = jax.vmap(lambda ev: switch_times(ev)[0], in_axes=(axes,))(events)
        terms = jax.vmap(
            lambda tr, t: scenario_terms(
                problem.case, tr, t, lc["band_angle"], lc["band_speed"]
            )
        )(trs, t0)
        keep = conv.astype(jnp.float64)
        n = jnp.maximum(jnp.sum(keep), 1.0)
        mean = {k: jnp.sum(v * keep) / n for k, v in terms.items()}
        d, zmin = damping_term(problem, raw, refs)
        if not lc["damping"]:
            # weight 0: the term adds nothing to the value or the gradient; no
            # reverse pass through the eigenvalues (zeta_min is still reported)
            d, zmin = jax.lax.stop_gradient((d, zmin))
        mean["damping"] = d
        total = sum(lc[k] * mean[k] for k in TERMS)
        info = {
            **mean,
            "stable": jnp.mean(trs.stable * keep) * keep.size / n,
            "dropped": jnp.sum(1.0 - keep),
            "zeta_min": zmin,
        }
        return total, info

    return loss


def make_step(problem: GridProblem):
    """step(raw, opt_state, events, lfs, refs) -> (raw, opt_state, loss, info,
    grad_norm, skipped): one clipped Adam step, projected into the bounds; a
    non-finite gradient skips the update."""
    loss = make_loss(problem)
    grad = eqx.filter_jit(jax.value_and_grad(loss, has_aux=True))

    def step(raw, opt_state, events, lfs, refs):
        (val, info), g = grad(raw, events, lfs, refs)
        gn = float(optax.tree.norm(g))
        if not (math.isfinite(gn) and math.isfinite(float(val))):
            return raw, opt_state, val, info, gn, True
        upd, opt_state = problem.opt.update(g, opt_state, raw)
        raw = problem.space.project(optax.apply_updates(raw, upd))
        return raw, opt_state, val, info, gn, False

    return step, grad
