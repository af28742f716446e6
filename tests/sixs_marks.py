"""Decorator for tests that run 6S: ``@pytest.mark.sixs`` plus a skip that names what is missing."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from s2cl.atmos.sixs import sixs_executable
from s2cl.errors import DependencyError


def _missing() -> str | None:
    try:
        sixs_executable()
    except DependencyError as err:
        return str(err)
    return None


SIXS_MISSING = _missing()


def sixs_test(func: Callable) -> Callable:
    """Mark ``func`` as needing 6S and skip it, with the install hint, when 6S is absent."""
    skip = pytest.mark.skipif(SIXS_MISSING is not None, reason=f"6S is not available: {SIXS_MISSING}")
    return pytest.mark.sixs(skip(func))
