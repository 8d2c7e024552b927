"""The shared 3x3 solve of the photometric-stereo methods, after it moved into ``_common.cofactors``:
bit-identical to the inline cofactor solve the methods had before (random, ill-conditioned too)."""

import numpy as np

from pbrbench.infer.photometric_stereo._common import cofactors, sym_solve
from pbrbench.infer.photometric_stereo.ikehata2012_sbl import _pairs6, _quad_from_cofactors


def _inline_solve(a, b):   # the solve as it was written out in _common before the move
    axx, ayy, azz, axy, axz, ayz = a
    c00 = ayy * azz - ayz * ayz
    c01 = axz * ayz - axy * azz
    c02 = axy * ayz - axz * ayy
    c11 = axx * azz - axz * axz
    c12 = axy * axz - axx * ayz
    c22 = axx * ayy - axy * axy
    det = axx * c00 + axy * c01 + axz * c02
    ok = det > 1e-9 * ((axx + ayy + azz) * (1.0 / 3.0)) ** 3
    inv_det = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    b0, b1, b2 = b
    x = np.stack([(c00 * b0 + c01 * b1 + c02 * b2) * inv_det, (c01 * b0 + c11 * b1 + c12 * b2) * inv_det,
                  (c02 * b0 + c12 * b1 + c22 * b2) * inv_det])
    return x, ok, det


def test_sym_solve_is_bit_identical_to_the_inline_solve():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((6, 20000))
    a[:3] = np.abs(a[:3]) * 2
    a[:, :50] = 0.0                                     # singular systems
    b = rng.standard_normal((3, 20000))
    x, ok = sym_solve(a, b)
    x0, ok0, det0 = _inline_solve(a, b)
    assert 0 < ok.sum() < ok.size                       # both branches exercised
    assert x.tobytes() == x0.tobytes() and np.array_equal(ok, ok0)
    assert cofactors(a)[-1].tobytes() == det0.tobytes()
    np.testing.assert_allclose(np.einsum("ijn,jn->in", _full(a)[:, :, ok], x[:, ok]), b[:, ok], atol=1e-6)


def _full(a):
    axx, ayy, azz, axy, axz, ayz = a
    return np.array([[axx, axy, axz], [axy, ayy, ayz], [axz, ayz, azz]])


def _quad_inv(a, s):   # h_k = s_k^T A^-1 s_k as the SBL iteration forms it from the cofactors
    *cof, det = cofactors(a)
    return _quad_from_cofactors(_pairs6(s), cof, np.divide(1.0, det, out=np.zeros_like(det), where=det > 0))


def test_quad_inv_is_s_ainv_s():
    rng = np.random.default_rng(4)
    m = rng.standard_normal((3, 3, 40))
    full = np.einsum("ijn,kjn->ikn", m, m) + 0.1 * np.eye(3)[:, :, None]
    a = np.stack([full[0, 0], full[1, 1], full[2, 2], full[0, 1], full[0, 2], full[1, 2]])
    s = rng.standard_normal((5, 3))
    want = np.einsum("kj,jkn->kn", s, np.linalg.solve(full.transpose(2, 0, 1), s.T[None]).transpose(1, 2, 0))
    np.testing.assert_allclose(_quad_inv(a, s), want, rtol=1e-9)


def test_sbl_em_in_pixel_blocks_is_independent_of_the_block_size(monkeypatch):
    # the EM runs block by block (pixels are independent); a block boundary must change nothing,
    # down to the last bit (a block of 7 pixels against one block of every pixel)
    import pbrbench.infer.photometric_stereo.ikehata2012_sbl as sbl
    from pbrbench.shading.lambert import blinn_phong_highlights, lambertian_images, ring_lights
    from pbrbench.shading.surfaces import on_grid

    s = on_grid("sphere", 40, half_width=1.05)
    lights = ring_lights(8)
    imgs = lambertian_images(s.normals, 0.6, lights, mask=s.mask) + blinn_phong_highlights(s.normals, lights, 200.0,
                                                                                            mask=s.mask)
    monkeypatch.setattr(sbl, "_CHUNK", 1 << 20)
    whole = sbl.photometric_stereo_ikehata2012_sbl(imgs, lights, mask=s.mask, max_iter=30)
    monkeypatch.setattr(sbl, "_CHUNK", 7)
    blocks = sbl.photometric_stereo_ikehata2012_sbl(imgs, lights, mask=s.mask, max_iter=30)
    assert whole.normals.tobytes() == blocks.normals.tobytes()
    assert whole.albedo.tobytes() == blocks.albedo.tobytes()
    assert np.array_equal(whole.n_used, blocks.n_used)
