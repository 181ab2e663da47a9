"""Files out (issue 16): atomic writes honour the umask, user-named files are never
replaced without --force, input files must be UTF-8."""

import os

import pytest

import smibjax as sj
from smibjax.cli import main
from smibjax.io import check_new_file, read_table, write_json, write_npz, write_text


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002, 0o027])
def test_atomic_writes_honour_the_umask(tmp_path, mask):
    old = os.umask(mask)
    try:
        paths = [
            write_text(tmp_path / "a.txt", "x"),
            write_json(tmp_path / "b.json", {"x": 1}),
            write_npz(tmp_path / "c.npz", {"x": [1.0]}),
            write_text(tmp_path / "a.txt", "replaced"),  # a replacement too
        ]
    finally:
        os.umask(old)
    for p in paths:
        assert p.stat().st_mode & 0o777 == 0o666 & ~mask, p
    assert os.umask(old) == old  # the process's umask is left as it was


def test_check_new_file(tmp_path):
    f = tmp_path / "f.json"
    assert check_new_file(f) == f
    f.write_text("mine")
    with pytest.raises(sj.ParameterError, match="must be a new file .*add --force"):
        check_new_file(f)
    assert check_new_file(f, force=True) == f
    with pytest.raises(sj.ParameterError, match="must be a file name .*folder"):
        check_new_file(tmp_path, force=True)


def test_read_table_refuses_non_utf8(tmp_path):
    p = tmp_path / "g.json"
    p.write_bytes(b'{"beta1": -1}\xff')
    with pytest.raises(sj.ParameterError, match=r"must be UTF-8 text \(byte 0xff"):
        read_table(p)


def test_compare_and_montecarlo_never_fill_a_folder_that_holds_files(tmp_path, capsys):
    for cmd in ("compare", "montecarlo"):
        out = tmp_path / cmd
        out.mkdir()
        (out / "keep.txt").write_text("mine")
        assert main([cmd, "--n", "2", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "not empty" in err
        assert [p.name for p in out.iterdir()] == ["keep.txt"]
