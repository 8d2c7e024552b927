"""Scratch directories of this process (heightfield meshes, ...), removed when it ends.

A directory is named ``pbrbench-<what>-<pid>-<random>`` in the system temporary directory.  It is
removed at interpreter exit (``atexit``), which also runs after SIGTERM / SIGHUP when the command
line is in charge (it turns those signals into a normal, interrupted exit: :mod:`pbrbench.cli.main`).
A process killed outright (SIGKILL, power loss) cannot clean up, so each new scratch directory
first removes the directories of processes of this user that no longer exist.

Only the standard library is imported here.
"""

from __future__ import annotations

import atexit
import glob
import os
import re
import shutil
import tempfile
import time

_DIRS: dict[str, str] = {}
_NAME = re.compile(r"^pbrbench-([a-z]+)-(\d+)-")
OLD_FORMAT_AGE_S = 24 * 3600   # unnamed leftovers of older versions (no pid in the name)


def pid_alive(pid: int) -> bool:
    """True when a process ``pid`` exists (of any user)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    return True


def remove_stale(tmp: str | None = None) -> list[str]:
    """Remove scratch directories of dead processes of this user; returns what was removed."""
    tmp = tmp or tempfile.gettempdir()
    removed = []
    uid = os.getuid() if hasattr(os, "getuid") else None
    for d in glob.glob(os.path.join(tmp, "pbrbench-*-*")):
        try:
            st = os.lstat(d)
        except OSError:
            continue
        if not os.path.isdir(d) or os.path.islink(d) or (uid is not None and st.st_uid != uid):
            continue
        m = _NAME.match(os.path.basename(d))
        if m:
            stale = int(m.group(2)) != os.getpid() and not pid_alive(int(m.group(2)))
        else:  # a directory of an older pbrbench (pbrbench-mesh-XXXX): only when old
            stale = os.path.basename(d).startswith("pbrbench-mesh-") and time.time() - st.st_mtime > OLD_FORMAT_AGE_S
        if stale:
            shutil.rmtree(d, ignore_errors=True)
            removed.append(d)
    return removed


def scratch_dir(what: str) -> str:
    """This process's scratch directory for ``what`` (created once, removed at exit)."""
    d = _DIRS.get(what)
    if d is not None and os.path.isdir(d):
        return d
    try:
        remove_stale()
    except OSError:  # cleaning up is a courtesy; never fail a render for it
        pass
    d = tempfile.mkdtemp(prefix=f"pbrbench-{what}-{os.getpid()}-")
    _DIRS[what] = d
    return d


def cleanup() -> None:
    """Remove this process's scratch directories (registered with atexit)."""
    for what, d in list(_DIRS.items()):
        shutil.rmtree(d, ignore_errors=True)
        _DIRS.pop(what, None)


atexit.register(cleanup)
