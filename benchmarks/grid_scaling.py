"""The GENCLS ladder (issue 46): how the grid engine's costs grow with the network,
against ANDES 2.0 on the same runs, in one run of this script.

Cases (every machine classical, GENCLS): Kundur (11 buses), IEEE 39, NPCC (140
buses; ANDES's npcc.raw with npcc_full.dyr, GENROU machines read as they are: the
one case not all GENCLS), WECC 179 (ANDES's wecc.raw + wecc_gencls.dyr) and ANDES's GB
network (2,224 buses, 394 GENCLS; built from ANDES's parsed GBnetwork.xlsx, in this
script only). Per case, each in a fresh process (so that its peak memory is its own):
power flow (the sparse default; the dense Newton too with --dense-pf), the operating
point, a 10 s run with a bus fault through j1e-4 pu from 1.0 to 1.1 s saved every
10 ms (compile = the first call less the second; warm = the second), the process's
peak resident memory; ANDES (in its own process) at its defaults (trapezoid, 1/30 s,
tol 1e-4) on the same run; the largest |COI angle difference| between the two over
the run. Growth exponents: least-squares slopes of log(cost) against log(buses).

    python benchmarks/grid_scaling.py                 # all cases
    python benchmarks/grid_scaling.py --cases kundur ieee39 --tag quick

Writes benchmarks/results/grid_scaling.json (grid_scaling_TAG.json with --tag), with
the machine's load averages (`uptime`) before and after each case: the 2 cores are
shared with other jobs, so wall times are loaded figures; CPU seconds are given too.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
XF = 1e-4
T_FAULT, T_CLEAR, T_END, DT = 1.0, 1.1, 10.0, 0.01
CASES = {  # name: (raw, dyr, fault bus number)
    "kundur": ("builtin:kundur-gencls", None, 8),
    "ieee39": ("builtin:ieee39-gencls", None, 16),
    "npcc": ("andes:npcc/npcc.raw", "andes:npcc/npcc_full.dyr", 2),
    "wecc": ("andes:wecc/wecc.raw", "andes:wecc/wecc_gencls.dyr", 2),
    "gb": ("andes:GBnetwork/GBnetwork.xlsx", None, 100),
}


def _andes_path(p: str) -> str:
    import andes

    return str(Path(andes.__file__).parent / "cases" / p[len("andes:") :])


def _files(name):
    raw, dyr, bus = CASES[name]
    if raw.startswith("builtin:"):
        from smibjax.grid.case import case_files

        r, d = case_files(raw[len("builtin:") :])
        return str(r), str(d), bus
    return _andes_path(raw), (_andes_path(dyr) if dyr else None), bus


def _cpu() -> float:
    t = os.times()
    return t.user + t.system


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


# ---------------------------------------------------------------- the GB network


def gb_case(ss=None):
    """smibjax's Case of ANDES's GB network (every machine GENCLS), from ANDES's
    parsed GBnetwork.xlsx: buses, lines and transformers (ANDES's Line: tap on the
    from side, as smibjax's Branches), PQ loads, shunts, PV and slack generators,
    GENCLS H = M / 2, D and X'd (machine base, as a raw file's ZSOURCE)."""
    import tempfile

    import andes

    from smibjax.grid.case import build_case
    from smibjax.grid.psse import read_dyr
    from smibjax.grid.system import (
        Branches,
        Buses,
        Generators,
        Loads,
        Shunts,
        System,
    )

    if ss is None:
        andes.config_logger(stream_level=50)
        ss = andes.load(
            _files("gb")[0], setup=True, no_output=True, default_config=True
        )
    bus_idx = [int(i) for i in ss.Bus.idx.v]
    pos = {b: k for k, b in enumerate(bus_idx)}
    kind = np.ones(len(bus_idx), dtype=int)
    sg = []  # (model, k)
    for m, code in (("PV", 2), ("Slack", 3)):
        mdl = getattr(ss, m)
        for k, b in enumerate(mdl.bus.v):
            kind[pos[int(b)]] = code
            sg.append((mdl, k))
    buses = Buses(
        number=bus_idx,
        kind=kind,
        vm=ss.Bus.v0.v,
        va=ss.Bus.a0.v,
        base_kv=ss.Bus.Vn.v,
        area=np.ones(len(bus_idx)),
    )
    L = ss.Line
    branches = Branches(
        fr=[pos[int(b)] for b in L.bus1.v],
        to=[pos[int(b)] for b in L.bus2.v],
        r=L.r.v,
        x=L.x.v,
        b=L.b.v,
        tap=L.tap.v,
        shift=L.phi.v,
        status=L.u.v,
        is_transformer=(np.asarray(L.tap.v) != 1) | (np.asarray(L.phi.v) != 0),
    )
    shunts = Shunts(
        bus=[pos[int(b)] for b in ss.Shunt.bus.v], g=ss.Shunt.g.v, b=ss.Shunt.b.v
    )
    loads = Loads(bus=[pos[int(b)] for b in ss.PQ.bus.v], p=ss.PQ.p0.v, q=ss.PQ.q0.v)
    gidx = {}
    count: dict[int, int] = {}
    rows = []
    for mdl, k in sg:
        b = int(mdl.bus.v[k])
        count[b] = count.get(b, 0) + 1
        gidx[mdl.idx.v[k]] = (b, str(count[b]))
        rows.append((mdl, k, b, str(count[b])))
    G = ss.GENCLS
    xd = {
        gidx[g][0:2]: (ra, x, sn)
        for g, ra, x, sn in zip(G.gen.v, G.ra.vin, G.xd1.vin, G.Sn.v, strict=True)
    }
    mb = [float(xd.get((b, i), (0, 0, 100.0))[2]) for _, _, b, i in rows]
    gens = Generators(
        bus=[pos[b] for _, _, b, _ in rows],
        p=[float(m.p0.v[k]) for m, k, _, _ in rows],
        q=[float(m.q0.v[k]) for m, k, _, _ in rows],
        v_set=[float(m.v0.v[k]) for m, k, _, _ in rows],
        qmin=[float(m.qmin.v[k]) for m, k, _, _ in rows],
        qmax=[float(m.qmax.v[k]) for m, k, _, _ in rows],
        mbase=mb,
        status=[float(m.u.v[k]) for m, k, _, _ in rows],
        ident=tuple(i for _, _, _, i in rows),
        zsource=[complex(*xd.get((b, i), (0, 0.3, 0))[:2]) for _, _, b, i in rows],
    )
    system = System(
        buses,
        branches,
        shunts,
        loads,
        gens,
        s_base=float(ss.config.mva),
        f_base=float(ss.config.freq),
        name="GB",
    )
    lines = [
        f"{gidx[g][0]} 'GENCLS' {gidx[g][1]} {float(m) / 2!r} {float(d)!r} /"
        for g, m, d in zip(G.gen.v, G.M.vin, G.D.vin, strict=True)
    ]
    path = Path(tempfile.mkdtemp(prefix="gb_")) / "gb.dyr"
    path.write_text("\n".join(lines) + "\n")
    return build_case(system, read_dyr(path), name="gb")


# ---------------------------------------------------------------- one case, smibjax


def smibjax_child(name: str, dense_pf: bool) -> dict:
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from smibjax.grid.case import load_case
    from smibjax.grid.events import BusFault
    from smibjax.grid.operating import operating_point
    from smibjax.grid.powerflow import solve_power_flow
    from smibjax.grid.simulate import coi_angles, simulate_jit

    out: dict = {"load_before": _load()}
    raw, dyr, bus = _files(name)
    t0, c0 = time.perf_counter(), _cpu()
    case = gb_case() if name == "gb" else load_case(raw, dyr)
    out["read_s"] = time.perf_counter() - t0
    sys_ = case.system
    out |= dict(
        buses=sys_.n_bus,
        branches=len(sys_.branches.fr),
        machines=case.n_gen,
        ports=len(case.layout.ports),
    )
    for method in ("sparse", "dense") if dense_pf else ("sparse",):
        solve_power_flow(sys_, method=method)  # compile
        t0, c0 = time.perf_counter(), _cpu()
        pf = solve_power_flow(sys_, method=method)
        out[f"pf_{method}_s"] = time.perf_counter() - t0
        out[f"pf_{method}_cpu_s"] = _cpu() - c0
        out[f"pf_{method}_iterations"] = int(pf.iterations)
    t0 = time.perf_counter()
    op, pf = operating_point(case)
    out["operating_point_s"] = time.perf_counter() - t0
    ev = (BusFault(bus=sys_.bus_index(bus), t_on=T_FAULT, t_off=T_CLEAR, x=XF),)
    opts = dict(t_end=T_END, dt_save=DT)
    t0, c0 = time.perf_counter(), _cpu()
    tr = jax.block_until_ready(simulate_jit(case, op, ev, **opts))
    first, first_cpu = time.perf_counter() - t0, _cpu() - c0
    t0, c0 = time.perf_counter(), _cpu()
    tr = jax.block_until_ready(simulate_jit(case, op, ev, **opts))
    out["warm_s"], out["warm_cpu_s"] = time.perf_counter() - t0, _cpu() - c0
    out["compile_s"] = first - out["warm_s"]
    out["compile_cpu_s"] = first_cpu - out["warm_cpu_s"]
    out["stable"] = bool(tr.stable)
    out["steps"] = int(tr.n_steps)
    out["peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    rel = np.asarray(coi_angles(case, tr.delta, jnp.ones(case.n_gen)))
    out["_t"] = np.asarray(tr.ts).tolist()
    out["_coi"] = rel.tolist()
    out["_gen_bus"] = [
        int(b) for b in np.asarray(sys_.buses.number)[np.asarray(case.layout.gen_bus)]
    ]
    out["_w"] = np.asarray(
        __import__("smibjax.grid.simulate", fromlist=["coi_weights"]).coi_weights(
            case, jnp.ones(case.n_gen)
        )
    ).tolist()
    out["load_after"] = _load()
    return out


# ---------------------------------------------------------------- one case, ANDES


def andes_child(name: str) -> dict:
    import andes

    andes.config_logger(stream_level=50)
    raw, dyr, bus = _files(name)
    out: dict = {"load_before": _load()}
    t0 = time.perf_counter()
    if name == "gb":
        ss = andes.load(raw, setup=False, no_output=True, default_config=True)
        for i in range(ss.Toggler.n):  # the file's own line trips: not this run's
            ss.Toggler.u.v[i] = 0
    else:
        ss = andes.load(
            raw, addfile=dyr, setup=False, no_output=True, default_config=True
        )
    ss.add("Fault", dict(bus=bus, tf=T_FAULT, tc=T_CLEAR, xf=XF, rf=0.0))
    ss.setup()
    for k, v in dict(
        pq2z=1, p2p=0.0, p2i=0.0, p2z=1.0, q2q=0.0, q2i=0.0, q2z=1.0
    ).items():
        setattr(ss.PQ.config, k, v)
    out["read_s"] = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), _cpu()
    ss.PFlow.run()
    out["pf_s"], out["pf_cpu_s"] = time.perf_counter() - t0, _cpu() - c0
    ss.TDS.config.tf = T_END
    ss.TDS.config.no_tqdm = 1
    t0, c0 = time.perf_counter(), _cpu()
    ss.TDS.run()
    out["tds_s"], out["tds_cpu_s"] = time.perf_counter() - t0, _cpu() - c0
    out["peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    t = np.asarray(ss.dae.ts.t)
    mdls = [getattr(ss, m) for m in ("GENCLS", "GENROU") if getattr(ss, m).n]
    delta = np.concatenate([np.asarray(ss.dae.ts.x)[:, m.delta.a] for m in mdls], 1)
    out["_t"] = t.tolist()
    out["_delta"] = delta.tolist()
    out["_bus"] = [int(b) for m in mdls for b in m.bus.v]
    out["_gen"] = [str(g) for m in mdls for g in m.gen.v]
    out["completed"] = bool(t[-1] >= T_END - 1e-9)
    out["load_after"] = _load()
    return out


def _child(kind: str, name: str, dense_pf: bool) -> dict:
    cmd = [sys.executable, __file__, f"--child-{kind}", name] + (
        ["--dense-pf"] if dense_pf else []
    )
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    if r.returncode:
        return {
            "error": r.stderr.strip().splitlines()[-1]
            if r.stderr.strip()
            else str(r.returncode)
        }
    return json.loads(r.stdout.strip().splitlines()[-1])


def _accuracy(s: dict, a: dict) -> float | None:
    """The largest |COI angle difference| (rad) over the run, ANDES interpolated to
    smibjax's samples, machines matched by bus (in order at a bus)."""
    if "error" in s or "error" in a:
        return None
    ts, coi = np.asarray(s["_t"]), np.asarray(s["_coi"])
    ta, da = np.asarray(a["_t"]), np.asarray(a["_delta"])
    keys_s, keys_a = [], []
    for b in s["_gen_bus"]:
        keys_s.append((b, sum(k[0] == b for k in keys_s)))
    for b in a["_bus"]:
        keys_a.append((b, sum(k[0] == b for k in keys_a)))
    if sorted(keys_s) != sorted(keys_a):
        return None
    cols = [keys_a.index(k) for k in keys_s]
    da = da[:, cols]
    w = np.asarray(s["_w"])
    da = da - (da @ w / w.sum())[:, None]
    ai = np.stack([np.interp(ts, ta, da[:, j]) for j in range(da.shape[1])], 1)
    ok = np.all(np.isfinite(coi), axis=1)
    return float(np.max(np.abs(coi[ok] - ai[ok])))


def _slope(x, y):
    x, y = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    return float(np.polyfit(x, y, 1)[0]) if len(x) >= 2 else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument(
        "--dense-pf", action="store_true", help="time the dense power flow too"
    )
    ap.add_argument("--no-andes", action="store_true")
    ap.add_argument("--tag", default="")
    ap.add_argument("--out", default=str(HERE / "results"))
    args = ap.parse_args()
    rows = {}
    for name in args.cases:
        s = _child("smibjax", name, args.dense_pf)
        a = {} if args.no_andes else _child("andes", name, False)
        row = {k: v for k, v in s.items() if not k.startswith("_")}
        if a:
            row["andes"] = {k: v for k, v in a.items() if not k.startswith("_")}
            row["max_coi_angle_difference_rad"] = _accuracy(s, a)
            if "warm_cpu_s" in s and "tds_cpu_s" in a:
                row["warm_cpu_over_andes_tds_cpu"] = s["warm_cpu_s"] / a["tds_cpu_s"]
        rows[name] = row
        print(name, json.dumps(row), flush=True)
    good = [r for r in rows.values() if "warm_s" in r]
    growth = {}
    for key in ("pf_sparse_cpu_s", "warm_cpu_s", "compile_cpu_s", "peak_rss_gib"):
        pts = [(r["buses"], r[key]) for r in good if r.get(key, 0) > 0]
        if len(pts) >= 2:
            growth[key] = _slope(*zip(*pts, strict=True))
    sys.path.insert(0, str(HERE))
    from _results import write_results

    name = f"grid_scaling_{args.tag}" if args.tag else "grid_scaling"
    path = write_results(
        args.out,
        name,
        {
            "t_end": T_END,
            "dt_save": DT,
            "fault": f"bus fault j{XF} pu {T_FAULT}-{T_CLEAR} s",
            "cases": args.cases,
        },
        {"cases": rows, "growth_exponents_vs_buses": growth},
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] in ("--child-smibjax", "--child-andes"):
        if sys.argv[1] == "--child-smibjax":
            res = smibjax_child(sys.argv[2], "--dense-pf" in sys.argv)
        else:
            res = andes_child(sys.argv[2])
        print(json.dumps(res))
    else:
        main()
