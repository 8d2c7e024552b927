r"""Facet interreflection kernel of a Lambertian height field (private to :mod:`.nayar1991`).

The surface seen orthographically is cut into facets, ``block`` x ``block`` pixel blocks; the
geometry is in pixel units (x right, y up, z toward the camera, ``docs/conventions.md``).  A
pixel of unit normal ``N`` is a planar patch of area ``1 / N_z`` (its footprint is one pixel);
a facet sums its pixels' vector areas,

.. math:: \mathbf a_J = \sum_{p \in J} \frac{N_p}{N_{z,p}} = \sum_{p \in J} (-f_x, -f_y, 1)_p,
    \qquad A_J = |\mathbf a_J|, \quad n_J = \mathbf a_J / A_J,

sits at the centroid of its pixels, at the height of the facet gradients integrated by
:func:`pbrbench.infer.integration.integrate_lsq`, and has the mean radiance of its pixels.
Between two facets (``d = x_J - x_I``) the Lambertian transport is

.. math:: K_{IJ} = \frac{\max(0, n_I \cdot d)\,\max(0, -n_J \cdot d)}{\pi\,|d|^4}\, A_J,
    \qquad L_I = L^{\mathrm{local}}_I + \rho_I \sum_J K_{IJ} L_J,

the radiance form (``L = B / pi``) of the radiosity equation ``B_I = E_I + rho_I sum_J F_IJ B_J``
with the point form factor ``F_IJ = cos(theta_I) cos(theta_J) A_J / (pi r^2)`` (Goral, Torrance,
Greenberg & Battaile, "Modeling the interaction of light between diffuse surfaces", SIGGRAPH
1984; Nayar, Ikeuchi & Kanade, "Shape from interreflections", IJCV 6(3), 1991).  The kernel is
scale invariant (``A_J / |d|^2`` and the cosines do not change when the scene is scaled), so it
needs no pixel size: pixel units are exact.

Visibility: two facets exchange light when each lies in front of the other (the two cosine
tests); occlusion by a third part of the surface is ignored.  That is exact for a concave
surface (the segment between two of its points lies above it) and for a convex one (no facet
lies in front of another: the kernel vanishes), an approximation in between.

Outside the image: where the mask touches an image border and the surface crosses it unchanged
(in the strip of ``CONT_PIXELS`` next to the border, the mean normals of its outer and inner
halves agree within ``INVARIANCE_DEG`` and the outer half's slope across the border is below
that angle: a groove or cylinder whose axis crosses the border, a level plane) the border facets
are continued by translation, ``pad`` times the facet grid deep; elsewhere the surface ends at
the border and at the mask's edge (nothing outside reflects light).

The interreflected term of a facet is brought back to the pixels by bilinear interpolation
between the four nearest facet centres, each weight multiplied by ``max(0, N_p . n_J)^16`` so
that a pixel takes no light from facets of another face across a crease (joint bilateral
upsampling; Kopf, Cohen, Lischinski & Uyttendaele, "Joint bilateral upsampling", SIGGRAPH
2007).  :func:`interreflect` is the forward model with exactly this discretisation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

MIN_NZ = 0.05        # pixels steeper than ~87 deg count as this steep (area 1 / N_z capped at 20)
SIMILARITY_POWER = 16  # exponent of the normal-similarity weight of the upsampling
CONT_PIXELS = 16       # depth (pixels) of the strip next to a border that must be invariant for it to continue
INVARIANCE_DEG = 2.0   # tolerance of that invariance (normal change and slope across the border)
_CHUNK_PAIRS = 65_536  # receiver x source pairs per block of the kernel (temporaries of 512 kB)


@dataclass
class Facets:
    """Facets of a height field and the sparse maps between them and the pixels.

    ``pos`` (n, 3), ``normal`` (n, 3), ``area`` (n,): the kept facets (in pixel units);
    ``src_pos``, ``src_normal``, ``src_area`` (n_s, 3/3/1): the sources, the kept facets followed
    by their continuation beyond the image borders; ``src_of`` (n_s,): the kept facet whose
    radiance each source carries (a continued facet carries its border facet's); ``average``
    (n, n_pix) sparse: the block mean over the used pixels; ``spread`` (n_pix, n) sparse: the
    upsampling to the used pixels; ``pix`` (n_pix,): flat indices of the used pixels; ``grid``:
    the facet grid's shape.
    """

    pos: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    src_pos: np.ndarray
    src_normal: np.ndarray
    src_area: np.ndarray
    src_of: np.ndarray
    average: sparse.csr_matrix
    spread: sparse.csr_matrix
    pix: np.ndarray
    grid: tuple[int, int]

    @property
    def n(self) -> int:
        return self.pos.shape[0]


def _block_sum(a, hb, wb, b):
    h, w = a.shape
    full = np.zeros((hb * b, wb * b))
    full[:h, :w] = a
    return full.reshape(hb, b, wb, b).sum(axis=(1, 3))


def build_facets(normals, used, block: int, pad: float) -> Facets:
    """Facets of the surface whose unit normals on the pixels ``used`` are ``normals``.

    ``normals`` (H, W, 3), ``used`` (H, W) bool, ``block`` pixels per facet side, ``pad`` the
    depth of the continuation beyond an image border as a fraction of the facet grid (module
    docstring).
    """
    from pbrbench.infer.integration import integrate_lsq

    h, w = used.shape
    b = int(block)
    hb, wb = -(-h // b), -(-w // b)
    rows, cols = np.mgrid[0:h, 0:w]
    x_pix = cols + 0.5
    y_pix = -(rows + 0.5)
    nz = np.maximum(normals[..., 2], MIN_NZ)
    ok = used & (normals[..., 2] > 0)
    slope = [np.where(ok, normals[..., i] / nz, 0.0) for i in range(2)]   # -f_x, -f_y
    cnt = _block_sum(ok.astype(float), hb, wb, b)
    keep = cnt > 0
    c = np.maximum(cnt, 1.0)
    va = np.stack([_block_sum(slope[0], hb, wb, b), _block_sum(slope[1], hb, wb, b), cnt], axis=-1)
    xc = _block_sum(np.where(ok, x_pix, 0.0), hb, wb, b) / c
    yc = _block_sum(np.where(ok, y_pix, 0.0), hb, wb, b) / c
    # facet slopes f_x = -a_x / a_z, f_y = -a_y / a_z, integrated at the block centres
    fx = np.where(keep, -va[..., 0] / c, 0.0)
    fy = np.where(keep, -va[..., 1] / c, 0.0)
    z0 = integrate_lsq(gradients=(fx, fy), mask=keep, pixel_size=float(b))
    bi, bj = np.mgrid[0:hb, 0:wb]
    zc = z0 + fx * (xc - (bj + 0.5) * b) + fy * (yc + (bi + 0.5) * b)
    area = np.linalg.norm(va, axis=-1)
    nrm = va / np.maximum(area, 1e-300)[..., None]
    pos = np.stack([xc, yc, zc], axis=-1)
    ids = -np.ones((hb, wb), dtype=np.int64)
    ids[keep] = np.arange(int(keep.sum()))
    kpos, knrm, karea = pos[keep], nrm[keep], area[keep]

    # continuation by translation across the image borders the surface crosses unchanged
    src = [(np.arange(kpos.shape[0]), kpos, knrm)]
    tan_tol = np.tan(np.radians(INVARIANCE_DEG))
    cos_tol = np.cos(np.radians(INVARIANCE_DEG))
    depth_s = max(2, -(-CONT_PIXELS // b))
    for touches, lines, step in (
            (ok[0].any(), ids[:depth_s], (0.0, 1.0)),                 # top: outward +y
            (ok[-1].any(), ids[::-1][:depth_s], (0.0, -1.0)),         # bottom: -y
            (ok[:, 0].any(), ids[:, :depth_s].T, (-1.0, 0.0)),        # left: -x
            (ok[:, -1].any(), ids[:, ::-1][:, :depth_s].T, (1.0, 0.0))):  # right: +x
        depth = int(round(pad * (hb if step[0] == 0.0 else wb)))
        if not touches or depth <= 0 or lines.shape[0] < depth_s:
            continue
        full = (lines >= 0).all(axis=0)                  # (n_lines,) the strip is all surface
        strip = np.where(full[None, :], lines, 0)
        half = depth_s // 2
        outer = knrm[strip[:half]].sum(axis=0)           # mean normals of the strip's two halves
        inner = knrm[strip[half:]].sum(axis=0)
        outer /= np.linalg.norm(outer, axis=-1, keepdims=True)
        inner /= np.linalg.norm(inner, axis=-1, keepdims=True)
        same = np.einsum("lk,lk->l", outer, inner) >= cos_tol
        across = np.abs(outer[:, 0] * step[0] + outer[:, 1] * step[1]) / np.maximum(outer[:, 2], 1e-12)
        go = np.flatnonzero(full & same & (across <= tan_tol))   # |slope across the border|
        if go.size == 0:
            continue
        sid = np.repeat(lines[0, go], depth)
        t = np.tile(np.arange(1, depth + 1, dtype=float) * b, go.size)
        p = kpos[sid].copy()
        p[:, 0] += step[0] * t
        p[:, 1] += step[1] * t
        src.append((sid, p, knrm[sid]))
    src_of = np.concatenate([s[0] for s in src])
    src_pos = np.concatenate([s[1] for s in src])
    src_nrm = np.concatenate([s[2] for s in src])

    # pixel <-> facet maps
    pix = np.flatnonzero(ok.ravel())
    pr_, pc_ = rows.ravel()[pix], cols.ravel()[pix]
    own = ids[pr_ // b, pc_ // b]
    average = sparse.csr_matrix((1.0 / cnt[keep][own], (own, np.arange(pix.size))), shape=(kpos.shape[0], pix.size))
    u = (pc_ + 0.5) / b - 0.5
    v = (pr_ + 0.5) / b - 0.5
    j0, i0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - j0, v - i0
    npx = normals.reshape(-1, 3)[pix]
    rows_w, cols_w, vals_w = [], [], []
    for di, dj, wt in ((0, 0, (1 - fv) * (1 - fu)), (0, 1, (1 - fv) * fu), (1, 0, fv * (1 - fu)), (1, 1, fv * fu)):
        ii, jj = i0 + di, j0 + dj
        inside = (ii >= 0) & (ii < hb) & (jj >= 0) & (jj < wb)
        fid = np.where(inside, ids[np.clip(ii, 0, hb - 1), np.clip(jj, 0, wb - 1)], -1)
        has = fid >= 0
        sim = np.einsum("pk,pk->p", npx, knrm[np.where(has, fid, 0)])
        wgt = np.where(has, wt * np.maximum(sim, 0.0) ** SIMILARITY_POWER, 0.0)
        rows_w.append(np.arange(pix.size))
        cols_w.append(np.where(has, fid, 0))
        vals_w.append(wgt)
    rows_w, cols_w, vals_w = np.concatenate(rows_w), np.concatenate(cols_w), np.concatenate(vals_w)
    tot = np.bincount(rows_w, weights=vals_w, minlength=pix.size)
    lone = tot <= 1e-12   # no similar neighbour: the pixel's own facet
    vals_w = vals_w / np.where(lone, 1.0, tot)[rows_w]
    rows_w = np.concatenate([rows_w, np.flatnonzero(lone)])
    cols_w = np.concatenate([cols_w, own[lone]])
    vals_w = np.concatenate([vals_w, np.ones(int(lone.sum()))])
    spread = sparse.csr_matrix((vals_w, (rows_w, cols_w)), shape=(pix.size, kpos.shape[0]))
    return Facets(pos=kpos, normal=knrm, area=karea, src_pos=src_pos, src_normal=src_nrm,
                  src_area=karea[src_of], src_of=src_of, average=average, spread=spread, pix=pix,
                  grid=(hb, wb))


def kernel(f: Facets) -> np.ndarray:
    r"""Dense transport ``K`` (n, n_s): ``max(0, n_I.d) max(0, -n_J.d) A_J / (pi |d|^4)``.

    The three pair terms are products of 4-vectors (``n_I . d = [n_I, -n_I.x_I] . [x_J, 1]``,
    ``|d|^2 = [x_I, |x_I|^2, 1] . [-2 x_J, 1, |x_J|^2]``), evaluated in cache-sized blocks.
    """
    n, ns = f.n, f.src_pos.shape[0]
    out = np.empty((n, ns))
    ps, qs = f.src_pos, f.src_normal
    one_s = np.ones((ns, 1))
    src_ci = np.hstack([ps, one_s])                                       # [x_J, 1]
    src_cj = np.hstack([qs, -np.einsum("jk,jk->j", qs, ps)[:, None]])     # [n_J, -n_J.x_J]
    src_r2 = np.hstack([-2.0 * ps, one_s, np.einsum("jk,jk->j", ps, ps)[:, None]])
    one_r = np.ones((n, 1))
    rec_ci = np.hstack([f.normal, -np.einsum("ik,ik->i", f.normal, f.pos)[:, None]])
    rec_cj = np.hstack([f.pos, one_r])
    rec_r2 = np.hstack([f.pos, np.einsum("ik,ik->i", f.pos, f.pos)[:, None], one_r])
    w = f.src_area / np.pi
    step = max(1, _CHUNK_PAIRS // max(ns, 1))
    for a in range(0, n, step):
        sl = slice(a, min(n, a + step))
        ci = rec_ci[sl] @ src_ci.T                 # n_I . d
        cj = rec_cj[sl] @ src_cj.T                 # -n_J . d
        r2 = rec_r2[sl] @ src_r2.T                 # |d|^2
        np.maximum(ci, 0.0, out=ci)
        np.maximum(cj, 0.0, out=cj)
        ci *= cj
        np.maximum(r2, 1e-12, out=r2)
        r2 *= r2
        ci /= r2
        ci *= w
        out[sl] = ci
    # a facet does not light itself (its continued copies may light it)
    own = np.arange(n)
    out[own, own] = 0.0
    return out


def source_map(f: Facets) -> sparse.csr_matrix:
    """Sparse ``S`` (n_s, n): source ``s`` carries the radiance of kept facet ``src_of[s]``."""
    ns = f.src_of.size
    return sparse.csr_matrix((np.ones(ns), (np.arange(ns), f.src_of)), shape=(ns, f.n))


def transport(f: Facets, k: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``spread @ (K @ S @ (average @ values))``: the interreflected term per pixel before the
    albedo, for ``values`` (n_pix, M) radiances of the used pixels."""
    lf = f.average @ values                 # (n, M) facet radiances
    g = k @ lf[f.src_of]                    # (n, M)
    return f.spread @ g


def interreflect(direct, normals, rho, mask, *, block: int, pad: float):
    r"""Images with interreflection from local (direct) images, by the facet model.

    Solves ``L = D + rho * spread(K S average(L))`` exactly (a dense solve on the facets):
    with ``T = average diag(rho) spread K S`` (n x n), ``(1 - T) L_f = average D`` and then
    ``L = D + rho spread K S L_f``; the model that
    :func:`pbrbench.infer.photometric_stereo.photometric_stereo_nayar1991` inverts (with the same
    ``block`` and ``pad``).  ``direct`` (K, H, W) or (K, H, W, C); ``normals`` (H, W, 3) unit;
    ``rho`` (H, W) or (H, W, C) reflectances in [0, 1); ``mask`` (H, W).  Returns an array shaped
    like ``direct``; pixels outside the mask keep their values.  A test fixture and a reference,
    dense in the facets (``n^2`` memory, ``n^3`` time).
    """
    d = np.asarray(direct, float)
    colour = d.ndim == 4
    img = d if colour else d[..., None]
    kk, h, w, nc = img.shape
    f = build_facets(np.asarray(normals, float), np.asarray(mask, bool), block, pad)
    k = kernel(f)
    rho = np.asarray(rho, float)
    rho = (rho if rho.ndim == 3 else rho[..., None]) * np.ones((1, 1, nc))
    rp = rho.reshape(-1, nc)[f.pix]                       # (n_pix, C)
    vals = img.reshape(kk, h * w, nc)[:, f.pix, :]        # (K, n_pix, C)
    ks = k @ source_map(f)                                # K S (n x n)
    out = img.copy().reshape(kk, h * w, nc)
    for c in range(nc):
        t = f.average @ (f.spread.multiply(rp[:, c][:, None])).tocsr() @ ks
        lf = np.linalg.solve(np.eye(f.n) - t, (f.average @ vals[:, :, c].T))   # (n, K)
        out[:, f.pix, c] = vals[:, :, c] + (rp[:, c][:, None] * (f.spread @ (ks @ lf))).T
    out = out.reshape(kk, h, w, nc)
    return out if colour else out[..., 0]


def shadowed(normals, used, lights, margin: float = 0.25) -> np.ndarray:
    r"""(K, H, W) bool: the measurements that the surface of ``normals`` puts in shadow.

    A pixel is in light ``k``'s *attached* shadow when ``N . s_k <= 0``, and in its *cast*
    shadow when the ray from the pixel toward the source passes below the surface: with the
    heights ``z`` of the normals integrated over ``used`` (:func:`pbrbench.infer.integration.integrate_lsq`,
    pixel units; each connected part of ``used`` on its own), some pixel ``q`` of the same part
    on the ray's ground track at distance ``t`` (pixels) satisfies
    ``z_q > z_p + t \tan(e_k) + margin`` (``e_k`` the source's elevation over the image plane;
    ``margin`` in pixels absorbs the integration's rounding).  Pixels outside ``used`` occlude
    nothing (empty space) and are never in shadow.
    """
    from scipy import ndimage

    from pbrbench.infer.integration import integrate_lsq

    h, w = used.shape
    s = np.asarray(lights, float)
    s = s / np.maximum(np.linalg.norm(s, axis=1, keepdims=True), 1e-300)
    out = (np.einsum("hwc,kc->khw", normals, s) <= 0.0) & used[None]
    ok = used & (normals[..., 2] > 0)
    if ok.sum() < 2:
        return out
    nz = np.maximum(normals[..., 2], MIN_NZ)
    # integrate_lsq's gradients: f_x along x (columns), f_y along y (up); a unit normal is (-f_x, -f_y, 1) / norm
    z = integrate_lsq(gradients=(np.where(ok, -normals[..., 0] / nz, 0.0), np.where(ok, -normals[..., 1] / nz, 0.0)),
                      mask=ok)
    part, _ = ndimage.label(ok)
    pr, pc = np.nonzero(ok)                  # only lit-capable pixels can be in a cast shadow
    pz, pp = z[pr, pc], part[pr, pc]
    zmax = np.zeros(int(part.max()) + 1)      # the highest point of each part: no ray rises above it
    np.maximum.at(zmax, pp, pz)
    relief = float(z[ok].max() - z[ok].min())
    for k in range(len(s)):
        hor = float(np.hypot(s[k, 0], s[k, 1]))
        if hor < 1e-9:
            continue            # a source on the axis casts no shadow on a height field seen along it
        dx, dy, tan = s[k, 0] / hor, s[k, 1] / hor, s[k, 2] / hor
        t_max = min(1.5 * max(h, w), relief / max(tan, 1e-9) + 1.0)
        cast = np.zeros((h, w), bool)
        live = np.arange(pr.size)            # pixels whose ray is still inside the image, below its part's top, unoccluded
        for t in np.arange(1.0, t_max + 1.0, 1.0):
            if live.size == 0:
                break
            r = np.rint(pr[live] - t * dy).astype(int)     # rows grow downward: y up is -row
            c = np.rint(pc[live] + t * dx).astype(int)
            ins = (r >= 0) & (r < h) & (c >= 0) & (c < w)
            r, c = np.where(ins, r, 0), np.where(ins, c, 0)
            level = pz[live] + t * tan + margin
            hit = ins & (part[r, c] == pp[live]) & (z[r, c] > level)
            cast[pr[live[hit]], pc[live[hit]]] = True
            # a ray that left the image never comes back (a straight ground track), nor one above its part's top
            live = live[ins & ~hit & (level < zmax[pp[live]])]
        out[k] |= cast
    return out
