r"""A height field on the image grid of an orthographic camera (NumPy only).

The surface is a triangle mesh whose vertices sit at the **pixel corners** of the camera's film:
corner ``(i, j)`` (``i = 0..H`` rows from the top, ``j = 0..W`` columns from the left) lies at
film-plane coordinates ``x_j = -w + j h``, ``y_i = w H / W - i h`` (``w`` the camera's half width,
``h = 2 w / W`` the pixel size) and height ``z_ij`` along the camera's axis toward the camera, so
pixel ``(i, j)`` sees exactly one quad, split into the triangles ``(a, c, b)`` and ``(b, c, d)``
with ``a, b, c, d`` its top-left, top-right, bottom-left and bottom-right corners.  With face
normals the rendered pixel (box filter) is the mean of its two triangles' shading, and the
pixel's normal is the normalised mean of their unit normals

.. math::  n_{1,2} = \frac{(-p_{1,2}, -q_{1,2}, 1)}{\sqrt{1 + p_{1,2}^2 + q_{1,2}^2}}, \quad
           p_1 = \frac{z_b - z_a}{h},\; q_1 = \frac{z_a - z_c}{h},\;
           p_2 = \frac{z_d - z_c}{h},\; q_2 = \frac{z_b - z_d}{h}.

Three pixel sets (:func:`pixel_sets`): the *data* pixels (the object mask, with gaps of up to two
pixels closed where the images are lit: e.g. the crease of a groove, where the mask leaves out
the pixels on the boundary between two faces) enter the image loss; the *surface* pixels (data
plus a one-pixel ring of lit pixels around it: partially covered pixels at the silhouette) carry
mesh quads but no loss; and where the surface reaches the film border it is continued beyond the
frame (:class:`HeightField`, ``extend``) by one ring of quads whose outer vertices are the linear
extrapolation of the border slope (the surface assumed to continue as its tangent plane).

Every height of the mesh is a linear function ``A z`` of the free heights ``z`` (the corners of
surface quads inside the frame), so a gradient with respect to the mesh's heights maps back as
``A^T g``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


def _close(mask: np.ndarray, radius: int = 1) -> np.ndarray:
    """Binary closing with a (2r+1)^2 square, the image border treated as edge-replicated."""
    from scipy.ndimage import binary_dilation, binary_erosion

    s = np.ones((2 * radius + 1, 2 * radius + 1), bool)
    pad = radius + 1
    m = np.pad(mask, pad, mode="edge")
    m = binary_erosion(binary_dilation(m, s), s, border_value=1)
    return m[pad:-pad, pad:-pad]


def pixel_sets(mask: np.ndarray, images: np.ndarray, *, lit: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """``(data, surface)`` pixel sets of an object mask (see the module docstring).

    A pixel is *lit* when its brightest image exceeds ``lit`` times the brightest pixel of the
    mask; gaps closed in the mask and the silhouette ring must be lit (background is black).
    """
    from scipy.ndimage import binary_dilation

    peak = float(images[:, mask].max()) if mask.any() else 0.0
    bright = images.max(axis=0) > lit * max(peak, 1e-30)
    data = mask | (_close(mask) & bright)
    ring = binary_dilation(data, np.ones((3, 3), bool)) & ~data & bright
    return data, data | ring


def downsample_mask(m: np.ndarray, f: int) -> np.ndarray:
    """A coarse pixel is in the set when all its ``f x f`` fine pixels are."""
    h, w = m.shape
    return m[: h // f * f, : w // f * f].reshape(h // f, f, w // f, f).all(axis=(1, 3))


def downsample_any(m: np.ndarray, f: int) -> np.ndarray:
    """A coarse pixel is in the set when any of its ``f x f`` fine pixels is."""
    h, w = m.shape
    return m[: h // f * f, : w // f * f].reshape(h // f, f, w // f, f).any(axis=(1, 3))


def downsample_images(images: np.ndarray, f: int) -> np.ndarray:
    """(K, H/f, W/f) box averages: what a box-filtered film of 1/f the resolution records."""
    k, h, w = images.shape
    return images[:, : h // f * f, : w // f * f].reshape(k, h // f, f, w // f, f).mean(axis=(2, 4))


def upsample_corners(z: np.ndarray, f: int) -> np.ndarray:
    """Bilinear interpolation of a corner grid ``(h+1, w+1)`` to ``(f h + 1, f w + 1)``."""
    h, w = z.shape[0] - 1, z.shape[1] - 1
    t = np.arange(f * h + 1) / f
    s = np.arange(f * w + 1) / f
    i0 = np.minimum(np.floor(t).astype(int), h - 1)
    j0 = np.minimum(np.floor(s).astype(int), w - 1)
    ti, sj = (t - i0)[:, None], (s - j0)[None, :]
    z00, z01 = z[i0][:, j0], z[i0][:, j0 + 1]
    z10, z11 = z[i0 + 1][:, j0], z[i0 + 1][:, j0 + 1]
    return (1 - ti) * ((1 - sj) * z00 + sj * z01) + ti * ((1 - sj) * z10 + sj * z11)


def triangle_gradients(zc: np.ndarray, h: float):
    """``(p1, q1, p2, q2)``, each (H, W): the slopes of the two triangles of every pixel quad of
    the corner heights ``zc`` (H+1, W+1)."""
    a, b, c, d = zc[:-1, :-1], zc[:-1, 1:], zc[1:, :-1], zc[1:, 1:]
    return (b - a) / h, (a - c) / h, (d - c) / h, (b - d) / h


def pixel_normals(zc: np.ndarray, h: float) -> np.ndarray:
    """(H, W, 3) unit normals (camera frame) of the pixel quads: the normalised mean of the two
    triangles' unit normals (module docstring)."""
    p1, q1, p2, q2 = triangle_gradients(zc, h)
    n1 = np.stack([-p1, -q1, np.ones_like(p1)], -1)
    n2 = np.stack([-p2, -q2, np.ones_like(p2)], -1)
    n = n1 / np.linalg.norm(n1, axis=-1, keepdims=True) + n2 / np.linalg.norm(n2, axis=-1, keepdims=True)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def pixel_heights(zc: np.ndarray) -> np.ndarray:
    """(H, W) height of each pixel quad's centre (mean of its corners)."""
    return 0.25 * (zc[:-1, :-1] + zc[:-1, 1:] + zc[1:, :-1] + zc[1:, 1:])


def thin_plate_matrix(hf: HeightField) -> sp.csr_matrix:
    r"""Sparse ``D`` with ``D z`` the dimensionless second differences of the free heights:
    ``(z_{i,j-1} - 2 z_{ij} + z_{i,j+1}) / h`` and ``(z_{i-1,j} - 2 z_{ij} + z_{i+1,j}) / h`` at every
    corner whose two neighbours along that axis are free (the change of slope across the corner),
    and ``sqrt(2) (z_a + z_d - z_b - z_c) / h`` for every surface quad (its twist: the slope
    difference of its two triangles).  ``|D z|^2`` is the discrete thin-plate energy
    ``z_xx^2 + 2 z_xy^2 + z_yy^2``, zero for planes, and its Euler-Lagrange equation
    ``\Delta^2 z = 0`` holds for every quadratic surface: a smoothness prior that biases creases
    and the rims of strongly curved parts but neither planes nor paraboloids."""
    h, idx, act = hf.h, hf.param_index, hf.active
    rows, cols, vals = [], [], []
    n = 0
    for di, dj in ((0, 1), (1, 0)):
        i0, j0 = np.nonzero(act)
        i1, j1 = i0 - di, j0 - dj
        i2, j2 = i0 + di, j0 + dj
        ok = (i1 >= 0) & (j1 >= 0) & (i2 <= hf.H) & (j2 <= hf.W)
        i0, j0, i1, j1, i2, j2 = i0[ok], j0[ok], i1[ok], j1[ok], i2[ok], j2[ok]
        ok = act[i1, j1] & act[i2, j2]
        i0, j0, i1, j1, i2, j2 = i0[ok], j0[ok], i1[ok], j1[ok], i2[ok], j2[ok]
        k = np.arange(len(i0)) + n
        rows += [k, k, k]
        cols += [idx[i1, j1], idx[i0, j0], idx[i2, j2]]
        vals += [np.full(len(k), 1 / h), np.full(len(k), -2 / h), np.full(len(k), 1 / h)]
        n += len(i0)
    qi, qj = np.nonzero(hf.surface)
    k = np.arange(len(qi)) + n
    r2 = np.sqrt(2.0) / h
    rows += [k, k, k, k]
    cols += [idx[qi, qj], idx[qi + 1, qj + 1], idx[qi, qj + 1], idx[qi + 1, qj]]
    vals += [np.full(len(k), r2), np.full(len(k), r2), np.full(len(k), -r2), np.full(len(k), -r2)]
    n += len(qi)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n, hf.n_params))


@dataclass
class HeightField:
    """The mesh topology of a height field on an ``H x W`` film (see the module docstring).

    ``surface`` (H, W): pixels that carry a quad; ``extend`` = (left, right, top, bottom) world
    distances by which the surface continues beyond the frame (0: not at all; only where the
    surface reaches that border).  ``half_width``: the camera's; heights are along its axis.
    """

    surface: np.ndarray
    half_width: float
    extend: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    def __post_init__(self):
        self.surface = np.asarray(self.surface, bool)
        H, W = self.surface.shape
        self.H, self.W = H, W
        self.h = 2.0 * self.half_width / W
        corner = np.zeros((H + 1, W + 1), bool)
        s = self.surface
        corner[:-1, :-1] |= s
        corner[:-1, 1:] |= s
        corner[1:, :-1] |= s
        corner[1:, 1:] |= s
        self.active = corner                       # free heights: corners of surface quads
        self.param_index = -np.ones((H + 1, W + 1), int)
        self.param_index[corner] = np.arange(int(corner.sum()))
        self.n_params = int(corner.sum())
        self._build()

    # ------------------------------------------------------------------ coordinates
    def corner_xy(self) -> tuple[np.ndarray, np.ndarray]:
        """Film-plane coordinates (x, y) of the corner grid (H+1, W+1)."""
        xs = -self.half_width + self.h * np.arange(self.W + 1)
        ys = self.half_width * self.H / self.W - self.h * np.arange(self.H + 1)
        return np.meshgrid(xs, ys)

    def corners(self, z: np.ndarray, fill: float = 0.0) -> np.ndarray:
        """The free heights ``z`` (n_params,) on the corner grid (H+1, W+1); ``fill`` elsewhere."""
        zc = np.full((self.H + 1, self.W + 1), float(fill))
        zc[self.active] = z
        return zc

    def params_from_corners(self, zc: np.ndarray) -> np.ndarray:
        return np.asarray(zc, float)[self.active]

    # ------------------------------------------------------------------ mesh
    def _build(self):
        H, W, h = self.H, self.W, self.h
        el, er, et, eb = (float(e) for e in self.extend)
        s = self.surface
        el = el if el > 0 and s[:, 0].any() else 0.0
        er = er if er > 0 and s[:, -1].any() else 0.0
        et = et if et > 0 and s[0, :].any() else 0.0
        eb = eb if eb > 0 and s[-1, :].any() else 0.0
        self.extend_used = (el, er, et, eb)
        # extended corner grid: optional extra line on each side
        ol, ot = int(el > 0), int(et > 0)
        He, We = H + ot + int(eb > 0), W + ol + int(er > 0)
        xs = -self.half_width + h * np.arange(W + 1)
        ys = self.half_width * H / W - h * np.arange(H + 1)
        if el > 0:
            xs = np.concatenate([[xs[0] - el], xs])
        if er > 0:
            xs = np.concatenate([xs, [xs[-1] + er]])
        if et > 0:
            ys = np.concatenate([[ys[0] + et], ys])
        if eb > 0:
            ys = np.concatenate([ys, [ys[-1] - eb]])
        # quads of the extended grid
        quads = np.zeros((He, We), bool)
        quads[ot:ot + H, ol:ol + W] = s
        if et > 0:
            quads[0, ol:ol + W] = s[0]
        if eb > 0:
            quads[-1, ol:ol + W] = s[-1]
        if el > 0:
            quads[ot:ot + H, 0] = s[:, 0]
        if er > 0:
            quads[ot:ot + H, -1] = s[:, -1]
        if el > 0 and et > 0:
            quads[0, 0] = s[0, 0]
        if er > 0 and et > 0:
            quads[0, -1] = s[0, -1]
        if el > 0 and eb > 0:
            quads[-1, 0] = s[-1, 0]
        if er > 0 and eb > 0:
            quads[-1, -1] = s[-1, -1]
        used = np.zeros((He + 1, We + 1), bool)
        used[:-1, :-1] |= quads
        used[:-1, 1:] |= quads
        used[1:, :-1] |= quads
        used[1:, 1:] |= quads
        # heights of the extended grid as sparse rows over the free heights: in-frame corners are
        # themselves; extension rows/columns extrapolate the border slope linearly
        rows: dict[tuple[int, int], dict[int, float]] = {}
        for i, j in zip(*np.nonzero(self.active), strict=True):
            rows[(i + ot, j + ol)] = {int(self.param_index[i, j]): 1.0}

        def combo(r0, r1, t):  # (1 + t) r0 - t r1 (r1 may be missing: constant continuation)
            if r1 is None:
                return dict(r0)
            out = {k: (1 + t) * v for k, v in r0.items()}
            for k, v in r1.items():
                out[k] = out.get(k, 0.0) - t * v
            return out

        if et > 0:
            for j in range(ol, ol + W + 1):
                if (1, j) in rows:
                    rows[(0, j)] = combo(rows[(1, j)], rows.get((2, j)), et / h)
        if eb > 0:
            for j in range(ol, ol + W + 1):
                if (He - 1, j) in rows:
                    rows[(He, j)] = combo(rows[(He - 1, j)], rows.get((He - 2, j)), eb / h)
        if el > 0:
            for i in range(He + 1):
                if (i, 1) in rows:
                    rows[(i, 0)] = combo(rows[(i, 1)], rows.get((i, 2)), el / h)
        if er > 0:
            for i in range(He + 1):
                if (i, We - 1) in rows:
                    rows[(i, We)] = combo(rows[(i, We - 1)], rows.get((i, We - 2)), er / h)
        vid = -np.ones((He + 1, We + 1), int)
        verts = [ij for ij in zip(*np.nonzero(used), strict=True)]
        data_i, data_j, data_v = [], [], []
        for n, ij in enumerate(verts):
            vid[ij] = n
            for k, v in rows[(int(ij[0]), int(ij[1]))].items():
                data_i.append(n)
                data_j.append(k)
                data_v.append(v)
        self.A = sp.csr_matrix((data_v, (data_i, data_j)), shape=(len(verts), self.n_params))
        vi = np.array([ij[0] for ij in verts])
        vj = np.array([ij[1] for ij in verts])
        self.vertex_xy = np.stack([xs[vj], ys[vi]], -1)
        a, b, c, d = vid[:-1, :-1][quads], vid[:-1, 1:][quads], vid[1:, :-1][quads], vid[1:, 1:][quads]
        self.faces = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)]).astype(np.int32)
        # texture coordinates: the film rectangle is [0, 1]^2 (texture row 0 = bottom row)
        x0, y1 = -self.half_width, self.half_width * H / W
        u = (self.vertex_xy[:, 0] - x0) / (W * h)
        v = (self.vertex_xy[:, 1] - (y1 - H * h)) / (H * h)
        self.uv = np.stack([u, v], -1)

    def vertex_heights(self, z: np.ndarray) -> np.ndarray:
        """Heights of every mesh vertex (n_vertices,) from the free heights."""
        return self.A @ z

    def laplacian(self) -> sp.csr_matrix:
        """Combinatorial graph Laplacian of the free heights (edges of surface quads)."""
        s = self.surface
        idx = self.param_index
        e = set()
        for i, j in zip(*np.nonzero(s), strict=True):
            a, b, c, d = idx[i, j], idx[i, j + 1], idx[i + 1, j], idx[i + 1, j + 1]
            for u, v in ((a, b), (c, d), (a, c), (b, d)):
                e.add((min(u, v), max(u, v)))
        e = np.array(sorted(e), int).reshape(-1, 2)
        n = self.n_params
        adj = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
        adj = (adj + adj.T).tocsr()
        return (sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj).tocsr()


def heights_from_normals(normals: np.ndarray, valid: np.ndarray, hf: HeightField, *,
                         regularisation: float = 1e-3, min_nz: float = 0.05) -> np.ndarray:
    r"""Free corner heights whose triangles best match a normal field (least squares).

    Each valid pixel gives four equations, its two triangles' slopes against the normal's
    ``p = -n_x / n_z``, ``q = -n_y / n_z`` (``n_z`` clipped at ``min_nz``), which also removes the
    checkerboard mode that a pixel-mean slope would leave free; a weak second-difference term
    (weight ``regularisation``, along rows and columns) continues the surface linearly over the
    pixels without a valid normal; the mean height is 0.
    """
    h, idx = hf.h, hf.param_index
    nz = np.maximum(normals[..., 2], min_nz)
    p, q = -normals[..., 0] / nz, -normals[..., 1] / nz
    ok = valid & hf.surface
    ii, jj = np.nonzero(ok)
    a, b, c, d = idx[ii, jj], idx[ii, jj + 1], idx[ii + 1, jj], idx[ii + 1, jj + 1]
    m = len(ii)
    r = np.arange(m)
    rows = [r, r, r + m, r + m, r + 2 * m, r + 2 * m, r + 3 * m, r + 3 * m]
    cols = [b, a, a, c, d, c, b, d]
    vals = [1 / h, -1 / h] * 4
    rhs = [p[ok], q[ok], p[ok], q[ok]]
    A = sp.coo_matrix((np.concatenate([np.full(m, v) for v in vals]), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(4 * m, hf.n_params)).tocsr()
    b_vec = np.concatenate(rhs)
    # second differences along rows and columns over active corners
    act = hf.active
    regs = []
    for di, dj in ((0, 1), (1, 0)):
        i0, j0 = np.nonzero(act)
        i1, j1, i2, j2 = i0 + di, j0 + dj, i0 + 2 * di, j0 + 2 * dj
        inb = (i2 <= hf.H) & (j2 <= hf.W)
        i0, j0, i1, j1, i2, j2 = i0[inb], j0[inb], i1[inb], j1[inb], i2[inb], j2[inb]
        keep = act[i1, j1] & act[i2, j2]
        i0, j0, i1, j1, i2, j2 = i0[keep], j0[keep], i1[keep], j1[keep], i2[keep], j2[keep]
        k = len(i0)
        rr = np.arange(k)
        regs.append(sp.coo_matrix((np.concatenate([np.ones(k), -2 * np.ones(k), np.ones(k)]) / h,
                                   (np.concatenate([rr, rr, rr]),
                                    np.concatenate([idx[i0, j0], idx[i1, j1], idx[i2, j2]]))),
                                  shape=(k, hf.n_params)))
    R = sp.vstack(regs).tocsr()
    w = float(regularisation) * max(m, 1) / max(R.shape[0], 1)
    N = (A.T @ A + w * (R.T @ R)).tocsc()
    # the constant (one per connected part) is free: a tiny ridge fixes it at mean zero
    N = N + 1e-9 * float(N.diagonal().mean()) * sp.identity(hf.n_params, format="csc")
    from scipy.sparse.linalg import spsolve

    z = spsolve(N, A.T @ b_vec)
    return z - z.mean()
