"""The mutation list stays runnable: every mutant of `tests/mutations.py` applies to
today's code, and the tests it names exist.

A mutant whose old text no longer occurs is reported "stale" by the script and guards
nothing; five had drifted that way (reformatted or rewritten lines) before this test.
"""

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import mutations  # noqa: E402


@pytest.mark.parametrize("m", mutations.MUTANTS, ids=lambda m: m.name)
def test_each_mutant_applies_once_and_names_existing_tests(m):
    text = (ROOT / m.file).read_text()
    assert text.count(m.old) == 1, f"{m.name}: old text found {text.count(m.old)}x"
    assert m.new != m.old
    assert m.select
    for node in m.select:
        path, _, rest = node.partition("::")
        assert (ROOT / path).is_file(), node
        if rest:
            name = re.sub(r"\[.*\]$", "", rest.split("::")[-1])
            assert re.search(rf"def {name}\(", (ROOT / path).read_text()), node


def test_mutant_names_are_unique():
    names = [m.name for m in mutations.MUTANTS]
    assert len(names) == len(set(names))
