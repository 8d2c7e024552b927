"""Choose a Mitsuba variant safely, *before* mitsuba or drjit is imported.

Order of preference:

1. an explicit variant (``--variant``, else the ``variant`` setting, ``PBRBENCH_VARIANT``:
   :class:`pbrbench.settings.Settings`);
2. ``cuda_ad_rgb`` if a CUDA device works (probed through the driver API with ctypes, which
   cannot crash the process);
3. ``llvm_ad_rgb`` if a libLLVM of version >= 16 is found; ``DRJIT_LIBLLVM_PATH`` is then set to
   it, because drjit loads libLLVM at ``import drjit``;
4. ``scalar_rgb`` with a one-line notice on stderr.

Why so careful: with libLLVM 14 or 15, drjit aborts the whole process (SIGABRT, "LLVM ERROR:
Cannot select ... fminimum") on its first kernel compile.  Python cannot catch that, so those
libraries must never be chosen, even when ``DRJIT_LIBLLVM_PATH`` names one.

A library's file name is never trusted (``libLLVM-19.so`` may be a symbolic link to LLVM 15):
the path is resolved to the real file, whose version is read from the file itself, the ELF
``SONAME`` it was built with (``libLLVM-15.so.1``, ``libLLVM.so.19.1``), or, when it has none,
from ``LLVMGetVersion`` (which exists only since LLVM 16) in a short subprocess, so no
unsuitable libLLVM is ever loaded into this process.

``DRJIT_LIBLLVM_PATH`` set to ``os.devnull`` means "no libLLVM" (pbrbench sets it so when none
is usable, and child processes inherit it): it is not reported as a bad path.  Each notice is
printed once per process.
"""

from __future__ import annotations

import ctypes
import glob
import os
import re
import subprocess
import sys
from dataclasses import dataclass

from pbrbench.errors import UserError
from pbrbench.memo import Memo

RGB_VARIANTS = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
MIN_LLVM = 16
DEFAULT_LLVM_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib64",
    "/usr/lib",
    "/usr/local/lib",
    "/opt/homebrew/opt/llvm/lib",
)


@dataclass(frozen=True)
class VariantChoice:
    """The chosen variant, the libLLVM used (if any) and why."""

    variant: str
    llvm_path: str | None
    reason: str
    notice: str | None = None


def llvm_major_from_name(path: str) -> int | None:
    """Major LLVM version encoded in a library file name (``libLLVM-15.so.1``,
    ``libLLVM.so.19.1``), or None if the name has none.  Used on the SONAME a library carries,
    never on the name a file happens to have."""
    candidate = os.path.basename(path)
    m = re.search(r"libLLVM[-.]?(\d+)", candidate)
    if m:
        return int(m.group(1))
    m = re.search(r"libLLVM\.so\.(\d+)", candidate)
    if m:
        return int(m.group(1))
    return None


def elf_soname(path: str) -> str | None:
    """The ``DT_SONAME`` of an ELF shared library (read from the file, without loading it), or
    None when the file is not ELF or has none."""
    import struct

    try:
        with open(path, "rb") as f:
            ident = f.read(16)
            if len(ident) < 16 or ident[:4] != b"\x7fELF":
                return None
            is64, end = ident[4] == 2, "<" if ident[5] == 1 else ">"
            hdr = f.read(48 if is64 else 36)
            if is64:
                shoff, = struct.unpack_from(end + "Q", hdr, 24)
                shentsize, shnum = struct.unpack_from(end + "HH", hdr, 42)
            else:
                shoff, = struct.unpack_from(end + "I", hdr, 16)
                shentsize, shnum = struct.unpack_from(end + "HH", hdr, 30)
            if not shoff or not shnum or shnum > 100000:
                return None
            f.seek(shoff)
            table = f.read(shentsize * shnum)
            secs = []
            for i in range(shnum):
                b = table[i * shentsize:(i + 1) * shentsize]
                if is64:
                    _, typ, _, _, off, size, link, _, _, entsize = struct.unpack_from(end + "IIQQQQIIQQ", b)
                else:
                    _, typ, _, _, off, size, link, _, _, entsize = struct.unpack_from(end + "IIIIIIIIII", b)
                secs.append((typ, off, size, link, entsize))
            for typ, off, size, link, _entsize in secs:
                if typ != 6 or link >= len(secs) or size > 1 << 24:  # SHT_DYNAMIC
                    continue
                f.seek(off)
                dyn = f.read(size)
                step = 16 if is64 else 8
                fmt = end + ("qQ" if is64 else "iI")
                for k in range(0, len(dyn) - step + 1, step):
                    tag, val = struct.unpack_from(fmt, dyn, k)
                    if tag == 0:
                        break
                    if tag == 14:  # DT_SONAME
                        _, str_off, str_size, _, _ = secs[link]
                        f.seek(str_off + val)
                        raw = f.read(min(256, max(str_size - val, 0)))
                        return raw.split(b"\x00", 1)[0].decode("ascii", "replace") or None
    except (OSError, struct.error, ValueError):
        return None
    return None


_PROBE = (
    "import ctypes,sys\n"
    "lib=ctypes.CDLL(sys.argv[1])\n"
    "f=getattr(lib,'LLVMGetVersion',None)\n"
    "if f is None: print(0); raise SystemExit\n"
    "a,b,c=ctypes.c_uint(),ctypes.c_uint(),ctypes.c_uint()\n"
    "f(ctypes.byref(a),ctypes.byref(b),ctypes.byref(c)); print(a.value)\n"
)


_MAJOR_CACHE = Memo("libLLVM major versions by (path, size, mtime)", 64)


def llvm_major(path: str) -> int | None:
    """Major version of the libLLVM at ``path`` (None if it does not exist or cannot be loaded).

    Symbolic links are resolved and the version is read from the real file: its ELF SONAME, else
    ``LLVMGetVersion`` called in a subprocess (a library without it is older than LLVM 16 and is
    reported as 0).  The file's name is not trusted.
    """
    real = os.path.realpath(path)
    if not os.path.isfile(real):
        return None
    try:
        st = os.stat(real)
    except OSError:
        return None
    key = (real, st.st_size, st.st_mtime_ns)
    if key in _MAJOR_CACHE:
        return _MAJOR_CACHE[key]
    soname = elf_soname(real)
    major = llvm_major_from_name(soname) if soname else None
    if major is None:
        try:
            out = subprocess.run([sys.executable, "-c", _PROBE, real], capture_output=True, text=True, timeout=30)
            major = int(out.stdout.strip()) if out.returncode == 0 else None
        except (subprocess.SubprocessError, ValueError, OSError):
            major = None
    _MAJOR_CACHE[key] = major
    return major


_PREFERRED: dict = {}
_NOTICED: set[str] = set()


def configure(settings) -> None:
    """Use ``settings`` (variant, llvm_search, no_cuda) for this process's variant choice; call it
    before the first render (the command line does, with the settings it resolved)."""
    _PREFERRED["settings"] = settings


class _Defaults:
    """The settings' defaults, when no process has configured this module (the API without
    :func:`configure`: no preferred variant, the system library directories, CUDA when it works)."""

    variant = None
    llvm_search = None
    no_cuda = False


def _settings():
    return _PREFERRED.get("settings") or _Defaults


def find_llvm(search_dirs=None) -> tuple[str | None, list[tuple[str, int | None]]]:
    """Best libLLVM >= 16 in ``search_dirs`` (or the ``llvm_search`` setting, or the system dirs).

    Returns ``(path or None, [(candidate, major), ...])``.
    """
    if search_dirs is None:
        search_dirs = _settings().llvm_search or DEFAULT_LLVM_DIRS
    cands: list[str] = []
    for d in search_dirs:
        cands += sorted(glob.glob(os.path.join(d, "libLLVM*.so*")))
        cands += sorted(glob.glob(os.path.join(d, "llvm-*", "lib", "libLLVM*.so*")))
        cands += sorted(glob.glob(os.path.join(d, "libLLVM*.dylib")))
    seen: dict[str, tuple[str, int | None]] = {}
    for c in cands:
        real = os.path.realpath(c)
        if real not in seen:
            seen[real] = (c, llvm_major(c))
    found = list(seen.values())
    good = [(c, v) for c, v in found if v is not None and v >= MIN_LLVM]
    if not good:
        return None, found
    good.sort(key=lambda cv: cv[1], reverse=True)
    return good[0][0], found


def cuda_available() -> bool:
    """True when the CUDA driver loads and reports at least one device (no crash possible)."""
    if _settings().no_cuda:
        return False
    for name in ("libcuda.so.1", "libcuda.so", "nvcuda.dll"):
        try:
            lib = ctypes.CDLL(name)
        except OSError:
            continue
        try:
            if lib.cuInit(0) != 0:
                return False
            count = ctypes.c_int(0)
            return lib.cuDeviceGetCount(ctypes.byref(count)) == 0 and count.value > 0
        except AttributeError:
            return False
    return False


def _notice(notes: list[str]) -> str | None:
    """The notice of a choice, printed on stderr the first time it is made in this process (the
    choice is made several times per command: its notice reaches the user once)."""
    if not notes:
        return None
    text = "pbrbench: " + "; ".join(notes)
    if text not in _NOTICED:
        _NOTICED.add(text)
        print(text, file=sys.stderr, flush=True)
    return text


def choose_variant(explicit: str | None = None) -> VariantChoice:
    """Decide the Mitsuba variant and set ``DRJIT_LIBLLVM_PATH`` accordingly.

    Must be called before ``import drjit`` / ``import mitsuba``.
    """
    explicit = explicit or _settings().variant or None
    if explicit:
        check_variant_name(explicit)
    user_llvm = os.environ.get("DRJIT_LIBLLVM_PATH")
    if user_llvm == os.devnull:  # "no libLLVM", set by pbrbench (or the user): nothing to report
        user_llvm = None
    notes = []
    llvm_path = None
    if user_llvm:
        major = llvm_major(user_llvm)
        if major is not None and major >= MIN_LLVM:
            llvm_path = os.path.realpath(user_llvm)
        else:
            real = os.path.realpath(user_llvm)
            via = f" (a link to {real})" if real != os.path.abspath(user_llvm) and os.path.exists(real) else ""
            why = ("does not exist or is not a loadable libLLVM" if major is None
                   else f"is LLVM {major}{via}, older than {MIN_LLVM}")
            notes.append(f"DRJIT_LIBLLVM_PATH={user_llvm} {why}; ignoring it")
            os.environ.pop("DRJIT_LIBLLVM_PATH", None)
    if llvm_path is None:
        llvm_path, _ = find_llvm()
        llvm_path = os.path.realpath(llvm_path) if llvm_path else None
    if llvm_path is not None:
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm_path
    else:
        # drjit would otherwise pick up an old libLLVM by itself; point it at nothing usable.
        os.environ["DRJIT_LIBLLVM_PATH"] = os.devnull

    if explicit:
        if explicit.startswith("llvm") and llvm_path is None:
            raise UserError(
                f"variant {explicit!r} needs libLLVM >= {MIN_LLVM}, none found; install Debian's "
                "libllvm19 (apt-get install libllvm19) or choose --variant scalar_rgb"
            )
        if explicit.startswith("cuda") and not cuda_available():
            raise UserError(f"variant {explicit!r} needs a working CUDA device, none found; choose llvm_ad_rgb or scalar_rgb")
        return VariantChoice(explicit, llvm_path, "explicit", _notice(notes))
    if cuda_available():
        return VariantChoice("cuda_ad_rgb", llvm_path, "CUDA device found", _notice(notes))
    if llvm_path is not None:
        return VariantChoice("llvm_ad_rgb", llvm_path, f"libLLVM >= {MIN_LLVM} at {llvm_path}", _notice(notes))
    notes.append(
        f"no CUDA device and no libLLVM >= {MIN_LLVM}: rendering with scalar_rgb "
        "(slow); apt-get install libllvm19 for the fast LLVM variant"
    )
    return VariantChoice("scalar_rgb", None, "fallback", _notice(notes))


_STATE: dict = {}


def known_variants() -> list[str] | None:
    """The variants of the installed mitsuba build, read from its ``config.py`` without importing
    mitsuba (which would load drjit); None when that cannot be read."""
    import ast
    import importlib.machinery

    try:
        # the path finder, not importlib.util.find_spec: once mitsuba is imported, sys.modules holds
        # its variant alias module, whose spec has no package folder (and no config.py)
        spec = importlib.machinery.PathFinder.find_spec("mitsuba")
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    for d in spec.submodule_search_locations:
        cfg = os.path.join(d, "config.py")
        try:
            tree = ast.parse(open(cfg, encoding="utf-8").read())
        except (OSError, SyntaxError, ValueError):
            continue
        for node in tree.body:
            if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "MI_VARIANTS" for t in node.targets):
                try:
                    return [str(v) for v in ast.literal_eval(node.value)]
                except ValueError:
                    return None
    return None


def check_variant_name(name: str) -> str:
    """``name`` if the installed mitsuba has that variant, else a one-line UserError."""
    known = known_variants()
    if not isinstance(name, str) or not name or (known is not None and name not in known):
        rgb = [v for v in (known or RGB_VARIANTS) if v.endswith("_rgb")]
        raise UserError(f"--variant {name!r} (or PBRBENCH_VARIANT) is not a variant of this mitsuba build; choose one of "
                        f"{', '.join(rgb)}")
    return name


def mitsuba(variant: str | None = None):
    """Import mitsuba with a safely chosen variant (once per process) and return the module."""
    if "mi" in _STATE:
        if variant and variant != _STATE["choice"].variant:
            raise UserError(
                f"this process already renders with {_STATE['choice'].variant}; "
                f"run a new process for variant {variant!r}"
            )
        return _STATE["mi"]
    choice = choose_variant(variant)
    mi = _import_mitsuba()

    if choice.variant not in mi.variants():
        raise UserError(f"variant {choice.variant!r} is not in this mitsuba build; choose one of {', '.join(mi.variants())}")
    mi.set_variant(choice.variant)
    _STATE.update(mi=mi, choice=choice, appender=_route_logs(mi))
    return mi


def _route_logs(mi):
    """Send Mitsuba's log lines to stderr (prefixed ``pbrbench: mitsuba``, without colours), never to
    stdout, which carries only the results that scripts parse; its progress bars are dropped.
    Returns the appender (kept alive in ``_STATE``), or None where the logger cannot be reached."""
    try:
        logger = mi.logger() if hasattr(mi, "logger") else mi.Thread.thread().logger()
    except Exception:  # noqa: BLE001 - a build without the logger API: leave Mitsuba's default
        return None
    if logger is None:
        return None

    class StderrAppender(mi.Appender):
        def append(self, level, text):
            from pbrbench.errors import printable

            for line in str(text).splitlines() or [""]:
                print(f"pbrbench: mitsuba: {printable(line)}", file=sys.stderr, flush=True)

        def log_progress(self, progress, name, formatted, eta, ptr=None):
            pass

    appender = StderrAppender()
    logger.clear_appenders()
    logger.add_appender(appender)
    return appender


def _import_mitsuba():
    """``import mitsuba``; when pbrbench disabled libLLVM (``DRJIT_LIBLLVM_PATH=/dev/null``),
    drjit's own two lines about failing to load it are dropped: the notice of
    :func:`choose_variant` has said so once, in words that say what to do."""
    if os.environ.get("DRJIT_LIBLLVM_PATH") != os.devnull or "drjit" in sys.modules:
        import mitsuba as mi  # noqa: PLC0415 - must follow choose_variant

        return mi
    import tempfile

    with tempfile.TemporaryFile() as tmp:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(tmp.fileno(), 2)
        try:
            import mitsuba as mi  # noqa: PLC0415 - must follow choose_variant
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        text = tmp.read().decode("utf-8", "replace")
    for line in text.splitlines():
        if os.devnull in line or "jitc_llvm_init" in line:
            continue
        print(line, file=sys.stderr)
    return mi


def current_choice() -> VariantChoice | None:
    """The choice made by :func:`mitsuba` in this process, if any."""
    return _STATE.get("choice")
