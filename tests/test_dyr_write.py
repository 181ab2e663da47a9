"""Tuned parameters written back into a dyr file (`smibjax.grid.dyr_write`, issue 48
part 1): the named records' numbers replaced, every other byte kept."""

from __future__ import annotations

import dataclasses
import glob
import warnings
from pathlib import Path

import pytest

from smibjax.grid.dyr_write import dyr_updates, rewrite_dyr
from smibjax.grid.psse import PsseError, _split, read_dyr

ROOT = Path(__file__).resolve().parent.parent

# comments after '/', an '@!' line, records spanning lines, ANDES's E-notation, a
# record of a model smibjax does not read (WT3G1), a ',,' field, a CRLF line
SMALL = (
    "@! a PSS/E comment line, 'IEEEST' 1 1 / not a record\n"
    "  1 'GENROU' 1   8.0000   0.030000   0.40000   0.050000\n"
    "       6.5000   0.0000   1.8000   1.7000   0.30000   0.55000\n"
    "       0.25000   0.20000   0.039175   0.22268  / G1: Kundur, KS = 20\n"
    "  1 'IEEEST' 1   1   0   0.0   0.0   0.0   0.0   0.0   0.0\n"
    "       0.50000E-01   0.020000   3.0000   5.4000   10.000   10.000\n"
    "       20.000   0.20000   -0.20000   0.0000   0.0000  / PSS: 'KS' = 20 / TW\r\n"
    "  1 'WT3G1' 1   0   0   20.000   0.10000  /  unsupported, kept\n"
    "  2 'GENCLS' 1   5.0000,,   0.0000  / a ',,' field\n"
    "  2 'IEEEST' 1   1   0   0.0   0.0   0.0   0.0   0.0   0.0   0.05   0.02\n"
    "       3.0   5.4   10.0   10.0   20.0   0.2   -0.2   0.0   0.0 /\n"
)


@pytest.fixture
def small(tmp_path):
    p = tmp_path / "small.dyr"
    p.write_bytes(SMALL.encode())
    return p


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # WT3G1 skipped
        return read_dyr(path, skip_unsupported=True)


def test_rewrite_replaces_exactly_the_named_numbers(small, tmp_path):
    """read_dyr of the new text: the given values exactly (float64 round trip), every
    other parameter of every record unchanged; the lines without a replaced number
    are byte for byte the old ones, and the touched lines differ only in the
    replaced tokens."""
    ks = 31.234567890123456  # 17 significant digits: repr is needed
    t1 = 1.0 / 3.0
    r = rewrite_dyr(
        small,
        {
            ("IEEEST", 1, "1"): {"KS": ks, "T1": t1, "T6": 7.5},
            ("ieeest", 2, "1"): {"T4": 2e-7},
            ("GENCLS", 2, "1"): {"D": 1.25},
        },
    )
    out = tmp_path / "new.dyr"
    out.write_bytes(r.text.encode())
    old, new = _read(small), _read(out)
    assert [(x.model, x.bus, x.ident, x.line) for x in old] == [
        (x.model, x.bus, x.ident, x.line) for x in new
    ]
    want = {
        (1, "IEEEST"): {"KS": ks, "T1": t1, "T6": 7.5},
        (2, "IEEEST"): {"T4": 2e-7},
        (2, "GENCLS"): {"D": 1.25},
    }
    for a, b in zip(old, new, strict=True):
        changed = want.get((a.bus, a.model), {})
        for p, v in a.params.items():
            assert b.params[p] == changed.get(p, v), (a.model, a.bus, p)
    la = SMALL.splitlines(keepends=True)
    lb = r.text.splitlines(keepends=True)
    assert len(la) == len(lb)
    touched = {5, 6, 8, 10}  # 0-based: IEEEST 1's 2nd/3rd lines, GENCLS, IEEEST 2
    for k, (x, y) in enumerate(zip(la, lb, strict=True)):
        if k not in touched:
            assert x == y, k
    assert lb[6].endswith("/ PSS: 'KS' = 20 / TW\r\n")  # comment and CRLF kept
    assert lb[5].split() == [repr(t1), "0.020000", "3.0000", "5.4000", "10.000", "7.5"]
    assert lb[8] == "  2 'GENCLS' 1   5.0000,,     1.25  / a ',,' field\n"
    assert [(c.device, c.param, c.old, c.new, c.line) for c in r.changes] == [
        ("IEEEST[1:1]", "T1", 0.05, t1, 5),
        ("IEEEST[1:1]", "T6", 10.0, 7.5, 5),
        ("IEEEST[1:1]", "KS", 20.0, ks, 5),
        ("GENCLS[2:1]", "D", 0.0, 1.25, 9),
        ("IEEEST[2:1]", "T4", 5.4, 2e-7, 10),
    ]


def test_no_update_gives_every_builtin_dyr_byte_for_byte():
    """Nothing to write: the text is the file's bytes (all the package's dyr files,
    ANDES's among them), and the field spans agree with the reader's lexer on every
    line (the writer's guard)."""
    files = sorted(glob.glob(str(ROOT / "src/smibjax/grid/cases/*.dyr")))
    assert len(files) >= 10
    for f in files:
        r = rewrite_dyr(f, {})
        assert r.text.encode("utf-8", "surrogateescape") == Path(f).read_bytes(), f
        assert r.changes == ()


def test_andes_record_and_icon(tmp_path):
    """WECC 179's IEEEST (ANDES's layout: E-notation, '/' on its own line) rewritten:
    the ICON ICS written as an integer, the CON in full precision; reading back
    gives them."""
    src = ROOT / "src/smibjax/grid/cases/wecc179.dyr"
    recs = [r for r in _read(src) if r.model == "IEEEST"]
    rec = recs[0]
    r = rewrite_dyr(src, {("IEEEST", rec.bus, rec.ident): {"ICS": 1, "KS": 0.1 + 0.2}})
    out = tmp_path / "w.dyr"
    out.write_bytes(r.text.encode())
    new = [x for x in _read(out) if x.model == "IEEEST"]
    assert new[0].params == {**rec.params, "ICS": 1.0, "KS": 0.1 + 0.2}
    # the other records as read from the shipped file
    assert new[1:] == [dataclasses.replace(x, file=str(out)) for x in recs[1:]]
    assert [c.text.strip() for c in r.changes] == ["1", "0.30000000000000004"]


@pytest.mark.parametrize(
    "updates,message",
    [
        ({("IEEEST", 1, "1"): {"KQ": 1.0}}, "IEEEST record has no parameter 'KQ'"),
        ({("WT3G1", 1, "1"): {"K": 1.0}}, "dyr model 'WT3G1' is not one smibjax"),
        (
            {("IEEEST", 9, "1"): {"KS": 1.0}},
            "no IEEEST record for generator '1' at bus 9",
        ),
        ({("IEEEST", 1, "1"): {"KS": float("nan")}}, "IEEEST field KS: nan is not a"),
    ],
)
def test_refusals_are_one_line(small, updates, message):
    with pytest.raises(PsseError) as e:
        rewrite_dyr(small, updates)
    assert message in str(e.value) and "\n" not in str(e.value)


def test_dyr_updates_maps_names_to_records():
    """Parameter names of smibjax.grid.params -> dyr records: every device for
    MODEL.PARAM, one for MODEL[BUS:ID].PARAM (a later name overriding), a
    machine's field by its dyr name; a field from the raw file is refused."""
    from smibjax.grid.case import load_case
    from smibjax.grid.params import ParamError

    case = load_case("kundur")
    up = dyr_updates(
        case,
        {"IEEEST.KS": 30.0, "IEEEST[3:1].KS": 12.5, "GENROU[2:1].xdp": 0.31},
    )
    assert up == {
        ("IEEEST", 1, "1"): {"KS": 30.0},
        ("IEEEST", 2, "1"): {"KS": 30.0},
        ("IEEEST", 3, "1"): {"KS": 12.5},
        ("IEEEST", 4, "1"): {"KS": 30.0},
        ("GENROU", 2, "1"): {"Xd_p": 0.31},
    }
    with pytest.raises(ParamError, match="GENROU.ra is not a parameter of the GENROU"):
        dyr_updates(case, {"GENROU.ra": 0.0})


def test_spans_agree_with_the_reader_on_odd_lines():
    """Quoted fields with blanks, commas and slashes, empty fields: the writer's
    field spans give the reader's fields."""
    from smibjax.grid.dyr_write import _spans

    for line in [
        "  1 ' IEEEST ' 1,2,,3 'a/b, c' 4/ x",
        "1,'GENCLS',1,,0.0,,",
        "  'x''y'  5e-3   -1.E+2",
    ]:
        got = [line[a:b] if (q or b > a) else None for a, b, q in _spans(line)]
        assert got == _split(line, "t")[0], line
