"""--phi-layer: the boundary layer of the evolution law from the command line (issue
15): validated by the library, refused for controllers without it, kept by resume."""

import json

import pytest

from smibjax.cli import _parser, main
from smibjax.cli.cct import _sets
from smibjax.controllers import Synergetic
from smibjax.parameters import GAIN_NAMES, Gains


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


def _stable_spec(**kw):
    from smibjax.montecarlo import MonteCarloSpec

    g = Gains.paper("aftsc", beta1=-1.0, beta2=-1.0)
    gains = {k: float(getattr(g, k)) for k in GAIN_NAMES}
    return MonteCarloSpec(gains=gains, t_end=3.0, **{"n": 8, "chunk": 4, **kw})


def test_reclose_delay_order_changes_the_chunks_not_the_rows():
    import numpy as np

    from smibjax.montecarlo import COLUMNS, compute_chunk

    def rows(spec):
        parts = [compute_chunk(spec, k) for k in range(spec.n_chunks)]
        return {c: np.concatenate([p[c] for p in parts]) for c in COLUMNS}, parts

    ref, _ = rows(_stable_spec())
    for chunk in (4, 3):
        spec = _stable_spec(order="reclose_delay", chunk=chunk)
        got, parts = rows(spec)
        index = got["index"]
        assert not np.array_equal(index, np.arange(8))  # chunks hold other indices
        for k, p in enumerate(parts):  # each chunk: its indices, in index order
            assert np.array_equal(p["index"], np.sort(spec.chunk_indices(k)))
        rank = np.argsort(index)
        for c in COLUMNS:  # every row bitwise the same
            assert np.array_equal(got[c][rank], ref[c], equal_nan=True), c
    delay = ref["t_reclose"] - ref["t_clear"]
    spec = _stable_spec(order="reclose_delay")
    first = spec.chunk_indices(0)
    assert delay[first].max() <= delay[spec.chunk_indices(1)].min()


def test_order_on_the_command_line_and_old_runs_resume(tmp_path, capsys):
    import numpy as np

    from smibjax.cli.runs import read_rows

    out = tmp_path / "run"
    argv = ["montecarlo", "--n", "6", "--chunk", "3", "--t-end", "3"]
    argv += ["--set", "beta1=-1", "--set", "beta2=-1", "--out", str(out)]
    assert main([*argv, "--order", "reclose-delay"]) == 0
    spec = json.loads((out / "run.json").read_text())["spec"]
    assert spec["order"] == "reclose_delay"
    rows = read_rows(out / "scenarios.csv")
    assert np.array_equal(rows["index"], np.arange(6))
    capsys.readouterr()
    assert main([*argv, "--order", "bogus"]) == 2
    _one_line(capsys, "argument --order: invalid choice: 'bogus'")
    # a run written before the spec had `order`: resumes as the index order it was
    old = tmp_path / "old"
    assert main([*argv[:-1], str(old)]) == 0
    manifest = json.loads((old / "run.json").read_text())
    del manifest["spec"]["order"]
    manifest["complete"] = False
    (old / "run.json").write_text(json.dumps(manifest))
    (old / "chunks" / "000001.npz").unlink()
    capsys.readouterr()
    assert main([*argv[:-1], str(old), "--resume"]) == 0
    again = read_rows(old / "scenarios.csv")
    for c in rows:
        assert np.array_equal(again[c], rows[c], equal_nan=True), c
