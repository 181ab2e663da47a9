import math

import jax
import jax.numpy as jnp
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import smibjax as sj
from smibjax._parameters import PLANT_NAMES
from smibjax.controllers.synergetic import GAIN_NAMES


def test_paper_defaults():
    g = sj.Gains()
    assert float(g.beta1) == 50 and float(g.T1) == 0.005 and float(g.T2) == 1
    assert float(g.alpha) == pytest.approx(5 / 7)
    assert float(sj.Gains.paper("asc").alpha) == 1.0
    p = sj.Plant()
    assert float(p.M) == pytest.approx(10 / (2 * jnp.pi * 60))
    assert float(p.X1) == pytest.approx(0.3)
    assert float(p.uf_max) == jnp.inf
    r = sj.Plant.preset("realistic")
    assert (float(r.uf_min), float(r.uf_max), float(r.ur_min), float(r.ur_max)) == (
        -5,
        5,
        -1,
        1,
    )
    assert float(sj.Gains().realizable().k1) == 0.0
    assert "alpha" in GAIN_NAMES and "uf_min" in PLANT_NAMES


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: sj.Gains(alpha=1.5), r"Gains.alpha = 1.5 .* \(1/2, 1\]"),
        (lambda: sj.Gains(alpha=0.5), r"Gains.alpha = 0.5"),
        (lambda: sj.Gains(T1=-1.0), r"Gains.T1 = -1 .*> 0"),
        (lambda: sj.Gains(beta2=0.0), r"Gains.beta2 = 0 .*non-zero"),
        (lambda: sj.Gains(k1=-0.1), r"Gains.k1 = -0.1 .*>= 0"),
        (
            lambda: sj.Fault(t_fault=0.5, t_clear=0.4),
            r"t_clear = 0.4 .*> t_fault = 0.5",
        ),
        (lambda: sj.Fault(t_reclose=0.6), r"t_reclose = 0.6 .*>= t_clear = 0.7"),
        (lambda: sj.Fault(lam=1.0), r"Fault.lam = 1 .*\(0, 1\)"),
        (lambda: sj.Fault(Xf=-0.01), r"Fault.Xf = -0.01"),
        (lambda: sj.Plant(T0=-4.0), r"Plant.T0 = -4 .*> 0"),
        (lambda: sj.Plant(Xd=0.1), r"Plant.Xd = 0.1 .*> Xdp"),
        (lambda: sj.Plant(uf_min=2.0, uf_max=1.0), r"uf_min = 2"),
        (lambda: sj.Plant.preset("bogus"), r"preset = 'bogus'"),
        (lambda: sj.OperatingPoint(delta_e=2.0), r"delta_e = 2"),
    ],
)
def test_bad_values_raise_one_line(build, match):
    with pytest.raises(sj.ParameterError, match=match) as info:
        build()
    assert "\n" not in str(info.value)


def test_batched_values_are_validated_elementwise():
    sj.Gains(alpha=jnp.array([0.6, 1.0]))
    with pytest.raises(sj.ParameterError, match="alpha"):
        sj.Gains(alpha=jnp.array([0.6, 1.2]))


def test_validation_is_skipped_under_tracing():
    # inside jit the values are tracers; construction must not fail or recompile checks
    out = jax.jit(lambda a: sj.Gains(alpha=a).alpha * 2)(0.75)
    assert float(out) == 1.5


def test_validation_compiles_nothing():
    # Validation is NumPy work: an eager jax.numpy comparison compiles a kernel on its
    # first use in a process (~17 ms each, ~0.25 s before the first simulation). A
    # fresh process, so that nothing is compiled already.
    import subprocess
    import sys

    code = (
        "import logging, jax, smibjax as sj\n"
        "jax.config.update('jax_log_compiles', True)\n"
        "sj.Gains.paper('aftsc', beta1=-1.0, beta2=-1.0); sj.Plant.preset('realistic')\n"
        "sj.Fault(t_clear=0.8); sj.OperatingPoint(); sj.InitialEstimates()\n"
        "try:\n    sj.Fault(t_clear=0.4)\nexcept sj.ParameterError:\n    pass\n"
        "import sys; print('PROBE', file=sys.stderr, flush=True)\n"
        "jax.numpy.asarray(2.0) > 1.0  # one eager comparison: the log works\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]
    before, after = (
        [
            line.split("Compiling ")[1].split(" ")[0]
            for line in part.splitlines()
            if "Compiling " in line
        ]
        for part in p.stderr.split("PROBE")
    )
    # building the sets: the conversions of the fields to float arrays only
    assert set(before) <= {"jit(convert_element_type)"}, before
    assert "jit(greater)" in after, after


# Issue 16, class 1: no parameter passes validation with a value the model cannot use.
_OP_NAMES = ("delta_e", "Pm_ref")
_INIT_NAMES = ("th1", "th2")
_LIMITS = ("uf_min", "uf_max", "ur_min", "ur_max")
_ALL_NAMES = (*GAIN_NAMES, *PLANT_NAMES, *_OP_NAMES, *_INIT_NAMES)
_BOUNDED = tuple(
    n for n in (*PLANT_NAMES, *_OP_NAMES, *_INIT_NAMES) if n not in _LIMITS
)


def _build(name, value):
    """The parameter sets with one value changed, as the CLI builds them (--set)."""
    from smibjax.cli.options import build_parameters

    return build_parameters("aftsc", "paper", None, {name: value})


@settings(max_examples=300, deadline=None)
@given(
    name=st.sampled_from(_ALL_NAMES),
    value=st.sampled_from([math.nan, math.inf, -math.inf]),
)
def test_no_parameter_accepts_nan_or_inf(name, value):
    if name in _LIMITS and not math.isnan(value):
        # an infinite limit is "no limit"; the other end must stay above/below it
        low = name.endswith("_min")
        if (value < 0) == low:
            _build(name, value)  # -inf lower / +inf upper limit: accepted
            return
    # (a limit may be reported through the other end: "uf_min = -inf ... < uf_max")
    who = rf"{name[:2]}_(min|max)" if name in _LIMITS else name
    with pytest.raises(sj.ParameterError, match=rf"\.{who} = ") as info:
        _build(name, value)
    assert "\n" not in str(info.value)


@settings(max_examples=300, deadline=None)
@given(
    name=st.sampled_from(_BOUNDED),
    value=st.floats(min_value=1.0000001e6, max_value=1e308),
    sign=st.sampled_from([1.0, -1.0]),
)
def test_plant_operating_point_and_estimates_refuse_huge_values(name, value, sign):
    with pytest.raises(sj.ParameterError, match=rf"\.{name} = .* is not allowed"):
        _build(name, sign * value)


@pytest.mark.parametrize("name", ["th1", "th2", "H", "Pm", "Pm_ref", "D", "Xd"])
def test_the_magnitude_bound_is_inclusive_and_stated(name):
    _build(name, 1e6)  # |value| <= 1e6: accepted
    with pytest.raises(sj.ParameterError, match=r"finite with \|value\| <= 1e\+06"):
        _build(name, 1.5e6)


@settings(max_examples=100, deadline=None)
@given(
    name=st.sampled_from(sj.FAULT_NAMES),
    value=st.sampled_from([math.nan, math.inf, -math.inf]),
)
def test_fault_times_and_location_must_be_finite(name, value):
    with pytest.raises(sj.ParameterError, match=rf"Fault\.{name} = "):
        sj.Fault(**{name: value})


@settings(max_examples=100, deadline=None)
@given(
    name=st.sampled_from(GAIN_NAMES),
    value=st.sampled_from([math.nan, math.inf, -math.inf]),
)
def test_gains_file_with_non_finite_values_is_refused(tmp_path_factory, name, value):
    from smibjax.cli.options import build_parameters

    path = tmp_path_factory.mktemp("g") / "g.toml"
    path.write_text(f"{name} = {'nan' if math.isnan(value) else value}\n")
    with pytest.raises(sj.ParameterError, match=rf"Gains\.{name} = "):
        build_parameters("aftsc", "paper", str(path), {})
