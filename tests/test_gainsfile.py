"""Gains files that carry their context (schema smibjax.gains/1): the tuner writes
it, every command uses it by default, a contradicting flag wins with a warning, a flat
file loads with the paper's defaults and a note, bad context is one line and exit 2."""

import json
import types

import pytest

import smibjax as sj
from smibjax import _gainsfile as gainsfile
from smibjax._files import read_gains, read_gains_file, write_gains_file
from smibjax.cli import main

STABLE = {
    k: float(getattr(sj.Gains.paper("aftsc", beta1=-1.0, beta2=-1.0), k))
    for k in sj.GAIN_NAMES
}
REALISTIC = {"uf_min": -5.0, "uf_max": 5.0, "ur_min": -1.0, "ur_max": 1.0}


@pytest.fixture
def tuned(tmp_path):
    """A gains.json as the tuner writes it after tuning under the realistic limits
    with realizable adaptation (its writer, `_gains_file`, without the tuning)."""
    from tuning.outputs import gains_file as _gains_file

    cfg = {"controller": "aftsc", "adaptation": "realizable", "preset": "realistic"}
    path = tmp_path / "run" / "gains.json"
    write_gains_file(path, _gains_file(cfg, sj.Gains(**STABLE)))
    return path


def test_the_tuner_writes_the_documented_schema(tuned):
    assert json.loads(tuned.read_text()) == {
        "schema": "smibjax.gains/1",
        "controller": "aftsc",
        "adaptation": "realizable",
        "plant": {"preset": "realistic", **REALISTIC},
        "options": {},
        "gains": STABLE,
    }
    gf = read_gains_file(tuned, complete=True)
    assert gf == gainsfile.GainsFile(
        "aftsc", "realizable", {"preset": "realistic", **REALISTIC}, {}, STABLE
    )
    assert read_gains(tuned, complete=True) == STABLE  # flat readers get the gains
    # an infinite limit is written as null and read back as no limit
    wide = gainsfile.GainsFile(
        "aftsc", "oracle", {"preset": "realistic", "uf_max": float("inf")}, {}, {}
    )
    write_gains_file(tuned, wide)
    assert json.loads(tuned.read_text())["plant"]["uf_max"] is None
    assert read_gains_file(tuned) == wide


def test_resolve_flag_then_file_then_paper(tuned):
    gf = read_gains_file(tuned)
    ctx, gains, msgs = gainsfile.resolve(gf)
    assert (ctx.controller, ctx.adaptation, ctx.preset) == (
        "aftsc",
        "realizable",
        "realistic",
    )
    assert ctx.plant == REALISTIC and gains == STABLE and msgs == []
    ctx, gains, msgs = gainsfile.resolve(gf, "asc", "oracle", "paper", source="F")
    assert (ctx.controller, ctx.adaptation, ctx.preset) == ("asc", "oracle", "paper")
    assert ctx.plant == {} and "alpha" not in gains  # asc sets alpha = 1
    assert msgs == [
        "warning: --controller asc overrides controller aftsc of F",
        "warning: --adaptation oracle overrides adaptation realizable of F",
        "warning: --preset paper overrides preset realistic of F",
    ]
    ctx, _, msgs = gainsfile.resolve(None)
    assert (ctx.controller, ctx.adaptation, ctx.preset) == ("aftsc", "oracle", "paper")


def test_flat_file_loads_with_paper_defaults_and_a_note(tmp_path, capsys):
    flat = tmp_path / "g.json"
    flat.write_text(json.dumps({**STABLE, "alpha": 1.0}))
    gf = read_gains_file(flat)
    assert gf.legacy and gf.controller == "asc" and gf.adaptation == "oracle"
    ctx, _, msgs = gainsfile.resolve(gf, adaptation="realizable", source="F")
    assert msgs == [
        "note: F is a flat table of gains (no context): assuming controller asc, "
        "preset paper (the paper's defaults; controller by alpha)"
    ]
    out = tmp_path / "r.npz"
    argv = ["simulate", "--gains", str(flat), "--t-end", "6", "--out", str(out)]
    assert main(argv) == 0
    err = _messages(capsys)
    assert len(err) == 1 and err[0].startswith("smibjax: note: --gains")
    assert "assuming controller asc, adaptation oracle, preset paper" in err[0]


def _messages(capsys) -> list[str]:
    """The stderr lines of a successful run but the `compiling ...` line."""
    err = capsys.readouterr().err.strip().splitlines()
    return [line for line in err if not line.startswith("compiling ")]


def _context_of(npz):
    import numpy as np

    return json.loads(str(np.load(npz)["meta"]))


def test_round_trip_every_command_uses_the_context(
    tuned, tmp_path, capsys, monkeypatch
):
    """Tuned under realistic + realizable, then simulate, montecarlo, cct and compare
    with no flags run under that context (before: oracle on the paper plant)."""
    out = tmp_path / "sim.npz"
    argv = ["simulate", "--gains", str(tuned), "--t-end", "1", "--out", str(out)]
    assert main(argv) == 0
    meta = _context_of(out)
    assert meta["adaptation"] == "realizable"
    assert meta["plant"]["uf_max"] == 5.0 and meta["plant"]["ur_min"] == -1.0
    assert meta["context"]["plant"]["preset"] == "realistic"
    err = capsys.readouterr().err  # nothing to warn about
    assert "warning" not in err and "note" not in err

    mc = tmp_path / "mc"
    argv = ["montecarlo", "--gains", str(tuned), "--n", "2", "--chunk", "2"]
    assert main([*argv, "--t-end", "3", "--out", str(mc)]) == 0
    spec = json.loads((mc / "run.json").read_text())["spec"]
    assert spec["adaptation"] == "realizable" and spec["plant"]["uf_max"] == 5.0
    assert spec["gains"] == STABLE

    # the CCT engine is replaced by a recorder: what matters is what reaches it
    seen = []

    def fake_cct(sets, plant, **kw):
        seen.append((dict(sets), plant, kw))
        names = list(sets)
        per = {"cct": [0.3], "status": ["ok"], "islands": [[]]}
        res = {"fault_location": [0.5], "fault_time": 0.5, "reclose_time": 2.0}
        res.update(window=1.5, tol=0.01, criterion=kw["criterion"], t_end=3.0)
        res["sets"] = {n: dict(per) for n in names}
        for k in per:
            res[k] = per[k] if len(names) == 1 else {n: per[k] for n in names}
        return types.SimpleNamespace(to_dict=lambda: res)

    import smibjax._cct

    monkeypatch.setattr(smibjax._cct, "critical_clearing_times", fake_cct)
    cct = tmp_path / "c.json"
    argv = ["cct", "--gains", str(tuned), "--fault-location", "0.5", "--out", str(cct)]
    assert main(argv) == 0
    sets, plant, kw = seen.pop()
    assert kw["adaptation"] == "realizable" and float(plant.uf_max) == 5.0
    assert list(sets) == ["aftsc"] and float(sets["aftsc"].gains.beta1) == -1.0
    assert sets["aftsc"].oracle is False  # the lanes run the realizable law
    assert json.loads(cct.read_text())["context"]["aftsc"]["adaptation"] == (
        "realizable"
    )

    cmp = tmp_path / "cmp"
    argv = ["compare", "--gains", str(tuned), "--gains", "stable", "--n", "2"]
    argv += ["--chunk", "2", "--t-end", "3", "--fault-location", "0.5"]
    assert main([*argv, "--out", str(cmp)]) == 0
    table = (cmp / "compare.md").read_text()
    # issue 32: a comparison is fair: the built-in set runs on the plant and with
    # the adaptation the file states (before: the paper plant, oracle), with a note
    assert "| run | aftsc | realizable | realistic |" in table
    assert "| stable | aftsc | realizable | realistic |" in table
    data = json.loads((cmp / "compare.json").read_text())
    assert data["context"]["run"]["adaptation"] == "realizable"
    assert data["context"]["run"]["plant"]["uf_max"] == 5.0
    for name in ("run", "stable"):
        spec = json.loads((cmp / name / "run.json").read_text())["spec"]
        assert spec["adaptation"] == "realizable" and spec["plant"]["uf_max"] == 5.0
    # one CCT sweep: every set on one plant under one adaptation
    by_set = {n: (float(p.uf_max), kw["adaptation"]) for s, p, kw in seen for n in s}
    assert by_set == {"run": (5.0, "realizable"), "stable": (5.0, "realizable")}
    err = capsys.readouterr().err
    assert "warning" not in err
    assert "note: every set runs on the realistic plant (u_f in [-5, 5]" in err
    assert "note: stable run with realizable adaptation" in err
    assert "D at the plant's 0.2" in err  # the tuner drew D: said, with the fix


def test_a_contradicting_flag_wins_with_one_warning(tuned, tmp_path, capsys):
    out = tmp_path / "sim.npz"
    argv = ["simulate", "--gains", str(tuned), "--t-end", "2", "--out", str(out)]
    assert main([*argv, "--adaptation", "oracle", "--set", "uf_max=3"]) == 0
    err = _messages(capsys)
    assert err == [
        f"smibjax: warning: --adaptation oracle overrides adaptation realizable of "
        f"--gains {tuned}",
        "smibjax: warning: --set uf_max=3 overrides uf_max = 5 of the gains file",
    ]
    meta = _context_of(out)
    assert meta["adaptation"] == "oracle" and meta["plant"]["uf_max"] == 3.0
    assert meta["plant"]["uf_min"] == -5.0  # the rest of the file's plant stays


@pytest.mark.parametrize(
    "change, match",
    [
        ({"controller": "pid"}, "controller = 'pid' in .* must be one of aftsc, asc"),
        ({"adaptation": "magic"}, "adaptation = 'magic' in .* oracle, realizable"),
        ({"plant": {"preset": "x"}}, "plant preset = 'x' in .* paper, realistic"),
        ({"schema": "smibjax.gains/9"}, "schema = 'smibjax.gains/9' in .* reads"),
        ({"options": {"c1": 2}}, "option 'c1' is not allowed for controller 'aftsc'"),
        ({"controller": "asc"}, "alpha = 0.714286 in .* not allowed for .*'asc'"),
        ({"plant": {"preset": "paper", "speed": 1}}, "unknown plant field 'speed'"),
    ],
)
@pytest.mark.parametrize("command", ["simulate", "montecarlo", "cct", "compare"])
def test_bad_context_is_one_line_exit_2(
    tuned, tmp_path, capsys, change, match, command
):
    import re

    data = {**json.loads(tuned.read_text()), **change}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    out = tmp_path / "out"
    assert main([command, "--gains", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("smibjax: error:")
    assert re.search(match, err), err
    assert not out.exists()


@pytest.mark.parametrize("command", ["simulate", "montecarlo", "cct"])
def test_another_controllers_gains_under_a_controller_flag_is_one_line(
    tmp_path, capsys, command
):
    """Issue 32: an avr-pss gains file under `--controller aftsc` was a warning, then
    a TypeError (Gains got K_A), exit 1; now one line naming both, exit 2, nothing
    written."""
    avr = tmp_path / "avr.json"
    gf = gainsfile.GainsFile(
        "avr-pss", "oracle", {"preset": "realistic", **REALISTIC}, {}, {"K_A": 100.0}
    )
    write_gains_file(avr, gf)
    out = tmp_path / "out"
    argv = [command, "--gains", str(avr), "--controller", "aftsc", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "--controller aftsc cannot run" in err and "avr-pss: K_A" in err
    assert not out.exists()


def test_a_gains_file_records_only_the_context_that_applies(tmp_path):
    """Issue 32: an avr-pss (or none) gains file has no adaptation entry (the paper's
    law's), the tuner's writer included; one written by an older version (with the
    entry) still loads; the paper's law's file keeps its adaptation."""
    from tuning.config import load_config
    from tuning.outputs import gains_file as _gains_file

    cfg = load_config(controller="avr-pss")
    gf = _gains_file(cfg, sj.AvrPss())
    path = write_gains_file(tmp_path / "g.json", gf)
    data = json.loads(path.read_text())
    assert "adaptation" not in data and data["controller"] == "avr-pss"
    assert "adaptation" not in gainsfile.resolve(gf)[0].describe()
    old = tmp_path / "old.json"
    old.write_text(json.dumps({**data, "adaptation": "realizable"}))
    assert read_gains_file(old).gains == data["gains"]
    aftsc = _gains_file(
        {"controller": "aftsc", "adaptation": "realizable", "preset": "paper"},
        sj.Gains(**STABLE),
    )
    assert aftsc.to_dict()["adaptation"] == "realizable"
    no_entry = {k: v for k, v in aftsc.to_dict().items() if k != "adaptation"}
    with pytest.raises(sj.ParameterError, match="'adaptation' is missing"):
        gainsfile.validate(no_entry)


def test_adaptation_flag_for_a_controller_without_one_is_one_line(tmp_path, capsys):
    out = tmp_path / "o.npz"
    argv = ["simulate", "--controller", "avr-pss", "--adaptation", "realizable"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "does not apply to controller" in err
    assert not out.exists()


def test_compare_refuses_files_that_state_different_plants(tuned, tmp_path, capsys):
    """Two gains files tuned on different plants: one line, exit 2, unless --preset
    puts every set on one."""
    data = json.loads(tuned.read_text())
    other = tmp_path / "paper.json"
    other.write_text(json.dumps({**data, "plant": {"preset": "paper"}}))
    out = tmp_path / "cmp"
    argv = ["compare", "--gains", str(tuned), "--gains", str(other), "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "state different plants" in err, err
    assert "give --preset" in err and not out.exists()


def test_compare_labels_and_physics_columns():
    from smibjax.cli.compare import compare_table, split_label

    assert split_label("tuned=runs/a/gains.json") == ("tuned", "runs/a/gains.json")
    assert split_label("avr-pss") == (None, "avr-pss")
    with pytest.raises(sj.ParameterError, match="expected LABEL=FILE"):
        split_label("=x.json")
    ph = {
        "tv_uf_mean": 12.5,
        "tv_ur_mean": 0.25,
        "limit_time_uf_mean": 0.125,
        "limit_time_ur_mean": 0.0,
        "peak_uf_cmd_max": 4500.0,
        "peak_ur_cmd_max": 3.0,
        "Vt_min": 0.2,
        "Vt_max": 1.25,
    }
    summary = {
        "stable_fraction": 1.0,
        "stable_fraction_ci95": [0.9, 1.0],
        "settling_time": {"mean": 2.0, "p95": 3.0},
        "overshoot": {"p95": 0.5},
        "physics": ph,
    }
    cct = {
        "fault_location": [0.5],
        "window": 1.5,
        "sets": {"a": {"cct": [0.3], "status": ["ok"], "islands": [[]]}},
    }
    table = compare_table({"a": summary}, cct)
    assert "chatter u_f / u_r (pu) | time on a limit u_f / u_r (%)" in table
    assert "| 12.5 / 0.25 | 12.5 / 0.0 | 4.5e+03 / 3 | 0.200..1.250 | 0.300 |" in table


def test_dist_takes_a_tuning_configs_scenarios():
    """Issue 32: `--dist tuning/configs/default.toml` was refused ("unknown scenario
    key 'controller'"); it is the tuner's distribution, D drawn in [0.1, 0.4]."""
    from helpers import ROOT
    from smibjax.cli.options import read_dist

    dist = read_dist(ROOT / "tuning" / "configs" / "default.toml").to_dict()
    assert dist["D"] == [0.1, 0.4] and dist["clear_duration"] == [0.05, 0.25]
