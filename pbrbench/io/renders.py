"""The public loader of renders written by ``pbrbench render --out DIR`` (:func:`load_render`)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from pbrbench.io.exr import read_exr


class Render:
    """A render written by ``pbrbench render --out DIR``: the EXR's named arrays and the JSON's
    metadata (lights and camera in the camera frame, units, noise).

    ``render["radiance"]`` is an (H, W, 3) float32 array; ``light_vectors`` the (K, 3) source
    vectors of the light set (direction toward the source in the camera frame x irradiance, the
    ``lights`` argument of :func:`pbrbench.infer.photometric_stereo.photometric_stereo`) or None;
    ``light_stack(kind)`` the (K, H, W, 3) per-light images; ``mask`` the pure-pixel mask.
    """

    def __init__(self, arrays: dict[str, np.ndarray], meta: dict, path: Path | None = None):
        self.arrays = arrays
        self.meta = meta
        self.path = path

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.arrays[name]
        except KeyError:
            raise KeyError(f"render has no {name!r}; it has {', '.join(sorted(self.arrays))}") from None

    def __contains__(self, name: str) -> bool:
        return name in self.arrays

    def keys(self):
        return self.arrays.keys()

    @property
    def mask(self) -> np.ndarray:
        return self.arrays["mask"] > 0.5

    @property
    def lights(self) -> list[dict]:
        """The light set (one dict per ``lightNN`` image; see ``pbrbench render --help``)."""
        return list(self.meta.get("light_set") or [])

    @property
    def light_vectors(self) -> np.ndarray | None:
        v = self.meta.get("light_vectors")
        return None if v is None else np.asarray(v, np.float64)

    @property
    def camera(self) -> dict:
        return dict(self.meta.get("camera") or {})

    def light_stack(self, kind: str = "radiance") -> np.ndarray:
        """(K, H, W, 3) images of the light set, one light at a time (``kind``: radiance or direct)."""
        n = len(self.lights) or sum(1 for k in self.arrays if k.endswith(f".{kind}") and k.startswith("light"))
        return np.stack([self[f"light{k:02d}.{kind}"] for k in range(n)])

    def __repr__(self) -> str:
        return f"Render({self.meta.get('scene', '?')!r}, {len(self.arrays)} arrays)"


def load_render(path: str | os.PathLike) -> Render:
    """Load a render written by ``pbrbench render --out DIR``: ``path`` is the scene's folder, its
    ``gt.exr`` or its ``gt.json``.  Returns a :class:`Render` (arrays + metadata); a missing or
    unreadable file raises ``ValueError`` naming it."""
    import json

    p = Path(path)
    folder = p if p.is_dir() else p.parent
    exr, js = folder / "gt.exr", folder / "gt.json"
    for f in (exr, js):
        if not f.is_file():
            raise ValueError(f"{f}: missing; pass a folder written by `pbrbench render SCENE --out DIR`")
    try:
        meta = json.loads(js.read_text())
    except ValueError as e:
        raise ValueError(f"{js}: not valid JSON ({e})") from None
    return Render(read_exr(exr), meta, folder)
