"""Atomic writes and small file helpers shared by the image modules.

Every writer of :mod:`pbrbench.io` is atomic: the data goes to a temporary file beside the
target, which is renamed over it only once complete, so a full disk or a kill mid-write never
leaves a partial file under the final name (:func:`atomic_path`).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from pathlib import Path

MAX_IMAGE_BYTES = 256 * 2**20
"""The largest decoded image (width x height x channels x bytes per sample) a reader allocates;
the data limit of a scene data file (:data:`pbrbench.scene.data.MAX_DATA_BYTES`, checked equal
by the tests).  Larger headers are refused before any pixel is decoded."""


class TooLarge(ValueError):
    """A header announcing more pixels than pbrbench decodes (one line naming the file and the fix)."""


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path`` (same suffix); on success it replaces ``path`` in
    one rename, on any error it is removed.  Errors (``OSError``) propagate unchanged.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.

    Yields
    ------
    pathlib.Path
        The temporary file to write instead.
    """
    p = Path(path)
    tmp = p.with_name(f".tmp-{os.getpid()}-{secrets.token_hex(3)}-{p.name}")
    try:
        yield tmp
        if not tmp.exists():
            raise OSError(f"{tmp}: the writer produced no file")
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns ``path``."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns ``path``."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)


def copy_file(src: str | os.PathLike, dst: str | os.PathLike) -> Path:
    """Copy ``src`` to ``dst`` atomically (``dst`` is whole or untouched); returns ``dst``."""
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)
        if os.path.getsize(tmp) != os.path.getsize(src):
            raise OSError(f"{dst}: copy is incomplete")
    return Path(dst)


def ensure_dir(p: str | os.PathLike) -> Path:
    """Create the directory ``p`` (and its parents) when missing; returns it as a ``Path``."""
    p = Path(p)
    p.mkdir(parents=True, exist_ok=True)
    return p


def fmt_bytes(n: float) -> str:
    """``n`` bytes in readable units (``"256.00 MiB"``)."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.2f} {unit}"
        n /= 1024
    return f"{n:.2f} PiB"  # pragma: no cover


def check_size(path, shape: tuple, itemsize: int, limit: int = MAX_IMAGE_BYTES) -> None:
    """Refuse a header announcing more than ``limit`` bytes of pixels, before anything is decoded.

    Parameters
    ----------
    path : str or os.PathLike
        The file, for the message.
    shape : tuple of int
        The declared (H, W[, C]) of the decoded array.
    itemsize : int
        Bytes per decoded sample.
    limit : int
        The largest number of bytes allowed.

    Raises
    ------
    TooLarge
        A ``ValueError``: one line naming the file, the declared size and the fix.
    """
    n = itemsize
    for s in shape:
        n *= int(s)
    if n > limit:
        dims = " x ".join(str(int(s)) for s in shape)
        raise TooLarge(f"{path}: its header announces {dims} samples ({fmt_bytes(n)} decoded), above the "
                         f"{fmt_bytes(limit)} pbrbench reads from one image; check the file or crop / downsample it")


@contextlib.contextmanager
def quiet_output():
    """Hold back what C libraries print on file descriptors 1 and 2 (OpenEXR's decoder reports a
    damaged file there before raising) so that a user sees one line.

    Yields
    ------
    list of str
        Receives, on exit, the first line held back from descriptor 2 (else from 1).

    Notes
    -----
    Does nothing where the descriptors cannot be redirected.
    """
    import sys
    import tempfile

    held: list[str] = []
    try:
        for s in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                s.flush()
        saved = {fd: os.dup(fd) for fd in (1, 2)}
    except (OSError, ValueError, AttributeError):
        yield held
        return
    import io

    py_out, py_err = io.StringIO(), io.StringIO()     # what bindings print through Python's streams
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        os.dup2(out.fileno(), 1)
        os.dup2(err.fileno(), 2)
        try:
            with contextlib.redirect_stdout(py_out), contextlib.redirect_stderr(py_err):
                yield held
        finally:
            for fd, s in saved.items():
                os.dup2(s, fd)
                os.close(s)
            for f in (err, out):
                f.seek(0)
                texts = [f.read(4000).decode("utf-8", "replace")] + [py_err.getvalue() if f is err else py_out.getvalue()]
                text = "\n".join(t.strip() for t in texts if t.strip())
                if text and not held:
                    held.append(" ".join(text.splitlines()[0].split()))
