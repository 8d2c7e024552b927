"""``pbrbench`` entry point: discovers the subcommand modules of :mod:`pbrbench.cli`.

Exit codes (README.md): **0** ok; **1** a user error, printed as one line (a bad scene file, a
bad argument, a usage error, a full or read-only disk, a job that failed); **2** regressions found
(``run --check``, ``validate``); **130** interrupted (Ctrl-C, SIGTERM, SIGHUP: completed work is
kept and the run can be resumed).  Every message that reaches the terminal passes through
:func:`pbrbench.errors.printable`, so text from a scene file cannot drive the terminal.

An unexpected exception is a bug: it is reported in one line with exit code 1; ``--debug``
shows its traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import pkgutil
import signal
import sqlite3
import sys
import threading

import pbrbench
from pbrbench.errors import UserError, disk_error, printable

EXIT_OK, EXIT_USER, EXIT_REGRESSION, EXIT_INTERRUPTED = 0, 1, 2, 130


class Parser(argparse.ArgumentParser):
    """argparse with usage errors as one line and exit code 1 (2 is reserved for regressions).

    ``fill`` (a keyword of ``add_parser``): a function ``parser -> None`` that adds the parser's
    arguments (and sub-subcommands) when the parser is first used: parsed, or its usage or help
    formatted.  A subcommand whose options need heavy imports (the methods tables of ``infer``,
    the checks of ``validate``) then costs nothing to ``pbrbench --help``, ``pbrbench scenes`` or
    a usage error of another subcommand; only its name and help line are needed up front.
    """

    def __init__(self, *args, fill=None, **kwargs):
        super().__init__(*args, **kwargs)
        self._deferred_fill = fill

    def _fill(self) -> None:
        fill, self._deferred_fill = self._deferred_fill, None
        if fill is not None:
            fill(self)

    def parse_known_args(self, args=None, namespace=None):
        self._fill()
        return super().parse_known_args(args, namespace)

    def format_usage(self):
        self._fill()
        return super().format_usage()

    def format_help(self):
        self._fill()
        return super().format_help()

    def error(self, message):
        self.exit(EXIT_USER, f"{self.prog}: error: {printable(message)} (see `{self.prog} --help`)\n")


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="pbrbench", description=(
        "Physically based rendering testbed for light-and-shading vision: renders ground truth "
        "with Mitsuba 3, runs NumPy inference, scores and reports."),
        epilog="Exit codes: 0 ok, 1 user error (one line), 2 regressions found, 130 interrupted.")
    p.add_argument("--version", action="version", version=f"pbrbench {pbrbench.__version__}")
    p.add_argument("--debug", action="store_true", help="show the traceback of an unexpected error")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    import pbrbench.cli as cli_pkg

    for info in sorted(pkgutil.iter_modules(cli_pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_") or info.name in ("main", "common"):
            continue
        mod = importlib.import_module(f"pbrbench.cli.{info.name}")
        if hasattr(mod, "register"):
            mod.register(sub)
    return p


def _interrupt(signum, frame):
    raise KeyboardInterrupt(signal.Signals(signum).name)


@contextlib.contextmanager
def signals_as_interrupts():
    """SIGTERM and SIGHUP end the command like Ctrl-C: the run is marked interrupted, scratch
    directories are removed (atexit), and the exit code is 130."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            with contextlib.suppress(ValueError, OSError):
                old[sig] = signal.signal(sig, _interrupt)
    try:
        yield
    finally:
        for sig, h in old.items():
            with contextlib.suppress(ValueError, OSError):
                signal.signal(sig, h)


def _say(msg: str) -> None:
    print(f"pbrbench: {printable(msg)}", file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors (Parser.error)
        return int(exc.code or 0) if isinstance(exc.code, int) else EXIT_USER
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USER
    with signals_as_interrupts():
        try:
            return int(args.func(args) or 0)
        except UserError as exc:
            _say(f"error: {exc}")
            return EXIT_USER
        except KeyboardInterrupt:
            _say("interrupted; completed work is kept (renders in the cache, scores in the store)")
            return EXIT_INTERRUPTED
        except BrokenPipeError:
            # the reader of our output went away (``pbrbench scenes | head``): nothing to say to it;
            # stdout goes to /dev/null so the interpreter's final flush stays quiet (Python's advice)
            import os

            with contextlib.suppress(OSError):
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return EXIT_USER
        except OSError as exc:
            # a disk or permission fault the command did not turn into a message itself
            if args.debug:
                raise
            import errno

            writing = exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.ENOTDIR,
                                    errno.EEXIST, errno.EISDIR)
            what = "cannot write" if writing else "cannot read or write"
            if exc.filename is None:   # a failed write() names no file: name the places this command writes
                places = [f"--{o} {getattr(args, o)}" for o in ("out", "store", "cache") if getattr(args, o, None)]
                what += f" (in {', '.join(places)})" if places else " (in --out, --store or --cache)"
            _say(f"error: {disk_error(exc, what)}")
            return EXIT_USER
        except sqlite3.Error as exc:
            if args.debug:
                raise
            _say(f"error: results database: {type(exc).__name__}: {exc}; check --store")
            return EXIT_USER
        except MemoryError:
            _say("error: out of memory; lower the resolution, the samples or the number of scenes")
            return EXIT_USER
        except Exception as exc:  # noqa: BLE001 - a bug: one line, the traceback on request
            if args.debug:
                raise
            where = ""
            tb = exc.__traceback__
            while tb is not None:
                where = f" at {os.path.basename(tb.tb_frame.f_code.co_filename)}:{tb.tb_lineno}"
                tb = tb.tb_next
            _say(f"internal error: {type(exc).__name__}: {exc}{where}; this is a bug in pbrbench: please report it "
                 "with the output of `pbrbench --debug ...`")
            return EXIT_USER
        finally:
            sys.stdout.flush()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
