"""Atomic writes: a failure in the middle of a write leaves the old file intact and no
temporary file behind."""

import json

import numpy as np
import pytest

import smibjax.io as sio


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
