"""benchmarks/suite_time.py (the suite's runtime and where it goes) on what it reads:
its summary of the profiler's files against hand-computed totals, its parse of the
calibration lines `tests/bench_chain.py` prints, its refusal of a bad --ref before
any work, and the `_suite_profile` plugin in a real pytest process."""

import importlib.util
import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from bench_chain import timing_line

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def suite_time():
    spec = importlib.util.spec_from_file_location("suite_time", BENCH / "suite_time.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_summary_adds_up_the_processes_and_ranks_the_largest(suite_time):
    start = 1000.0
    gw0 = {
        "process": "gw0",
        "cpu_s": 50.0,
        "tests": [
            ["tests/test_a.py::t1", 1001.0, 4.0, 3.5, {"compile": [2, 3.0]}],
            ["tests/test_a.py::t2", 1005.0, 1.0, 0.5, {"trace": [1, 0.25]}],
        ],
        "programs": {"jit(run)": [2, 3.0]},
        "outside_tests": {"compile": [1, 0.5]},
    }
    gw1 = {
        "process": "gw1",
        "cpu_s": 40.0,
        "tests": [["tests/test_b.py::t3", 1002.0, 9.0, 8.0, {"compile": [1, 6.0]}]],
        "programs": {"jit(_simulate)": [1, 6.0], "jit(run)": [1, 0.5]},
        "outside_tests": {},
    }
    s = suite_time.summarize([gw1, gw0], start)
    assert [p["process"] for p in s["processes"]] == ["gw0", "gw1"]
    p0, p1 = s["processes"]
    assert (p0["tests"], p0["busy_s"], p0["last_end_s"]) == (2, 5.0, 6.0)
    assert (p1["tests"], p1["busy_s"], p1["last_end_s"]) == (1, 9.0, 11.0)
    assert s["events"]["compile"] == {"count": 4, "s": 9.5}  # 2 + 1 + 1 outside
    assert s["events"]["trace"] == {"count": 1, "s": 0.25}
    assert s["modules_wall_s"] == {"tests/test_b.py": 9.0, "tests/test_a.py": 5.0}
    assert s["programs"][0] == {
        "function": "jit(_simulate)",
        "compiles": 1,
        "compile_s": 6.0,
    }
    assert s["programs"][1] == {"function": "jit(run)", "compiles": 3, "compile_s": 3.5}
    assert [t["test"] for t in s["tests"]] == [
        "tests/test_b.py::t3",
        "tests/test_a.py::t1",
        "tests/test_a.py::t2",
    ]
    assert s["tests"][1]["compile_s"] == 3.0 and s["tests"][2]["trace_s"] == 0.25


def test_calibration_lines_are_read_as_bench_chain_prints_them(suite_time):
    text = "\n".join(
        [
            "some other output",
            timing_line("throughput", 0, 19.54, 28.25),
            timing_line("stiff_solvers", 1, 1.9, 2.1),
        ]
    )
    got = suite_time.parse_calibration(text)
    assert got == {
        "throughput": {"rc": 0, "wall_s": 19.5, "cpu_s": 28.2},
        "stiff_solvers": {"rc": 1, "wall_s": 1.9, "cpu_s": 2.1},
    }


def test_a_bad_ref_is_one_line_before_any_work(suite_time, tmp_path, capsys):
    assert suite_time.main(["--ref", "no-such-ref", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "error: --ref = 'no-such-ref' is not allowed: must name a commit here"
    assert list(tmp_path.iterdir()) == []


def test_profiler_plugin_records_each_test_and_its_compiles(tmp_path):
    (tmp_path / "test_tiny.py").write_text(
        "import jax, jax.numpy as jnp\n"
        "def at_import(x):\n"
        "    return x + 1.0\n"
        "jax.jit(at_import)(1.0)  # at collection, outside any test\n"
        "def test_jit():\n"
        "    def tiny_program(x):\n"
        "        return jnp.sin(x) * 2.0\n"
        "    assert float(jax.jit(tiny_program)(1.0)) > 0\n"
        "def test_nothing():\n"
        "    pass\n"
        "def test_child():\n"
        "    import subprocess, sys\n"
        "    code = 'import time\\nt = time.process_time()\\n'"
        " 'while time.process_time() - t < 0.3: pass'\n"
        "    subprocess.run([sys.executable, '-c', code], check=True)\n"
    )
    out = tmp_path / "profile"
    out.mkdir()
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(BENCH), os.environ.get("PYTHONPATH", "")]),
        "SMIBJAX_SUITE_PROFILE": str(out),
        # a persistent cache of its own, every program kept: its misses are logged
        "JAX_COMPILATION_CACHE_DIR": str(tmp_path / "cache"),
        "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0",
    }
    env.pop("PYTEST_XDIST_WORKER", None)
    p = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "_suite_profile"]
        + ["-p", "no:cacheprovider", "-p", "no:xdist", "test_tiny.py"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    prof = json.loads((out / "controller.json").read_text())
    rows = {r[0]: r for r in prof["tests"]}
    assert set(rows) == {
        "test_tiny.py::test_jit",
        "test_tiny.py::test_nothing",
        "test_tiny.py::test_child",
    }
    jit_row = rows["test_tiny.py::test_jit"]
    assert jit_row[4]["compile"][0] >= 1 and jit_row[4]["trace"][0] >= 1
    assert "compile" not in rows["test_tiny.py::test_nothing"][4]
    # the CPU of a test's subprocess is the test's (it burns 0.3 CPU-s), not another's
    assert rows["test_tiny.py::test_child"][5] >= 0.3
    assert rows["test_tiny.py::test_nothing"][5] < 0.05
    # each test's own programs: the at-import compile is nobody's
    assert rows["test_tiny.py::test_jit"][6]["jit(tiny_program)"][0] == 1
    assert "jit(at_import)" not in rows["test_tiny.py::test_jit"][6]
    assert rows["test_tiny.py::test_nothing"][6] == {}
    assert prof["programs"]["jit(tiny_program)"][0] == 1
    assert prof["programs"]["jit(at_import)"][0] == 1
    assert prof["outside_tests"]["compile"][0] >= 1  # kept, not dropped at test start
    assert prof["cpu_s"] > 0
    # each test's persistent-cache misses, by key: the at-import one is nobody's
    jit_keys = rows["test_tiny.py::test_jit"][7]
    assert [k.rsplit("-", 1)[0] for k in jit_keys].count("jit_tiny_program") == 1
    assert all(len(k.rsplit("-", 1)[1]) == 64 for k in jit_keys)  # name-sha256
    assert not any(k.startswith("jit_at_import-") for k in jit_keys)
    assert rows["test_tiny.py::test_nothing"][7] == []
    assert any(k.startswith("jit_at_import-") for k in prof["misses_outside_tests"])


def test_repeated_misses_count_the_programs_compiled_twice(suite_time):
    """A key missed n times is n - 1 compiles another process had already done (or
    was doing); a key missed once is none."""
    repeated_misses = suite_time.repeated_misses
    a1, a2, b = "jit_a-" + "1" * 64, "jit_a-" + "2" * 64, "jit_b-" + "3" * 64
    rep = repeated_misses(Counter({a1: 2, a2: 1, b: 3}))
    assert rep == {
        "misses": 6,
        "keys": 3,
        "repeated_keys": 2,
        "extra_compiles": 3,
        "extra_by_function": {"jit_b": 2, "jit_a": 1},
    }
    assert repeated_misses(Counter())["extra_compiles"] == 0
