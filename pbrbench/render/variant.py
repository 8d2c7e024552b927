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

The LLVM version is read from the file name (``libLLVM-15.so.1``, ``libLLVM.so.19.1``) or,
when the name has no version, from ``LLVMGetVersion`` (which exists only since LLVM 16) in a
short subprocess, so no unsuitable libLLVM is ever loaded into this process.
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
    """Major LLVM version encoded in a library file name, or None if the name has none."""
    for candidate in (os.path.basename(path), os.path.basename(os.path.realpath(path))):
        m = re.search(r"libLLVM[-.]?(\d+)", candidate)
        if m:
            return int(m.group(1))
        m = re.search(r"libLLVM\.so\.(\d+)", candidate)
        if m:
            return int(m.group(1))
    return None


_PROBE = (
    "import ctypes,sys\n"
    "lib=ctypes.CDLL(sys.argv[1])\n"
    "f=getattr(lib,'LLVMGetVersion',None)\n"
    "if f is None: print(0); raise SystemExit\n"
    "a,b,c=ctypes.c_uint(),ctypes.c_uint(),ctypes.c_uint()\n"
    "f(ctypes.byref(a),ctypes.byref(b),ctypes.byref(c)); print(a.value)\n"
)


def llvm_major(path: str) -> int | None:
    """Major version of the libLLVM at ``path`` (None if it cannot be loaded).

    A library without ``LLVMGetVersion`` is older than LLVM 16 and reported as 0.
    """
    if not os.path.isfile(path):
        return None
    major = llvm_major_from_name(path)
    if major is not None:
        return major
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE, path], capture_output=True, text=True, timeout=30)
        return int(out.stdout.strip()) if out.returncode == 0 else None
    except (subprocess.SubprocessError, ValueError, OSError):
        return None


_PREFERRED: dict = {}


def configure(settings) -> None:
    """Use ``settings`` (variant, llvm_search, no_cuda) for this process's variant choice; call it
    before the first render (the command line does, with the settings it resolved)."""
    _PREFERRED["settings"] = settings


def _settings():
    s = _PREFERRED.get("settings")
    if s is None:
        from pbrbench.settings import Settings

        s = Settings.from_env()
    return s


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


def choose_variant(explicit: str | None = None) -> VariantChoice:
    """Decide the Mitsuba variant and set ``DRJIT_LIBLLVM_PATH`` accordingly.

    Must be called before ``import drjit`` / ``import mitsuba``.
    """
    explicit = explicit or _settings().variant or None
    user_llvm = os.environ.get("DRJIT_LIBLLVM_PATH")
    notes = []
    llvm_path = None
    if user_llvm:
        major = llvm_major(user_llvm)
        if major is not None and major >= MIN_LLVM:
            llvm_path = user_llvm
        else:
            why = "does not exist" if major is None else f"is LLVM {major}, older than {MIN_LLVM}"
            notes.append(f"DRJIT_LIBLLVM_PATH={user_llvm} {why}; ignoring it")
            os.environ.pop("DRJIT_LIBLLVM_PATH", None)
    if llvm_path is None:
        llvm_path, _ = find_llvm()
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
        return VariantChoice(explicit, llvm_path, "explicit", "; ".join(notes) or None)
    if cuda_available():
        return VariantChoice("cuda_ad_rgb", llvm_path, "CUDA device found", "; ".join(notes) or None)
    if llvm_path is not None:
        return VariantChoice("llvm_ad_rgb", llvm_path, f"libLLVM >= {MIN_LLVM} at {llvm_path}", "; ".join(notes) or None)
    notes.append(
        f"pbrbench: no CUDA device and no libLLVM >= {MIN_LLVM}: rendering with scalar_rgb "
        "(slow); apt-get install libllvm19 for the fast LLVM variant"
    )
    return VariantChoice("scalar_rgb", None, "fallback", "; ".join(notes))


_STATE: dict = {}


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
    if choice.notice:
        print(choice.notice, file=sys.stderr)
    import mitsuba as mi  # noqa: PLC0415 - must follow choose_variant

    if choice.variant not in mi.variants():
        raise UserError(f"variant {choice.variant!r} is not in this mitsuba build; choose one of {', '.join(mi.variants())}")
    mi.set_variant(choice.variant)
    _STATE.update(mi=mi, choice=choice)
    return mi


def current_choice() -> VariantChoice | None:
    """The choice made by :func:`mitsuba` in this process, if any."""
    return _STATE.get("choice")
