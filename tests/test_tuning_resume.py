"""tuning/resume.py (issue 16, class 5): a resume never silently changes the run it
finishes, a run killed before its first checkpoint can be finished, and the report's
wall time covers every session."""

import json
import os
import time

import pytest

import smibjax as sj
from test_tuning import tiny_toml
from tuning.config import load_config
from tuning.loop import CHECKPOINT
from tuning.optimize import main
from tuning.resume import SESSIONS, SessionClock, first_difference, start_mode

# with the tuner's runs of tests/test_tuning.py: the same tiny validation program
pytestmark = pytest.mark.xdist_group("tuner")


def _tiny(tmp_path):
    cfg = tmp_path / "tiny.toml"
    cfg.write_text(tiny_toml(0))
    return cfg


def _saved_run(tmp_path, **over):
    """A run folder as the tuner leaves it: config.json (+ a checkpoint)."""
    from tuning.optimize import parse_args, resolve_config

    cfgfile = _tiny(tmp_path)
    cfg = resolve_config(parse_args(["--config", str(cfgfile)]))
    cfg.update(over)
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.json").write_text(json.dumps(cfg))
    return out, cfg, cfgfile


@pytest.mark.parametrize(
    "flags, key",
    [
        (["--batch", "3"], "batch = 3"),
        (["--seed", "5"], "seed = 5"),
        (["--steps", "7"], "steps = 7"),
        (["--controller", "asc"], "controller = 'asc'"),
        (["--preset", "paper"], "preset = 'paper'"),
        (["--init", "x.json"], "init = 'x.json'"),
    ],
)
def test_resume_refuses_options_that_differ(tmp_path, capsys, flags, key):
    out, _, cfgfile = _saved_run(tmp_path)
    (out / CHECKPOINT).write_bytes(b"x")
    argv = ["--config", str(cfgfile), "--out", str(out), "--resume", "--quiet"]
    assert main([*argv, *flags]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("tuning.optimize: error:")
    assert f"--resume: {key} differs from the run in" in err
    assert "repeat its options" in err
    assert sorted(p.name for p in out.iterdir()) == [CHECKPOINT, "config.json"]


def test_resume_refuses_a_changed_config_key(tmp_path, capsys):
    out, _, cfgfile = _saved_run(tmp_path)
    (out / CHECKPOINT).write_bytes(b"x")
    other = tmp_path / "other.toml"
    other.write_text(cfgfile.read_text() + "[optimizer]\nlearning_rate = 0.05\n")
    assert main(["--config", str(other), "--out", str(out), "--resume"]) == 2
    assert "optimizer.learning_rate = 0.05 differs" in capsys.readouterr().err


def test_a_run_from_before_the_training_layer_resumes(tmp_path, capsys):
    """A config.json without train.phi_layer (written before the key) is a run
    trained without it: it resumes under the default (0) and not under another."""
    out, cfg, _ = _saved_run(tmp_path)
    saved = json.loads((out / "config.json").read_text())
    del saved["train"]["phi_layer"]
    (out / "config.json").write_text(json.dumps(saved))
    (out / CHECKPOINT).write_bytes(b"x")
    assert start_mode(out, cfg, True, CHECKPOINT) is True
    cfg["train"]["phi_layer"] = 0.001
    with pytest.raises(sj.ParameterError, match="train.phi_layer = 0.001 differs"):
        start_mode(out, cfg, True, CHECKPOINT)


def test_first_difference():
    a = load_config()
    assert first_difference(a, json.loads(json.dumps(a))) is None
    b = json.loads(json.dumps(a))
    b["loss"]["cvar_q"] = 0.5
    assert first_difference(a, b) == ("loss.cvar_q", 0.9, 0.5)
    b = json.loads(json.dumps(a))
    b["scenarios"]["t_fault"] = [0.2, 1.1]
    assert first_difference(a, b)[0] == "scenarios.t_fault"
    assert first_difference({"steps": 1}, {"steps": 1.0}) is None
    assert first_difference({"x": True}, {"x": 1}) == ("x", True, 1)
    # the grid tuner's --resume was always refused: a flag equal to itself differed
    # ("case.skip_unsupported = False differs from the run (... = False)")
    assert first_difference({"x": False}, {"x": False}) is None
    assert first_difference({"c": {"x": True}}, {"c": {"x": False}})[0] == "c.x"


def test_start_mode(tmp_path, capsys):
    out, cfg, _ = _saved_run(tmp_path)
    # killed before its first checkpoint: --resume starts afresh and says so
    assert start_mode(out, cfg, True, CHECKPOINT) is False
    assert "starting it from scratch" in capsys.readouterr().err
    (out / CHECKPOINT).write_bytes(b"x")
    assert start_mode(out, cfg, True, CHECKPOINT) is True
    with pytest.raises(sj.ParameterError, match="already holds files"):
        start_mode(out, cfg, False, CHECKPOINT)
    with pytest.raises(sj.ParameterError, match="no checkpoint"):
        start_mode(tmp_path / "none", cfg, True, CHECKPOINT)
    assert start_mode(tmp_path / "new", cfg, False, CHECKPOINT) is False


def test_an_old_pickle_checkpoint_is_one_clear_line(tmp_path, capsys):
    """A run folder of the older tuner (checkpoint.pkl) is refused by --resume with
    one line naming the file, not started afresh and not unpickled."""
    out, _, cfgfile = _saved_run(tmp_path)
    (out / "checkpoint.pkl").write_bytes(b"\x80\x04not a pickle to load")
    argv = ["--config", str(cfgfile), "--out", str(out), "--quiet", "--resume"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "checkpoint of an older tuner" in err
    assert "checkpoint.pkl" in err and not (out / "gains.json").exists()


def test_run_killed_before_its_first_checkpoint_can_be_finished(tmp_path, capsys):
    out, _, cfgfile = _saved_run(tmp_path)  # only config.json, as after such a kill
    now = time.time()  # the killed session: started 100 s ago, last wrote 70 s ago
    (out / SESSIONS).write_text(json.dumps([{"started": now - 100}]))
    os.utime(out / "config.json", (now - 70, now - 70))
    argv = ["--config", str(cfgfile), "--out", str(out), "--quiet"]
    assert main(argv) == 2  # a fresh start still refuses the folder
    assert "already holds files" in capsys.readouterr().err
    assert main([*argv, "--resume"]) == 0
    captured = capsys.readouterr()
    assert "starting it from scratch" in captured.err
    beta1 = json.loads((out / "gains.json").read_text())["gains"]["beta1"]
    assert beta1 == pytest.approx(50.0, rel=1e-12)  # steps = 0: the start
    report = (out / "report.md").read_text()
    wall = float(report.split("Wall time ")[1].split(" s")[0])
    assert 30 <= wall < 30 + 600 and "(sum over 2 sessions)" in report


def test_wall_time_is_summed_over_sessions(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    now = time.time()
    # a first session that ran 100 s and finished, a second killed 60 s after it
    # started (its last write in the folder: the checkpoint)
    (out / SESSIONS).write_text(
        json.dumps([{"started": now - 500, "seconds": 100.0}, {"started": now - 100}])
    )
    (out / CHECKPOINT).write_bytes(b"x")
    os.utime(out / CHECKPOINT, (now - 40, now - 40))
    clock = SessionClock(out, resume=True)
    total, n = clock.finish(5.0)
    assert n == 3 and total == pytest.approx(100 + 60 + 5, abs=0.5)
    saved = json.loads((out / SESSIONS).read_text())
    assert saved[1]["interrupted"] is True and saved[2]["seconds"] == 5.0
    # a fresh start forgets earlier sessions
    assert SessionClock(out, resume=False).finish(2.0) == (2.0, 1)


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda c: c["optimizer"].update(learning_rate=float("inf")), "learning_rate"),
        (lambda c: c["train"].update(dt=float("nan")), "train.dt = nan"),
        (lambda c: c["loss"].update(effort=float("-inf")), "loss.effort = -inf"),
        (lambda c: c["gains"]["bounds"].update(T1=[0.002, float("inf")]), "T1 = inf"),
        (lambda c: c.update(seed=-1), r"seed = -1 is not allowed"),
        (lambda c: c["validation"].update(seed=2**32), r"validation.seed = 4294967296"),
    ],
)
def test_config_numbers_must_be_finite_and_seeds_in_range(change, match):
    """Issue 16, class 1 (a config): inf/NaN anywhere in a tuning config is refused."""
    from tuning.config import check_config

    cfg = load_config()
    change(cfg)
    with pytest.raises(sj.ParameterError, match=match):
        check_config(cfg)
