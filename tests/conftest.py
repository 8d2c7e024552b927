"""Shared fixtures.  The render cache of the test session is a temporary directory unless
PBRBENCH_TEST_CACHE names a persistent one (CI keeps it per clone).

A skip whose reason is not on tests/allowed_skips.txt (what the platform cannot provide) fails
the run: the hooks at the end of this file."""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ALLOWED_SKIPS = Path(__file__).resolve().parent / "allowed_skips.txt"

# The suite writes its bytecode caches (__pycache__, ignored by git) even where the environment
# sets PYTHONDONTWRITEBYTECODE, for `make test` and a bare `pytest` alike: otherwise every run
# compiles pbrbench again and pytest rewrites the asserts of every test module again (7 of the
# fast loop's 13 s of collection, in each worker), and the suite's child interpreters compile
# pbrbench again.  Set here, before the test modules are imported; the children inherit the
# environment.
sys.dont_write_bytecode = False
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)

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
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):   # one cache for all the workers of this run
        root = root.parent
    p = root / "render-cache"
    p.mkdir(parents=True, exist_ok=True)
    return p


@pytest.fixture(scope="session")
def python_exe() -> str:
    return sys.executable


# ----------------------------------------------------------------------------- scheduling
def pytest_collection_modifyitems(config, items):
    """The tests marked ``longest`` (a minute or more, or tens of seconds) first, each followed by
    one ordinary test: pytest-xdist (``-n``, pyproject.toml's addopts, ``--maxschedchunk 1``) hands
    each worker two tests to start with, so the longest tests start at once on different workers
    and the rest fill in around them.  Without xdist only the order changes."""
    longest = [it for it in items if it.get_closest_marker("longest")]
    if not longest:
        return
    rest = [it for it in items if not it.get_closest_marker("longest")]
    front = []
    for it in longest:
        front.append(it)
        if rest:
            front.append(rest.pop(0))
    items[:] = front + rest


# ----------------------------------------------------------------------------- allowed skips
def allowed_skip_patterns(path: Path = ALLOWED_SKIPS) -> list[tuple[re.Pattern, str]]:
    """(pattern, why) of every line of the allowed list: ``REGEX # why``; blank lines and lines
    starting with ``#`` are comments.  A line without its why is an error."""
    out = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        pattern, sep, why = line.partition(" # ")
        if not sep or not why.strip() or not pattern.strip():
            raise ValueError(f"{path}:{n}: write 'REGEX # why the platform may lack it', not {line!r}")
        out.append((re.compile(pattern.strip()), why.strip()))
    return out


def skip_reason(report) -> str:
    """The reason of a skipped test's report (without pytest's ``Skipped: ``)."""
    lr = report.longrepr
    text = lr[2] if isinstance(lr, tuple) and len(lr) == 3 else str(lr)
    return text.removeprefix("Skipped: ")


def unexpected_skips(skips: list[tuple[str, str]], patterns) -> list[tuple[str, str]]:
    """The (test id, reason) of ``skips`` whose reason no pattern matches."""
    return [(nodeid, reason) for nodeid, reason in skips if not any(p.search(reason) for p, _ in patterns)]


_SKIPS: list[tuple[str, str]] = []


def pytest_runtest_logreport(report):
    if report.skipped and not hasattr(report, "wasxfail"):
        _SKIPS.append((report.nodeid, skip_reason(report)))


def pytest_collectreport(report):   # a module skipped as a whole (importorskip at its top)
    if report.skipped:
        _SKIPS.append((report.nodeid, skip_reason(report)))


def _unexpected() -> list[tuple[str, str]]:
    return unexpected_skips(_SKIPS, allowed_skip_patterns(ALLOWED_SKIPS))


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session, exitstatus):
    if _unexpected() and exitstatus in (pytest.ExitCode.OK, pytest.ExitCode.NO_TESTS_COLLECTED):
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter):
    bad = _unexpected()
    if bad:
        terminalreporter.write_sep("=", f"{len(bad)} skip(s) not on tests/allowed_skips.txt: the run fails", red=True)
        for nodeid, reason in bad:
            terminalreporter.write_line(f"{nodeid}: {reason}")
        terminalreporter.write_line("install what the test needs in the set-up (scripts/setup.sh, requirements.lock) or "
                                    "build it in a fixture; list only what the platform cannot provide")
