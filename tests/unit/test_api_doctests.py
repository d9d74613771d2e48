"""The examples of the library's API (``import mavreg``; docs/api.md) run as doctests.

One test per docstring, so a failure names its function and xdist spreads them. Run here, not
by ``--doctest-modules``: the examples then plan into this run's plan cache
(``tests/conftest.py``), and the default suite (``scripts/test.sh``, ``.ci/run``) needs no
option or path of its own for them.
"""
from __future__ import annotations

import doctest
import io

import pytest

import mavreg
import mavreg.api

MODULES = (mavreg, mavreg.api)
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _examples() -> list[doctest.DocTest]:
    finder = doctest.DocTestFinder(exclude_empty=True)
    return [t for module in MODULES for t in finder.find(module, module.__name__) if t.examples]


EXAMPLES = _examples()


def test_every_public_function_of_the_api_has_an_example():
    named = {t.name.rsplit(".", 1)[-1] for t in EXAMPLES}
    functions = set(mavreg.api.__all__)
    assert functions <= named, sorted(functions - named)
    assert functions <= set(mavreg.__all__)


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda t: t.name)
def test_example(example: doctest.DocTest):
    out = io.StringIO()
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    result = runner.run(example, out=out.write, clear_globs=True)
    assert result.attempted == len(example.examples)
    assert result.failed == 0, out.getvalue()
