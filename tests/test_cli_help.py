"""Every command's --help prints (argparse formats help strings with %: a stray % in a help text
is a traceback for the user who asks for help)."""

import argparse

import pytest

from pbrbench.cli.main import build_parser, main


def _commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sorted(sub.choices)


@pytest.mark.parametrize("command", _commands())
def test_every_command_help_prints(command, capsys):
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage:") and command in out


def test_top_level_help_prints(capsys):
    assert main(["--help"]) == 0
    assert "usage:" in capsys.readouterr().out


def test_the_command_lines_hdr_merge_default_is_merge_hdrs():
    import inspect

    from pbrbench.cli.main import build_parser
    from pbrbench.infer.hdr import merge_hdr

    args = build_parser().parse_args(["infer", "hdr", "somewhere", "--out", "x"])
    assert args.merge == inspect.signature(merge_hdr).parameters["method"].default == "granados2010"


def test_a_reader_that_stops_early_gets_no_error_line():
    """``pbrbench scenes | head -1``: the pipe closes under the command; no "Broken pipe" error."""
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-m", "pbrbench", "scenes", "--expand"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, bufsize=0)
    first = p.stdout.read(64)
    p.stdout.close()
    err = p.stderr.read().decode()
    p.wait(timeout=60)
    assert first and "Broken pipe" not in err and "error" not in err.lower(), err


def test_the_infer_defaults_are_the_dispatchers():
    """``pbrbench infer`` offers the defaults of the Python calls: one place decides each."""
    import argparse

    from pbrbench.cli.infer import _add_hdr_options, _add_ps_options, _add_retinex_options
    from pbrbench.infer.hdr import calibrate_response, merge_hdr
    from pbrbench.infer.lightness import estimate_lightness
    from pbrbench.infer.photometric_stereo import solve_photometric_stereo
    from tests.test_cli_help import _default

    for add, want in ((_add_ps_options, {"method": _default(solve_photometric_stereo)}),
                      (_add_retinex_options, {"method": _default(estimate_lightness)}),
                      (_add_hdr_options, {"method": _default(calibrate_response), "merge": _default(merge_hdr)})):
        p = argparse.ArgumentParser()
        add(p)
        for k, v in want.items():
            assert p.get_default(k) == v, (add.__name__, k)


def _default(fn):
    import inspect

    return inspect.signature(fn).parameters["method"].default
