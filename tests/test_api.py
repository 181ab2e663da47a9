"""The public API (issue 31): `smibjax/__init__.py` names every public object once
(its `TYPE_CHECKING` block of `X as X` re-exports), each resolves to the object its
private module defines, importing smibjax loads neither JAX nor equinox, and the
controller interface answers what the core used to ask with isinstance."""

import ast
import subprocess
import sys

import pytest

import smibjax as sj
from helpers import ROOT

SRC = ROOT / "src" / "smibjax"


def test_import_loads_neither_jax_nor_equinox():
    code = (
        "import sys, smibjax as sj; "
        "print('jax' in sys.modules, 'equinox' in sys.modules, len(sj.__all__))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONPATH": str(ROOT / "src"), "PATH": ""},
    ).stdout.split()
    assert out[:2] == ["False", "False"] and int(out[2]) == len(sj.__all__)


def test_every_public_name_resolves_to_its_defining_module():
    tree = ast.parse((SRC / "__init__.py").read_text(encoding="utf-8"))
    block = next(n for n in tree.body if isinstance(n, ast.If))
    pairs = [(a.asname, n.module) for n in block.body for a in n.names]
    assert all(a is not None for a, _ in pairs)  # every import is `X as X`
    assert sorted(a for a, _ in pairs) == sj.__all__
    for name, module in pairs:
        obj = getattr(sj, name)
        mod = sys.modules[f"smibjax.{module}"]
        assert getattr(mod, name) is obj, name
    # the paper's internals are not top-level names; the law's subpackage has them
    for name in ("spow", "paper_coordinates", "control_law", "drift_and_gain"):
        assert name not in sj.__all__
        with pytest.raises(AttributeError):
            getattr(sj, name)
    assert sj.controllers.synergetic.spow(-8.0, 1.0) == -8.0
    # no public module shares a name with a public function any more
    public_modules = {p.stem for p in SRC.glob("*.py") if not p.stem.startswith("_")}
    assert public_modules == set() and not (SRC / "controller.py").exists()


def test_the_interface_answers_what_the_core_asks():
    """The paper's law and the others differ only through the interface."""
    g = sj.Gains.paper("asc", beta1=-1.0, beta2=-1.0)
    syn = sj.make_controller("asc", {"beta1": -1.0, "beta2": -1.0})
    avr, none = sj.AvrPss(), sj.NoControl()
    assert syn.has_adaptation and not avr.has_adaptation and not none.has_adaptation
    assert syn.option_names == ("projection", "phi_layer") and avr.option_names == ()
    assert syn.with_adaptation("realizable").oracle is False
    assert avr.with_adaptation("realizable") is avr
    assert float(syn.specialized().gains.alpha) == 1.0
    assert syn.specialized().gains.alpha == 1.0 and isinstance(
        syn.specialized().gains.alpha, float
    )  # compiled in as the Python number
    assert type(sj.Synergetic.parameter_set("asc", {})) is sj.Gains
    assert float(sj.Synergetic.parameter_set("asc", {}).alpha) == 1.0
    assert sj.controllers.parameter_set("avr-pss", {"K_A": 50.0}).K_A == 50.0
    with pytest.raises(sj.ParameterError, match="'x' is not a parameter"):
        sj.controllers.parameter_set("aftsc", {"x": 1.0})
    assert sj.Synergetic.options_for_file(
        "aftsc", {"alpha": 1.0}, {"projection": [], "phi_layer": 0}
    ) == ("asc", {"projection": [], "phi_layer": 0.0})
    assert sj.AvrPss.options_for_file("avr-pss", {}, {"phi_layer": 1}) == (
        "avr-pss",
        {},
    )
    with pytest.raises(sj.ParameterError, match="it has no options"):
        sj.NoControl.check_options("none", {"phi_layer": 0.1})
    assert sj.Synergetic.check_options("aftsc", {"phi_layer": 1}) == {"phi_layer": 1.0}
    assert sj.controllers.describe(g) == "ASC: beta = (-1, -1), alpha = 1"
    assert sj.controllers.describe(none) == "no control"


def test_option_objects_are_validated_and_hashable():
    a = sj.SolverOptions(rtol=1e-7)
    assert hash(a) == hash(sj.SolverOptions(rtol=1e-7)) and a.max_steps == 50_000
    assert sj.SaveOptions().t_end == 10.0 and sj.SaveOptions().dt_save == 0.01
    with pytest.raises(sj.ParameterError, match="method = 'rk4' is not allowed"):
        sj.SolverOptions(method="rk4")
    with pytest.raises(sj.ParameterError, match="max_steps = 0 is not allowed"):
        sj.SolverOptions(max_steps=0)
    with pytest.raises(sj.ParameterError, match="dt_save = 2 is not allowed"):
        sj.SaveOptions(t_end=1.0, dt_save=2.0)


def test_the_old_simulate_keywords_are_a_deprecated_shim_with_the_same_run():
    g = sj.Gains.paper("aftsc", **{"beta1": -1.0, "beta2": -1.0})
    new = sj.simulate(
        g, solver=sj.SolverOptions(rtol=1e-6), save=sj.SaveOptions(t_end=1.0)
    )
    with pytest.warns(DeprecationWarning, match="SolverOptions"):
        old = sj.simulate(g, t_end=1.0, rtol=1e-6)
    assert old.delta.shape == new.delta.shape == (101,)
    assert (old.delta == new.delta).all() and int(old.num_steps) == int(new.num_steps)
    with pytest.raises(TypeError, match="unexpected keyword argument 'tend'"):
        sj.simulate(g, tend=1.0)


def test_the_grid_face_resolves_each_name_and_loads_lazily():
    """`smibjax.grid`'s curated names (issue 44): each is its module's object, and
    importing the face loads no JAX."""
    import smibjax.grid as sg

    tree = ast.parse((SRC / "grid" / "__init__.py").read_text(encoding="utf-8"))
    block = next(n for n in tree.body if isinstance(n, ast.If))
    pairs = [(a.asname, n.module) for n in block.body for a in n.names]
    assert sorted(a for a, _ in pairs) == sg.__all__
    for name in ("load_case", "simulate_case", "BusFault", "ParamError"):
        assert name in sg.__all__
    for name, module in pairs:
        assert getattr(sg, name) is getattr(sys.modules[f"smibjax.grid.{module}"], name)
    assert issubclass(sg.PsseError, sj.ParameterError)
    with pytest.raises(AttributeError):
        sg.no_such_name  # noqa: B018
    code = (
        "import sys, smibjax.grid as sg; print('jax' in sys.modules, len(sg.__all__))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONPATH": str(ROOT / "src"), "PATH": ""},
    ).stdout.split()
    assert out == ["False", str(len(sg.__all__))]
