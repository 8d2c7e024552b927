"""Whether a run is alive: the process that runs it, and the status a ``running`` run reads as.

A run records its process when it starts (host, pid, and the process's start time, so a reused
pid is not mistaken for it) and refreshes a heartbeat every :data:`HEARTBEAT_S` seconds
(:mod:`pbrbench.bench.lifecycle`).  A run whose status is ``running`` reads as ``interrupted``
(:func:`effective_status`) when

* it ran on this host and its process is gone (or the pid now belongs to another process), or
* it ran on another host and its heartbeat is older than :data:`STALE_S`, or
* it was written by a pbrbench that recorded no process and started more than :data:`STALE_S` ago.

A leaf of the bench layer: the store reads it to show a run's status, and the lifecycle to run one.
"""

from __future__ import annotations

import os
import socket
from datetime import UTC, datetime
from pathlib import Path

from pbrbench.scratch import pid_alive

HEARTBEAT_S = 30.0
STALE_S = 15 * 60.0


# ----------------------------------------------------------------------------- processes
def _boot_id() -> str:
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return ""


def process_start(pid: int) -> str | None:
    """An identifier of the process ``pid``'s start (boot id + start time in clock ticks, from
    /proc), or None where /proc is not available."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat[stat.rfind(")") + 2:].split()
    try:
        return f"{_boot_id()}:{fields[19]}"   # field 22 of stat: starttime
    except IndexError:  # pragma: no cover
        return None


def this_process() -> dict:
    return {"host": socket.gethostname(), "pid": os.getpid(), "pid_start": process_start(os.getpid())}


def age_s(stamp: str | None, now: datetime | None = None) -> float | None:
    if not stamp:
        return None
    try:
        t = datetime.fromisoformat(stamp)
    except ValueError:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=UTC)
    return ((now or datetime.now(UTC)) - t).total_seconds()


def is_alive(run: dict, *, now: datetime | None = None) -> bool | None:
    """Whether the process of a ``running`` run still exists; None when nothing was recorded."""
    pid, host = run.get("pid"), run.get("host")
    if pid is None or not host:
        return None
    if host == socket.gethostname():
        if not pid_alive(int(pid)):
            return False
        rec = run.get("pid_start")
        cur = process_start(int(pid))
        return not (rec and cur and rec != cur)
    age = age_s(run.get("heartbeat"), now)
    return None if age is None else age < STALE_S


def effective_status(run: dict, *, now: datetime | None = None) -> str | None:
    """The status to show: ``interrupted`` for a ``running`` run that is no longer alive."""
    st = run.get("status")
    if st != "running":
        return st
    alive = is_alive(run, now=now)
    if alive is None:  # recorded by an older pbrbench: judge by its age
        age = age_s(run.get("heartbeat") or run.get("time"), now)
        return "interrupted" if age is not None and age > STALE_S else "running"
    return "running" if alive else "interrupted"
