"""The command line answers at once: ``pbrbench --help``, ``pbrbench scenes`` and usage errors
import neither the renderer (mitsuba, drjit) nor what only other subcommands need (the
optimisers of the inference package, the plots and templates of the report).

Each command runs in a fresh interpreter, as ``python -m pbrbench`` does, and the modules loaded
by the time it exits are checked.  A subcommand whose options need heavy imports fills its parser
only when it is used (``fill`` of :class:`pbrbench.cli.main.Parser`).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from pbrbench.cli.main import main

# runs the command as `python -m pbrbench ARGS` and writes its exit code and sys.modules to a file
PROBE = """
import json, runpy, sys
out, argv = sys.argv[1], json.loads(sys.argv[2])
sys.argv = ["pbrbench", *argv]
try:
    runpy.run_module("pbrbench", run_name="__main__")
    code = 0
except SystemExit as exc:
    code = exc.code
with open(out, "w") as f:
    json.dump({"code": code, "modules": sorted(sys.modules)}, f)
"""

NEVER = ("mitsuba", "drjit", "scipy.optimize", "matplotlib", "jinja2")
# what a command that parses nothing but its arguments has no use for either
NOT_FOR_ARGUMENTS = ("pbrbench.infer", "pbrbench.render.proofs", "pbrbench.scene", "pbrbench.bench",
                     "pbrbench.report", "pydantic")


def run_cli(argv: list[str], tmp_path) -> tuple[int, set[str]]:
    out = tmp_path / "probe.json"
    proc = subprocess.run([sys.executable, "-c", PROBE, str(out), json.dumps(argv)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert out.is_file(), f"pbrbench {' '.join(argv)} did not finish: {proc.stderr[-2000:]}"
    res = json.loads(out.read_text())
    return res["code"], set(res["modules"])


def loaded(modules: set[str], names) -> list[str]:
    return sorted(m for m in modules if any(m == n or m.startswith(n + ".") for n in names))


def case(argv, code, arguments_only, **kw):
    """argv, its exit code, and whether the command only parses its arguments."""
    return pytest.param(argv, code, arguments_only, id=" ".join(argv) or "(no command)", **kw)


COMMANDS = [
    case(["--help"], 0, True),
    case([], 1, True),
    case(["--version"], 0, True),
    case(["nosuchcommand"], 1, True),
    case(["run", "--quality", "nope"], 1, True),
    case(["run", "--help"], 0, True),
    case(["render", "--help"], 0, True),
    case(["infer", "--help"], 0, True),
    case(["infer", "nosuch"], 1, True),
    case(["scenes", "--help"], 0, True),
    case(["scenes"], 0, False),
    case(["scenes", "--expand"], 0, False),
    case(["validate", "--quality", "nope"], 1, False),   # its --checks help lists the checks
    case(["infer", "hdr", "--method", "nope"], 1, False),   # the methods tables import pbrbench.infer, not its optimisers
]


@pytest.mark.parametrize("argv, code, arguments_only", COMMANDS)
def test_command_imports_nothing_it_does_not_need(argv, code, arguments_only, tmp_path):
    got, modules = run_cli(argv, tmp_path)
    assert got == code
    assert not loaded(modules, NEVER), f"pbrbench {' '.join(argv)} imported {loaded(modules, NEVER)[:5]}"
    if arguments_only:
        assert not loaded(modules, NOT_FOR_ARGUMENTS), \
            f"pbrbench {' '.join(argv)} imported {loaded(modules, NOT_FOR_ARGUMENTS)[:5]}"


@pytest.mark.parametrize("problem", ["photometric-stereo", "photometric_stereo", "retinex", "lightness", "hdr"])
def test_every_infer_problem_help_prints(problem, capsys):
    # the infer parsers are filled when used: each problem's options (and choices) are there
    assert main(["infer", problem, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: pbrbench infer") and "--out OUT" in out and "--method" in out


def test_a_bad_choice_of_a_filled_parser_is_a_usage_error(capsys):
    assert main(["infer", "photometric-stereo", "d", "--out", "o", "--method", "nope"]) == 1
    err = capsys.readouterr().err
    assert "invalid choice: 'nope'" in err and "woodham1980" in err
