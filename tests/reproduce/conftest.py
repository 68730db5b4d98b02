"""One reproduction context per test session: the virtual test-stand campaigns are the
expensive part and are shared by many claims."""

from __future__ import annotations

import pytest

from flowtwin.reproduce import ReproContext


@pytest.fixture(scope="session")
def repro_ctx() -> ReproContext:
    """The context of the default run (seed 2021), cached across the session."""
    return ReproContext(seed=2021)
