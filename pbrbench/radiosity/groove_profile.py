"""Radiosity across a concave V groove under a distant source (the chapter's Figs 1.18 and 1.20).

A groove of two planar faces of width ``w`` meeting at a crease along the y axis with opening
angle ``phi`` (90 degrees: right-angled), opening toward +z (the camera).  In the cross-section
(x, z) the left face runs from the crease ``(0, 0)`` to ``w (-sin(phi/2), cos(phi/2))`` with
inward normal ``(cos(phi/2), sin(phi/2))``; the right face is its mirror image.

The local model gives ``B = rho E0 max(0, N . S)``, a constant per face (a step between the
faces when the source is parallel to one of them, a constant when it lies on the bisector).
Interreflection adds light that grows toward the crease, where each face sees most of the other:
a roof-shaped profile with a bright reflex at the crease.

Two solvers:

* ``method="2d"`` -- the infinitely long groove.  The 3-D kernel integrated along the groove is
  ``cos(phi) cos(phi') / (2 r)`` in the cross-section, and the factors between strips follow
  exactly from Hottel's crossed strings (:func:`pbrbench.shading.form_factors.strip_form_factors_2d`);
  only the piecewise-constant approximation of ``B`` across the faces remains.
* ``method="3d"`` -- a groove of finite ``length`` cut into ``n`` x ``n_along`` rectangles per
  face, with the 3-D form factors of :func:`pbrbench.radiosity.form_factor_matrix.form_factor_matrix`
  (no visibility test is needed: the faces of a V see each other wholly); the profile is read at
  the middle row.  As ``length / w`` grows it tends to the 2-D profile (the missing ends subtend
  a kernel integral of order ``(w / length)^3``).

Shadows are exact in both: when the source lies beyond one face's plane that face is back-lit and
the other face's rim shades the part of the lit face near the crease.

References
----------
D. A. Forsyth and A. Zisserman, "Reflections on shading", IEEE PAMI 13(7), 1991, and "Mutual
illumination", CVPR 1989 (the groove's reflex); H. C. Hottel and A. F. Sarofim, *Radiative
Transfer*, 1967 (crossed strings); C. M. Goral et al., SIGGRAPH 1984.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pbrbench.checks import as_float_array, check_int, check_number, check_positive
from pbrbench.radiosity.form_factor_matrix import form_factor_matrix
from pbrbench.radiosity.patches import Patches, make_patches
from pbrbench.radiosity.solver import solve_radiosity
from pbrbench.shading.form_factors import strip_form_factors_2d

__all__ = ["GrooveProfile", "groove_profile", "groove_segments", "groove_patches", "groove_lit_fraction"]


@dataclass(frozen=True)
class GrooveProfile:
    """Radiosity across the groove, ordered from the left rim through the crease to the right rim.

    ``x``: the x coordinate of each strip's centre; ``s``: signed distance along the faces from
    the crease (negative on the left face); ``B``: radiosity; ``E``: direct radiosity (the local
    model); ``face``: 0 left, 1 right.
    """

    x: np.ndarray
    s: np.ndarray
    B: np.ndarray
    E: np.ndarray
    face: np.ndarray
    method: str


def _geometry(opening_deg, width):
    half = np.radians(check_number(opening_deg, "opening_deg", lo=0.0, hi=180.0, lo_open=True, hi_open=True)) / 2
    w = check_positive(width, "width")
    uL, uR = np.array([-np.sin(half), np.cos(half)]), np.array([np.sin(half), np.cos(half)])
    nL, nR = np.array([np.cos(half), np.sin(half)]), np.array([-np.cos(half), np.sin(half)])
    return w, (uL, nL), (uR, nR)


def groove_segments(n: int, *, opening_deg: float = 90.0, width: float = 1.0):
    """Cross-section strips: end points (2n, 2, 2), inward normals (2n, 2), signed arc position (2n,).

    Ordered left rim -> crease -> right rim; each segment runs crease-outward on the right face
    and rim-inward on the left one (orientation does not matter to the 2-D factors).
    """
    n = check_int(n, "n", 1, 100000)
    w, (uL, nL), (uR, nR) = _geometry(opening_deg, width)
    t = np.linspace(0.0, w, n + 1)
    left = np.stack([t[::-1][:-1, None] * uL, t[::-1][1:, None] * uL], axis=1)
    right = np.stack([t[:-1, None] * uR, t[1:, None] * uR], axis=1)
    mid = 0.5 * (t[:-1] + t[1:])
    segs = np.concatenate([left, right])
    normals = np.concatenate([np.repeat(nL[None], n, 0), np.repeat(nR[None], n, 0)])
    s = np.concatenate([-mid[::-1], mid])
    return segs, normals, s


def groove_lit_fraction(s, direction, *, opening_deg: float = 90.0, width: float = 1.0, ds: float = 0.0) -> np.ndarray:
    """Fraction of the strip ``[|s| - ds/2, |s| + ds/2]`` (signed position ``s``) in the source's light.

    ``direction`` is the source direction in the cross-section, (S_x, S_z) or (S_x, S_y, S_z)
    with the y component ignored (a source in the plane of the cross-section).  A face is lit
    where ``N . S > 0`` and the ray toward the source clears the other face: the other face's
    rim shades the lit face from the crease up to where the line through that rim along ``-S``
    meets it.
    """
    w, (uL, nL), (uR, nR) = _geometry(opening_deg, width)
    d = as_float_array(direction, "direction").ravel()
    S = np.array([d[0], d[-1]], float)
    if d.size not in (2, 3) or not np.all(np.isfinite(S)) or np.linalg.norm(S) < 1e-12:
        raise ValueError(f"direction: expected a non-zero (S_x, S_z) or (S_x, S_y, S_z) in the cross-section, got {direction!r}")
    S = S / np.linalg.norm(S)
    s = as_float_array(s, "s")
    out = np.zeros(s.shape)
    for sign, (u, nrm), (u_o, _) in ((-1, (uL, nL), (uR, nR)), (1, (uR, nR), (uL, nL))):
        on = (s < 0) if sign < 0 else (s >= 0)
        if nrm @ S <= 0:
            continue
        # shadow of the other face's rim r = w u_o: points t u with t u + k S = w u_o for some k > 0
        A = np.array([u, S]).T
        t_sh, k = np.linalg.solve(A, w * u_o) if abs(np.linalg.det(A)) > 1e-14 else (0.0, -1.0)
        shade = float(np.clip(t_sh, 0.0, w)) if k > 0 else 0.0
        a = np.abs(s[on])
        if ds > 0:
            lo, hi = a - ds / 2, a + ds / 2
            out[on] = np.clip((hi - np.maximum(lo, shade)) / ds, 0.0, 1.0)
        else:
            out[on] = (a > shade).astype(float)
    return out


def groove_patches(n: int, n_along: int, *, length: float = 8.0, opening_deg: float = 90.0, width: float = 1.0,
                   albedo=0.5) -> tuple[Patches, np.ndarray, np.ndarray]:
    """The finite groove as patches: ``n`` strips across each face times ``n_along`` along y.

    Returns the patches, the signed position ``s`` of each patch's strip and its row along y
    (``n_along // 2`` is the middle row).
    """
    n_along = check_int(n_along, "n_along", 1, 100000)
    L = check_positive(length, "length")
    segs, normals, s = groove_segments(n, opening_deg=opening_deg, width=width)
    y = np.linspace(-L / 2, L / 2, n_along + 1)
    quads, ss, rows = [], [], []
    for k, (seg, nrm) in enumerate(zip(segs, normals, strict=True)):
        a = np.array([seg[0, 0], 0.0, seg[0, 1]])
        b = np.array([seg[1, 0], 0.0, seg[1, 1]])
        for r in range(n_along):
            q = np.array([a + [0, y[r], 0], b + [0, y[r], 0], b + [0, y[r + 1], 0], a + [0, y[r + 1], 0]])
            nq = np.cross(q[1] - q[0], q[3] - q[0])
            if nq[0] * nrm[0] + nq[2] * nrm[1] < 0:
                q = q[::-1]
            quads.append(q)
            ss.append(s[k])
            rows.append(r)
    face = (np.array(ss) >= 0).astype(int)
    return make_patches(np.array(quads), albedo, face_id=face), np.array(ss), np.array(rows)


def groove_profile(rho, direction, *, opening_deg: float = 90.0, width: float = 1.0, n: int = 64,
                   method: str = "2d", length: float = 8.0, n_along: int | None = None,
                   irradiance: float = 1.0) -> GrooveProfile:
    """Radiosity across a V groove of albedo ``rho`` under a distant source.

    Parameters
    ----------
    rho : float
        Albedo in [0, 1).
    direction : array_like
        Source direction (toward the source) in the cross-section: (S_x, S_z) or
        (S_x, 0, S_z).  ``(0, 1)`` is the bisector (Fig 1.20); ``(-1, 1)`` is parallel to the
        left face of a right-angled groove (Fig 1.18: the left face is dark, the right one lit).
    opening_deg, width : float
        Angle between the faces and width of each face (crease to rim).
    n : int
        Strips across each face.
    method : {'2d', '3d'}
        Infinitely long groove (exact strip factors) or a finite one of ``length`` with
        ``n_along`` patches along it (default: patches about 4 strips long).
    irradiance : float
        ``E0`` of the source.

    Returns
    -------
    GrooveProfile
    """
    from pbrbench.checks import check_method

    check_method(method, ("2d", "3d"))
    rho = check_number(rho, "rho", lo=0.0, hi=1.0, hi_open=True)
    e0 = check_number(irradiance, "irradiance", lo=0.0)
    d = as_float_array(direction, "direction").ravel()
    S2 = np.array([d[0], d[-1]], float)
    S2 = S2 / max(np.linalg.norm(S2), 1e-300)
    segs, normals, s = groove_segments(n, opening_deg=opening_deg, width=width)
    ds = float(width) / n
    lit = groove_lit_fraction(s, d, opening_deg=opening_deg, width=width, ds=ds)
    E_strip = rho * e0 * np.maximum(normals @ S2, 0.0) * lit
    x = 0.5 * (segs[:, 0, 0] + segs[:, 1, 0])
    face = (s >= 0).astype(int)
    if method == "2d":
        F = strip_form_factors_2d(segs, segs)
        F[face[:, None] == face[None, :]] = 0.0
        B = solve_radiosity(F, np.full(len(s), rho), E_strip, method="direct").B
        return GrooveProfile(x, s, B, E_strip, face, "2d")
    L = check_positive(length, "length")
    if n_along is None:
        n_along = max(1, int(round(L / (4 * ds))))
        n_along += 1 - n_along % 2  # odd: a middle row centred at y = 0
    patches, ps, rows = groove_patches(n, n_along, length=L, opening_deg=opening_deg, width=width, albedo=rho)
    F = form_factor_matrix(patches, visibility=False)
    E = np.interp(ps, s, E_strip)
    B = solve_radiosity(F, np.full(len(ps), rho), E, method="direct").B
    mid = rows == n_along // 2
    order = np.argsort(ps[mid])
    return GrooveProfile(x, s, B[mid][order], E_strip, face, "3d")
