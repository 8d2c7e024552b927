"""Shared fixtures.  The render cache of the test session is a temporary directory unless
PBRBENCH_TEST_CACHE names a persistent one (CI keeps it per clone)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Choose the Mitsuba variant before anything imports drjit (docs/rendering.md).
from pbrbench.render.variant import choose_variant  # noqa: E402

choose_variant()


@pytest.fixture(scope="session")
def cache_dir(tmp_path_factory) -> Path:
    env = os.environ.get("PBRBENCH_TEST_CACHE")
    if env:
        p = Path(env)
        p.mkdir(parents=True, exist_ok=True)
        return p
    return tmp_path_factory.mktemp("render-cache")


@pytest.fixture(scope="session")
def python_exe() -> str:
    return sys.executable
