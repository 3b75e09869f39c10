"""Shared fixtures of the agents tests: one torch thread (the machine has two shared cores)."""

from __future__ import annotations

import pytest

from agents.policies.sb3 import limit_torch_threads


@pytest.fixture(autouse=True, scope="session")
def _one_torch_thread() -> None:
    limit_torch_threads(1)
