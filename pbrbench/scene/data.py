"""Data files a scene reads (``.npy`` albedo images and height arrays), found and loaded safely.

A scene file names its data files by paths relative to its own directory.  Before any byte of
array data is read:

* the path is resolved (symbolic links followed) and must lie inside the scene file's directory,
  or inside a directory of the ``data_dirs`` setting (``PBRBENCH_DATA_DIRS``, paths separated by
  ``os.pathsep``): a scene file cannot make pbrbench read ``/etc/...`` or ``../../secret.npy``;
* the ``.npy`` header is parsed on its own: the dtype must be a real number type (never Python
  objects: nothing is unpickled), and the array it announces must fit :data:`MAX_DATA_BYTES` and
  the file's actual size, so a file that lies in its header cannot make pbrbench allocate
  terabytes.

Every error is a :class:`~pbrbench.errors.SceneError` whose one-line message names the scene
file, the key that points at the data file and the file as written, e.g.
``x.toml: shapes[0].path: data/h.npy: not a NumPy .npy file (it starts with b'1.0 2.0 '); save the
array with numpy.save``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from pbrbench.errors import SceneError
from pbrbench.memo import Memo

MAX_DATA_BYTES = 256 * 2**20   # largest array a scene data file may hold
MAX_HEIGHT = 1e6               # largest |height| of a height array (scene units, like positions)



class DataDir(str):
    """A scene file's directory (a ``str``: paths join as usual) that also carries ``extra``, the
    other directories its data files may lie in (the ``data_dirs`` setting the scene was loaded
    with: :attr:`pbrbench.scene.spec.SceneSpec.data_root`)."""

    extra: tuple[str, ...]

    def __new__(cls, base: str | os.PathLike, extra=()):
        s = super().__new__(cls, os.fspath(base))
        s.extra = tuple(str(x) for x in extra or ())
        return s


def data_roots(base_dir: str | os.PathLike, extra: tuple | list | None = None) -> list[Path]:
    """The directories a scene's data files may lie in: its own, and those of ``extra`` (else the
    ones ``base_dir`` carries, when it is a :class:`DataDir`; else none)."""
    if extra is None:
        extra = getattr(base_dir, "extra", ())
    roots = [Path(base_dir or ".").resolve()]
    roots += [Path(d).resolve() for d in extra if str(d)]
    return roots


def resolve_data_path(base_dir: str | os.PathLike, rel: str, *, where: str, extra_roots=None) -> Path:
    """The real path of the data file ``rel`` of a scene in ``base_dir``; SceneError (message
    prefixed with ``where``, e.g. ``"x.toml: shapes[0].path"``) when it is outside the allowed
    directories, missing or not a file."""
    if not isinstance(rel, str) or not rel.strip():
        raise SceneError(f"{where}: is empty; give the path of a .npy file relative to the scene file")
    if "\x00" in rel:
        raise SceneError(f"{where}: {rel!r} holds a NUL character; give a plain relative path")
    roots = data_roots(base_dir, extra_roots)
    p = Path(rel)
    try:
        real = (p if p.is_absolute() else roots[0] / p).resolve()
    except (OSError, RuntimeError) as exc:  # a symlink loop
        raise SceneError(f"{where}: {rel}: cannot be resolved ({exc}); give a plain relative path") from None
    if not any(real == r or real.is_relative_to(r) for r in roots):
        raise SceneError(
            f"{where}: {rel}: lies outside the scene file's directory {roots[0]}; data files must sit beside "
            "the scene (copy it there), or allow its directory with PBRBENCH_DATA_DIRS")
    if not real.exists():
        raise SceneError(f"{where}: {rel}: does not exist (looked for {real}); fix the path (it is relative to "
                         "the scene file)")
    if not real.is_file():
        raise SceneError(f"{where}: {rel}: is not a file ({real}); give the path of a .npy file")
    return real


def read_npy(path: str | os.PathLike, *, where: str, max_bytes: int | None = None) -> np.ndarray:
    """A real-valued array from the ``.npy`` file at ``path`` (:func:`pbrbench.io.read_npy`: no
    unpickling, the header checked against the file size and ``max_bytes`` first); a
    :class:`SceneError` naming ``where`` otherwise."""
    from pbrbench.io.images import read_npy as read

    try:
        return read(path, where=where, limit=MAX_DATA_BYTES if max_bytes is None else max_bytes,
                    what="a scene data file")
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def check_height(a: np.ndarray, *, where: str) -> np.ndarray:
    """A height array: 2-D, at least 2 x 2, finite and within :data:`MAX_HEIGHT`, as float64."""
    if a.ndim != 2:
        raise SceneError(f"{where}: a height array must be 2-D (rows, columns), got shape {a.shape}")
    if min(a.shape) < 2:
        raise SceneError(f"{where}: a height array must be at least 2 x 2, got shape {a.shape}")
    z = a.astype(np.float64)
    bad = ~np.isfinite(z)
    if bad.any():
        raise SceneError(f"{where}: {int(bad.sum())} non-finite height(s) (NaN or inf); replace them "
                         "(e.g. np.nan_to_num) before saving")
    if np.abs(z).max() > MAX_HEIGHT:
        raise SceneError(f"{where}: heights reach {np.abs(z).max():.3g}; they must be finite numbers >= "
                         f"{-MAX_HEIGHT:g} and <= {MAX_HEIGHT:g} (scene units)")
    return z


def check_texture(a: np.ndarray, *, where: str) -> np.ndarray:
    """An albedo image: (H, W) or (H, W, 3), finite, in [0, 1], as float32 (H, W, 3)."""
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] != 3:
        raise SceneError(f"{where}: an albedo image must be (H, W) or (H, W, 3), got shape {a.shape}")
    if a.shape[0] < 1 or a.shape[1] < 1:
        raise SceneError(f"{where}: an albedo image must have at least one pixel, got shape {a.shape}")
    x = a.astype(np.float64)
    bad = ~np.isfinite(x)
    if bad.any():
        raise SceneError(f"{where}: {int(bad.sum())} non-finite value(s) (NaN or inf); albedos are numbers in [0, 1]")
    if x.min() < 0 or x.max() > 1:
        raise SceneError(f"{where}: albedos must lie in [0, 1] (linear, energy conservation), got "
                         f"[{x.min():.3g}, {x.max():.3g}]")
    return x.astype(np.float32)


def load_data(base_dir: str | os.PathLike, rel: str, kind: str, *, where: str, extra_roots=None) -> np.ndarray:
    """Resolve, read and check one data file of a scene (``kind``: ``"height"`` or ``"texture"``)."""
    path = resolve_data_path(base_dir, rel, where=where, extra_roots=extra_roots)
    at = f"{where}: {rel}"
    a = read_npy(path, where=at)
    return check_height(a, where=at) if kind == "height" else check_texture(a, where=at)


_CHECKED = Memo("scene data files checked (largest |value| by real path, size, mtime, kind)", 256)


def check_data_file(base_dir: str | os.PathLike, rel: str, kind: str, *, where: str) -> float:
    """:func:`load_data` for validation: returns the largest absolute value; a file already checked
    (same real path, size and modification time) is not read again (a sweep shares its files)."""
    path = resolve_data_path(base_dir, rel, where=where)
    st = path.stat()
    key = (str(path), st.st_size, st.st_mtime_ns, kind)
    if key not in _CHECKED:
        a = load_data(base_dir, rel, kind, where=where)
        _CHECKED[key] = float(np.abs(a).max()) if a.size else 0.0
    return _CHECKED[key]
