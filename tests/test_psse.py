"""smibjax.grid.psse: the PSS/E raw and dyr readers against values worked out by hand
from the PSS/E 33 POM's definitions (tests/data/psse/*, written for these tests), and
against ANDES's own PSS/E reader on the same files and on the cases ANDES ships."""

import ast
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from smibjax.grid import psse

DATA = Path(__file__).parent / "data" / "psse"
CASE = DATA / "case33.raw"
DEFAULTS = DATA / "defaults.raw"
DYR = DATA / "case.dyr"
SVC = DATA / "svc.dyr"


@pytest.fixture(scope="module")
def raw():
    return psse.read_raw(CASE)


@pytest.fixture(scope="module")
def system(raw):
    return psse.to_system(raw)


def _branch(system, ckt):
    k = system.branches.ckt.index(ckt)
    br = system.branches
    return {
        "fr": int(system.buses.number[br.fr[k]]),
        "to": int(system.buses.number[br.to[k]]),
        **{
            n: float(getattr(br, n)[k])
            for n in ("r", "x", "b", "tap", "shift", "status")
        },
        "xf": int(br.is_transformer[k]),
    }


def _shunt_by_bus(system):
    """Total shunt admittance g + j b per PSS/E bus number (buses with none omitted)."""
    out = {}
    for k, g, b in zip(
        system.shunts.bus, system.shunts.g, system.shunts.b, strict=True
    ):
        n = int(system.buses.number[k])
        out[n] = out.get(n, 0.0) + complex(g, b)
    return out


# ------------------------------------------------------------------- raw reader


def test_case_identification(raw, system):
    assert raw.version == 33
    assert raw.sbase == 100.0 and system.s_base == 100.0
    assert raw.basfrq == 50.0 and system.f_base == 50.0
    assert raw.title[0] == "SMALL TEST CASE, EVERY RECORD KIND"
    assert system.name.startswith(
        "SMALL TEST CASE, EVERY RECORD KIND / TRANSFORMERS CW=1,2,3"
    )


def test_buses(system):
    bus = system.buses
    np.testing.assert_array_equal(bus.number, [1, 2, 3, 4, 5, 6, 7, 8])
    np.testing.assert_array_equal(bus.kind, [3, 1, 1, 2, 1, 1, 4, 1])
    np.testing.assert_allclose(bus.vm, [1.02, 1.0, 0.99, 1.01, 0.98, 1.0, 1.0, 0.97])
    va_deg = [0.0, -5.0, -10.0, -8.0, -12.0, -15.0, 0.0, -14.0]
    np.testing.assert_allclose(bus.va, np.deg2rad(va_deg), rtol=1e-15)
    np.testing.assert_allclose(bus.base_kv, [20, 230, 230, 13.8, 115, 230, 66, 34.5])
    np.testing.assert_array_equal(bus.area, [1, 1, 2, 2, 2, 1, 1, 2])
    # quoted names keep their commas and slashes; the padding is stripped
    assert bus.name[:2] == ("GEN, NORTH", "HV 1 / A")
    assert system.bus_index(8) == 7


def test_loads(system):
    ld = system.loads
    # the load at bus 6 is out of service: dropped
    np.testing.assert_array_equal(system.buses.number[ld.bus], [3, 5])
    np.testing.assert_allclose(ld.p, [100.0 / 100, 40.0 / 100])
    np.testing.assert_allclose(ld.q, [50.0 / 100, 10.0 / 100])
    assert ld.ident == ("1", "L2")


def test_generators(system):
    gen = system.generators
    np.testing.assert_array_equal(system.buses.number[gen.bus], [1, 4, 4])
    np.testing.assert_allclose(gen.p, [1.5, 0.8, 0.2])
    np.testing.assert_allclose(gen.q, [0.2, 0.1, 0.0])
    np.testing.assert_allclose(gen.v_set, [1.02, 1.01, 1.01])
    np.testing.assert_allclose(gen.qmax, [3.0, 0.5, 0.1])
    np.testing.assert_allclose(gen.qmin, [-1.0, -0.5, -0.1])
    np.testing.assert_allclose(gen.mbase, [200.0, 100.0, 50.0])
    np.testing.assert_array_equal(
        gen.status, [1.0, 1.0, 0.0]
    )  # G3 kept, out of service
    assert gen.ident == ("1", "G2", "G3")


def test_lines(system):
    assert _branch(system, "1") == {
        "fr": 2, "to": 3, "r": 0.01, "x": 0.1, "b": 0.2,
        "tap": 1.0, "shift": 0.0, "status": 1.0, "xf": 0,
    }  # fmt: skip
    assert _branch(system, "2")["b"] == 0.1
    out = _branch(system, "9")  # out of service: kept with status 0
    assert (out["fr"], out["to"], out["x"], out["status"]) == (3, 6, 0.05, 0.0)


def test_transformer_cw1_cz1_cm1(system):
    """CW = 1: t1 = WINDV1, t2 = WINDV2 in pu of the bus base voltages; the branch is
    tap t1/t2 with the impedance moved through t2: Z t2^2; MAG2 at bus I."""
    t = _branch(system, "T1")
    assert (t["fr"], t["to"], t["xf"]) == (1, 2, 1)
    assert t["tap"] == pytest.approx(1.05 / 0.98, rel=1e-15)
    assert t["r"] == 0.0
    assert t["x"] == pytest.approx(0.05 * 0.98**2, rel=1e-15)
    assert (t["b"], t["shift"], t["status"]) == (0.0, 0.0, 1.0)
    assert _shunt_by_bus(system)[1] == pytest.approx(complex(0.0, -0.002), rel=1e-15)


def test_transformer_cw2_cz2(system):
    """CW = 2: winding voltages in kV over the bus base kV; CZ = 2: Z on SBASE1-2."""
    t = _branch(system, "T2")
    t1, t2 = 14.49 / 13.8, 236.9 / 230.0
    assert t["tap"] == pytest.approx(t1 / t2, rel=1e-15)
    assert t["r"] == pytest.approx(0.002 * 100 / 200 * t2**2, rel=1e-14)
    assert t["x"] == pytest.approx(0.12 * 100 / 200 * t2**2, rel=1e-14)


def test_transformer_cw3_cz3_cm2(system):
    """CW = 3: WINDV in pu of NOMV; CZ = 3: R from the load loss in W, X from |Z|;
    CM = 2: G from the no-load loss in W, |Y| the exciting current in pu on SBASE1-2
    and NOMV1, B = -sqrt(|Y|^2 - G^2) at bus I."""
    t = _branch(system, "T3")
    t1, t2 = 1.02 * 110.0 / 115.0, 1.0 * 34.0 / 34.5
    rw = 3.0e5 / (1e6 * 50.0)  # 0.006 pu on 50 MVA
    xw = math.sqrt(0.08**2 - rw**2)
    assert t["tap"] == pytest.approx(t1 / t2, rel=1e-15)
    assert t["r"] == pytest.approx(rw * 2.0 * t2**2, rel=1e-14)
    assert t["x"] == pytest.approx(xw * 2.0 * t2**2, rel=1e-14)
    k = (115.0 / 110.0) ** 2
    g = 5000.0 / 100e6 * k
    y = 0.01 * 50.0 / 100.0 * k
    assert _shunt_by_bus(system)[5] == pytest.approx(
        complex(g, -math.sqrt(y * y - g * g)) + complex(0.0, 0.25), rel=1e-14
    )  # + the switched shunt's BINIT = 25 Mvar


def test_phase_shifter_and_out_of_service_transformer(system):
    ps = _branch(system, "PS")
    assert ps["shift"] == pytest.approx(math.pi / 6, rel=1e-15)
    assert (ps["tap"], ps["x"], ps["fr"], ps["to"]) == (1.0, 0.1, 2, 6)
    t5 = _branch(system, "T5")
    assert t5["status"] == 0.0 and t5["xf"] == 1
    assert 6 not in _shunt_by_bus(
        system
    )  # T5's MAG2 and the off switched shunt: dropped


def test_shunts(system):
    """Line-end shunts of in-service branches, magnetizing admittances, the loads'
    constant-admittance part (YQ < 0 inductive), fixed and switched shunts in service."""
    sh = _shunt_by_bus(system)
    assert sorted(sh) == [1, 2, 3, 5]
    assert sh[2] == pytest.approx(complex(0.001, 0.01) + complex(0.005, 0.2), rel=1e-15)
    assert sh[3] == pytest.approx(complex(0.0, 0.02) + complex(0.1, -0.05), rel=1e-15)


def test_defaults(recwarn):
    """Blank and missing trailing fields take the POM's defaults."""
    raw = psse.read_raw(DEFAULTS)
    s = psse.to_system(raw)
    assert (raw.sbase, raw.basfrq, raw.title) == (100.0, 60.0, ("DEFAULTS", ""))
    np.testing.assert_array_equal(s.buses.kind, [3, 1])
    np.testing.assert_array_equal(s.buses.vm, [1.0, 1.0])
    load = raw.loads[0]
    assert (load["ID"], load["STATUS"], load["AREA"], load["OWNER"], load["YP"]) == (
        "L1",
        1,
        1,
        1,
        0.0,
    )
    # IP, IQ are converted to constant power at VM = 1.0, with a warning
    assert (s.loads.p[0], s.loads.q[0]) == (pytest.approx(0.6), pytest.approx(0.24))
    assert "constant-current" in str(recwarn.pop(UserWarning).message)
    assert raw.fixed_shunts[0] == {"I": 2, "ID": "1", "STATUS": 1, "GL": 0.0, "BL": 0.0,
                                   "_line": 9}  # fmt: skip
    g1, g2 = raw.generators
    assert (g1["ID"], g1["PG"], g1["QT"], g1["QB"], g1["VS"], g1["MBASE"]) == (
        "1",
        0.0,
        9999.0,
        -9999.0,
        1.0,
        100.0,
    )
    assert (g1["ZR"], g1["ZX"], g1["STAT"]) == (0.0, 1.0, 1)
    assert (g2["ID"], g2["PG"]) == ("G2", 30.0)  # an unquoted ID
    br = raw.branches[0]
    assert (br["J"], br["CKT"], br["R"], br["X"], br["B"], br["ST"]) == (
        2,
        "1",
        0.0,
        0.1,
        0.0,
        1,
    )
    x1, x2 = raw.transformers
    assert (x1["CW"], x1["CZ"], x1["CM"], x1["STAT"], x1["SBASE1-2"]) == (
        1,
        1,
        1,
        1,
        100.0,
    )
    assert (x1["R1-2"], x1["WINDV1"], x1["NOMV1"], x1["ANG1"]) == (0.0, 1.0, 0.0, 0.0)
    # CW = 2, WINDV blank: the winding's nominal voltage, NOMV = 0: the bus base kV
    assert (x2["CW"], x2["CKT"], x2["WINDV1"], x2["WINDV2"]) == (2, "B", 230.0, 230.0)
    assert s.branches.tap[2] == 1.0 and s.branches.x[2] == 0.05
    np.testing.assert_array_equal(s.shunts.g, [0.0])  # the zero fixed shunt is kept


def test_v32_is_read_with_the_v33_layout(tmp_path):
    text = CASE.read_text().replace("0,   100.00, 33,", "0,   100.00, 32,", 1)
    (tmp_path / "v32.raw").write_text(text)
    raw = psse.read_raw(tmp_path / "v32.raw")
    assert raw.version == 32
    ref = psse.to_system(psse.read_raw(CASE))
    np.testing.assert_array_equal(psse.to_system(raw).branches.x, ref.branches.x)


THREE = DATA / "three_winding.raw"


def test_three_winding_transformers():
    """A star point bus per transformer (numbered above the largest bus) and three
    branches winding -> star: Z_1 = (Z12 + Z31 - Z23) / 2 and its rotations, each
    winding's ratio t_w and angle ANGw on the winding side, STAT 3: winding 3 out."""
    s = psse.to_system(psse.read_raw(THREE))
    bus = s.buses
    np.testing.assert_array_equal(bus.number, [1, 2, 3, 7, 8, 9])
    np.testing.assert_array_equal(bus.kind, [3, 1, 1, 1, 1, 1])
    np.testing.assert_allclose(bus.vm[4:], [1.01, 1.0])
    np.testing.assert_allclose(bus.va[4:], [math.radians(-2.0), 0.0])
    np.testing.assert_allclose(bus.base_kv[4:], [345.0, 340.0])  # NOMV1, or bus I's kV
    assert bus.name[4:] == ("STAR 1-2-3 W1", "STAR 1-2-7 W2")
    br = s.branches
    np.testing.assert_array_equal(bus.number[br.fr], [1, 2, 3, 1, 2, 7])
    np.testing.assert_array_equal(bus.number[br.to], [8, 8, 8, 9, 9, 9])
    np.testing.assert_array_equal(br.is_transformer, [1] * 6)
    np.testing.assert_array_equal(br.status, [1, 1, 1, 1, 1, 0])
    assert br.ckt == ("W1",) * 3 + ("W2",) * 3
    # W1: CW = 1, CZ = 2 (Z12 on 200 MVA, Z23 and Z31 on 100 MVA)
    z12, z23, z31 = complex(0.002, 0.1) / 2, complex(0.004, 0.15), complex(0.003, 0.2)
    star = [(z12 + z31 - z23) / 2, (z12 + z23 - z31) / 2, (z23 + z31 - z12) / 2]
    z = br.r[:3] + 1j * br.x[:3]
    np.testing.assert_allclose(z, star, rtol=1e-14, atol=1e-17)
    np.testing.assert_allclose(br.tap[:3], [1.02, 1.0, 0.97], rtol=1e-15)
    np.testing.assert_allclose(br.shift[:3], [0.0, 0.0, math.radians(-5.0)], rtol=1e-15)
    # W2: CW = 3 (NOMV1 = 340 of 345 kV, NOMV2 = 0, NOMV3 = 13.2 of 13.8 kV), CZ = 3
    np.testing.assert_allclose(br.tap[3:], [340 / 345, 1.01, 13.2 / 13.8], rtol=1e-15)
    np.testing.assert_allclose(br.shift[3:], [0.0, 0.0, math.pi / 6], rtol=1e-15)
    r12, r23, r31 = 4e5 / 200e6, 2e5 / 100e6, 3e5 / 100e6  # pu on each pair's base
    z12 = complex(r12, math.sqrt(0.1**2 - r12**2)) * 100 / 200
    z23 = complex(r23, math.sqrt(0.15**2 - r23**2))
    z31 = complex(r31, math.sqrt(0.2**2 - r31**2))
    star = [(z12 + z31 - z23) / 2, (z12 + z23 - z31) / 2, (z23 + z31 - z12) / 2]
    np.testing.assert_allclose(br.r[3:] + 1j * br.x[3:], star, rtol=1e-13, atol=1e-17)
    # W2's magnetizing admittance (CM = 2) at bus 1: on SBASE1-2 = 200 MVA and NOMV1
    k = (345 / 340) ** 2
    g, y = 2e4 / 100e6 * k, 0.005 * 200 / 100 * k
    np.testing.assert_array_equal(bus.number[s.shunts.bus], [1])
    assert complex(s.shunts.g[0], s.shunts.b[0]) == pytest.approx(
        complex(g, -math.sqrt(y * y - g * g)), rel=1e-14
    )


def test_three_winding_out_of_service(tmp_path):
    text = THREE.read_text().replace("'THREE, ONE  ',1,", "'THREE, ONE  ',0,")
    (tmp_path / "off.raw").write_text(text)
    s = psse.to_system(psse.read_raw(tmp_path / "off.raw"))
    np.testing.assert_array_equal(s.branches.status, [0, 0, 0, 1, 1, 0])
    assert s.buses.kind[4] == 4  # the star point of an out-of-service transformer


def test_a_star_leg_of_zero_impedance_is_a_tie(tmp_path):
    """W1 with Z31 = Z12 + Z23 (on the system base: 0.005 + j0.2) has a star leg 2
    of zero impedance (it was refused), read as a tie of j ZERO_Z (1e-4 pu, a finite
    admittance); the other two legs as the formula gives them."""
    w1 = " 2.00000E-3, 1.00000E-1,   200.00, 4.00000E-3, 1.50000E-1,   100.00, 3.00000E-3,"
    text = THREE.read_text()
    assert w1 in text
    text = text.replace(w1, w1.replace("3.00000E-3,", "5.00000E-3,"))
    (tmp_path / "tie.raw").write_text(text)
    s = psse.to_system(psse.read_raw(tmp_path / "tie.raw"))
    br = s.branches
    assert (br.r[1], br.x[1]) == (0.0, psse.ZERO_Z) and psse.ZERO_Z == 1e-4
    z12, z23, z31 = complex(0.002, 0.1) / 2, complex(0.004, 0.15), complex(0.005, 0.2)
    np.testing.assert_allclose(
        [br.r[0] + 1j * br.x[0], br.r[2] + 1j * br.x[2]],
        [(z12 + z31 - z23) / 2, (z23 + z31 - z12) / 2],
        rtol=1e-14,
    )


# ---------------------------------------------------------------- raw errors


def _slug(message):
    """A test id from an error message: its words after `{f}:line:`."""
    words = re.sub(r"^\{f\}(:\d+)?: ", "", message).split()[:6]
    return "-".join(re.sub(r"\W", "", w) for w in words)


HEAD = "0, 100.0, 33, 0, 1, 60.0\nT1\nT2\n"
BUSES = "1, 'A', 230.0, 3\n2, 'B', 230.0, 1\n0 / END OF BUS DATA\n"
TO_GEN = "0 / load\n0 / fixed shunt\n"
TO_BRANCH = TO_GEN + "0 / gen\n"
TO_XF = TO_BRANCH + "0 / branch\n"


RAW_ERRORS = [
    (
        HEAD + BUSES + TO_XF + "1, 2, 0, '1'\n0.0, 0.0\n1.0\n1.0\n",
        "{f}:12: transformer field X1-2: zero impedance (R = X = 0) is not supported",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 0, '1', 1, 2\n0.0, 0.1, -5\n1.0\n1.0\n",
        "{f}:12: transformer field SBASE1-2: -5.0 is not positive",
    ),
    (
        HEAD
        + "1, 'A', 230.0, 3\n2, 'B', 0.0\n0 /\n"
        + TO_XF
        + "1, 2, 0, '1', 2\n0.0, 0.1\n230.0\n1.0\n",
        "{f}:11: transformer field CW: CW = 2, CM = 1 need the base kV of bus 2, "
        "which is 0.0",
    ),
    (
        HEAD
        + BUSES
        + TO_XF
        + "1, 2, 0, '1', 1, 1, 2, 1e6, 0.001\n0.0, 0.1\n1.0\n1.0\n",
        "{f}:12: transformer field MAG2: exciting current 0.001 is below the no-load "
        "loss's conductance (CM = 2)",
    ),
    (
        "0, -100.0, 33\n",
        "{f}:1: case identification field SBASE: -100.0 is not positive",
    ),
    (
        HEAD + BUSES + TO_BRANCH + "1, 2, '1', 0.0, abc\n",
        "{f}:10: branch field X: 'abc' is not a number",
    ),
    (
        HEAD + BUSES + TO_BRANCH + "1, 2, '1', 0.0, nan\n",
        "{f}:10: branch field X: 'nan' is not a number",
    ),
    (HEAD + "inf, 'A', 230.0, 3\n", "{f}:4: bus field I: 'inf' is not an integer"),
    (
        HEAD + BUSES + TO_BRANCH + "1, 2, '1', 0.01\n",
        "{f}:10: branch field X: missing (it has no default)",
    ),
    (
        HEAD + BUSES + TO_BRANCH + "1, 2, '1', 0.0, 0.0\n",
        "{f}:10: branch field X: zero impedance (R = X = 0) is not supported",
    ),
    (
        HEAD + BUSES + TO_BRANCH + "1, 3, '1', 0.0, 0.1\n",
        "{f}:10: branch field J: bus 3 is not in the bus data",
    ),
    (
        HEAD + BUSES + "9, '1', 1, 1, 1, 10.0\n",
        "{f}:7: load field I: bus 9 is not in the bus data",
    ),
    (
        HEAD + BUSES + TO_GEN + "1, '1', 10.0, 0.0, , , , , -1.0\n",
        "{f}:9: generator field MBASE: -1.0 is not positive",
    ),
    (
        "0, 100.0, 36, 0, 1, 60.0\nT1\nT2\n",
        "{f}:1: case identification field REV: version 36 is not supported "
        "(this reader reads PSS/E 32, 33, 34 and 35 raw files)",
    ),
    (  # a version written as a huge number: shown short, not as 309 digits
        "0, 100.0, 1e308, 0, 1, 60.0\nT1\nT2\n",
        "{f}:1: case identification field REV: version 1e+308 is not supported "
        "(this reader reads PSS/E 32, 33, 34 and 35 raw files)",
    ),
    (
        "0, abc, 33\n",
        "{f}:1: case identification field SBASE: 'abc' is not a number",
    ),
    (
        HEAD + "1, 'A, 230.0, 3\n",
        '{f}:4: unterminated quoted string "\'A, 230.0, 3"',
    ),
    (
        HEAD + "1, 'A', 230.0, 3\n1, 'B', 230.0\n",
        "{f}:5: bus field I: bus 1 is already defined on line 4",
    ),
    (HEAD + "1.5, 'A', 230.0, 3\n", "{f}:4: bus field I: '1.5' is not an integer"),
    (
        HEAD
        + BUSES
        + TO_XF
        + "1, 2, 3, '1'\n0.0, 0.1, , 0.0, 0.1, , 0.0, 0.1\n1.0\n1.0\n1.0\n",
        "{f}:11: transformer field K: bus 3 is not in the bus data",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 1, '1'\n0.0, 0.1\n1.0\n1.0\n",
        "{f}:11: transformer record ends early (a 3-winding record has 5 lines)",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 1, '1', 1, 1, 1, 0, 0, 2, '', 5\n"
        "0.0, 0.1, , 0.0, 0.1, , 0.0, 0.1\n1.0\n1.0\n1.0\n",
        "{f}:11: transformer field STAT: 5 is not one of 0, 1, 2, 3, 4",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 0, '1', 1, 1, 1, 0, 0, 2, '', 2\n"
        "0.0, 0.1\n1.0\n1.0\n",
        "{f}:11: transformer field STAT: 2 is not one of 0, 1",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 0, '1'\n0.0, 0.1\n",
        "{f}:11: transformer record ends early (a 2-winding record has 4 lines)",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 0, '1', 4\n0.0, 0.1\n1.0\n1.0\n",
        "{f}:11: transformer field CW: 4 is not one of 1, 2, 3",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 0, '1', 1, 3\n1e6, 0.001, 100\n1.0\n1.0\n",
        "{f}:12: transformer field X1-2: |Z| = 0.001 is below R = 0.01 from the "
        "load loss (CZ = 3)",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 0, '1'\n0.0, 0.1\n0.0\n1.0\n",
        "{f}:13: transformer field WINDV1: 0 is not a winding ratio",
    ),
    (
        HEAD + BUSES + TO_XF + "1, 2, 0, '1'\n0.0, x\n1.0\n1.0\n",
        "{f}:12: transformer field X1-2: 'x' is not a number",
    ),
]


@pytest.mark.parametrize(
    "text, message", RAW_ERRORS, ids=[_slug(m) for _, m in RAW_ERRORS]
)
def test_raw_errors(tmp_path, text, message):
    path = tmp_path / "case.raw"
    path.write_text(text)
    with pytest.raises(psse.PsseError) as err:
        psse.to_system(psse.read_raw(path))
    assert str(err.value) == message.format(f=path)
    assert "\n" not in str(err.value)


# -------------------------------------------------------------------- dyr reader


def test_dyr_models_table():
    assert psse.DYR_MODELS["GENROU"] == (
        "Tdo_p", "Tdo_pp", "Tqo_p", "Tqo_pp", "H", "D", "Xd", "Xq",
        "Xd_p", "Xq_p", "Xd_pp", "Xl", "S10", "S12",
    )  # fmt: skip
    assert psse.DYR_MODELS["GENROE"] == psse.DYR_MODELS["GENROU"]
    assert psse.DYR_MODELS["GENSAL"] == psse.DYR_MODELS["GENSAE"] == (
        "Tdo_p", "Tdo_pp", "Tqo_pp", "H", "D", "Xd", "Xq", "Xd_p", "Xd_pp", "Xl",
        "S10", "S12",
    )  # fmt: skip
    assert psse.DYR_MODELS["IEEEST"][:3] == ("ICS", "IB", "A1")
    assert psse.DYR_MODELS["EXDC2"] == psse.DYR_MODELS["IEEEX1"]
    assert len(psse.DYR_MODELS["IEEEX1"]) == 16 and len(psse.DYR_MODELS["CSVGN1"]) == 10
    assert set(psse.DYR_KINDS) == set(psse.DYR_MODELS)
    # the table's docstring (an attribute docstring, read by mkdocstrings) cites it
    body = ast.parse(Path(psse.__file__).read_text()).body
    k = next(
        i for i, node in enumerate(body)
        if isinstance(node, ast.AnnAssign) and node.target.id == "DYR_MODELS"
    )  # fmt: skip
    doc = body[k + 1].value.value
    assert "PSS/E 33 Model Library" in doc and "andes/io/psse-dyr.yaml" in doc


def test_read_dyr(system):
    recs = psse.read_dyr(DYR)
    assert [(r.bus, r.model, r.ident, r.line) for r in recs] == [
        (1, "GENROU", "1", 2),
        (1, "IEEEX1", "1", 4),
        (1, "IEEEST", "1", 5),
        (1, "TGOV1", "1", 6),
        (4, "GENTRA", "G2", 7),
        (4, "SEXS", "G2", 8),
        (4, "STAB1", "G2", 9),
        (4, "GENCLS", "G3", 10),
        (4, "EXST1", "G3", 11),
    ]
    genrou = recs[0].params  # spans two lines
    assert list(genrou) == list(psse.DYR_MODELS["GENROU"])
    assert (genrou["Tdo_p"], genrou["H"], genrou["Xd_pp"], genrou["S12"]) == (
        8.0,
        6.5,
        0.25,
        0.3,
    )
    assert (recs[2].params["ICS"], recs[2].params["IB"], recs[2].params["KS"]) == (
        1.0,
        0.0,
        10.0,
    )
    assert recs[6].params == {
        "K_T": 20.0, "T": 10.0, "T1_T3": 1.0, "T3": 0.1, "T2_T4": 1.0, "T4": 0.1, "HLIM": 0.05,
    }  # fmt: skip
    assert recs[0].file == str(DYR)
    by_gen = psse.check_dynamics(system, recs)
    assert sorted(by_gen[0]) == ["exciter", "governor", "machine", "pss"]
    assert by_gen[1]["machine"].model == "GENTRA" and by_gen[1]["pss"].model == "STAB1"
    assert (
        by_gen[2]["exciter"].model == "EXST1"
    )  # G3 is out of service: a record is allowed
    svc = psse.read_dyr(SVC)
    assert svc[0].params["CBASE"] == 100.0 and svc[1].params["SE2"] == 1.0


def test_dyr_skip_unsupported(tmp_path):
    """With skip_unsupported: one warning naming every unsupported model (records,
    first line); ANDES's Toggle: its own one warning, skipped with or without."""
    path = tmp_path / "x.dyr"
    path.write_text(
        "1 'GENCLS' 1 3.0 0.0 /\n1 'USRMDL' 1 2 3 /\n2 'USRMDL' 1 4 /\n"
        "Line 'Toggle' Line_8 2.0 /\n3 'WT3G1' 1 5 /\n"
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        recs = psse.read_dyr(path, skip_unsupported=True)
    assert [r.model for r in recs] == ["GENCLS"]
    toggle = (
        f"{path}:4: 1 ANDES Toggle record skipped (ANDES's switching event, not "
        "PSS/E data; give the event to the simulation: --trip-line, --fault-line)"
    )
    assert [str(w.message) for w in caught] == [
        toggle,
        f"{path}:2: dyr models 'USRMDL', 'WT3G1' are not supported; their records "
        "are skipped ('USRMDL': 2 records from line 2; 'WT3G1': 1 record from line 5)",
    ]
    assert psse.unsupported_models(path) == ["USRMDL", "WT3G1"]
    # without skip_unsupported: one refusal naming both, and how to skip them
    with pytest.raises(psse.PsseError) as err:
        psse.read_dyr(path)
    assert str(err.value) == (
        f"{path}:2: dyr models 'USRMDL', 'WT3G1' are not supported (supported: "
        f"{SUPPORTED}); 'USRMDL': 2 records from line 2; 'WT3G1': 1 record from line "
        "5; " + SKIP
    )
    # a Toggle alone is not a refusal
    path.write_text("1 'GENCLS' 1 3.0 0.0 /\n  Line  'Toggle'  Line_1  1.0 /\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert [r.model for r in psse.read_dyr(path)] == ["GENCLS"]
    assert [str(w.message) for w in caught] == [toggle.replace(":4:", ":2:")]


SUPPORTED = ", ".join(psse.DYR_MODELS)
SKIP = (
    "--skip-unsupported (skip_unsupported=True) skips their records, which leaves a "
    "skipped exciter's field voltage and a skipped governor's mechanical power constant"
)


DYR_ERRORS = [
    (
        "/ c\n1 'GENCLS' 1 3.0 0.0 /\n 2 'USRMDL' 1\n 1 2 3 /\n",
        "{f}:3: dyr model 'USRMDL' is not supported (supported: " + SUPPORTED + "); "
        "'USRMDL': 1 record from line 3; " + SKIP,
    ),
    (
        "1 'GENCLS' 1 3.0 /\n",
        "{f}:1: GENCLS record has 1 parameters, expected 2 (H D)",
    ),
    (
        "1 'TGOV1' 1 0.05 0.5 1.05 0.3 1.0 2.0 0.0 0.0 /\n",
        "{f}:1: TGOV1 record has 8 parameters, expected 7 (R T1 VMAX VMIN T2 T3 Dt)",
    ),
    ("1 'GENCLS' 1 3.0\n abc /\n", "{f}:1: GENCLS field D: 'abc' is not a number"),
    ("1 'GENCLS' 1 inf 0 /\n", "{f}:1: GENCLS field H: 'inf' is not a number"),
    (
        "x 'GENCLS' 1 3.0 0.0 /\n",
        "{f}:1: GENCLS field BUS: 'x' is not a bus number",
    ),
    (
        "1 'GENCLS' 1 3.0 0.0 /\n2 'GENCLS' 1 3.0\n",
        "{f}:2: dyr record is not ended by '/'",
    ),
    (
        "1 'GENCLS' /\n",
        "{f}:1: dyr record field ID: missing (a record is BUS 'MODEL' ID ...)",
    ),
]


@pytest.mark.parametrize(
    "text, message", DYR_ERRORS, ids=[_slug(m) for _, m in DYR_ERRORS]
)
def test_dyr_errors(tmp_path, text, message):
    path = tmp_path / "case.dyr"
    path.write_text(text)
    with pytest.raises(psse.PsseError) as err:
        psse.read_dyr(path)
    assert str(err.value) == message.format(f=path)


MACHINES = ", ".join(m for m, k in psse.DYR_KINDS.items() if k == "machine")


DYNAMICS_ERRORS = [
        (
            "1 'GENROU' 1" + " 1.0" * 14 + " /\n9 'GENCLS' 1 3.0 0.0 /\n",
            "{f}:2: GENCLS field BUS: bus 9 is not in the raw file",
        ),
        (
            "1 'GENCLS' 7 3.0 0.0 /\n",
            "{f}:1: GENCLS field ID: no generator '7' at bus 1 in the raw file",
        ),
        (
            "1 'GENCLS' 1 3.0 0.0 /\n1 'GENROU' 1" + " 1.0" * 14 + " /\n",
            "{f}:2: GENROU is a second machine record for generator '1' at bus 1 (the "
            "first: GENCLS on line 1)",
        ),
        (
            "1 'GENCLS' 1 3.0 0.0 /\n1 'SEXS' 1 0.1 10 100 0.05 0 4 /\n"
            "1 'SEXS' 1 0.1 10 100 0.05 0 4 /\n",
            "{f}:3: SEXS is a second exciter record for generator '1' at bus 1 (the "
            "first: SEXS on line 2)",
        ),
        (
            "1 'GENCLS' 1 3.0 0.0 /\n4 'TGOV1' 'G2' 0.05 0.5 1.05 0.3 1.0 2.0 0.0 /\n",
            "{f}:2: TGOV1 for generator 'G2' at bus 4 has no machine record (" + MACHINES + ")",
        ),
        (
            "1 'GENCLS' 1 3.0 0.0 /\n",
            "{f}: generator 'G2' at bus 4 is in service but has no machine record ("
            + MACHINES + ")",
        ),
]  # fmt: skip


@pytest.mark.parametrize(
    "text, message", DYNAMICS_ERRORS, ids=[_slug(m) for _, m in DYNAMICS_ERRORS]
)
def test_check_dynamics_errors(tmp_path, system, text, message):
    path = tmp_path / "case.dyr"
    path.write_text(text)
    with pytest.raises(psse.PsseError) as err:
        psse.check_dynamics(system, psse.read_dyr(path))
    assert str(err.value) == message.format(f=path)


# ------------------------------------------------------------- against ANDES


def _andes(raw, dyr=None):
    andes = pytest.importorskip("andes")
    andes.config_logger(40)
    return andes.load(
        str(raw), addfile=None if dyr is None else str(dyr), setup=True,
        no_output=True, default_config=True,
    )  # fmt: skip


def _compare_with_andes(raw, system, ss, transformers=None):
    """Buses, lines, loads, generators as both readers convert them; `transformers`
    (circuit ids) limits the transformers compared to those whose data both readers
    convert the same way (docs/psse.md lists ANDES's deviations). Returns the number
    of branches compared."""
    num = system.buses.number
    np.testing.assert_array_equal(ss.Bus.idx.v, num)
    np.testing.assert_allclose(ss.Bus.v0.v, system.buses.vm, rtol=1e-14)
    np.testing.assert_allclose(ss.Bus.a0.v, system.buses.va, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(ss.Bus.Vn.v, system.buses.base_kv)
    assert ss.config.mva == system.s_base and ss.config.freq == system.f_base
    L, br = ss.Line, system.branches
    # ANDES keeps no circuit id: match the k-th branch of a bus pair and kind
    ours: dict = {}
    for j in range(len(br.ckt)):
        key = (int(num[br.fr[j]]), int(num[br.to[j]]), int(br.is_transformer[j]))
        ours.setdefault(key, []).append(j)
    count: dict = {}
    seen = 0
    for k in range(L.n):
        key = (int(L.bus1.v[k]), int(L.bus2.v[k]), int(L.trans.v[k]))
        j = ours[key][count.get(key, 0)]
        count[key] = count.get(key, 0) + 1
        if key[2] and transformers is not None and br.ckt[j] not in transformers:
            continue
        seen += 1
        assert L.u.v[k] == br.status[j]
        for a, b in (("r", "r"), ("x", "x"), ("tap", "tap"), ("phi", "shift")):
            assert getattr(L, a).v[k] == pytest.approx(
                float(getattr(br, b)[j]), rel=1e-12
            ), a
        if not key[2]:
            assert L.b.v[k] == pytest.approx(float(br.b[j]), rel=1e-12)
    # loads in service; ANDES folds the constant-admittance part into P, Q at VM:
    # p0 = (PL + YP VM^2) / SBASE, q0 = (QL - YQ VM^2) / SBASE
    andes_on = [k for k in range(ss.PQ.n) if ss.PQ.u.v[k] == 1]
    raw_on = [r for r in raw.loads if r["STATUS"] != 0]
    assert len(andes_on) == len(raw_on) == len(system.loads.p)
    for n, (k, r) in enumerate(zip(andes_on, raw_on, strict=True)):
        v2 = float(system.buses.vm[system.loads.bus[n]]) ** 2
        assert ss.PQ.bus.v[k] == r["I"] == num[system.loads.bus[n]]
        p = float(system.loads.p[n]) + r["YP"] / raw.sbase * v2
        q = float(system.loads.q[n]) - r["YQ"] / raw.sbase * v2
        assert (ss.PQ.p0.v[k], ss.PQ.q0.v[k]) == (
            pytest.approx(p, rel=1e-12),
            pytest.approx(q, rel=1e-12),
        )
    gen = system.generators
    ag = {}
    for m in (ss.PV, ss.Slack):
        for k in range(m.n):
            ag[(int(m.bus.v[k]), str(m.subidx.v[k]).strip())] = [
                m.p0.v[k], m.q0.v[k], m.v0.v[k], m.qmax.v[k], m.qmin.v[k], m.Sn.v[k], m.u.v[k]
            ]  # fmt: skip
    assert len(ag) == len(gen.ident)
    for k, ident in enumerate(gen.ident):
        want = [
            gen.p[k],
            gen.q[k],
            gen.v_set[k],
            gen.qmax[k],
            gen.qmin[k],
            gen.mbase[k],
            gen.status[k],
        ]
        np.testing.assert_allclose(ag[(int(num[gen.bus[k]]), ident)], want, rtol=1e-12)
    return seen


def test_against_andes_on_the_fixture(raw, system):
    """ANDES reads case33.raw the same where its conventions are PSS/E's: the lines,
    the phase shifter PS and the out-of-service T5 (WINDV2 = 1, NOMV = 0, CM = 1)."""
    ss = _andes(CASE)
    assert _compare_with_andes(raw, system, ss, transformers={"PS", "T5"}) == 5
    # where ANDES deviates (docs/psse.md): it ignores WINDV2 for CW = 1 ...
    k = list(ss.Line.bus1.v).index(1)
    assert ss.Line.tap.v[k] == 1.05 and _branch(system, "T1")["tap"] == pytest.approx(
        1.05 / 0.98
    )
    # ... and does not move the impedance through t2 (T2: CW = 2, t2 = 236.9 / 230)
    k = list(ss.Line.bus1.v).index(4)
    assert ss.Line.tap.v[k] == pytest.approx(_branch(system, "T2")["tap"], rel=1e-12)
    assert ss.Line.x.v[k] * (236.9 / 230) ** 2 == pytest.approx(
        _branch(system, "T2")["x"], rel=1e-12
    )


def test_against_andes_on_kundur():
    """ANDES's kundur.raw (PSS/E 32) and kundur_full.dyr: every bus, branch, load and
    generator, and the dyr parameters as ANDES reads them (its own column names)."""
    pytest.importorskip("andes")
    raw = psse.read_raw(_andes_cases() / "kundur" / "kundur.raw")
    system = psse.to_system(raw)
    ss = _andes(raw.path, _andes_cases() / "kundur" / "kundur_full.dyr")
    assert _compare_with_andes(raw, system, ss) == 15
    with pytest.warns(UserWarning, match="1 ANDES Toggle record skipped"):
        recs = psse.read_dyr(_andes_cases() / "kundur" / "kundur_full.dyr")
    by_gen = psse.check_dynamics(system, recs)
    assert [sorted(v) for v in by_gen.values()] == [
        ["exciter", "governor", "machine"]
    ] * 4
    _compare_dyr_with_andes(recs, ss.dyr_dict)
    with pytest.warns(UserWarning, match="1 ANDES Toggle record skipped"):
        cls = psse.read_dyr(_andes_cases() / "kundur" / "kundur_gencls.dyr")
    assert [r.params["H"] for r in cls] == [13.0, 13.0, 12.35, 12.35]


def test_against_andes_on_ieee39():
    pytest.importorskip("andes")
    raw = psse.read_raw(_andes_cases() / "ieee39" / "ieee39.raw")
    system = psse.to_system(raw)
    ss = _andes(raw.path)
    # the 12 transformers have WINDV2 = 1, NOMV = 0, CZ = CM = 1: all comparable
    assert _compare_with_andes(raw, system, ss) == 46
    # the two switched shunts at BINIT, as ANDES reads them
    np.testing.assert_allclose(ss.Shunt.b.v, system.shunts.b, rtol=1e-14)
    np.testing.assert_array_equal(
        ss.Shunt.bus.v, system.buses.number[system.shunts.bus]
    )


def test_against_andes_on_three_winding():
    """ANDES also makes a star of W1 (CW = 1, CZ = 2, CM = 1): the same three legs
    (ANDES writes X = 1e-8 for a zero star reactance). For W2 it deviates
    (docs/psse.md): it takes WINDV as the ratio whatever CW is and keeps a winding
    out by STAT 3 in service."""
    s = psse.to_system(psse.read_raw(THREE))
    ss = _andes(THREE)
    L, br = ss.Line, s.branches
    np.testing.assert_array_equal(L.bus1.v, s.buses.number[br.fr])
    np.testing.assert_allclose(L.r.v[:3], br.r[:3], rtol=1e-12)
    np.testing.assert_allclose(L.x.v[:3], br.x[:3], rtol=1e-12, atol=2e-8)
    np.testing.assert_allclose(L.tap.v[:3], br.tap[:3], rtol=1e-15)
    np.testing.assert_allclose(L.phi.v, br.shift, rtol=1e-15)
    np.testing.assert_allclose(L.r.v[3:], br.r[3:], rtol=1e-12)  # CZ = 3 agrees
    assert list(L.tap.v[3:]) == [1.0, 1.01, 1.0] and list(L.u.v[3:]) == [1, 1, 1]
    np.testing.assert_allclose(ss.Bus.v0.v, s.buses.vm, rtol=1e-15)
    np.testing.assert_allclose(ss.Bus.a0.v, s.buses.va, rtol=1e-15)


def _compare_dyr_with_andes(recs, dyr_dict):
    """ANDES's dyr_dict holds each model's columns BUS, ID, then the parameters in
    the order of andes/io/psse-dyr.yaml: the same order as DYR_MODELS."""
    for model, df in dyr_dict.items():
        name = model.strip().upper()
        if name not in psse.DYR_MODELS:
            continue
        ours = [r for r in recs if r.model == name]
        assert len(ours) == len(df)
        for r, row in zip(ours, df.itertuples(index=False), strict=True):
            row = list(row)
            assert (row[0], str(row[1]).strip()) == (r.bus, r.ident)
            np.testing.assert_allclose(row[2:], list(r.params.values()), rtol=1e-15)


def test_dyr_order_against_andes_yaml():
    """The parameter names of every model both readers know, position by position:
    the same order (ANDES names them differently: Td10 for Tdo_p, TATB for TA_TB ...)."""
    pytest.importorskip("andes")
    import yaml

    table = yaml.safe_load((_andes_cases().parent / "io" / "psse-dyr.yaml").read_text())
    both = [m for m in psse.DYR_MODELS if m in table]
    assert both == [
        "GENCLS",
        "GENROU",
        "GENSAL",  # ANDES reads it into its GENROU (X'q = X'd): docs/machines.md
        "SEXS",
        "IEEEX1",
        "EXDC2",
        "EXST1",
        "IEEEST",
        "TGOV1",
        # exciters and the compensator of issue 45
        "ESST3A",
        "ESDC2A",
        "SCRX",  # ANDES reads it into its SEXS
        "IEEEVC",
        "ESDC1A",
        "IEEET1",
        # exciters of issue 45, part 2
        "ESST4B",
        "ESST1A",
        "EXAC1",
        "ESAC1A",
        "EXAC2",
        "EXPIC1",  # ANDES reads it into its SEXS
        "ESAC6A",  # ANDES reads it into its SEXS
        # governors and stabilizers of issue 45
        "IEEEG1",
        "HYGOV",
        "IEESGO",
        "ST2CUT",
        "GAST",
        # issue 45: ANDES reads GGOV1 into a TGOV1 (R only), in PSS/E's CON order
        "GGOV1",
        # issue 47: inverter-based resources
        "REGCA1",
        "REECB1",
        "REPCA1",
    ]
    # our name -> ANDES's, where they differ
    alias = {
        "Tdo_p": "Td10", "Tdo_pp": "Td20", "Tqo_p": "Tq10", "Tqo_pp": "Tq20",
        "Xd_p": "Xd1", "Xq_p": "Xq1", "Xd_pp": "Xd2", "TA_TB": "TATB",
        "SWITCH": "Switch", "ICS": "MODE", "IB": "BUSR",
        "RC": "rc", "XC": "xc", "rc_rfd": "rcrfd",
    }  # fmt: skip
    # issue 45, part 2: ANDES lists ESST1A's and ESAC1A's CONs in orders that the
    # public records (ACTIVSg2000, the Australian 14-generator case, PSID's PSS/E
    # benchmarks) do not fit; smibjax keeps PSS/E's (tests/test_grid_exciters2.py)
    pssorder = {"ESST1A", "ESAC1A"}
    for m in both:
        if m in pssorder:
            theirs = table[m]["inputs"][2:]
            assert sorted(psse.DYR_MODELS[m]) == sorted(theirs), m  # same names
            assert psse.DYR_MODELS[m] != tuple(theirs), m
            continue
        theirs = table[m]["inputs"][2:]  # after BUS, ID
        names = {**alias, "KF": "KF1"} if m in ("IEEEX1", "EXDC2") else alias
        # governors and stabilizers of issue 45
        names = {**names, "JBUS": "BUS2", "M": "ID2", "TW": "Tw", "ICS1": "MODE"}
        names |= {"IB1": "BUSR", "ICS2": "MODE2", "IB2": "BUSR2"}
        names |= {"Dturb": "Dt"} if m == "GAST" else {}
        if m == "GGOV1":
            names |= {"Flag": "Fswitch", "Kigov": "KIgov", "Vmax": "VMAX"}
            names |= {"Vmin": "VMIN", "Kiload": "KIload", "Kimw": "KImw"}
        # issue 47: inverter-based resources
        names |= {"LVPLSW": "Lvplsw"} if m == "REGCA1" else {}
        if m in ("REECB1", "REPCA1"):
            names = {"Qmax": "QMax", "Qmin": "QMin", "Vmax": "VMAX", "Vmin": "VMIN"}
            names |= {"Pmax": "PMAX", "Pmin": "PMIN", "IREG": "BUSR"}
            names |= {"BRCH_FROM": "BUS1", "BRCH_TO": "BUS2", "CKT": "CKTID"}
            names |= {"Tlag": "Tg"}
            if m == "REPCA1":  # ANDES keeps REPCA1's limits in PSS/E's case
                names |= {
                    "Qmax": "Qmax",
                    "Qmin": "Qmin",
                    "Pmax": "Pmax",
                    "Pmin": "Pmin",
                }
        assert [names.get(n, n) for n in psse.DYR_MODELS[m]] == theirs, m


def _andes_cases() -> Path:
    """ANDES's bundled cases folder (the test is skipped without ANDES). Looked up
    when a test runs, not at import: an import of ANDES that failed while the module
    was collected made the folder /nonexistent and the tests fail, not skip."""
    andes = pytest.importorskip("andes")
    return Path(andes.__file__).parent / "cases"


# ------------------------------------------------------- raw versions 34 and 35


def test_raw_v34_solves_to_psse_34s_own_load_flow():
    """IEEE 9-bus written by PSS/E 34.3 (tests/data/psse/ieee9_v34.raw, README.md
    there): system-wide data, `@!` header lines, 12 ratings per branch and winding.
    Our power flow of it lands on the voltages PSS/E saved, which it printed to 5
    decimals (measured: 2.9e-5 pu, 2.3e-3 deg; a v33 reader's layout misreads every
    branch, the first rating taken for GI)."""
    from smibjax.grid.powerflow import solve_power_flow

    raw = psse.read_raw(DATA / "ieee9_v34.raw")
    assert raw.version == 34 and raw.title == ("", "")
    assert (len(raw.buses), len(raw.loads), len(raw.generators)) == (9, 3, 3)
    assert (len(raw.branches), len(raw.transformers)) == (6, 3)
    br = raw.branches[0]
    assert (br["I"], br["J"], br["X"], br["B"], br["RATE1"], br["GI"]) == (
        4, 5, 0.085, 0.176, 250.0, 0.0,
    )  # fmt: skip
    assert raw.generators[1]["MBASE"] == 310.0 and raw.transformers[2]["X1-2"] == 0.0586
    pf = solve_power_flow(psse.to_system(raw))
    vm = np.array([b["VM"] for b in raw.buses])
    va = np.array([b["VA"] for b in raw.buses])
    assert np.abs(np.asarray(pf.vm) - vm).max() < 1e-4
    assert np.abs(np.degrees(np.asarray(pf.va)) - va).max() < 5e-3


def test_raw_v35_reads_a_file_psse_35_wrote():
    """IEEE 25-bus written by PSS/E 35.1 (tests/data/psse/case25_v35.raw): v35's
    generator NREG before MBASE, the winding's NOD, the switched shunt's ID, SWREG
    and NREG, and two system switching devices (read as branches of their X); the
    values against the file's own lines; the power flow solves. (PSS/E's saved
    voltages are not this file's load flow: its transformers use impedance
    correction tables, which this reader does not apply.)"""
    from smibjax.grid.powerflow import solve_power_flow

    raw = psse.read_raw(DATA / "case25_v35.raw")
    assert raw.version == 35 and raw.title[0] == "IEEE 25 BUS NETWORK"
    counts = [len(raw.buses), len(raw.loads), len(raw.fixed_shunts)]
    counts += [len(raw.generators), len(raw.branches), len(raw.transformers)]
    assert counts == [25, 17, 1, 42, 35, 7]
    g = raw.generators[2]  # 101,'3 ', 76.0, ..., IREG 101, NREG 0, MBASE 100.0
    assert (g["I"], g["ID"], g["PG"], g["IREG"], g["NREG"], g["MBASE"]) == (
        101, "3", 76.0, 101, 0, 100.0,
    )  # fmt: skip
    assert (g["ZX"], g["STAT"], g["PT"]) == (0.181, 1, 80.0)
    assert raw.generators[0]["STAT"] == 0
    sw = [b for b in raw.branches if b.get("_switch")]
    assert [(b["I"], b["J"], b["X"], b["R"], b["ST"]) for b in sw] == [
        (220, 222, 1e-4, 0.0, 1),
        (219, 213, 1e-4, 0.0, 1),
    ]
    t = raw.transformers[0]  # 103-224: WINDV1 1.0375, ..., CONT1 215, NOD1 0, RMA1 1.05
    assert (t["WINDV1"], t["CONT1"], t["NOD1"], t["RMA1"], t["NTP1"]) == (
        1.0375, 215, 0, 1.05, 17,
    )  # fmt: skip
    assert (t["R1-2"], t["X1-2"], t["WINDV2"]) == (2.3e-3, 2.0e-2, 1.0)
    sh = raw.switched_shunts[0]
    assert (sh["I"], sh["ID"], sh["SWREG"], sh["BINIT"]) == (101, "1", 152, -115.0)
    assert bool(solve_power_flow(psse.to_system(raw)).converged)


FOREIGN = [
    ("case9.m", "function mpc = case9\nmpc.baseMVA = 100;\n", "a MATPOWER case (.m)"),
    ("case9.txt", "%% MATPOWER\nmpc.bus = [\n1 3 0 0;\n];\n", "a MATPOWER case (.m)"),
    ("case.json", '{"Bus": []}\n', "a JSON file"),
    ("case.raw", '[{"bus": 1}]\n', "a JSON file"),
    ("case.xlsx", "PK\x03\x04 zipped", "a spreadsheet (xlsx, xls)"),
]


@pytest.mark.parametrize(("file", "text", "what"), FOREIGN)
def test_a_foreign_format_is_named(tmp_path, file, text, what):
    path = tmp_path / file
    path.write_text(text)
    for read, kind in ((psse.read_raw, "raw"), (psse.read_dyr, "dyr")):
        with pytest.raises(psse.PsseError) as err:
            read(path)
        assert str(err.value) == (
            f"{path}:1: this is {what}, not a PSS/E {kind} file: smibjax reads "
            "PSS/E v32-v35 raw + dyr files"
        )


@pytest.mark.parametrize("command", ["modes", "simulate"])
def test_every_command_refuses_unsupported_models_in_one_line(
    tmp_path, capsys, command
):
    """`modes` gave a traceback for a dyr with an unsupported model; now it refuses
    as `simulate` does: exit 2, one line naming every unsupported model and
    --skip-unsupported, nothing written."""
    from smibjax.cli import main
    from smibjax.grid.cases import case_file

    dyr = tmp_path / "x.dyr"
    dyr.write_text(
        case_file("smib_gencls.dyr").read_text()
        + "     1 'WT3E1' 1  0.02 0.2 -0.2 /\n     1 'WT3G1' 1  1 2 3 /\n"
    )
    out = tmp_path / "out"
    argv = [command, "--case", str(case_file("smib.raw")), "--dyr", str(dyr)]
    if command == "simulate":  # (without an event it is refused before the files)
        argv += ["--fault-bus", "1"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "dyr models 'WT3E1', 'WT3G1' are not supported" in err[0]
    assert "--skip-unsupported" in err[0] and not out.exists()
