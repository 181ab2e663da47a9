"""smibjax's models against PSS/E's own simulation results (issue 45, part 7).

PSS/E's channels for small test systems (a 3-bus system with an infinite bus, a
machine and a load; a one-machine-infinite-bus system; the 4-bus TVC system), as
NREL-Sienna/PowerSimulationsDynamics.jl keeps them, are stored in
tests/data/psse/<MODEL>/ (`make_psid_cases.py` there: raw, dyr, the CSV down-sampled
to 20 ms with a header naming each channel, `cases.json` with the event). Each case
is run here through the same event (a line trip at 1 s, or a step of the exciter's
voltage reference at 1 s) with constant-impedance loads (PSID's tests convert the
loads the same way, `transform_load_to_constant_impedance`), and every PSS/E channel
is compared on PSS/E's samples: the largest absolute error per channel and case.

Channels (header of the stored CSV, PSS/E's units): `ANGL g` rotor angle (deg, the
infinite bus's frame), `SPD g` speed deviation (pu), `SPEED g` speed (pu, 1 + SPD),
`VOLT b` bus voltage magnitude (pu), `EFD g` field voltage (pu), `PMECH g`
mechanical power (pu, machine base), `PELEC g` electrical power (pu, system base),
`PFLOW a-b:c` / `QFLOW a-b:c` active / reactive power flow at bus a into branch a-b
circuit c (MW / Mvar). The errors are reported in rad for angles, pu for the others,
pu on the system base for the flows.

    PYTHONPATH=src:. python benchmarks/vs_psse.py            # every case, 20 s
    PYTHONPATH=src:. python benchmarks/vs_psse.py --cases GENROU HYGOV --t-end 5

Writes benchmarks/results/vs_psse.json (vs_psse_TAG.json with --tag) and prints the
table.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "psse"
# the models whose PSS/E results are stored, in this order
MODELS = (
    "GENROU",
    "GENROE",
    "GENSAL",
    "GENSAE",
    "SEXS",
    "IEEEST",
    "STAB1",
    "PSS2A",
    "PSS2B",
    "HYGOV",
    "GAST",
    "TGOV1",
    "EXST1",
)
KINDS = ("ANGL", "SPD", "SPEED", "VOLT", "EFD", "PMECH", "PELEC", "PFLOW", "QFLOW")


@dataclasses.dataclass(frozen=True)
class PsseCase:
    """One stored PSS/E run: its folder (model), name, files, event and channels."""

    model: str
    name: str
    raw: Path
    dyr: Path
    csv: Path
    event: dict

    def reference(self, t_end: float | None = None) -> tuple[np.ndarray, dict]:
        """PSS/E's samples: times (s) up to `t_end` and {channel: values} in the
        stored CSV's units (see the module docstring)."""
        with open(self.csv) as fh:
            header = fh.readline().strip().split(",")
        a = np.loadtxt(self.csv, delimiter=",", skiprows=1, ndmin=2)
        if t_end is not None:
            a = a[a[:, 0] <= t_end + 1e-9]
        return a[:, 0], {h: a[:, i] for i, h in enumerate(header) if i > 0}


def cases(models=MODELS) -> list[PsseCase]:
    """The stored cases of `models` (folders of tests/data/psse)."""
    out = []
    for model in models:
        folder = DATA / model
        for c in json.loads((folder / "cases.json").read_text()):
            out.append(
                PsseCase(
                    model=model,
                    name=c["name"],
                    raw=folder / c["raw"],
                    dyr=folder / c["dyr"],
                    csv=folder / c["csv"],
                    event=c["event"],
                )
            )
    return out


def _gen_position(case, label: str) -> int:
    from smibjax.grid.loop import gen_names

    names = gen_names(case)
    bus, ident = label.split(":")
    key = f"{int(bus)}:{ident.strip()}"
    if key not in names:
        raise KeyError(f"generator {label} is not in {case.name}")
    return names.index(key)


def _setup(pc: PsseCase):
    """(case, operating point, events) of a stored run in smibjax."""
    import equinox as eqx
    import jax.numpy as jnp

    from smibjax.grid.case import load_case
    from smibjax.grid.events import BranchTrip
    from smibjax.grid.operating import operating_point
    from smibjax.grid.scenarios import branch_positions

    case = load_case(pc.raw, pc.dyr)
    ev = pc.event
    if "f_base" in ev:  # the frequency PSS/E ran at, where the raw file says another
        case = _with_f_base(case, float(ev["f_base"]))
    op, _ = operating_point(case)
    if ev["kind"] == "branch_trip":
        b = branch_positions(case.system, [(ev["from"], ev["to"], ev["ckt"])])[0]
        return case, op, (BranchTrip(branch=int(b), t=float(ev["t"])),), 0.0
    if ev["kind"] == "vref":
        # a step of the exciter's voltage reference to `value` (pu) at t: the run
        # starts at rest, so it starts at t with the new reference (no event before
        # it) and its times are shifted by t
        g = _gen_position(case, ev["gen"])
        for i, c in enumerate(case.controllers):
            if c.output == "Efd" and g in tuple(int(x) for x in c.gen):
                k = tuple(int(x) for x in c.gen).index(g)
                ref = op.refs[i]
                new = ref.at[k].set(jnp.asarray(float(ev["value"])))
                op = eqx.tree_at(lambda o, i=i: o.refs[i], op, new)
                return case, op, (), float(ev["t"])
        raise KeyError(f"{pc.name}: no exciter at generator {ev['gen']}")
    raise ValueError(f"{pc.name}: unknown event kind {ev['kind']!r}")


def _with_f_base(case, f_base: float):
    """`case` at the base frequency `f_base` (Hz): its system's and machines'."""
    machines = tuple(dataclasses.replace(m, f_base=f_base) for m in case.machines)
    system = dataclasses.replace(case.system, f_base=f_base)
    return dataclasses.replace(case, system=system, machines=machines)


def _branch_flow(case, vbus, label: str, reactive: bool) -> np.ndarray:
    """P (or Q) at bus a into line a-b circuit c (pu, system base) from the complex
    bus voltages `vbus` (T, n_bus)."""
    ends, ckt = label.split(":")
    a, b = (int(x) for x in ends.split("-"))
    sys_ = case.system
    br = sys_.branches
    num = np.asarray(sys_.buses.number)
    fr, to = num[np.asarray(br.fr)], num[np.asarray(br.to)]
    k = [
        i
        for i in range(len(fr))
        if {int(fr[i]), int(to[i])} == {a, b} and br.ckt[i].strip() == ckt
    ][0]
    if int(br.is_transformer[k]):
        raise ValueError(f"{label}: flows are computed for lines only")
    va, vb = vbus[:, sys_.bus_index(a)], vbus[:, sys_.bus_index(b)]
    z = complex(br.r[k]) + 1j * complex(br.x[k])
    i_ab = (va - vb) / z + 0.5j * float(br.b[k]) * va
    s = va * np.conj(i_ab) * float(br.status[k])
    return np.imag(s) if reactive else np.real(s)


def bus_phasors(case, op, events, ts) -> np.ndarray:
    """Complex bus voltages (pu) at the times `ts` (s) of the run of `case` from
    `op` through `events` (rtol 1e-8): the states from the engine's adaptive solve,
    the network of the stage in force at each sample."""
    import jax
    import jax.numpy as jnp

    from smibjax._options import SolverOptions
    from smibjax._solve import adaptive_solve
    from smibjax.grid.events import switch_times
    from smibjax.grid.loop import evaluate, vector_field
    from smibjax.grid.network import stage_configs, stage_matrices

    cfgs = stage_configs(op.grid, events)
    mats = stage_matrices(op.grid, cfgs, events)
    t_sw = switch_times(events)
    f = vector_field(case, op, mats, t_sw)
    ts = jnp.asarray(ts)
    sol = adaptive_solve(
        f,
        op.y0,
        ts,
        t_sw,
        SolverOptions(rtol=1e-8, atol=1e-10, max_steps=100_000),
        lambda t, y, args, **kw: False,
        dt0=1e-3,
    )
    ys = sol.ys[: ts.shape[0]]
    stage = np.asarray(jnp.sum(ts[:, None] >= t_sw[None, :], axis=1))
    out = np.zeros((ts.shape[0], case.system.n_bus), dtype=complex)
    for s in np.unique(stage):
        i_s = jax.vmap(lambda y, s=int(s): evaluate(case, op, mats, s, y)[2])(ys)
        v_s = np.asarray(mats.bus_voltages(int(s), i_s))
        out[stage == s] = v_s[stage == s]
    return out


def compare(pc: PsseCase, t_end: float = 20.0, rtol: float = 1e-8) -> dict:
    """Run `pc` in smibjax to `t_end` (s) and compare every PSS/E channel on PSS/E's
    samples: {channel: {"max_abs": largest |smibjax - PSS/E| (rad for angles, pu
    otherwise, flows in pu on the system base), "t_max": when (s), "unit": ...}},
    with the run's "stable" flag and the "t_end" used."""
    from smibjax.grid.simulate import simulate_jit

    case, op, events, shift = _setup(pc)
    t_ref, ref = pc.reference(t_end)
    dt = 0.02
    n = int(round((t_end - shift) / dt))
    tr = simulate_jit(
        case, op, events, t_end=n * dt, dt_save=dt, rtol=rtol, atol=rtol * 1e-2
    )
    ts = np.asarray(tr.ts) + shift
    sbase = float(case.system.s_base)
    mbase = np.asarray(case.system.generators.mbase, dtype=float)
    vbus = None
    # PSS/E's row at a branch trip's instant holds the new network's voltages with
    # the controllers' outputs of the old one (SEXS with TE = 0: Efd still at its
    # rest value, then 0.26 pu higher 20 ms later), a mix no state of the model
    # has: the instant itself is not compared (the samples 20 ms after it are)
    at_switch = np.zeros(t_ref.shape, dtype=bool)
    if pc.event["kind"] == "branch_trip":
        at_switch = np.abs(t_ref - float(pc.event["t"])) < 1e-9
    out = {}
    for ch, psse in ref.items():
        kind, target = ch.split(" ", 1)
        if kind in ("ANGL", "SPD", "SPEED", "EFD", "PMECH", "PELEC"):
            g = _gen_position(case, target)
        if kind == "ANGL":
            mine, psse, unit = np.asarray(tr.delta)[:, g], np.deg2rad(psse), "rad"
        elif kind == "SPD":
            mine, unit = np.asarray(tr.omega)[:, g], "pu"
        elif kind == "SPEED":
            mine, unit = 1.0 + np.asarray(tr.omega)[:, g], "pu"
        elif kind == "VOLT":
            b = case.system.bus_index(int(target))
            mine, unit = np.asarray(tr.v_bus)[:, b], "pu"
        elif kind == "EFD":
            mine, unit = np.asarray(tr.efd)[:, g], "pu"
        elif kind == "PMECH":
            mine, unit = np.asarray(tr.pm)[:, g], "pu machine base"
        elif kind == "PELEC":
            mine = np.asarray(tr.pe)[:, g] * mbase[g] / sbase
            unit = "pu system base"
        elif kind in ("PFLOW", "QFLOW"):
            if vbus is None:
                vbus = bus_phasors(case, op, events, np.asarray(tr.ts))
            mine = _branch_flow(case, vbus, target, kind == "QFLOW")
            psse, unit = psse / sbase, "pu system base"
        else:
            raise ValueError(f"{pc.csv}: unknown channel {ch!r}")
        # PSS/E's samples before the shifted start are the rest state: t = shift
        mine_at = np.interp(np.maximum(t_ref, shift), ts, mine)
        err = np.where(at_switch, 0.0, np.abs(mine_at - psse))
        k = int(np.argmax(err))
        out[ch] = {"max_abs": float(err[k]), "t_max": float(t_ref[k]), "unit": unit}
    return {
        "channels": out,
        "stable": bool(tr.stable),
        "t_end": float(t_end),
    }


def table(results: dict) -> str:
    """A Markdown table: case, channel, largest absolute error, when, unit."""
    lines = [
        "| case | channel | max abs error | at t (s) | unit |",
        "|---|---|---|---|---|",
    ]
    for name, r in results.items():
        for ch, c in r["channels"].items():
            lines.append(
                f"| {name} | {ch} | {c['max_abs']:.2e} | {c['t_max']:.2f} "
                f"| {c['unit']} |"
            )
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", nargs="*", default=list(MODELS), help="model folders")
    p.add_argument("--t-end", type=float, default=20.0, help="horizon (s)")
    p.add_argument("--rtol", type=float, default=1e-8, help="solver rtol")
    p.add_argument("--tag", default="", help="suffix of the results file")
    p.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    a = p.parse_args(argv)
    bad = [m for m in a.cases if m not in MODELS]
    if bad:
        print(f"--cases {bad[0]} is not allowed: one of {', '.join(MODELS)}")
        return 2
    from smibjax import configure

    configure(host_devices=False)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from _results import write_results

    from smibjax.grid.psse import PsseError

    results, not_run = {}, {}
    for pc in cases(a.cases):
        t0 = time.perf_counter()
        try:
            r = compare(pc, t_end=a.t_end, rtol=a.rtol)
        except PsseError as e:  # a model smibjax does not read (yet)
            not_run[pc.name] = str(e).split(";")[0]
            print(f"{pc.name}: not run: {not_run[pc.name]}", flush=True)
            continue
        r["wall_s"] = time.perf_counter() - t0
        results[pc.name] = r
        errs = ", ".join(
            f"{ch} {c['max_abs']:.2e} at {c['t_max']:.2f} s"
            for ch, c in r["channels"].items()
        )
        print(f"{pc.name}: {errs} ({r['wall_s']:.1f} s)", flush=True)
    print(table(results))
    name = "vs_psse" + (f"_{a.tag}" if a.tag else "")
    path = write_results(
        a.out,
        name,
        {"cases": a.cases, "t_end": a.t_end, "rtol": a.rtol},
        {"results": results, "not_run": not_run},
    )
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
