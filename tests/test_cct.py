"""Critical clearing time (MODEL.md section 4): the largest duration with every shorter
one stable, found by a scan of all lanes then bisection; non-monotone stability is
reported with its stable islands; the criteria "settled" and "synchronism"."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smibjax as sj
from helpers import STABLE
from smibjax._cct import _islands, critical_clearing_times, scan_durations
from smibjax.cli import main

# one worker runs the module: its tests share the module fixture `direct` and the
# CCT programs (under -n 2 a test on the other worker built them again)
pytestmark = pytest.mark.xdist_group("cct")

# The issue-19 case: beta = -1 under the realistic limits with realizable adaptation,
# fault at location 0.2: stable when cleared after 0.15 s, not settled by t_end after
# 0.20-0.35 s, stable again after 0.40 s, not settled after 0.45 s, but it never loses
# synchronism for these durations.
PLANT = sj.Plant.preset("realistic")
GAINS = sj.Gains.paper("aftsc", **STABLE)
LAM, TOL = 0.2, 0.01


@pytest.fixture(scope="module")
def direct():
    """Direct runs at chosen clearing durations (s): (stable, lost_sync) flags; up to
    8 durations per call, padded to 8 (one compilation)."""
    run = None

    def flags(durations):
        nonlocal run
        padded = list(durations) + [durations[-1]] * (8 - len(durations))

        def one(d):
            f = sj.Fault(t_fault=0.5, t_clear=0.5 + d, t_reclose=2.0, lam=LAM)
            tr = sj.simulate(
                GAINS, f, PLANT, adaptation="realizable", save=sj.SaveOptions(10.0)
            )
            return tr.stable, tr.lost_sync | tr.budget_exhausted

        run = run or jax.jit(jax.vmap(one))
        s, lost = (np.asarray(a) for a in run(jnp.asarray(padded, dtype=float)))
        return dict(zip(padded, s, strict=True)), dict(zip(padded, lost, strict=True))

    return flags


def cct(criterion, progress=None):
    return critical_clearing_times(
        {"stable": GAINS},
        PLANT,
        fault_locations=[LAM],
        tol=TOL,
        scan_step=0.05,
        adaptation="realizable",
        criterion=criterion,
        progress=progress,
    ).to_dict()  # the JSON layout the command line writes


def test_scan_grid_and_islands():
    np.testing.assert_allclose(scan_durations(1.5, 0.01, 0.5), [0.01, 0.5, 1.0, 1.5])
    assert len(scan_durations(1.5, 1e-3, 0.05)) == 31  # tol, then 30 steps of 0.05
    np.testing.assert_allclose(scan_durations(0.3, 0.1, 0.05), [0.1, 0.2, 0.3])
    d = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    ok = np.array([False, True, True, False, False, True])
    assert _islands(ok, d) == [[0.2, 0.3], [0.6, 0.6]]
    assert _islands(~ok, d) == [[0.1, 0.1], [0.4, 0.5]]
    assert _islands(np.zeros(3, bool), d[:3]) == []


def test_non_monotone_lane_gives_the_first_boundary(direct):
    """Settled criterion: the CCT is where stability first ends (below 0.2 s), not
    the later boundary bisection over the whole window found (0.402 s before)."""
    res = cct("settled")
    stable, _ = direct([0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, res["cct"][0]])
    assert [bool(stable[d]) for d in (0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45)] == [
        True,
        False,
        False,
        False,
        False,
        True,
        False,
    ]
    assert res["status"] == ["non_monotone"] and res["criterion"] == "settled"
    c = res["cct"][0]
    assert 0.15 <= c < 0.2 and stable[c]
    assert res["islands"] == [[[0.4, 0.4]]]  # the later stable island, from the scan
    assert res["sets"]["stable"]["islands"] == [[[0.4, 0.4]]]
    # every scan duration up to the CCT is stable; the first beyond it is not
    scan = np.asarray(res["scan"])
    before, _ = direct([float(d) for d in scan[scan <= c]])
    assert all(bool(v) for v in before.values())
    # the bisection ended on an unstable duration at most tol beyond the CCT
    hi = res["sets"]["stable"]["first_unstable"][0]
    assert c < hi <= c + TOL
    after, _ = direct([hi])
    assert not after[hi]


def test_synchronism_criterion_differs_from_settled(direct):
    """No loss of synchronism up to t_end: 0.2-0.45 s count (unsettled, not lost)."""
    calls = []
    res = cct("synchronism", progress=lambda done, total: calls.append((done, total)))
    # progress is a callback (the core never draws a bar): from 0 to its total,
    # never backwards, once before the scan and after each batched call
    total = calls[0][1]
    assert calls[0] == (0, total) and calls[-1] == (total, total)
    assert all(a[0] <= b[0] for a, b in zip(calls, calls[1:], strict=False))
    assert res["criterion"] == "synchronism" and res["status"] == ["ok"]
    c = res["cct"][0]
    assert 0.8 < c < 0.95  # settled gives < 0.2 s (above)
    hi = res["sets"]["stable"]["first_unstable"][0]
    assert c < hi <= c + TOL
    stable, lost = direct([0.3, 0.45, c, hi])
    assert not stable[0.3] and not lost[0.3]  # not settled, yet in synchronism
    assert not stable[0.45] and not lost[0.45]
    assert not lost[c] and lost[hi]


def test_cct_command_criterion_t_end_and_table(tmp_path, capsys):
    out = tmp_path / "c.json"
    argv = ["cct", "--set", "beta1=-1", "--set", "beta2=-1", "--preset", "realistic"]
    argv += ["--adaptation", "realizable", "--fault-location", "0.2", "--tol", "0.01"]
    assert main([*argv, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["status"] == ["non_monotone"] and data["islands"] == [[[0.4, 0.4]]]
    assert data["cct"][0] < 0.2 and data["criterion"] == "settled"
    assert "criterion settled" in text and f"{data['cct'][0]:.4f}*" in text
    assert "stable again for clearing durations [0.4, 0.4] s" in text
    assert data["context"]["aftsc"]["adaptation"] == "realizable"
    assert out.with_suffix(".png").stat().st_size > 10_000


@pytest.mark.parametrize(
    "argv, match",
    [
        (["cct", "--t-end", "1.5"], "--t-end 1.5 s is not allowed: must be after"),
        (["cct", "--criterion", "angle"], "invalid choice: 'angle'"),
        (["cct", "--scan-step", "0"], "--scan-step 0 is not allowed"),
    ],
)
def test_cct_bad_options(argv, match, capsys, tmp_path):
    assert main([*argv, "--out", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("smibjax: error:")
    assert match in err
    assert not (tmp_path / "c.json").exists()


def test_core_rejects_a_horizon_before_reclosure():
    with pytest.raises(sj.ParameterError, match="t_end = 1.5 s is not allowed"):
        critical_clearing_times({"a": GAINS}, t_end=1.5)
    with pytest.raises(sj.ParameterError, match="criterion = 'x' is not allowed"):
        critical_clearing_times({"a": GAINS}, criterion="x")
