"""The memory plan of grid runs (smibjax.grid.memory): a run that cannot fit is
refused in one line before any work, and a batch's chunk is what fits."""

import pytest

from smibjax.cli import main
from smibjax.grid.case import load_case
from smibjax.grid.memory import chunk_that_fits, run_size

pytestmark = pytest.mark.xdist_group("grid")


def test_a_run_that_cannot_fit_is_one_line_and_writes_nothing(tmp_path, capsys):
    """`simulate --case kundur --t-end 1000000` (1e8 samples) is refused with exit 2
    and one line naming --t-end, before compiling, and writes no file."""
    out = tmp_path / "run.npz"
    argv = ["simulate", "--case", "kundur", "--fault-bus", "7", "--t-end", "1000000"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--t-end 1e+06" in err[0] and "GiB" in err[0], err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_a_sweep_that_cannot_fit_is_one_line(capsys):
    argv = ["modes", "--case", "kundur-gencls", "--sweep", "GENCLS.D=0:10:1e11"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--sweep" in err[0], err


def test_the_chunk_is_what_fits_the_memory_limit(monkeypatch):
    """With SMIBJAX_MEMORY_LIMIT set to the shared part plus 3.5 runs, the chunk is
    3 (of the 128 asked); with less than one run, 0; the plan grows linearly in the
    samples."""
    case = load_case("kundur-gencls")
    size = run_size(case, 1001, n_events=1)
    monkeypatch.setenv(
        "SMIBJAX_MEMORY_LIMIT", str(int(size.shared + 3.5 * size.per_run))
    )
    assert chunk_that_fits(size, 128) == 3
    assert chunk_that_fits(size, 2) == 2
    monkeypatch.setenv(
        "SMIBJAX_MEMORY_LIMIT", str(int(size.shared + 0.5 * size.per_run))
    )
    assert chunk_that_fits(size, 128) == 0
    big = run_size(case, 2001, n_events=1)
    small = run_size(case, 1, n_events=1)
    assert big.per_run - size.per_run == pytest.approx(size.per_run - small.per_run)
