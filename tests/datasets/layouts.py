"""Small data sets written in the published on-disk layouts (no download): DiLiGenT objects,
MIT Intrinsic Images objects and exposure brackets, built from analytic scenes so the right
answers are known."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pbrbench.io import write_png_exact
from pbrbench.shading.surfaces import on_grid

# Light directions like DiLiGenT's: a dome of unit vectors toward the lights (x right, y up, z
# toward the camera), none grazing
_DIRS = np.array([[0.0, 0.0, 1.0], [0.5, 0.0, 0.866], [-0.5, 0.0, 0.866], [0.0, 0.5, 0.866], [0.0, -0.5, 0.866],
                  [0.35, 0.35, 0.866], [-0.35, 0.35, 0.866], [0.35, -0.35, 0.866], [-0.35, -0.35, 0.866],
                  [0.6, 0.2, 0.775], [-0.2, 0.6, 0.775], [0.2, -0.6, 0.775]])
DIRS = _DIRS / np.linalg.norm(_DIRS, axis=1, keepdims=True)


def _write_text(path: Path, rows, *, crlf=False, fmt="{:.8f}"):
    nl = "\r\n" if crlf else "\n"
    path.write_text(nl.join(" ".join(fmt.format(v) for v in r) for r in rows) + nl, newline="")


def diligent_object(folder: Path, *, size=48, surface="sphere", normal_file="Normal_gt.mat", filenames=True,
                    crlf=False, mask_rgb=False, flip_normals_y=False, intensities=True, filters=(4, 1, 2, 3, 0),
                    column_major=False):
    """A Lambertian object in the DiLiGenT layout; returns (normals, mask, lights, intensities,
    true 16-bit images)."""
    folder.mkdir(parents=True, exist_ok=True)
    s = on_grid(surface, size, 1.05)
    n, mask = s.normals, s.mask
    rng = np.random.default_rng(1)
    ints = rng.uniform(0.6, 1.4, (len(DIRS), 3)) if intensities else np.ones((len(DIRS), 3))
    albedo = np.array([0.8, 0.6, 0.4])
    shading = np.clip(np.einsum("hwc,kc->khw", n, DIRS), 0, None) * mask
    imgs = shading[..., None] * albedo * ints[:, None, None, :]
    raw = np.clip(np.round(imgs * 40000), 0, 65535).astype(np.uint16)
    names = [f"{k + 1:03d}.png" for k in range(len(DIRS))]
    for k, name in enumerate(names):
        write_png_exact(folder / name, raw[k], filters=filters)
    if filenames:
        (folder / "filenames.txt").write_text("\n".join(names) + "\n")
    _write_text(folder / "light_directions.txt", DIRS, crlf=crlf)
    if intensities:
        _write_text(folder / "light_intensities.txt", ints, crlf=crlf)
    m8 = mask.astype(np.uint8) * 255
    write_png_exact(folder / "mask.png", np.repeat(m8[..., None], 3, -1) if mask_rgb else m8)
    ngt = n * mask[..., None]
    if flip_normals_y:
        ngt = ngt * np.array([1, -1, 1])
    if normal_file.endswith(".mat"):
        import scipy.io

        scipy.io.savemat(folder / normal_file, {"Normal_gt": ngt})
    elif normal_file.endswith(".txt"):
        rows = ngt.transpose(1, 0, 2).reshape(-1, 3) if column_major else ngt.reshape(-1, 3)
        _write_text(folder / normal_file, rows, crlf=crlf)
    elif normal_file.endswith(".npy"):
        np.save(folder / normal_file, ngt)
    return n, mask, DIRS, ints, raw


def mit_object(folder: Path, *, size=64, seed=0, mask_file=True):
    """A Mondrian-like object in the MIT layout: (reflectance RGB, shading grey, mask)."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size] / size
    cells = rng.uniform(0.2, 0.9, (4, 4, 3))
    refl = cells[(yy * 4).astype(int), (xx * 4).astype(int)]
    shading = 0.3 + 0.7 * np.clip(np.cos(2.0 * (xx - 0.4)) * np.cos(1.5 * (yy - 0.5)), 0, 1)
    mask = (xx - 0.5) ** 2 + (yy - 0.5) ** 2 < 0.2
    diffuse = refl * shading[..., None]
    q = lambda a: np.clip(np.round(a * 60000), 0, 65535).astype(np.uint16)  # noqa: E731
    write_png_exact(folder / "diffuse.png", q(diffuse))
    write_png_exact(folder / "reflectance.png", q(refl))
    write_png_exact(folder / "shading.png", q(shading))
    write_png_exact(folder / "original.png", q(diffuse))
    if mask_file:
        write_png_exact(folder / "mask.png", mask.astype(np.uint8) * 255)
    for k in range(1, 11):
        write_png_exact(folder / f"light{k:02d}.png", q(refl * (0.2 + 0.08 * k)))
    return refl, shading, mask


def bracket(folder: Path, *, times=(1 / 250, 1 / 60, 1 / 15, 1 / 4, 1.0), layout="times", size=24):
    """A bracket of a scene with a 1e3 dynamic range through a gamma-2.2 camera, 8-bit PNGs."""
    folder.mkdir(parents=True, exist_ok=True)
    ramp = 10 ** np.linspace(-1.5, 1.5, size)[None, :] * np.ones((size, 1))
    rad = ramp[..., None] * np.array([1.0, 0.8, 0.6])
    names = [f"exp_{i:02d}.png" for i in range(len(times))]
    for name, t in zip(names, times, strict=True):
        z = np.clip(rad * t * 4, 0, 1) ** (1 / 2.2)
        write_png_exact(folder / name, np.round(z * 255).astype(np.uint8))
    if layout == "times":
        (folder / "times.txt").write_text("\n".join(f"1/{round(1 / t)}" if t < 1 else f"{t}" for t in times) + "\n")
    elif layout == "named":
        (folder / "exposure_times.txt").write_text("\n".join(f"{n} {t!r}" for n, t in reversed(list(zip(names, times, strict=True)))))
    elif layout == "opencv":
        (folder / "list.txt").write_text("\n".join(f"{n} {1 / t!r}" for n, t in zip(names, times, strict=True)))
    elif layout == "hdrshop":
        rows = [f"{Path(n).stem}.ppm {1 / t!r} 8 1 0" for n, t in zip(names, times, strict=True)]
        (folder / "scene.hdr_image_list.txt").write_text("#Reconstruction Image List\n#Format: name 1/shutter f-stop gain ND\n"
                                                         f"{len(times)}\n" + "\n".join(rows) + "\n")
    return rad, names
