"""A pytest plugin for `suite_time.py`: per test, its wall and process-CPU seconds,
the CPU seconds of the subprocesses it ran and waited for, and the JAX compilation
events it caused, written per process (the controller and each pytest-xdist worker)
to $SMIBJAX_SUITE_PROFILE/NAME.json at the end of the session.

Loaded with `-p _suite_profile` (this folder on PYTHONPATH); does nothing unless
SMIBJAX_SUITE_PROFILE names a folder. The events are JAX's own
(`jax.monitoring`): tracing to a jaxpr, lowering to MLIR, XLA's backend compile, and
the persistent cache's retrievals, each with the jitted function's name; and the
persistent cache's misses (JAX's compiler log, debug level), each with its cache key,
so that `suite_time.py` can count the programs that two processes compiled alike.
"""

from __future__ import annotations

import json
import logging
import os
import resource
import time
from collections import defaultdict

import pytest

ENV = "SMIBJAX_SUITE_PROFILE"
# jax.monitoring event name -> short name
EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "compile",
    "/jax/compilation_cache/cache_retrieval_time_sec": "cache_read",
}


class _Profile:
    def __init__(self):
        # [nodeid, start epoch s, wall s, cpu s, {event: [n, s]}, children's cpu s,
        #  {program: [n, s]} of its XLA compiles, [cache keys it missed]]
        self.tests = []
        self.misses = []  # the persistent-cache keys the current test missed
        self.misses_outside = []
        self.test_programs = defaultdict(lambda: [0, 0.0])
        self.outside = defaultdict(lambda: [0, 0.0])  # collection, between tests
        self.current = self.outside  # where events go now
        self.programs = defaultdict(lambda: [0, 0.0])  # compile: fun_name -> [n, s]

    def listen(self, event, duration, **kw):
        short = EVENTS.get(event)
        if short is None:
            return
        slot = self.current[short]
        slot[0] += 1
        slot[1] += float(duration)
        if short == "compile":
            name = str(kw.get("fun_name", "?"))
            for table in (self.programs, self.test_programs):
                table[name][0] += 1
                table[name][1] += float(duration)


_profile = _Profile()

COMPILER_LOG = "jax._src.compiler"
MISS = "PERSISTENT COMPILATION CACHE MISS"


class _MissLog(logging.Handler):
    """Keeps the cache key of each persistent-cache miss (JAX logs it at debug
    level: "PERSISTENT COMPILATION CACHE MISS for NAME with key KEY")."""

    def emit(self, record):
        if str(record.msg).startswith(MISS) and len(record.args or ()) == 2:
            _profile.misses.append(str(record.args[1]))


def pytest_configure(config):
    if not os.environ.get(ENV):
        return
    import jax.monitoring

    jax.monitoring.register_event_duration_secs_listener(_profile.listen)
    log = logging.getLogger(COMPILER_LOG)
    log.addHandler(_MissLog())
    if not log.isEnabledFor(logging.DEBUG):
        log.setLevel(logging.DEBUG)  # its records reach no other handler below WARNING
    _profile.misses = _profile.misses_outside
    config._suite_profile = True


def _children_cpu() -> float:
    """User + system CPU seconds of this process's ended, waited-for child
    processes (a test's subprocesses)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if not getattr(item.config, "_suite_profile", False):
        yield
        return
    _profile.current = defaultdict(lambda: [0, 0.0])
    _profile.test_programs = defaultdict(lambda: [0, 0.0])
    _profile.misses = []
    t0, c0, k0 = time.time(), time.process_time(), _children_cpu()
    yield
    wall, cpu = time.time() - t0, time.process_time() - c0
    kids = _children_cpu() - k0
    progs = dict(_profile.test_programs)
    _profile.tests.append(
        [item.nodeid, t0, wall, cpu, dict(_profile.current), kids, progs]
        + [_profile.misses]
    )
    _profile.current = _profile.outside
    _profile.misses = _profile.misses_outside


def pytest_unconfigure(config):
    folder = os.environ.get(ENV)
    if not folder or not getattr(config, "_suite_profile", False):
        return
    from smibjax._files import write_text

    name = os.environ.get("PYTEST_XDIST_WORKER", "controller")
    payload = {
        "process": name,
        "cpu_s": time.process_time(),
        "tests": _profile.tests,
        "programs": dict(_profile.programs),
        "outside_tests": dict(_profile.outside),
        "misses_outside_tests": _profile.misses_outside,
    }
    write_text(os.path.join(folder, f"{name}.json"), json.dumps(payload))
