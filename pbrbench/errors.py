"""Errors meant for users: the CLI prints them as one line and exits with code 1.

Also the helpers that turn a fault of the machine (a full or read-only disk, a missing
permission) into such an error, and that make any text safe to print on a terminal.
"""

from __future__ import annotations

import errno
import re


class UserError(Exception):
    """A problem with the user's input (a scene file, an argument, the environment).

    The message is one line: what is wrong, where (file, key path, argument) and how to fix it.
    """


class SceneError(UserError):
    """A scene file that cannot be parsed or does not validate."""


class DiskError(UserError):
    """A file or directory that cannot be written or read (full disk, read-only file system,
    missing permission, a file where a directory should be)."""


_HINTS = {
    errno.ENOSPC: "the disk is full: free some space or choose another place",
    errno.EDQUOT: "the disk quota is exhausted: free some space or choose another place",
    errno.EROFS: "the file system is read-only: choose another place",
    errno.EACCES: "permission denied: choose another place or fix the permissions",
    errno.EPERM: "permission denied: choose another place or fix the permissions",
    errno.ENOTDIR: "a file stands where a directory is needed: remove it or choose another place",
    errno.EEXIST: "a file stands where a directory is needed: remove it or choose another place",
    errno.EISDIR: "a directory stands where a file is needed: remove it or choose another place",
    errno.ENAMETOOLONG: "the file name is too long: choose a shorter place",
    errno.EIO: "an input/output error of the disk: check the disk",
}


def disk_error(exc: OSError, what: str, *, option: str | None = None, path=None) -> DiskError:
    """A one-line :class:`DiskError` for ``exc`` raised while writing ``what`` (e.g. ``"render
    cache /x"``); ``option`` names the setting that chooses the place (``--cache``)."""
    where = exc.filename if exc.filename is not None else path
    reason = exc.strerror or str(exc) or type(exc).__name__
    hint = _HINTS.get(exc.errno, "check the path and its permissions")
    if option:
        hint += f" (with {option})"
    loc = f" ({where})" if where is not None and str(where) not in what else ""
    return DiskError(f"{what}{loc}: {reason}; {hint}")


# C0 and C1 control characters, DEL, and the Unicode controls that reorder or hide text
_UNSAFE = re.compile("[\x00-\x1f\x7f-\x9f\u200b-\u200f\u2028-\u202e\u2066-\u2069\ufeff]")


def printable(text: object) -> str:
    """``text`` with every control character written as an escape (``\\x1b``, ``\\n``), so that text
    from a scene file or an exception cannot move the cursor, recolour or clear a terminal, or
    break a one-line message into several."""
    s = str(text)
    return _UNSAFE.sub(lambda m: m.group(0).encode("unicode_escape").decode("ascii"), s)
