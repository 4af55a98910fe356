"""Every groupoid the library builds (``symgroupoid.groupoids.examples()``) and the decorator
that runs a property test on each: ``@every_groupoid()`` parametrises the test's first
argument ``G`` with one groupoid of each kind, ``@every_groupoid(where=...)`` with those the
predicate accepts (a property that holds only for some families)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Collection

import pytest

import symgroupoid as sg
from symgroupoid.groupoids import examples

EXAMPLES: dict[str, Callable[[], sg.Groupoid]] = examples()


@functools.cache
def groupoid(name: str) -> sg.Groupoid:
    """The registry's groupoid ``name``, built once per test process."""
    return EXAMPLES[name]()


def every_groupoid(where: Callable[[sg.Groupoid], bool] | None = None,
                   slow: Collection[str] = (), exclude: Collection[str] = ()):
    """Parametrise a test over every registered groupoid (those ``where`` accepts and
    ``exclude`` does not name), passed as the argument ``G`` and named in the test id; the
    groupoids named in ``slow`` run with the slow tests only (where the property is costly
    on them).  ``exclude`` names groupoids a property does not apply to where deciding it
    is costly (the predicate runs when the tests are collected, in every test process)."""
    unknown = (set(slow) | set(exclude)) - set(EXAMPLES)
    if unknown:
        raise ValueError(f"every_groupoid: no registered groupoid {sorted(unknown)}")
    names = [n for n in sorted(EXAMPLES)
             if n not in exclude and (where is None or where(groupoid(n)))]
    if not names:
        raise ValueError("every_groupoid: the predicate accepts no registered groupoid")
    return pytest.mark.parametrize("G", [
        pytest.param(groupoid(n), id=n, marks=[pytest.mark.slow] if n in slow else [])
        for n in names])
