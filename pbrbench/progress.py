"""Progress of a long stage: a bar on a terminal, plain lines in a log.

On a terminal (or when the ``progress`` setting asks for it) a tqdm bar; otherwise one line per
tenth of the stage and one when it ends, e.g. ``pbrbench: jobs 40% (55/138, 41.2 s, ETA 62 s)``,
so a log of ``make bench > log`` shows where the run is and how long it has left (the ETA
assumes the rest goes at the pace so far).  Progress goes to stderr.
"""

from __future__ import annotations

import sys
import time


class Progress:
    """``with Progress(total, "render", bars=...) as p: ... p.update(1, note)``."""

    def __init__(self, total: int, desc: str, *, bars: bool, unit: str = "item", stream=None, lines: bool = True):
        self.total, self.desc, self.unit = int(total), desc, unit
        self.stream = stream or sys.stderr
        self.n = 0
        self.t0 = time.perf_counter()
        self.lines = lines and not bars
        self._next = 1          # the next tenth to report (integer: 0.1 + 0.1 + 0.1 > 0.3)
        self.bar = None
        if bars:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit=unit, leave=True, dynamic_ncols=True, file=self.stream)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def write(self, msg: str):
        """A message that does not break the bar."""
        if self.bar is not None:
            self.bar.write(msg, file=self.stream)
        else:
            print(msg, file=self.stream, flush=True)

    def update(self, k: int = 1, note: str = ""):
        self.n += k
        if self.bar is not None:
            if note:
                self.bar.set_postfix_str(note[:40])
            self.bar.update(k)
            return
        if self.lines and self.total and 10 * self.n >= self._next * self.total and self.n < self.total:
            pct = int(100 * self.n / self.total)
            el = time.perf_counter() - self.t0
            print(f"pbrbench: {self.desc} {pct}% ({self.n}/{self.total}, {el:.1f} s, ETA {eta(el, self.n, self.total)})",
                  file=self.stream, flush=True)
            while self._next * self.total <= 10 * self.n:
                self._next += 1

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        elif self.lines and self.total:
            print(f"pbrbench: {self.desc} done ({self.n}/{self.total} {self.unit}s, "
                  f"{time.perf_counter() - self.t0:.1f} s)", file=self.stream, flush=True)
            self.lines = False


def eta(elapsed: float, done: int, total: int) -> str:
    """The time left at the pace so far, e.g. ``62 s`` or ``3 min 20 s``."""
    if done <= 0:
        return "?"
    left = max(0.0, elapsed / done * (total - done))
    return f"{left:.0f} s" if left < 120 else f"{int(left // 60)} min {int(left % 60)} s"


def peak_memory_mib() -> float:
    """Peak resident memory of this process and its finished children, in MiB (``ru_maxrss``)."""
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    scale = 1 / 1024 if sys.platform != "darwin" else 1 / (1024 * 1024)   # kB on Linux, bytes on macOS
    return max(own, kids) * scale
