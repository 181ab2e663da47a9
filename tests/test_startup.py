"""Start-up of the entry points (issue 32): `--help` answers without JAX, every
entry point configures the process before equinox or JAX load, and a second
identical `simulate` finds its programs in the persistent compilation cache (nothing
new written to it, no "Not writing persistent cache entry" but for the programs too
quick to keep; the tuner's is tests/test_tuning.py's SIGKILL test)."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import ROOT

HEAVY = ("jax", "equinox", "diffrax", "matplotlib")


def _modules_after(code: str) -> list[str]:
    """The heavy modules loaded by a fresh interpreter after `code`."""
    probe = (
        "import sys\n"
        f"try:\n    {code}\nexcept SystemExit:\n    pass\n"
        f"print('LOADED:' + ','.join(m for m in {HEAVY!r} if m in sys.modules))"
    )
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}:{ROOT}"}
    r = subprocess.run(
        [sys.executable, "-c", probe],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
        check=True,
    )
    line = r.stdout.strip().splitlines()[-1]
    assert line.startswith("LOADED:"), r.stdout[-500:]
    return [m for m in line.removeprefix("LOADED:").split(",") if m]


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["simulate"],
        ["montecarlo"],
        ["cct"],
        ["compare"],
        ["reproduce"],
        ["modes"],
    ],
)
def test_help_imports_no_jax(argv):
    """`python -m smibjax [COMMAND] --help` loads none of JAX, equinox, diffrax,
    matplotlib (it took 2 s with them; benchmarks/README.md has the figure)."""
    code = f"from smibjax.cli import main; main({[*argv, '--help']!r})"
    assert _modules_after(code) == []


def test_tuner_help_and_usage_errors_import_no_jax():
    assert _modules_after("from tuning.optimize import main; main(['--help'])") == []
    assert _modules_after("from tuning.optimize import main; main(['--steps'])") == []


def test_the_library_names_the_help_offers_are_the_registries():
    """The jax-free names `--help` offers (`smibjax._names`) are the registries'."""
    from smibjax._names import CONTROLLER_NAMES, PRESETS
    from smibjax._parameters import PRESETS as PLANT_PRESETS
    from smibjax.controllers import CONTROLLERS

    assert CONTROLLER_NAMES == tuple(CONTROLLERS)
    assert PRESETS is PLANT_PRESETS


def _first_line(tree, pred) -> int | None:
    """The first line of a top-level statement (or one inside a top-level `if`)
    for which `pred(node)` holds."""
    lines = []
    for node in tree.body:
        for sub in [node, *(node.body if isinstance(node, ast.If) else [])]:
            if pred(sub):
                lines.append(sub.lineno)
    return min(lines) if lines else None


def _loads_jax(node) -> bool:
    light = {"smibjax": {"configure"}}
    if isinstance(node, ast.Import):
        return any(
            a.name.split(".")[0] in ("jax", "equinox", "diffrax", "smibjax")
            or a.name in ("_common", "_results")
            for a in node.names
        )
    if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
        top = node.module.split(".")[0]
        if node.module in light and {a.name for a in node.names} <= light[node.module]:
            return False
        return top in ("jax", "equinox", "diffrax", "smibjax", "tuning") or (
            node.module in ("_common", "_results")
        )
    return False


def _configures(node) -> bool:
    return (
        isinstance(node, ast.Expr)
        and isinstance(node.value, ast.Call)
        and getattr(node.value.func, "id", None) == "configure"
    )


@pytest.mark.parametrize(
    "script", sorted(p.name for p in (ROOT / "benchmarks").glob("[!_]*.py"))
)
def test_every_benchmark_configures_before_jax_loads(script):
    """A benchmark that loads smibjax, JAX or equinox at import calls
    `smibjax.configure` first (host devices, float64, equinox's error mode: an
    equinox loaded before it compiles host callbacks the cache refuses)."""
    tree = ast.parse((ROOT / "benchmarks" / script).read_text())
    first = _first_line(tree, _loads_jax)
    if first is None:
        return  # loads the library inside functions (after its own set-up)
    conf = _first_line(tree, _configures)
    assert conf is not None and conf < first, (script, conf, first)


def _refused(log: str) -> list[str]:
    """The log lines of programs the cache refused or missed for another reason
    than a compile too quick to keep."""
    return [
        line
        for line in log.splitlines()
        if "Not writing persistent cache entry" in line and "took <" not in line
    ]


def test_the_cache_state_names_the_programs_it_looks_for(tmp_path):
    """`cache_state` (the "(cache: warm|cold|off)" of the commands' compiling line,
    the tuner's with its programs `jit_run` and `jit_reduce`): cold in an empty or
    missing folder or one holding only other programs, warm once it holds an entry of
    one of them, off without a folder."""
    import jax

    from smibjax._process import cache_state

    names = ("jit_run", "jit_reduce")
    before = jax.config.jax_compilation_cache_dir
    try:
        jax.config.update("jax_compilation_cache_dir", str(tmp_path / "missing"))
        assert cache_state(*names) == "cold"
        jax.config.update("jax_compilation_cache_dir", str(tmp_path))
        assert cache_state(*names) == "cold"
        (tmp_path / "jit__simulate-0123").write_bytes(b"x")
        (tmp_path / "jit_runner-0123").write_bytes(b"x")
        assert cache_state(*names) == "cold"
        (tmp_path / "jit_reduce-4567").write_bytes(b"x")
        assert cache_state(*names) == "warm"
        assert cache_state("jit__simulate") == "warm"
        jax.config.update("jax_compilation_cache_dir", None)
        assert cache_state(*names) == "off"
    finally:
        jax.config.update("jax_compilation_cache_dir", before)


@pytest.mark.parametrize(
    ("argv", "shown"),
    [
        (["simulate"], ["--t-end T_END", "(default: 10.0)", "(default: 0.5)"]),
        (["montecarlo"], ["(default: 1000)"]),
        (["cct"], ["--tol", "(default: 0.001)"]),
        (["reproduce"], ["runs/reproduce-<time>", "(default: paper)"]),
    ],
)
def test_help_shows_the_defaults(capsys, argv, shown):
    """Issue 32: --n, --fault-time, --t-end, --tol, reproduce --out showed no
    default."""
    from smibjax.cli import main

    with pytest.raises(SystemExit):
        main([*argv, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for s in shown:
        assert s in text, s


def test_tuner_help_shows_the_config_defaults_and_a_whole_description(capsys):
    from tuning.optimize import main

    with pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: 100, from tuning/configs/default.toml)" in text
    assert "over batches of fault scenarios;" in text


# -- simulate's warm start: the stored (jax.export) programs ----------------------

_PROBE = """
import sys
from smibjax.cli import main
code = main(sys.argv[1:])
from smibjax.cli import _exported
heavy = ("diffrax", "optimistix", "lineax", "scipy", "matplotlib")
loaded = ",".join(m for m in heavy if m in sys.modules)
print(f"PATH {_exported.LAST_PATH} LOADED {loaded}", file=sys.stderr)
sys.exit(code)
"""


def _simulate_child(
    args, cache: Path, cwd: Path, log: list | None = None, **env_extra
) -> tuple[str, str, str]:
    """(path taken, heavy modules loaded, summary) of one `simulate` in a fresh
    process with the compilation cache `cache`. With `log` (a list), the process
    configures itself (no EQX_ON_ERROR inherited) and logs JAX's compiles and cache
    reads; its stderr is appended to `log`."""
    env = {
        **os.environ,
        "PYTHONPATH": f"{ROOT / 'src'}:{ROOT}",
        "SMIBJAX_CACHE_DIR": str(cache),
        **env_extra,
    }
    if log is not None:
        env.pop("EQX_ON_ERROR", None)
        env["JAX_LOGGING_LEVEL"] = "DEBUG"
    r = subprocess.run(
        [sys.executable, "-c", _PROBE, "simulate", "--force", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    if log is not None:
        log.append(r.stderr)
    line = next(x for x in r.stderr.splitlines() if x.startswith("PATH "))
    _, path, _, loaded = (line + " ").split(" ", 3)
    summary = "\n".join(x for x in r.stdout.splitlines() if not x.startswith("wrote"))
    return path, loaded.strip(), summary


def _same_bits(a: Path, b: Path) -> None:
    """Two npz files hold the same arrays, in the same order, bit for bit."""
    import numpy as np

    with np.load(a) as x, np.load(b) as y:
        assert list(x.keys()) == list(y.keys())
        for k in x:
            assert x[k].dtype == y[k].dtype and x[k].shape == y[k].shape, k
            assert x[k].tobytes() == y[k].tobytes(), k


def test_a_second_simulate_calls_the_stored_program_bit_for_bit(tmp_path):
    """Issue 32: a second identical `simulate` traced the simulator again and loaded
    diffrax (2.3-2.6 CPU-s). Now the first run exports and stores its programs, the
    second calls them (no trace; diffrax, SciPy and matplotlib not loaded), and both
    give the traced path's npz and summary bit for bit. New values of the same
    structure (`--set H=6`) call the stored programs too (values are arguments, not
    constants); a changed option (`--rtol`) misses, exports anew and differs.

    Issue 32's cache check for `simulate` (a second identical run writes nothing new
    to the cache and loads its compiled programs from it) on the first and second
    runs here, from a cold cache (they were a separate pair of processes)."""
    cache = tmp_path / "cache"
    out = ["--t-end", "3", "--out"]
    logs = []
    first = _simulate_child([*out, "b.npz"], cache, tmp_path, log=logs)
    assert first[0] == "exported"
    traced = _simulate_child([*out, "a.npz"], cache, tmp_path, SMIBJAX_EXPORTED="0")
    assert traced[0] == "traced"
    second = _simulate_child([*out, "c.npz"], cache, tmp_path, log=logs)
    assert second[:2] == ("stored", "")  # nothing heavy loaded
    # issue 32: nothing refused by the cache; the second run's program from it
    assert _refused(logs[0]) == [] and _refused(logs[1]) == []
    assert any(e.startswith("jit_call_exported-") for e in os.listdir(cache))
    log = logs[1].lower()
    assert "compilation cache hit for 'jit_call_exported'" in log
    assert "compilation cache miss for 'jit_call_exported'" not in log
    assert "compiling " in logs[0] and "(cache: cold)" in logs[0]
    assert "compiling " not in logs[1]  # nothing traced, nothing to announce
    assert traced[2] == first[2] == second[2]
    _same_bits(tmp_path / "a.npz", tmp_path / "b.npz")
    _same_bits(tmp_path / "a.npz", tmp_path / "c.npz")

    h6 = [*out, "h6.npz", "--set", "H=6"]
    h6_traced = [*out, "h6t.npz", "--set", "H=6"]
    new_values = _simulate_child(h6, cache, tmp_path)
    assert new_values[0] == "stored"
    reference = _simulate_child(h6_traced, cache, tmp_path, SMIBJAX_EXPORTED="0")
    assert new_values[2] == reference[2] != second[2]
    _same_bits(tmp_path / "h6.npz", tmp_path / "h6t.npz")

    # a damaged stored program falls back silently, with the same result (in this
    # cache: the re-export and the traced fallback find their XLA programs there
    # instead of compiling them cold in a cache of their own, 14 CPU-s before)
    _damaged_stored_program_falls_back_silently(cache, tmp_path, out)

    changed = _simulate_child([*out, "r.npz", "--rtol", "1e-7"], cache, tmp_path)
    assert changed[0] == "exported"
    assert changed[2] != second[2]  # another solver run (more steps)
    assert len(list((cache / "smibjax-exported").glob("*.bin"))) == 2


def _damaged_stored_program_falls_back_silently(cache: Path, cwd: Path, out) -> None:
    """A stored file cut short is a miss (exported and stored again); one whose
    program JAX cannot read runs the traced path; both with the same result as the
    undamaged program's run (`cwd`/b.npz, `simulate` with `out`)."""
    (stored,) = (cache / "smibjax-exported").glob("*.bin")
    data = stored.read_bytes()
    stored.write_bytes(data[: len(data) // 2])
    assert _simulate_child([*out, "cut.npz"], cache, cwd)[0] == "exported"
    data = stored.read_bytes()
    mid = len(data) // 2  # inside the simulation's program
    stored.write_bytes(data[:mid] + bytes(64) + data[mid + 64 :])
    assert _simulate_child([*out, "bad.npz"], cache, cwd)[0] == "traced"
    _same_bits(cwd / "b.npz", cwd / "cut.npz")
    _same_bits(cwd / "b.npz", cwd / "bad.npz")


@pytest.mark.parametrize(
    "argv, needle",
    [
        (
            ["simulate", "--case", "no/such.raw", "--dyr", "x.dyr", "--fault-bus", "1"],
            "--case 'no/such.raw': no such file",
        ),
        (
            [
                "simulate",
                "--case",
                "README.md",
                "--dyr",
                "README.md",
                "--fault-bus",
                "1",
            ],
            "not a PSS/E raw file",
        ),
        (
            [
                "modes",
                "--case",
                "src/smibjax/grid/cases/kundur.raw",
                "--dyr",
                "README.md",
            ],
            "not a PSS/E dyr file",
        ),
        (
            [
                "cct",
                "--case",
                "src/smibjax/grid/cases/kundur.raw",
                "--dyr",
                "docs/figures",
            ],
            "must be a PSS/E dyr file (a file)",
        ),
        (["simulate", "--out", "run.txt"], "the suffix must be one of .npz"),
        (["simulate", "--case", "kundur", "--out", "r.xlsx"], "suffix must be one"),
        (["simulate", "--case", "kundur"], "a --case run needs an event"),
    ],
)
def test_bad_files_and_outputs_are_refused_before_jax_loads(argv, needle):
    """A nonexistent or foreign --case/--dyr file and an --out of no known format
    are one line, exit 2, before JAX, equinox or matplotlib load (they took 12-37 s
    of start-up before the refusal, issue 50)."""
    code = (
        "import sys\nfrom smibjax.cli import main\n"
        f"rc = main({argv!r})\nprint('RC:', rc)"
    )
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}:{ROOT}"}
    probe = code + (
        f"\nprint('LOADED:' + ','.join(m for m in {HEAVY!r} if m in sys.modules))"
    )
    r = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT, env=env
    )
    out = r.stdout.strip().splitlines()
    assert out[-2] == "RC: 2" and out[-1] == "LOADED:", r.stdout + r.stderr
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("smibjax: error: "), r.stderr
    assert needle in err[0]


def test_the_built_in_and_andes_case_files_pass_the_early_check():
    """The jax-free look at a raw/dyr file accepts every case file smibjax ships."""
    import argparse

    from smibjax.cli.grid import precheck_case

    cases = ROOT / "src" / "smibjax" / "grid" / "cases"
    raws = sorted(cases.glob("*.raw"))
    assert raws
    for raw in raws:
        for dyr in sorted(cases.glob("*.dyr")):
            precheck_case(argparse.Namespace(case=str(raw), dyr=str(dyr)))
    precheck_case(argparse.Namespace(case="kundur", dyr=None))  # a built-in name


ALARM = (
    b"E1203 13:50:02.123456  4242 slow_operation_alarm.cc:140] \n"
    b"********************************\n"
    b"[Compiling module jit_simulate_jit] Very slow compile? If you want to file a "
    b"bug, run with envvar XLA_FLAGS=--xla_dump_to=/tmp/foo and attach the results.\n"
    b"********************************\n"
)


def test_xlas_slow_compile_alarm_becomes_a_line_of_ours():
    from smibjax._commandline import explain_xla_alarm

    out = explain_xla_alarm(b"before\n" + ALARM + b"after\n").decode()
    assert "Very slow compile" not in out and "****" not in out
    assert "slow_operation_alarm" not in out
    lines = out.split("\n")
    assert lines[0] == "before" and lines[2:] == ["after", ""]  # in its place
    assert lines[1].startswith("smibjax: still compiling jit_simulate_jit (XLA notes")
    assert explain_xla_alarm(b"a progress bar\r") == b"a progress bar\r"  # untouched


def test_the_alarm_written_to_fd_2_by_anyone_is_replaced_and_the_rest_kept():
    """The alarm comes from XLA's C++ logging on file descriptor 2, not through
    sys.stderr: a process writes it there (and Python's own lines) inside the
    filter; what reaches the real stderr is ours, in order, and nothing is lost."""
    code = (
        "import os, sys\n"
        "from smibjax._commandline import xla_alarms_explained\n"
        "with xla_alarms_explained():\n"
        "    print('first', file=sys.stderr, flush=True)\n"
        f"    os.write(2, {ALARM!r})\n"
        "    sys.stderr.write('bar 50%\\r'); sys.stderr.flush()\n"
        "    print('last', file=sys.stderr, flush=True)\n"
        "print('after', file=sys.stderr, flush=True)\n"
    )
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}:{ROOT}"}
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, cwd=ROOT, env=env
    )
    assert r.returncode == 0, r.stderr
    err = r.stderr.decode()
    assert "Very slow compile" not in err
    assert err.split("\n") == [
        "first",
        "smibjax: still compiling jit_simulate_jit (XLA notes a slow compile: not an "
        "error; a large case's first compile takes minutes on a small CPU, then it is "
        "cached)",
        "bar 50%\rlast",
        "after",
        "",
    ]
