"""The life of a run in the store: who runs it and how it ends.

A run records its process when it starts and refreshes a heartbeat every
:data:`~pbrbench.bench.liveness.HEARTBEAT_S` seconds from a background thread; whether it is alive,
and the status it then reads as, is :mod:`pbrbench.bench.liveness`.

:func:`preflight` checks, before a run is created, that its output directory can be written (so
a read-only or full ``--out`` gives one line and leaves no junk run); :func:`check_resumable`
refuses to resume a run that is still alive; :func:`finish` records the final status and never
lets a failure to record it hide the error that ended the run.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from pathlib import Path

from pbrbench.bench.liveness import HEARTBEAT_S, age_s, this_process
from pbrbench.errors import DiskError, UserError, disk_error


# ----------------------------------------------------------------------------- a run's life
class Heartbeat:
    """Refreshes a run's heartbeat every ``interval`` seconds on its own connection."""

    def __init__(self, store_path, run_id: str, interval: float = HEARTBEAT_S):
        self.store_path, self.run_id, self.interval = store_path, run_id, interval
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name=f"pbrbench-heartbeat-{run_id}", daemon=True)
        self._thread.start()

    def _loop(self):
        from pbrbench.bench.store import Store

        store = None
        while not self._stop.wait(self.interval):
            try:
                if store is None:
                    store = Store(self.store_path)
                store.beat(self.run_id)
            except Exception:  # noqa: BLE001 - a missed beat must never stop the run
                pass
        if store is not None:
            store.close()

    def stop(self):
        self._stop.set()
        self._thread.join(timeout=5)


def preflight(settings) -> Path:
    """Create the output directory and check that it can be written, before any run exists."""
    out = Path(settings.out)
    probe = out / f".pbrbench-write-test-{os.getpid()}"
    try:
        if out.exists() and not out.is_dir():
            raise NotADirectoryError(20, "Not a directory", str(out))
        out.mkdir(parents=True, exist_ok=True)
        probe.write_bytes(b"ok")
    except OSError as exc:
        raise disk_error(exc, f"--out {out}", option="--out") from None
    finally:
        with contextlib.suppress(OSError):
            probe.unlink()
    return out


def check_resumable(store, run_id: str) -> dict:
    """The run to resume; UserError when it is still alive in another process."""
    run = store.get_run(run_id)
    if run is None:
        raise UserError(f"run {run_id!r}: not in {store.path}; `pbrbench history` lists the runs")
    if run["status"] == "running":
        age = age_s(run.get("heartbeat"))
        beat = f", last heartbeat {age:.0f} s ago" if age is not None else ""
        raise UserError(f"run {run_id} is still running (pid {run.get('pid')} on {run.get('host')}{beat}); wait for it "
                        "to finish or stop it before resuming it")
    return run


def start(store, run_id: str, *, interval: float = HEARTBEAT_S) -> Heartbeat | None:
    """Record this process as the one running ``run_id`` and start its heartbeat."""
    p = this_process()
    store.set_process(run_id, host=p["host"], pid=p["pid"], pid_start=p["pid_start"])
    if store.path is None or interval <= 0:
        return None
    return Heartbeat(store.path, run_id, interval)


def ending_status(status: str, exc: BaseException | None = None) -> str:
    """The status to record for a run that ends with ``status`` while ``exc`` propagates.

    An exception may say how the run it ends should read (its ``run_status`` attribute): a lost
    Dask scheduler (:class:`pbrbench.bench.executors.SchedulerLost`) leaves an ``interrupted`` run,
    not a ``failed`` one, since every job it stored is kept and ``--resume`` finishes it.  Only a
    ``failed`` status is changed, and only to ``interrupted``.

    Parameters
    ----------
    status : str
        The status the caller would record.
    exc : BaseException, optional
        The exception in flight (default: the one being handled, :func:`sys.exc_info`).

    Returns
    -------
    str
        The status to record.
    """
    exc = exc if exc is not None else sys.exc_info()[1]
    if status == "failed" and getattr(exc, "run_status", None) == "interrupted":
        return "interrupted"
    return status


def finish(store, run_id: str, status: str, *, variant: str | None = None, heartbeat: Heartbeat | None = None,
           log=None) -> bool:
    """Stop the heartbeat and record the final status; a failure to record it (full or read-only
    store) is reported in one line and does not replace the error that ended the run: the run then
    reads as interrupted and can be resumed.  Returns whether the status was recorded.

    Called from a ``finally`` block, it records the status that the exception ending the run asks
    for (:func:`ending_status`) and tells that exception the run's id (``run_id``, where it has
    one), so that its message names the run to resume."""
    if heartbeat is not None:
        heartbeat.stop()
    exc = sys.exc_info()[1]
    status = ending_status(status, exc)
    if exc is not None and hasattr(exc, "run_id") and getattr(exc, "run_id", None) is None:
        with contextlib.suppress(AttributeError):
            exc.run_id = run_id
    try:
        store.set_status(run_id, status, variant=variant)
        return True
    except (DiskError, UserError) as exc:
        msg = f"could not record status {status!r} of run {run_id}: {exc}"
        (log or (lambda m: print(f"pbrbench: {m}", file=sys.stderr, flush=True)))(msg)
        return False
