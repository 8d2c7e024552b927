"""Bad calls to every public function of pbrbench.infer (tests/corpus/infer_fuzz.py): each is
refused with a one-line ValueError that names the argument; none returns NaN or accepts silently.
A subset with a known cause is checked for the expected words of its message."""

from __future__ import annotations

import numpy as np
import pytest

from tests.corpus.infer_fuzz import DISPATCHERS, Case, cases, classify

CASES = [c for c in cases() if not c.may_accept]

# (mutation) -> words one of which the message of an array argument must contain
ARRAY_WORDS = {
    "complex": ("complex", "unsigned integer"),
    "object": ("dtype object",),
    "strings": ("dtype <U",),
    "empty": ("empty array", "0 exposure", "does not match"),
    "nan": ("non-finite", "finite and > 0", "unsigned integer"),
    "inf": ("non-finite", "finite and > 0", "unsigned integer"),
    "flat": ("dimensions", "shape"),
    "more_dims": ("dimensions", "shape", "1-D"),
    "ragged": ("could not convert", "different shapes"),
    "none": ("None", "pass an array"),
    "scalar": ("dimensions", "shape", "pass an array"),
}
OPTION_WORDS = {
    "nan": ("finite number", "integer"),
    "inf": ("finite number", "integer"),
    "negative": (">", "integer"),
    "string": ("a number", "integer"),
    "complex": ("real number", "integer"),
    "list": ("a number", "integer"),
    "huge": ("<", "exceeds", "more than", "low_ratio", "no pixel", "in 1..16"),
}
RESPONSE_WORDS = {
    "decreasing": "decreases", "nan": "non-finite", "zero": "> 0", "negative": "> 0", "short": "expected shape",
    "complex": "complex", "1d": "dimensions", "empty": "empty", "not_a_response": "expected a CameraResponse",
}
SPECIAL_WORDS = {
    "constant_bracket": "carries no information", "coplanar_lights": "degenerate", "zero_lights": "zero vector",
    "zero_vector": "zero vector", "below_horizon": "behind the surface",
}


def expected_words(c: Case) -> tuple[str, ...] | None:
    if c.arg == "response" and c.mutation in RESPONSE_WORDS:
        return (RESPONSE_WORDS[c.mutation],)
    if c.mutation in SPECIAL_WORDS:
        return (SPECIAL_WORDS[c.mutation],)
    if c.arg in ("image", "profile") and c.mutation in ("negative", "all_zero"):
        return ("<= 0", "min_value")  # the log of the image is undefined
    if c.arg == "mask" and c.mutation in ("complex", "object", "strings"):
        return ("must be boolean",)
    if c.mutation in ARRAY_WORDS and c.arg in ("images", "image", "exposure_times", "lights", "light", "mask",
                                               "normals", "p", "q", "z", "gx", "gy", "profile", "intensities"):
        return ARRAY_WORDS[c.mutation]
    if c.mutation in OPTION_WORDS:
        return OPTION_WORDS[c.mutation]
    return None


def test_the_corpus_is_large_and_covers_every_public_function():
    import pbrbench.infer as I

    public = {n for n in I.__all__ if callable(getattr(I, n)) and not isinstance(getattr(I, n), type)}
    covered = {c.fn for c in CASES}
    # a table's methods are fuzzed through their dispatcher (_every_method), so a new method needs
    # no entry of its own in infer_fuzz
    covered |= {fn.__name__ for disp, table in DISPATCHERS.items() if disp in covered
                for fn in getattr(I, table).values()}
    # the aliases retinex / retinex_1d are the same functions as lightness_blake1985 / lightness_1d_horn1974
    assert public - covered <= {"retinex", "retinex_1d"}, sorted(public - covered)
    assert len(CASES) >= 1000
    assert sum(expected_words(c) is not None for c in CASES) >= 100


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_call_is_one_clear_line(case):
    outcome, msg = classify(case)
    assert outcome == "clear", f"{case.id}: {outcome}: {msg}"
    words = expected_words(case)
    if words is not None:
        assert any(w in msg for w in words), f"{case.id}: none of {words} in {msg!r}"


def test_camera_response_refuses_bad_curves():
    from pbrbench.infer import CameraResponse

    good = np.linspace(1e-3, 1.0, 256)[:, None]
    assert CameraResponse(good, 256, "x").levels == 256
    for bad, words in [(good[::-1], "decreases"), (np.ones((256, 1)), "constant"), (good[:100], "expected shape"),
                       (np.where(np.arange(256)[:, None] == 5, np.nan, good), "non-finite"), (good - 0.5, "> 0")]:
        with pytest.raises(ValueError, match="CameraResponse.inverse") as e:
            CameraResponse(bad, 256, "x")
        assert words in str(e.value)
    with pytest.raises(ValueError, match="levels"):
        CameraResponse(good, 1.5, "x")


def test_merge_never_returns_nan_for_a_valid_response():
    """The docstring promise: a valid (checked) response never yields NaN radiance."""
    from pbrbench.infer import CameraResponse, merge_hdr

    rng = np.random.default_rng(1)
    Z = rng.integers(0, 256, (3, 8, 8, 1)).astype(np.uint8)
    flat = np.concatenate([np.full(100, 1e-3), np.linspace(1e-3, 1.0, 156)])[:, None]  # flat at the bottom
    out = merge_hdr(Z, [0.25, 1.0, 4.0], CameraResponse(flat, 256, "x"))
    assert np.isfinite(out).all()


SCALE_CASES = __import__("tests.corpus.infer_fuzz", fromlist=["scale_cases"]).scale_cases()


@pytest.mark.parametrize("case", SCALE_CASES, ids=[c.id for c in SCALE_CASES])
def test_extreme_magnitudes_give_a_finite_answer_or_a_clear_refusal(case):
    outcome, msg = classify(case)
    assert outcome in ("accepted", "clear"), f"{case.id}: {outcome}: {msg}"


@pytest.mark.parametrize("scale", [1e300, 1e-300])
def test_scale_covariant_methods_answer_correctly_at_extreme_scales(scale):
    """Normals, light directions and gradients do not depend on the scale; albedo and height scale."""
    import pbrbench.infer as I
    from tests.corpus.infer_fuzz import _base

    B = _base()
    ref = I.solve_photometric_stereo(B["ps"], B["lights"], mask=B["mask"])
    for fn in (I.photometric_stereo_woodham1980, I.photometric_stereo_ikehata2012_l1, I.photometric_stereo_naive_lstsq):
        r0 = fn(B["ps"], B["lights"], mask=B["mask"])
        r = fn(B["ps"] * scale, B["lights"], mask=B["mask"])
        assert np.allclose(r.normals, r0.normals, atol=1e-9) and np.array_equal(r.valid, r0.valid)
        assert np.allclose(r.albedo / scale, r0.albedo, rtol=1e-9, atol=0)
    r = I.solve_photometric_stereo(B["ps"], B["lights"] * 1e-3, mask=B["mask"])
    assert np.allclose(r.normals, ref.normals, atol=1e-9)
    z0 = I.solve_gradient_field(B["p"], B["q"], mask=B["mask"])
    z = I.solve_gradient_field(B["p"] * scale, B["q"] * scale, mask=B["mask"])
    assert np.allclose(z / scale, z0, rtol=1e-6, atol=1e-9 * np.abs(z0).max())
    p0, q0, v0 = I.normals_to_gradients(B["normals"], B["mask"])
    p, q, v = I.normals_to_gradients(B["normals"] * scale, B["mask"])
    assert np.array_equal(v, v0) and np.allclose(p, p0) and np.allclose(q, q0)
    e0 = I.light_from_shading_lee_rosenfeld1985(B["shade"], B["mask"])
    e = I.light_from_shading_lee_rosenfeld1985(B["shade"] * scale, B["mask"])
    assert np.allclose(e.direction, e0.direction) and np.isclose(e.albedo / scale, e0.albedo)
