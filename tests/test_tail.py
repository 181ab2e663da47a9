"""--phi-layer: the boundary layer of the evolution law from the command line (issue
15): validated by the library, refused for controllers without it, kept by resume."""

import json

import pytest

from smibjax.cli import _parser, main
from smibjax.cli.cct import _sets
from smibjax.controllers import Synergetic
from smibjax.controllers.synergetic import GAIN_NAMES, Gains


def _one_line(capsys, needle):
    err = capsys.readouterr().err
    assert needle in err, err
    assert err.count("\n") == 1 and err.startswith("smibjax: error:"), err


@pytest.mark.parametrize(
    "value, needle",
    [
        ("-1", "--phi-layer -1.0 is not allowed: must be a finite number >= 0"),
        ("nan", "--phi-layer nan is not allowed: must be a finite number >= 0"),
        ("inf", "--phi-layer inf is not allowed: must be a finite number >= 0"),
        ("x", "argument --phi-layer: invalid float value: 'x'"),
    ],
)
def test_bad_width_is_one_line(value, needle, capsys, tmp_path):
    for sub in ("simulate", "montecarlo", "cct"):
        argv = [sub, "--phi-layer", value]
        if sub == "montecarlo":
            argv += ["--n", "2", "--out", str(tmp_path / "o")]
        assert main(argv) == 2
        _one_line(capsys, needle)
    assert (
        main(
            ["compare", "--n", "2", "--phi-layer", value, "--out", str(tmp_path / "k")]
        )
        == 2
    )
    _one_line(capsys, needle)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("controller", ["none", "avr-pss"])
def test_controller_without_the_law_refuses_it(controller, capsys, tmp_path):
    for sub in ("simulate", "cct"):
        assert main([sub, "--controller", controller, "--phi-layer", "0.01"]) == 2
        _one_line(capsys, "--phi-layer 0.01 is not allowed for controller")
    out = tmp_path / "o"
    argv = ["--n", "2", "--phi-layer", "0", "--out", str(out)]
    assert main(["montecarlo", "--controller", controller, *argv]) == 2
    _one_line(capsys, f"controller {controller!r}: only the paper's law")
    assert main(["compare", "--gains", controller, *argv]) == 2
    _one_line(capsys, f"controller {controller!r}: only the paper's law")
    assert not out.exists()


def test_width_overrides_the_gains_file_and_reaches_cct(tmp_path):
    g = Gains.paper("aftsc", beta1=-1.0, beta2=-1.0)
    gains = tmp_path / "g.json"
    gains.write_text(
        json.dumps(
            {
                "schema": "smibjax.gains/1",
                "controller": "aftsc",
                "adaptation": "oracle",
                "plant": {"preset": "paper"},
                "options": {"phi_layer": 0.01},
                "gains": {
                    **{k: float(getattr(g, k)) for k in GAIN_NAMES},
                },
            }
        )
    )
    for argv, want in (([], 0.01), (["--phi-layer", "0.003"], 0.003)):
        args = _parser().parse_args(["cct", "--gains", str(gains), *argv])
        lanes, _ = _sets(args)
        (ctrl,) = lanes.values()
        assert isinstance(ctrl, Synergetic) and ctrl.phi_layer == want
        assert args.contexts["aftsc"]["options"]["phi_layer"] == want


def test_montecarlo_keeps_the_width_and_resume_needs_it(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["montecarlo", "--n", "4", "--chunk", "2", "--t-end", "3"]
    argv += ["--set", "beta1=-1", "--set", "beta2=-1", "--out", str(out)]
    assert main([*argv, "--phi-layer", "0.01"]) == 0
    spec = json.loads((out / "run.json").read_text())["spec"]
    assert spec["options"] == {"phi_layer": 0.01}
    capsys.readouterr()
    assert main([*argv, "--resume"]) == 2  # without the width: a different run
    _one_line(capsys, "--resume: options = {} differs from the run")
    assert main([*argv, "--resume", "--phi-layer", "0.01"]) == 0
