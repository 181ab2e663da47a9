"""The test suite's own set-up: what the suite's runtime depends on."""

from __future__ import annotations

import os

import pytest

pytestmark = pytest.mark.xdist_group("suite_setup")


def test_xdist_groups_take_effect(request):
    """Under `--dist loadgroup` (pyproject's addopts) every test marked with an
    xdist_group runs with "@group" appended to its node id: that is how xdist keeps
    a group on one worker (its session fixtures and compiled programs made once).
    pytest 9.2 silently stopped the suffix (pytest-dev/pytest-xdist#1386) and with it
    the grouping; this fails where that happens again."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        pytest.skip("not under xdist")
    # a worker's own config says dist "no": read the run's addopts and command line
    argv = " ".join(request.config.workerinput.get("mainargv", []))
    addopts = " ".join(request.config.getini("addopts"))
    if "--dist" in argv or "loadgroup" not in addopts:
        pytest.skip("not --dist loadgroup")
    assert request.node.nodeid.endswith("@suite_setup"), request.node.nodeid
