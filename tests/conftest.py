"""Tests: ``tests/unit/`` (no processes, no DDS), ``tests/system/`` (real processes
over Fast DDS, marker ``ros``; fixtures in ``tests/system/conftest.py``) and
``tests/helpers/`` (importable as ``helpers``: ``pythonpath = ["tests"]`` in
pyproject.toml)."""
