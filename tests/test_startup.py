"""Start-up of the entry points (issue 32): `--help` answers without JAX, every
entry point configures the process before equinox or JAX load, and a second
identical `simulate` or tuning run finds its programs in the persistent compilation
cache (nothing new written to it, no "Not writing persistent cache entry" but for
the programs too quick to keep)."""

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


def _run_logged(argv, cache: Path, cwd: Path) -> str:
    env = {
        **os.environ,
        "PYTHONPATH": f"{ROOT / 'src'}:{ROOT}",
        "SMIBJAX_CACHE_DIR": str(cache),
        "JAX_LOGGING_LEVEL": "DEBUG",
    }
    env.pop("EQX_ON_ERROR", None)
    r = subprocess.run(
        [sys.executable, "-m", *argv],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    return r.stderr


def _refused(log: str) -> list[str]:
    """The log lines of programs the cache refused or missed for another reason
    than a compile too quick to keep."""
    return [
        line
        for line in log.splitlines()
        if "Not writing persistent cache entry" in line and "took <" not in line
    ]


@pytest.mark.parametrize(
    "argv",
    [
        ["smibjax", "simulate", "--t-end", "3", "--out", "run.npz", "--force"],
        [
            "tuning.optimize",
            "--config",
            "tiny.toml",
            "--out",
            "tune",
        ],
    ],
    ids=["simulate", "tuner"],
)
def test_a_second_identical_run_hits_the_persistent_cache(tmp_path, argv):
    """Issue 32: the tuner's programs carried host callbacks (equinox loaded before
    the process was configured) and were never cached. A second identical run now
    writes nothing new to the cache and loads its compiled programs from it."""
    (tmp_path / "tiny.toml").write_text(
        "steps = 1\nbatch = 2\n[validation]\nn = 2\nevery = 1\nt_end = 3.0\n"
        "[train]\nt_end = 3.0\n"
    )
    cache = tmp_path / "cache"
    first = _run_logged(argv, cache, tmp_path)
    assert _refused(first) == []
    assert any(e.startswith("jit__simulate-") for e in os.listdir(cache))
    if argv[0] == "tuning.optimize":
        import shutil

        shutil.rmtree(tmp_path / "tune")
    second = _run_logged(argv, cache, tmp_path)
    assert _refused(second) == []
    # the programs that take seconds to compile come from the cache (on a loaded
    # machine a few tiny ones may newly pass the 0.5 s threshold and be written)
    programs = ["jit__simulate"]
    if argv[0] == "tuning.optimize":
        programs += ["jit_run", "jit_reduce"]
    log = second.lower()
    for p in programs:
        assert f"compilation cache hit for '{p}'" in log, p
        assert f"compilation cache miss for '{p}'" not in log, p
    assert "compiling " in first and "(cache: cold)" in first
    assert "compiling " in second and "(cache: warm)" in second


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
