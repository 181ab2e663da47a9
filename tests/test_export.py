"""Trajectories in the formats engineers open (issue 50): each format read back by
another reader (the csv module, the COMTRADE configuration's own counts and
conversion factors, scipy.io.loadmat), the devices named by PSS/E numbers and ids,
and any other suffix refused in one line."""

import csv

import numpy as np
import pytest

from smibjax import _export


def _run(n_gen=3, n_bus=4, n=201):
    """A small synthetic `simulate --case` run with known values; sample 150 of
    generator 2's speed is missing (NaN)."""
    t = np.linspace(0.0, 2.0, n)
    g = np.arange(1, n_gen + 1)
    a = {
        "t": t,
        "gen": np.array([f"{b}:1" for b in (21, 22, 23)[:n_gen]]),
        "bus": np.array([1, 2, 7, 30])[:n_bus],
        "delta": 0.1 * g[None, :] + 0.05 * np.sin(3 * t)[:, None],
        "delta_coi": 0.2 * g[None, :] - 0.4 + 0.05 * np.sin(3 * t)[:, None],
        "omega": 1e-3 * np.cos(3 * t)[:, None] * g[None, :],
        "pe": 0.8 + 0 * t[:, None] * g,
        "pm": 0.8 + 0 * t[:, None] * g,
        "efd": 2.0 + 0.1 * t[:, None] * g,
        "vs": 0 * t[:, None] * g,
        "vt": 1.0 + 0.01 * t[:, None] * g,
        "v_bus": 1.0 - 0.01 * np.arange(n_bus)[None, :] + 0 * t[:, None],
        "meta": np.array('{"case": "x"}'),
    }
    a["omega"][150, 1] = np.nan
    return a


def test_csv_is_a_wide_table_naming_devices_and_units(tmp_path):
    a = _run()
    cols = _export.grid_columns(a)
    path = tmp_path / "run.csv"
    assert _export.write_trajectory(path, a, cols) == [path]
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head = rows[0]
    assert head[0] == "t (s)"
    assert "delta_coi G 21:1 (rad)" in head and "omega G 23:1 (pu)" in head
    assert "v_bus bus 30 (pu)" in head and "pm G 22:1 (pu)" in head
    assert len(head) == 1 + 8 * 3 + 4 and len(rows) == 1 + 201
    k = head.index("efd G 23:1 (pu)")
    got = np.array([float(r[k]) for r in rows[1:]])
    np.testing.assert_allclose(got, a["efd"][:, 2], rtol=1e-9)
    k = head.index("omega G 22:1 (pu)")
    assert rows[1 + 150][k] == ""  # the missing sample is an empty cell
    assert float(rows[1 + 151][k]) == pytest.approx(a["omega"][151, 1], rel=1e-9)


def test_mat_loads_in_scipy_with_every_array_and_the_signal_table(tmp_path):
    from scipy.io import loadmat

    a = _run()
    cols = _export.grid_columns(a)
    path = tmp_path / "run.mat"
    _export.write_trajectory(path, a, cols)
    m = loadmat(path)
    assert m["t"].shape == (201, 1)  # a column
    np.testing.assert_array_equal(m["delta"], a["delta"])
    np.testing.assert_array_equal(m["bus"].ravel(), a["bus"])
    assert [s.strip() for s in m["gen"]] == ["21:1", "22:1", "23:1"]
    names = [s.strip() for s in m["signal_names"]]
    assert names[0] == "delta_coi G 21:1 (rad)" and names[-1] == "v_bus bus 30 (pu)"
    k = names.index("vt G 22:1 (pu)")
    np.testing.assert_array_equal(m["signals"][:, k], a["vt"][:, 1])
    assert '"case"' in str(m["meta"][0])


def _read_comtrade(cfg_path):
    """A minimal C37.111-1999 ASCII reader: the channels' ids, units and values
    from the configuration's counts and conversion factors."""
    lines = cfg_path.read_bytes().decode().split("\r\n")
    station, dev, year = lines[0].split(",")
    total, na, nd = lines[1].split(",")
    na, nd = int(na.rstrip("A")), int(nd.rstrip("D"))
    chans = [lines[2 + i].split(",") for i in range(na)]
    rest = lines[2 + na :]
    freq, nrates = float(rest[0]), int(rest[1])
    rate, endsamp = (float(x) for x in rest[2].split(","))
    assert rest[5] == "ASCII" and float(rest[6]) == 1.0
    dat = cfg_path.with_suffix(".dat").read_bytes().decode().split("\r\n")
    rows = [list(map(int, r.split(","))) for r in dat if r]
    assert len(rows) == int(endsamp)
    x = np.array(rows)
    values = []
    for j, c in enumerate(chans):
        a, b = float(c[5]), float(c[6])
        raw = x[:, 2 + j].astype(float)
        assert raw.max() <= 99999 and raw.min() >= int(c[8])
        v = a * raw + b
        v[raw == 99999] = np.nan
        values.append(v)
    return {
        "station": station,
        "year": year,
        "counts": (int(total), na, nd),
        "ids": [c[1] for c in chans],
        "ccbm": [c[3] for c in chans],
        "units": [c[4] for c in chans],
        "freq": freq,
        "nrates": nrates,
        "rate": rate,
        "time_us": x[:, 1],
        "sample": x[:, 0],
        "values": np.array(values).T,
        "trigger": rest[4],
    }


def test_comtrade_reads_back_by_its_own_header(tmp_path):
    a = _run()
    cols = _export.grid_columns(a)
    cfg = tmp_path / "run.cfg"
    written = _export.write_trajectory(
        cfg, a, cols, station="npcc", frequency=60.0, trigger=1.0
    )
    assert written == [cfg, tmp_path / "run.dat"]
    c = _read_comtrade(cfg)
    assert c["station"] == "npcc" and c["year"] == "1999"
    assert c["counts"] == (28, 28, 0)
    assert c["ids"][0] == "delta_coi G 21:1" and c["ccbm"][-1] == "bus 30"
    assert c["units"][0] == "rad" and c["freq"] == 60.0 and c["nrates"] == 1
    assert c["rate"] == pytest.approx(100.0)  # 1 / 0.01 s
    np.testing.assert_array_equal(c["time_us"], np.rint(a["t"] * 1e6).astype(int))
    np.testing.assert_array_equal(c["sample"], np.arange(1, 202))
    assert c["trigger"] == "01/01/2000,00:00:01.000000"
    for j, (_, _, _, y) in enumerate(cols):
        span = max(np.nanmax(y) - np.nanmin(y), 1e-12)
        np.testing.assert_allclose(c["values"][:, j], y, atol=1e-5 * span, rtol=1e-9)
    k = c["ids"].index("omega G 22:1")
    assert np.isnan(c["values"][150, k]) and np.isfinite(c["values"][151, k])


def test_smib_columns_name_the_signals_with_units():
    t = np.linspace(0, 1, 11)
    a = {"t": t, "delta": t, "omega": t, "theta_hat": np.stack([t, t], 1)}
    cols = _export.smib_columns(a)
    assert [(c[0], c[2]) for c in cols] == [
        ("delta", "rad"),
        ("omega", "rad/s"),
        ("theta_hat1", "-"),
        ("theta_hat2", "-"),
    ]


@pytest.mark.parametrize("name", ["run.txt", "run.xlsx", "run.dat", "run.npz.bak"])
def test_other_suffixes_are_refused_in_one_line(name):
    with pytest.raises(_export.FormatError) as e:
        _export.check_trajectory_path(name)
    text = str(e.value)
    assert "\n" not in text and name in text
    assert all(s in text for s in (".npz", ".csv", ".mat", ".cfg"))


def test_a_name_without_suffix_gets_npz_and_known_suffixes_pass():
    assert _export.check_trajectory_path("runs/a").name == "a.npz"
    for s in (".npz", ".csv", ".mat", ".cfg", ".CSV"):
        assert _export.check_trajectory_path("a" + s).suffix == s


def test_comtrade_time_stamps_past_a_minute():
    """The trigger of a fault at 75.5 s (dd/mm/yyyy,hh:mm:ss.ssssss)."""
    assert _export._stamp(75.5) == "01/01/2000,00:01:15.500000"
    assert _export._stamp(3725.000001) == "01/01/2000,01:02:05.000001"


def test_mat_without_scipy_is_one_line_naming_the_extra(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util,
        "find_spec",
        lambda name, *a: None if name == "scipy" else real(name, *a),
    )
    with pytest.raises(_export.FormatError) as e:
        _export.check_trajectory_path("run.mat")
    assert "pip install 'smibjax[mat]'" in str(e.value) and "\n" not in str(e.value)
    assert _export.check_trajectory_path("run.csv").suffix == ".csv"
