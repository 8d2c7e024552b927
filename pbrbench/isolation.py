"""Run a user's algorithm in a child process that is killed when it exceeds its time limit.

Why a process, not a thread: a hung pure-Python function cannot be stopped from another thread
(Python has no safe way to kill a thread; a daemon thread would keep burning a core and holding
the GIL for the rest of the run).  A child process can be killed, so a plugin that loops forever,
crashes the interpreter (a segfault in an extension) or calls ``os._exit`` costs one failed
score, never the run.

How: one child per process (``python -c`` with a small loop, started on first use and reused
for every call, so the plugin's imports happen once), talking over its stdin/stdout pipes with
length-prefixed pickles.  The parent's ``sys.path`` travels with every call, so plugins on paths
added at run time resolve in the child.  A plugin's entry travels as a reference
(:class:`pbrbench.plugins.PluginFunction`: its module, or a plugin file's bytes), so the plugin
is imported in the child only, once; other callables travel by value (cloudpickle).  Inputs and
outputs are pickled, so the child computes on bit-identical copies, and nothing it does to them
reaches the other algorithms.  What the plugin prints goes to stderr (stdout carries the
protocol).  On a timeout the child is killed and a fresh one starts at the next call.
``subprocess`` (not ``multiprocessing``) is used because it works inside daemonic Dask worker
processes too.

The time limit is per job where the job runs inside :func:`job_budget` (the runner does): one
budget for all the calls of an algorithm in the job, and an algorithm that ran past it or whose
process died is not called again in that job.  The child dies with its parent, even on
``kill -9``: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` on Linux (when started from the main thread), and
a watchdog thread that polls the parent's pid everywhere.

Costs: starting the child (an interpreter plus the plugin's imports, once per process) and
pickling the inputs of each call (milliseconds for a benchmark job).  Built-in methods are never
isolated: they run in-process, bit for bit as before.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import pickle
import selectors
import signal
import struct
import subprocess
import sys
import threading
import time

__all__ = ["call_isolated", "job_budget", "shutdown", "PluginTimeout", "PluginCrash"]

_HEADER = struct.Struct("<Q")

# The child's main loop.  Each message is (the parent's sys.path, pickled (function reference,
# args, kwargs)); it answers ("ok", result) or ("err", type name, message).
_CHILD = r"""
import os, pickle, struct, sys, threading, time, warnings
PARENT = int(sys.argv[1])
if sys.argv[2] == "1" and sys.platform.startswith("linux"):
    try:                          # killed with the process that started it (kill -9 too)
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, 9)      # PR_SET_PDEATHSIG, SIGKILL
    except Exception:
        pass
def _watch():                     # and wherever prctl is not there: poll the parent
    while os.getppid() == PARENT:
        time.sleep(0.25)
    os._exit(0)
threading.Thread(target=_watch, daemon=True).start()
H = struct.Struct("<Q")
inp = sys.stdin.buffer
out = os.fdopen(os.dup(1), "wb")
os.dup2(2, 1)                     # the plugin's prints go to stderr; stdout carries the protocol
sys.stdout = sys.stderr
def read():
    h = inp.read(H.size)
    if len(h) < H.size:
        return None
    n = H.unpack(h)[0]
    data = inp.read(n)
    return data if len(data) == n else None
def send(obj):
    try:
        import cloudpickle as pk
    except ImportError:
        pk = pickle
    try:
        data = pk.dumps(obj)
    except Exception as e:
        data = pickle.dumps(("err", "ValueError", f"output: could not be sent back from the plugin's process ({type(e).__name__}: {e})"))
    out.write(H.pack(len(data)) + data)
    out.flush()
def resolve(ref):
    return pickle.loads(ref[1])
while True:
    msg = read()
    if msg is None:
        break
    try:
        path, payload = pickle.loads(msg)
        if path != sys.path:
            sys.path[:] = path
        ref, args, kwargs = pickle.loads(payload)
        fn = resolve(ref)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = fn(*args, **kwargs)
        send(("ok", res))
    except BaseException as e:
        if isinstance(e, KeyboardInterrupt):
            break
        send(("err", type(e).__name__, str(e)))
"""


class PluginTimeout(TimeoutError):
    """The algorithm ran past its time limit (its process was killed)."""


class PluginCrash(RuntimeError):
    """The algorithm's process died (a crash, ``os._exit``, killed from outside)."""


def _dumps(obj) -> bytes:
    try:
        import cloudpickle
    except ImportError:
        return pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    return cloudpickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)


def _reference(fn):
    """How the child finds ``fn``: ("pickle", bytes).  A plugin's entry is a
    :class:`pbrbench.plugins.PluginFunction`, pickled as a reference (its source), which loads
    the plugin in the child."""
    return ("pickle", _dumps(fn))


class _Child:
    def __init__(self):
        env = dict(os.environ)
        main = "1" if threading.current_thread() is threading.main_thread() else "0"
        # PR_SET_PDEATHSIG fires when the starting *thread* ends: set only from the main thread
        self.proc = subprocess.Popen([sys.executable, "-c", _CHILD, str(os.getpid()), main], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, env=env, close_fds=True)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def _send(self, data: bytes):
        self.proc.stdin.write(_HEADER.pack(len(data)) + data)
        self.proc.stdin.flush()

    def _read_exact(self, n: int, deadline: float | None) -> bytes:
        fd = self.proc.stdout.fileno()
        chunks, got = [], 0
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while got < n:
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    raise PluginTimeout
                if not sel.select(left):
                    raise PluginTimeout
                b = os.read(fd, min(n - got, 1 << 20))
                if not b:
                    raise PluginCrash
                chunks.append(b)
                got += len(b)
        return b"".join(chunks)

    def call(self, ref, args, kwargs, time_limit: float | None):
        deadline = None if time_limit is None else time.monotonic() + float(time_limit)
        try:
            payload = pickle.dumps((ref, args, kwargs), protocol=pickle.HIGHEST_PROTOCOL)
            self._send(pickle.dumps((list(sys.path), payload), protocol=pickle.HIGHEST_PROTOCOL))
        except (BrokenPipeError, OSError):
            raise PluginCrash from None
        (n,) = _HEADER.unpack(self._read_exact(_HEADER.size, deadline))
        return pickle.loads(self._read_exact(n, deadline))

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:  # pragma: no cover
            pass
        for f in (self.proc.stdin, self.proc.stdout):
            try:
                f.close()
            except OSError:
                pass

    def close(self):
        try:
            self.proc.stdin.close()
            self.proc.wait(timeout=2)
        except (OSError, subprocess.TimeoutExpired):
            pass
        self.kill()


_LOCK = threading.Lock()
_CHILDREN: dict[int, _Child] = {}     # pid of the owning process -> its child


def _child() -> _Child:
    c = _CHILDREN.get(os.getpid())
    if c is None or not c.alive():
        c = _CHILDREN[os.getpid()] = _Child()
    return c


def _death(code) -> str:
    if code is not None and code < 0:
        try:
            return f"killed by signal {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


_JOB = threading.local()


@contextlib.contextmanager
def job_budget():
    """Within this context (one job: its full scoring, replicates and second seed) an isolated
    algorithm's time limit is shared by all its calls, and one that ran past it or whose process
    died is not called again (each later call raises the same error at once)."""
    prev = getattr(_JOB, "state", None)
    _JOB.state = {"used": {}, "dead": {}}
    try:
        yield
    finally:
        _JOB.state = prev


def call_isolated(fn, args=(), kwargs=None, *, time_limit: float | None, name: str = "algorithm",
                  budget: bool = True):
    """``fn(*args, **kwargs)`` in the child process, within ``time_limit`` seconds (None: no
    limit; inside :func:`job_budget`, what is left of it for ``name`` in this job, unless
    ``budget`` is false).  Raises :class:`PluginTimeout` past the limit (the child is killed),
    :class:`PluginCrash` when the child dies, and the algorithm's own exception type (rebuilt
    as a ``RuntimeError`` subclass when it is not a built-in) when it raises."""
    import builtins

    kwargs = dict(kwargs or {})
    state = getattr(_JOB, "state", None) if budget else None
    if state is not None and name in state["dead"]:
        err = state["dead"][name]
        raise type(err)(str(err))
    with _LOCK:
        ref = _reference(fn)
        child = _child()
        limit = time_limit
        if state is not None and time_limit is not None:
            limit = float(time_limit) - state["used"].get(name, 0.0)
        t0 = time.monotonic()
        try:
            if limit is not None and limit <= 0:
                raise PluginTimeout
            reply = child.call(ref, tuple(args), kwargs, limit)
        except PluginTimeout:
            child.kill()
            per = " for the job" if state is not None else ""
            err = PluginTimeout(f"{name} ran past its time limit of {time_limit:g} s{per}; its process was killed "
                                "(raise the limit with --algorithm-time-limit)")
            if state is not None:
                state["dead"][name] = err
            raise err from None
        except PluginCrash:
            child.kill()
            code = child.proc.returncode
            err = PluginCrash(f"{name}'s process died ({_death(code)})")
            if state is not None:
                state["dead"][name] = err
            raise err from None
        finally:
            if state is not None:
                state["used"][name] = state["used"].get(name, 0.0) + time.monotonic() - t0
    if reply[0] == "ok":
        return reply[1]
    _, tname, msg = reply
    exc = getattr(builtins, tname, None)
    err = None
    if isinstance(exc, type) and issubclass(exc, Exception):
        try:
            err = exc(msg)
        except Exception:  # noqa: BLE001 - an exception type that takes other arguments
            err = None
    raise err if err is not None else type(tname, (RuntimeError,), {})(msg)


def shutdown():
    """Stop this process's child (called at exit)."""
    with _LOCK:
        c = _CHILDREN.pop(os.getpid(), None)
    if c is not None:
        c.close()


atexit.register(shutdown)
