"""Tests: ``tests/unit/`` (no processes, no DDS), ``tests/system/`` (real processes
over Fast DDS, marker ``ros``; fixtures in ``tests/system/conftest.py``) and
``tests/helpers/`` (importable as ``helpers``: ``pythonpath = ["tests"]`` in
pyproject.toml).

``pytest -n 2`` (pytest-xdist; the README's test command) runs two tests at a time,
except a test marked ``alone``, which runs with no other beside it
(:mod:`helpers.machine_share`)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from helpers.machine_share import machine_share


@pytest.fixture(autouse=True)
def _machine_share(request: pytest.FixtureRequest) -> Iterator[None]:
    """First of every test's fixtures, last to end: the test's share of the machine."""
    with machine_share(alone=request.node.get_closest_marker("alone") is not None):
        yield
