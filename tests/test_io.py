"""Files in and out (io.py): atomic writes survive a failure mid-write and honour
the umask, user-named files are never replaced without --force, input files must be
UTF-8."""

import json
import os

import numpy as np
import pytest

import smibjax as sj
import smibjax._files as sio
from smibjax._files import (
    check_new_file,
    read_table,
    write_json,
    write_npz,
    write_text,
)
from smibjax.cli import main


def _only(path):
    return sorted(p.name for p in path.parent.iterdir())


def test_a_writer_that_fails_midway_leaves_the_old_file(tmp_path):
    target = tmp_path / "table.json"
    sio.write_json(target, {"a": 1.0})
    old = target.read_bytes()

    def half_then_crash(tmp):
        with open(tmp, "w") as fh:
            fh.write('{"a": 2.0, "b"')  # half a JSON document
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        sio.atomic_write(target, half_then_crash)
    assert target.read_bytes() == old
    assert json.loads(target.read_text()) == {"a": 1.0}
    assert _only(target) == ["table.json"]  # the partial temporary file is gone


def test_npz_and_text_writers_fail_cleanly(tmp_path, monkeypatch):
    npz = tmp_path / "run.npz"
    sio.write_npz(npz, {"x": np.arange(3.0)})
    txt = tmp_path / "notes.md"
    sio.write_text(txt, "old\n")

    def savez_then_crash(fh, **arrays):
        fh.write(b"PK\x03\x04 truncated")
        raise OSError("killed mid-write")

    monkeypatch.setattr(np, "savez", savez_then_crash)
    with pytest.raises(OSError, match="killed mid-write"):
        sio.write_npz(npz, {"x": np.arange(5.0)})
    np.testing.assert_array_equal(np.load(npz)["x"], np.arange(3.0))

    def replace_fails(src, dst):
        raise OSError("rename failed")

    monkeypatch.setattr(sio.os, "replace", replace_fails)
    with pytest.raises(OSError, match="rename failed"):
        sio.write_text(txt, "new\n")
    assert txt.read_text() == "old\n"
    assert _only(txt) == ["notes.md", "run.npz"]


def test_a_successful_write_replaces_the_file(tmp_path):
    target = tmp_path / "sub" / "out.txt"  # the folder is created
    sio.write_text(target, "one\n")
    sio.write_text(target, "two\n")
    assert target.read_text() == "two\n" and _only(target) == ["out.txt"]


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
