"""Simulated disk faults for the command line, without root tricks (no tmpfs, no mounts).

``python -m tests.corpus.faults KIND DIR [BUDGET] -- ARGS...`` runs ``pbrbench ARGS`` with every
write below ``DIR`` failing the way the operating system would fail it:

- ``readonly``: a read-only file system (``EROFS``) for files, directories, renames, removals and
  SQLite (a read-write open fails, a read-only open of a WAL database fails for want of its -shm
  file, an ``immutable`` open works: what SQLite does in a read-only directory);
- ``denied``: ``EACCES`` (a directory without write permission), the same places;
- ``full``: a full disk: the first ``BUDGET`` bytes written below DIR (default 0) go through, then
  ``ENOSPC``, after the partial data reached the file (as a real full disk leaves it); OpenEXR's
  writer (C++) writes half the file and raises; SQLite writes fail with "database or disk is
  full" after ``BUDGET`` write statements.

Running as root does not matter: the faults are injected in Python, not by permissions.
"""

from __future__ import annotations

import builtins
import errno
import io
import os
import shutil
import sqlite3
import sys
from pathlib import Path

_REAL = {"open": builtins.open, "os_open": os.open, "mkdir": os.mkdir, "replace": os.replace, "rename": os.rename,
         "unlink": os.unlink, "rmdir": os.rmdir, "connect": sqlite3.connect, "rmtree": shutil.rmtree}
ERRNO = {"readonly": errno.EROFS, "denied": errno.EACCES, "full": errno.ENOSPC}


class Fault:
    def __init__(self, kind: str, under: str, budget: int = 0):
        self.kind, self.under, self.budget = kind, os.path.realpath(under), int(budget)
        self.written = 0
        self.sql_writes = 0

    def below(self, path) -> bool:
        try:
            p = os.path.realpath(os.fspath(path))
        except TypeError:
            return False
        return p == self.under or p.startswith(self.under + os.sep)

    def error(self, path) -> OSError:
        code = ERRNO[self.kind]
        return OSError(code, os.strerror(code), os.fspath(path))


class _FullFile(io.RawIOBase):
    """A writable file that takes ``room`` more bytes, then fails with ENOSPC."""

    def __init__(self, f, fault: Fault, path):
        self.f, self.fault, self.path = f, fault, path

    def writable(self):
        return True

    def write(self, b):
        room = self.fault.budget - self.fault.written
        data = bytes(b) if not isinstance(b, str) else b.encode()
        if self.f.closed:
            raise self.fault.error(self.path)
        if len(data) > room:
            self.f.write(data[:max(room, 0)])
            self.f.flush()
            self.fault.written += max(room, 0)
            raise self.fault.error(self.path)
        self.f.write(data)
        self.fault.written += len(data)
        return len(data)

    def flush(self):
        if not self.f.closed:
            self.f.flush()

    def fileno(self):
        return self.f.fileno()

    def close(self):
        if not self.f.closed:
            self.f.close()
        super().close()


_WRITE_SQL = ("INSERT", "UPDATE", "DELETE", "CREATE", "ALTER", "REPLACE", "DROP")


class _FullConnection:
    """A SQLite connection whose writes fail with 'database or disk is full' past the budget."""

    def __init__(self, conn, fault: Fault):
        object.__setattr__(self, "_c", conn)
        object.__setattr__(self, "_fault", fault)

    def _check(self, sql):
        if sql.lstrip().upper().startswith(_WRITE_SQL):
            self._fault.sql_writes += 1
            if self._fault.sql_writes > self._fault.budget:
                raise sqlite3.OperationalError("database or disk is full")

    def execute(self, sql, *a):
        self._check(sql)
        return self._c.execute(sql, *a)

    def executemany(self, sql, *a):
        self._check(sql)
        return self._c.executemany(sql, *a)

    def __getattr__(self, k):
        return getattr(self._c, k)

    def __setattr__(self, k, v):
        setattr(self._c, k, v)


def install(fault: Fault) -> None:
    def fopen(file, mode="r", *a, **k):
        writing = any(c in mode for c in "wax+")
        if writing and not isinstance(file, int) and fault.below(file):
            if fault.kind != "full":
                raise fault.error(file)
            binary = "b" in mode
            f = _REAL["open"](file, mode if binary else mode.replace("t", "") + "b")
            raw = _FullFile(f, fault, file)
            buf = io.BufferedWriter(raw)
            return buf if binary else io.TextIOWrapper(buf, encoding=k.get("encoding") or "utf-8")
        return _REAL["open"](file, mode, *a, **k)

    def os_open(path, flags, *a, **k):
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT) and fault.below(path) and fault.kind != "full":
            raise fault.error(path)
        return _REAL["os_open"](path, flags, *a, **k)

    def guard(name):
        real = _REAL[name]

        def fn(*args, **kw):
            if fault.kind != "full" and any(fault.below(p) for p in args[:2] if isinstance(p, (str, os.PathLike))):
                raise fault.error(args[0])
            return real(*args, **kw)
        return fn

    def rmtree(path, ignore_errors=False, onerror=None, **kw):
        if fault.kind != "full" and fault.below(path):
            if ignore_errors:
                return None
            exc = fault.error(path)
            if kw.get("onexc") is not None:
                return kw["onexc"](os.rmdir, path, exc)
            if onerror is not None:
                return onerror(os.rmdir, path, (type(exc), exc, None))
            raise exc
        return _REAL["rmtree"](path, ignore_errors=ignore_errors, onerror=onerror, **kw)

    def connect(database, *a, **k):
        """A read-only directory as SQLite meets it: a read-write open fails, a ``mode=ro`` open
        of a WAL database needs its -shm file (which cannot be created), ``immutable=1`` works."""
        target = str(database)
        uri = target.startswith("file:")
        path = target[5:].split("?", 1)[0] if uri else target
        if uri:
            from urllib.parse import unquote

            path = unquote(path)
        if not fault.below(path):
            return _REAL["connect"](database, *a, **k)
        if fault.kind == "full":
            return _FullConnection(_REAL["connect"](database, *a, **k), fault)
        query = target.split("?", 1)[1] if uri and "?" in target else ""
        if "immutable=1" in query:
            return _REAL["connect"](database, *a, **k)
        if "mode=ro" in query and os.path.exists(path + "-shm"):
            return _REAL["connect"](database, *a, **k)
        raise sqlite3.OperationalError("unable to open database file")

    builtins.open = fopen
    io.open = fopen
    os.open = os_open
    for name in ("mkdir", "replace", "rename", "unlink", "rmdir"):
        setattr(os, name, guard(name))
    shutil.rmtree = rmtree
    sqlite3.connect = connect
    shutil._USE_CP_SENDFILE = False  # copies go through write(), where a full disk shows

    try:
        import OpenEXR
    except ImportError:  # pragma: no cover
        return
    real_file = OpenEXR.File

    class FaultyFile:
        def __init__(self, *a, **k):
            self._f = real_file(*a, **k)

        def __enter__(self):
            self._f.__enter__()
            return self

        def __exit__(self, *exc):
            return self._f.__exit__(*exc)

        def write(self, path):
            if fault.below(path):
                if fault.kind != "full":
                    raise RuntimeError(f"Cannot open image file \"{path}\". {os.strerror(ERRNO[fault.kind])}.")
                self._f.write(path)
                size = os.path.getsize(path)
                if fault.written + size <= fault.budget:
                    fault.written += size
                    return None
                with _REAL["open"](path, "r+b") as f:
                    f.truncate(size // 2)
                raise RuntimeError(f"Error writing pixel data to image file \"{path}\". No space left on device.")
            return self._f.write(path)

        def __getattr__(self, k):
            return getattr(self._f, k)

    OpenEXR.File = FaultyFile


def main(argv: list[str]) -> int:
    if "--" not in argv or len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    i = argv.index("--")
    head, args = argv[:i], argv[i + 1:]
    kind, under = head[0], head[1]
    budget = int(head[2]) if len(head) > 2 else 0
    Path(under).mkdir(parents=True, exist_ok=True) if kind == "full" else None
    install(Fault(kind, under, budget))
    from pbrbench.cli.main import main as cli

    return cli(args)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
