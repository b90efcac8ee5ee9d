"""Tests: ``tests/unit/`` (no ROS nodes, no DDS), ``tests/system/`` (real processes
over Fast DDS, marker ``ros``; fixtures in ``tests/system/conftest.py``) and
``tests/helpers/`` (importable as ``helpers``: ``pythonpath = ["tests"]`` in
pyproject.toml).

``pytest -n 3 --dist loadgroup`` (pytest-xdist; the README's test command) runs three
tests at a time, except the tests marked ``alone``: one worker runs them one after the
other with no other test beside them (:mod:`helpers.machine_share`)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from helpers.machine_share import machine_share, release_kept

#: Whether the test after this one (on this worker) is ``alone`` too.
NEXT_ALONE = pytest.StashKey[bool]()


def _alone(item: pytest.Item | None) -> bool:
    return item is not None and item.get_closest_marker("alone") is not None


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The ``alone`` tests go to one worker (``--dist loadgroup``), in one row."""
    for item in items:
        if _alone(item):
            item.add_marker(pytest.mark.xdist_group("alone"))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    item.stash[NEXT_ALONE] = _alone(nextitem)
    return (yield)


@pytest.fixture(autouse=True)
def _machine_share(request: pytest.FixtureRequest) -> Iterator[None]:
    """First of every test's fixtures, last to end: the test's share of the machine."""
    node = request.node
    with machine_share(_alone(node), keep=node.stash.get(NEXT_ALONE, False)):
        yield


def pytest_sessionfinish() -> None:
    release_kept()
