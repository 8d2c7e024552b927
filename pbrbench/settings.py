"""One settings object, resolved once: command-line argument, else environment variable, else default.

The command line builds :class:`Settings` from its arguments (:meth:`Settings.resolve`) and hands
it to everything it calls; library functions that are called without one use
:meth:`Settings.from_env`.  This is the only module that reads ``PBRBENCH_*`` variables.

==========================  ===================  ==========================================================
setting                     environment          default
==========================  ===================  ==========================================================
``cache`` (render cache)    PBRBENCH_CACHE       ``$XDG_CACHE_HOME/pbrbench``, else ``~/.cache/pbrbench``
``out`` (reports)           --                   ``reports``
``store`` (results db)      PBRBENCH_STORE       ``<out>/history.sqlite``
``variant`` (Mitsuba)       PBRBENCH_VARIANT     chosen safely (:mod:`pbrbench.render.variant`)
``scenes`` (library)        PBRBENCH_SCENES      the library shipped with the package
``baselines``               PBRBENCH_BASELINES   ``tests/baselines`` of a source checkout (none in a wheel)
``progress`` (bars)         PBRBENCH_PROGRESS    bars on a terminal, one line per stage otherwise
``worker_threads``          PBRBENCH_WORKER_THREADS  Dr.Jit / BLAS threads per Dask worker (cores / workers)
``llvm_search`` (dirs)      PBRBENCH_LLVM_SEARCH the system library directories
``no_cuda``                 PBRBENCH_NO_CUDA     false (use CUDA when a device works)
``data_dirs`` (scene data)  PBRBENCH_DATA_DIRS   none: a scene's data files must lie in its own directory
``allow_large`` (limits)    PBRBENCH_ALLOW_LARGE false: refuse scene files whose renders exceed the limits
``plugin_load_limit`` (s)   PBRBENCH_PLUGIN_LOAD_LIMIT 60: seconds to import and register one plugin (in its child)
==========================  ===================  ==========================================================

Only the standard library is imported here.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:   # the profile type, for the annotations only (this module imports no pbrbench module)
    from pbrbench.quality import Quality

PACKAGE_DIR = Path(__file__).resolve().parent


def _library_dir() -> Path:
    """The shipped scene library: ``scenes/`` of the source checkout this package runs from (an
    editable install, or the repository on the path), else ``pbrbench/scenes`` of an installed
    wheel (setup.py maps ``scenes/`` there at build time)."""
    checkout = PACKAGE_DIR.parent / "scenes"
    if (PACKAGE_DIR.parent / "pyproject.toml").is_file() and checkout.is_dir():
        return checkout
    return PACKAGE_DIR / "scenes"


LIBRARY_DIR = _library_dir()


def _source_baselines() -> Path | None:
    """``tests/baselines`` of the source checkout this package runs from, if there is one."""
    p = PACKAGE_DIR.parent / "tests" / "baselines"
    return p if p.is_dir() else None


def _flag(v: str | None) -> bool | None:
    if v is None or v == "":
        return None
    return v.strip().lower() not in ("0", "false", "no", "off")


ENV = {
    "cache": "PBRBENCH_CACHE", "store": "PBRBENCH_STORE", "variant": "PBRBENCH_VARIANT",
    "scenes": "PBRBENCH_SCENES", "baselines": "PBRBENCH_BASELINES", "progress": "PBRBENCH_PROGRESS",
    "worker_threads": "PBRBENCH_WORKER_THREADS", "llvm_search": "PBRBENCH_LLVM_SEARCH",
    "no_cuda": "PBRBENCH_NO_CUDA", "data_dirs": "PBRBENCH_DATA_DIRS", "allow_large": "PBRBENCH_ALLOW_LARGE",
    "plugin_load_limit": "PBRBENCH_PLUGIN_LOAD_LIMIT",
}
PLUGIN_LOAD_LIMIT = 60.0   # seconds to import and register one plugin, in its isolated child


ARG_FIELDS = ("cache", "out", "store", "variant")   # settings the command line can give


@dataclass(frozen=True)
class Settings:
    """Where things live and how the process behaves (see the module docstring)."""

    cache: Path
    out: Path = Path("reports")
    store: Path | None = None
    variant: str | None = None
    scenes: Path = LIBRARY_DIR
    baselines: Path | None = None
    progress: bool | None = None
    worker_threads: int | None = None
    llvm_search: tuple[str, ...] | None = None
    no_cuda: bool = False
    data_dirs: tuple[str, ...] | None = None
    allow_large: bool = False
    plugin_load_limit: float = PLUGIN_LOAD_LIMIT

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_env(cls, env: Mapping[str, str] | None = None, **overrides) -> Settings:
        """Environment, else defaults; ``overrides`` (not None) win over both."""
        env = os.environ if env is None else env

        def get(key):
            v = env.get(ENV[key])
            return v if v not in (None, "") else None

        xdg = env.get("XDG_CACHE_HOME")
        cache = get("cache") or (Path(xdg) / "pbrbench" if xdg else Path.home() / ".cache" / "pbrbench")
        wt = get("worker_threads")
        try:
            wt = int(wt) if wt is not None else None
        except ValueError:
            from pbrbench.errors import UserError

            raise UserError(f"PBRBENCH_WORKER_THREADS={wt!r}: give a whole number of threads") from None
        pl = get("plugin_load_limit")
        try:
            pl = float(pl) if pl is not None else PLUGIN_LOAD_LIMIT
            if not pl > 0:
                raise ValueError
        except ValueError:
            from pbrbench.errors import UserError

            raise UserError(f"PBRBENCH_PLUGIN_LOAD_LIMIT={pl!r}: give the seconds a plugin may take to load, > 0") from None
        ls = get("llvm_search")
        dd = get("data_dirs")
        s = cls(cache=Path(cache), store=Path(get("store")) if get("store") else None, variant=get("variant"),
                scenes=Path(get("scenes")) if get("scenes") else LIBRARY_DIR,
                baselines=Path(get("baselines")) if get("baselines") else _source_baselines(),
                progress=_flag(get("progress")), worker_threads=wt,
                llvm_search=tuple(ls.split(os.pathsep)) if ls else None,
                no_cuda=bool(_flag(get("no_cuda"))),
                data_dirs=tuple(x for x in dd.split(os.pathsep) if x) if dd else None,
                allow_large=bool(_flag(get("allow_large"))), plugin_load_limit=pl)
        return s.with_(**overrides)

    @classmethod
    def resolve(cls, args=None, env: Mapping[str, str] | None = None) -> Settings:
        """From parsed command-line ``args`` (``--cache``, ``--out``, ``--store``, ``--variant``;
        None = not given), then the environment, then the defaults."""
        over = {}
        for name in ARG_FIELDS:
            v = getattr(args, name, None) if args is not None else None
            if v is not None:
                over[name] = v
        return cls.from_env(env, **over)

    def with_(self, **changes) -> Settings:
        """A copy with the given (not None) fields replaced; paths are converted to :class:`Path`."""
        clean = {}
        for k, v in changes.items():
            if v is None:
                continue
            if k in ("cache", "out", "store", "scenes", "baselines"):
                v = Path(v)
            clean[k] = v
        return replace(self, **clean) if clean else self

    # ------------------------------------------------------------------ derived
    def store_path(self) -> Path:
        """The results database: ``store``, else ``<out>/history.sqlite``."""
        return Path(self.store) if self.store is not None else Path(self.out) / "history.sqlite"

    def baseline_path(self, quality: Quality) -> Path | None:
        """``<baselines>/<quality name>.json`` (None when there is no baselines directory)."""
        return None if self.baselines is None else Path(self.baselines) / f"{quality.name}.json"

    def progress_bars(self, stream) -> bool:
        """Progress bars when asked for, else when ``stream`` is a terminal."""
        if self.progress is not None:
            return self.progress
        return bool(getattr(stream, "isatty", lambda: False)())
