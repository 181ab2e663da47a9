"""The built-in cases (src/smibjax/grid/cases/): the PSS/E files against their published
sources, and against ANDES (power flow and a flat-start time-domain run).

References, independent of the files: Kundur, Power System Stability and Control (1994),
Example 12.6 (the generators' load flow); the solved load flow of MATPOWER's case39.m
(data of Athay, Podmore, Virmani 1979 / Pai 1989); Pai (1989) Appendix's machine H and
X'd on 100 MVA; the paper's SMIB operating point (MODEL.md section 1, `Plant`).
The ANDES tests are skipped without ANDES (the `bench` environment); the file-structure
and unit-conversion tests run everywhere.
"""

from __future__ import annotations

import cmath
import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from smibjax import Plant
from smibjax.grid.cases import CASES_DIR, case_file, case_files

DATA = Path(__file__).resolve().parent / "data" / "andes_pflow.json"

# Kundur Example 12.6: bus -> (|Et| pu, angle deg, P MW, Q Mvar) of G1..G4
KUNDUR_BOOK = {
    1: (1.03, 20.2, 700.0, 185.0),
    2: (1.01, 10.5, 700.0, 235.0),
    3: (1.03, -6.8, 719.0, 176.0),
    4: (1.01, -17.0, 700.0, 202.0),
}

# MATPOWER case39.m, solved load flow: (bus, Vm pu, Va deg)
IEEE39_PUBLISHED = [
    (1, 1.0393836, -13.536602),
    (2, 1.0484941, -9.7852666),
    (3, 1.0307077, -12.276384),
    (4, 1.00446, -12.626734),
    (5, 1.0060063, -11.192339),
    (6, 1.0082256, -10.40833),
    (7, 0.99839728, -12.755626),
    (8, 0.99787232, -13.335844),
    (9, 1.038332, -14.178442),
    (10, 1.0178431, -8.170875),
    (11, 1.0133858, -8.9369663),
    (12, 1.000815, -8.9988236),
    (13, 1.014923, -8.9299272),
    (14, 1.012319, -10.715295),
    (15, 1.0161854, -11.345399),
    (16, 1.0325203, -10.033348),
    (17, 1.0342365, -11.116436),
    (18, 1.0315726, -11.986168),
    (19, 1.0501068, -5.4100729),
    (20, 0.99101054, -6.8211783),
    (21, 1.0323192, -7.6287461),
    (22, 1.0501427, -3.1831199),
    (23, 1.0451451, -3.3812763),
    (24, 1.038001, -9.9137585),
    (25, 1.0576827, -8.3692354),
    (26, 1.0525613, -9.4387696),
    (27, 1.0383449, -11.362152),
    (28, 1.0503737, -5.9283592),
    (29, 1.0501149, -3.1698741),
    (30, 1.0499, -7.3704746),
    (31, 0.982, 0.0),
    (32, 0.9841, -0.1884374),
    (33, 0.9972, -0.19317445),
    (34, 1.0123, -1.631119),
    (35, 1.0494, 1.7765069),
    (36, 1.0636, 4.4684374),
    (37, 1.0275, -1.5828988),
    (38, 1.0265, 3.8928177),
    (39, 1.03, -14.535256),
]
# MATPOWER case39.m generators: (bus, Pg MW, Qg Mvar)
IEEE39_GEN_PUBLISHED = [
    (30, 250.0, 161.762),
    (31, 677.871, 221.574),
    (32, 650.0, 206.965),
    (33, 632.0, 108.293),
    (34, 508.0, 166.688),
    (35, 650.0, 210.661),
    (36, 560.0, 100.165),
    (37, 540.0, -1.36945),
    (38, 830.0, 21.7327),
    (39, 1000.0, 78.4674),
]
# Pai (1989) Appendix machine data on 100 MVA: bus -> (H s, X'd pu)
PAI_H_XDP = {
    39: (500.0, 0.006),
    31: (30.3, 0.0697),
    32: (35.8, 0.0531),
    33: (28.6, 0.0436),
    34: (26.0, 0.132),
    35: (34.8, 0.05),
    36: (26.4, 0.049),
    37: (24.3, 0.057),
    38: (34.5, 0.057),
    30: (42.0, 0.031),
}

# PSS/E 33 Model Library: number of parameters (ICONs + CONs) after BUS 'MODEL' ID
N_PARAMS = {
    "GENCLS": 2,
    "GENTRA": 8,
    "GENROU": 14,
    "SEXS": 6,
    "IEEEX1": 16,
    "IEEEST": 19,
    "TGOV1": 7,
    "CSVGN1": 10,
}

ANDES_LACKS = {"GENTRA", "CSVGN1"}  # ANDES 2.0's andes/io/psse-dyr.yaml

PAIRS = [
    ("kundur.raw", "kundur_gencls.dyr"),
    ("kundur.raw", "kundur.dyr"),
    ("kundur.raw", "kundur_nopss.dyr"),
    ("ieee39.raw", "ieee39_gencls.dyr"),
    ("ieee39.raw", "ieee39.dyr"),
    ("ieee39.raw", "ieee39_pss.dyr"),
    ("smib.raw", "smib_gencls.dyr"),
]


def dyr_records(name: str) -> list[tuple[int, str, list[float]]]:
    """The records (bus, MODEL, parameters) of a dyr file: fields up to each '/', the
    rest of that line a comment."""
    text = "\n".join(
        line.split("/")[0] + " /" if "/" in line else line
        for line in case_file(name).read_text().splitlines()
    )
    out = []
    for rec in text.split("/"):
        toks = rec.replace(",", " ").split()
        if toks:
            out.append((int(toks[0]), toks[1].strip("'"), [float(t) for t in toks[3:]]))
    return out


def raw_block(name: str, begin: str) -> list[list[str]]:
    """The records of one data block of a raw file (the lines after the 'BEGIN <begin>'
    line up to the next '0 /'), as comma-separated fields without comments."""
    lines = case_file(name).read_text().splitlines()
    start = next(i for i, s in enumerate(lines) if f"BEGIN {begin}" in s) + 1
    out = []
    for s in lines[start:]:
        if s.strip().startswith("0 /") or s.strip() == "Q":
            break
        out.append([f.strip() for f in s.split("/")[0].split(",")])
    return out


# ------------------------------------------------------------ files, without ANDES


def test_case_files_are_package_data():
    assert case_files() == sorted(
        [
            "ieee14.dyr",
            "ieee14.raw",
            "ieee39.dyr",
            "ieee39.raw",
            "ieee39_gencls.dyr",
            "ieee39_pss.dyr",
            "kundur.dyr",
            "kundur.raw",
            "kundur_gencls.dyr",
            "kundur_nopss.dyr",
            "kundur_synex.dyr",
            "smib.dyr",
            "smib.raw",
            "smib_gencls.dyr",
            # ANDES 2.0's public cases (issue 45)
            "nordic44.dyr",
            "nordic44.raw",
            "npcc.dyr",
            "npcc.raw",
            "wecc179.dyr",
            "wecc179.raw",
            # ACTIVSg2000 (issues 45, 46)
            "activsg2000.dyr",
            "activsg2000.raw",
            # NREL's WECC 240-bus system with renewables (issue 47)
            "wecc240.dyr",
            "wecc240.raw",
        ]
    )
    assert (CASES_DIR / "README.md").is_file()
    with pytest.raises(ValueError, match="'nope.raw' is not built in"):
        case_file("nope.raw")


@pytest.mark.parametrize("raw,dyr", PAIRS + [("smib.raw", "smib.dyr")])
def test_dyr_records_match_psse_and_the_raw_generators(raw, dyr):
    gen_buses = {int(r[0]) for r in raw_block(raw, "GENERATOR DATA")}
    recs = dyr_records(dyr)
    for bus, model, params in recs:
        assert len(params) == N_PARAMS[model], (dyr, bus, model)
        assert bus in gen_buses, (dyr, bus, model)
    machines = [
        bus
        for bus, model, _ in recs
        if model in ("GENCLS", "GENROU", "GENTRA", "CSVGN1")
    ]
    assert sorted(machines) == sorted(gen_buses)  # one machine model per generator


def test_kundur_saturation_is_the_books_exponential_at_1_and_1_2():
    # S(psi) = Asat exp(Bsat (psi - psi_T1)) / psi, Kundur Example 12.6
    expect = [0.015 * math.exp(9.6 * (psi - 0.9)) / psi for psi in (1.0, 1.2)]
    for _, model, p in dyr_records("kundur.dyr"):
        if model == "GENROU":
            assert p[12:14] == pytest.approx(expect, rel=2e-5)  # 0.039175, 0.22268


def test_kundur_transformers_are_0_15_on_900_mva():
    xf = raw_block("kundur.raw", "TRANSFORMER DATA")
    for k in range(0, len(xf), 4):
        assert xf[k][5] == "2"  # CZ = 2: impedance on the winding base
        assert [float(v) for v in xf[k + 1][:3]] == [0.0, 0.15, 900.0]


def test_ieee39_machines_are_pai_s_data_on_their_mbase():
    mbase = {int(r[0]): float(r[8]) for r in raw_block("ieee39.raw", "GENERATOR DATA")}
    zx = {int(r[0]): float(r[10]) for r in raw_block("ieee39.raw", "GENERATOR DATA")}
    for bus, model, p in dyr_records("ieee39.dyr"):
        if model == "GENROU":
            h, xdp = PAI_H_XDP[bus]
            assert p[4] * mbase[bus] / 100 == pytest.approx(h, rel=1e-9)
            assert p[8] * 100 / mbase[bus] == pytest.approx(xdp, rel=1e-9)
            assert zx[bus] == pytest.approx(p[8], rel=1e-9)  # ZX = X'd for GENCLS


def test_smib_dyr_is_the_papers_plant():
    plant = Plant()
    recs = {model: p for _, model, p in dyr_records("smib.dyr")}
    tdo, h, d, xd, xq, xdp = recs["GENTRA"][:6]
    assert (tdo, h, xd, xq, xdp) == (4.0, 5.0, 1.1, 0.2, 0.2)
    assert d == pytest.approx(float(plant.D) * 2 * math.pi * float(plant.f), rel=1e-8)
    assert recs["CSVGN1"][0] == 0.0 and recs["CSVGN1"][5] == float(plant.Tr)


# ------------------------------------------------------------ ANDES


class _ParsedOnce:
    """Stands in for `yaml` in andes.io.psse: ANDES parses its 1,900-line
    psse-dyr.yaml with pure-Python PyYAML at every dyr read (1.8 s of each ANDES load
    here); this parses it once and hands out copies (ANDES edits what it gets)."""

    def __init__(self, yaml):
        self._yaml, self._parsed = yaml, None

    def full_load(self, stream):
        if self._parsed is None:
            self._parsed = self._yaml.full_load(stream)
        return copy.deepcopy(self._parsed)


@pytest.fixture(scope="module")
def andes():
    andes = pytest.importorskip("andes")
    psse = pytest.importorskip("andes.io.psse")
    andes.config_logger(stream_level=40)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(psse, "yaml", _ParsedOnce(psse.yaml))
        yield andes


@pytest.fixture(scope="module")
def pflow(andes):
    import make_andes_pflow

    return {
        name: make_andes_pflow.andes_pflow(CASES_DIR / f"{name}.raw")
        for name in make_andes_pflow.CASES
    }


def test_kundur_pflow_reproduces_example_12_6(pflow):
    r = pflow["kundur"]
    for bus, (v, a, p, q) in KUNDUR_BOOK.items():
        i = r["bus"].index(bus)
        g = r["gen_bus"].index(bus)
        assert r["V"][i] == pytest.approx(v, abs=0.01)
        assert r["angle_deg"][i] == pytest.approx(
            a, abs=0.5
        )  # measured: 0.07 deg at most
        assert r["gen_P_MW"][g] == pytest.approx(p, abs=0.5)  # the book rounds to 1 MW
        assert r["gen_Q_Mvar"][g] == pytest.approx(
            q, abs=1.0
        )  # measured: 0.41 Mvar at most


def test_ieee39_pflow_reproduces_the_published_load_flow(pflow):
    r = pflow["ieee39"]
    assert r["bus"] == [b for b, _, _ in IEEE39_PUBLISHED]
    v = np.array([vm for _, vm, _ in IEEE39_PUBLISHED])
    a = np.array([va for _, _, va in IEEE39_PUBLISHED])
    dv = np.abs(np.array(r["V"]) - v).max()
    da = np.abs(np.array(r["angle_deg"]) - a).max()
    assert dv < 0.01 and da < 1.0  # the brief's tolerances
    assert (
        dv < 1e-6 and da < 1e-4
    )  # measured 2.2e-7 pu, 2.2e-5 deg: same data and model
    for bus, pg, qg in IEEE39_GEN_PUBLISHED:
        g = r["gen_bus"].index(bus)
        assert r["gen_P_MW"][g] == pytest.approx(pg, abs=2e-3)
        assert r["gen_Q_Mvar"][g] == pytest.approx(qg, abs=2e-3)


def test_smib_pflow_gives_the_papers_operating_point(pflow):
    plant = Plant()
    r = pflow["smib"]
    i1, i3 = r["bus"].index(1), r["bus"].index(3)
    v1 = cmath.rect(r["V"][i1], math.radians(r["angle_deg"][i1]))
    s1 = complex(r["gen_P_MW"][0], r["gen_Q_Mvar"][0]) / 100.0
    emf = v1 + 1j * float(plant.Xdp) * (s1 / v1).conjugate()  # E' behind X'd
    delta = cmath.phase(emf) - math.radians(r["angle_deg"][i3])
    xs = float(plant.Xdp + plant.XT + plant.XL)
    delta_e = 0.4964
    assert (r["V"][i3], r["angle_deg"][i3]) == pytest.approx((1.0, 0.0), abs=1e-12)
    assert delta == pytest.approx(delta_e, abs=1e-6)
    assert abs(emf) == pytest.approx(float(plant.Pm) * xs / math.sin(delta_e), abs=1e-6)
    assert r["gen_P_MW"][0] == pytest.approx(100.0, abs=1e-6)
    assert r["gen_Q_Mvar"][1] == pytest.approx(0.0, abs=1e-4)  # the SVC: B0 = 0 (9e-6)


def test_andes_pflow_json_is_current(pflow):
    saved = json.loads(DATA.read_text())["cases"]
    assert set(saved) == set(pflow)
    for name, now in pflow.items():
        for key in ("bus", "gen_bus"):
            assert saved[name][key] == now[key]
        for key in ("V", "angle_deg", "gen_P_MW", "gen_Q_Mvar"):
            assert np.allclose(saved[name][key], now[key], rtol=0, atol=1e-8), (
                name,
                key,
            )


@pytest.mark.parametrize("raw,dyr", PAIRS)
def test_andes_flat_start(andes, raw, dyr):
    """1 s of ANDES's time-domain simulation, no event: the states must not move."""
    ss = andes.load(
        str(case_file(raw)),
        addfile=str(case_file(dyr)),
        no_output=True,
        default_config=True,
    )
    ss.PFlow.config.tol = 1e-10
    ss.PFlow.run()
    assert ss.PFlow.converged
    # every dyr record became an ANDES device, but those of the models ANDES lacks
    # (the SVC then stays a static PV generator with Q = 0)
    for model in {m for _, m, _ in dyr_records(dyr)} - ANDES_LACKS:
        n = sum(1 for _, m, _ in dyr_records(dyr) if m == model)
        assert getattr(ss, model).n == n, model
    ss.TDS.config.tf = 1.0
    ss.TDS.config.tstep = 0.05
    ss.TDS.config.tol = 1e-10
    ss.TDS.config.no_tqdm = 1
    ss.TDS.init()
    f0 = np.abs(ss.dae.f).max()  # initial derivatives
    g0 = np.abs(ss.dae.g).max()  # initial algebraic residuals
    assert ss.TDS.run()
    x = np.array(ss.dae.ts.x)
    assert x.shape[0] > 15  # 1 s in steps of 0.05 s
    drift = np.abs(x - x[0]).max()
    assert f0 < 1e-10 and g0 < 1e-8 and drift < 1e-8, (f0, g0, drift)


def _speed_spread_after_tie_trip(andes, dyr: str) -> tuple[float, float]:
    """ANDES: Kundur with `dyr`, one 110 km circuit 7-8 opened at 0.5 s, 8 s simulated;
    the rms over 4 s <= t <= 8 s of the machines' speeds about their mean (pu), and the
    largest |PSS output| (pu; 0 without PSS)."""
    ss = andes.load(
        str(case_file("kundur.raw")),
        addfile=str(case_file(dyr)),
        no_output=True,
        default_config=True,
        setup=False,
    )
    ss.add("Toggle", {"model": "Line", "dev": "Line_3", "t": 0.5})  # 7-8 circuit 1
    ss.setup()
    ss.PFlow.config.tol = 1e-10
    ss.PFlow.run()
    ss.TDS.config.tf = 8.0
    ss.TDS.config.no_tqdm = 1
    assert ss.TDS.run()
    t = np.array(ss.dae.ts.t)
    w = np.array(ss.dae.ts.x)[:, ss.GENROU.omega.a][t >= 4.0]
    vs = np.array(ss.dae.ts.y)[:, ss.IEEEST.vsout.a] if ss.IEEEST.n else np.zeros(1)
    spread = float(np.sqrt(((w - w.mean(axis=1, keepdims=True)) ** 2).mean()))
    return spread, float(np.abs(vs).max())


def test_kundur_pss_damps_the_inter_area_swing(andes):
    """Sign and hook-up of the PSS data: after a tie-circuit trip the 0.6 Hz inter-area
    swing persists without PSS (ANDES's eigenvalues: zeta = 0.002) and dies out with
    the four IEEEST of kundur.dyr (measured rms 6e-4 pu without, 1e-5 with)."""
    without, _ = _speed_spread_after_tie_trip(andes, "kundur_nopss.dyr")
    with_pss, vs_max = _speed_spread_after_tie_trip(andes, "kundur.dyr")
    assert without > 1e-4
    assert with_pss < without / 10
    assert 0 < vs_max < 0.2  # the stabilizer acts, within its limits
