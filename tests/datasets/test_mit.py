"""MIT Intrinsic Images layout and the Grosse et al. (2009) protocol: the loader, the LMSE against
an independent transcription of the published loops, `pbrbench evaluate lightness` and
`pbrbench infer retinex`."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pbrbench.cli.main import main
from pbrbench.datasets import load_mit_object, mit_objects, mit_scores
from pbrbench.errors import UserError
from tests.datasets.layouts import mit_object


def _published_local_error(correct, estimate, mask, window_size, window_shift):
    """The published ``local_error`` / ``ssq_error``, loop for loop (a reference, not the code
    under test)."""
    M, N = correct.shape[:2]
    ssq = total = 0.0
    for i in range(0, M - window_size + 1, window_shift):
        for j in range(0, N - window_size + 1, window_shift):
            c = correct[i:i + window_size, j:j + window_size]
            e = estimate[i:i + window_size, j:j + window_size]
            m = mask[i:i + window_size, j:j + window_size]
            if np.sum(e ** 2 * m) > 1e-5:
                alpha = np.sum(c * e * m) / np.sum(e ** 2 * m)
            else:
                alpha = 0.0
            ssq += np.sum(m * (c - alpha * e) ** 2)
            total += np.sum(m * c ** 2)
    return ssq / total


def test_an_object_loads_16_bit_linear(tmp_path):
    refl, shading, mask = mit_object(tmp_path / "box")
    obj = load_mit_object(tmp_path / "box", lights=True)
    q = lambda a: np.clip(np.round(a * 60000), 0, 65535) / 65535  # noqa: E731
    assert np.array_equal(obj.reflectance, q(refl)) and np.array_equal(obj.shading, q(shading))
    assert np.array_equal(obj.mask, mask) and obj.image.shape == mask.shape
    assert np.array_equal(obj.diffuse, q(refl * shading[..., None]))
    assert obj.extra["lights"].shape == (10, 64, 64, 3) and "original" in obj.extra
    mit_object(tmp_path / "nomask", mask_file=False)
    assert load_mit_object(tmp_path / "nomask").mask.all()
    mit_object(tmp_path / "MIT" / "data" / "cup1", size=32)
    mit_object(tmp_path / "MIT" / "data" / "box", size=32)
    assert [p.name for p in mit_objects(tmp_path / "MIT")] == ["box", "cup1"]


def test_the_protocol_is_the_published_score(tmp_path):
    mit_object(tmp_path / "box")
    obj = load_mit_object(tmp_path / "box")
    rng = np.random.default_rng(0)
    for est_r, est_s in ((obj.image, np.ones_like(obj.image)),
                         (obj.reflectance_grey * rng.uniform(0.8, 1.2, obj.image.shape), obj.shading + 0.05)):
        sc = mit_scores(est_r, est_s, obj)
        m = obj.mask.astype(float)
        want = 0.5 * _published_local_error(obj.shading, est_s, m, 20, 10) + \
            0.5 * _published_local_error(obj.reflectance_grey, est_r, m, 20, 10)
        assert sc["intrinsic_lmse"] == pytest.approx(want, rel=1e-10)
    perfect = mit_scores(obj.reflectance_grey, obj.shading, obj)
    assert perfect["intrinsic_lmse"] < 1e-20


@pytest.mark.parametrize("missing", ["diffuse.png", "reflectance.png", "shading.png"])
def test_a_malformed_object_is_a_one_line_error(tmp_path, missing):
    mit_object(tmp_path / "box", size=32)
    (tmp_path / "box" / missing).unlink()
    with pytest.raises(UserError, match=f"no {missing}"):
        load_mit_object(tmp_path / "box")


def test_evaluate_on_an_mit_folder_reports_the_lmse(tmp_path, capsys):
    for k, name in enumerate(("box", "cup1")):
        mit_object(tmp_path / "MIT" / "data" / name, seed=k)
    pred = tmp_path / "pred" / "box"
    pred.mkdir(parents=True)
    box = load_mit_object(tmp_path / "MIT" / "data" / "box")
    np.save(pred / "reflectance.npy", box.reflectance_grey)          # shading: image / reflectance
    args = ["evaluate", "lightness", str(tmp_path / "MIT"), "--predictions", str(tmp_path / "pred"),
            "--method", "blake1985", "--method", "baseline:image_is_reflectance", "--json", str(tmp_path / "s.json"),
            "--store", str(tmp_path / "h.sqlite"), "--out", str(tmp_path / "rep")]
    assert main(args) == 1                        # cup1 has no prediction
    out = capsys.readouterr().out
    assert "intrinsic_lmse" in out and "cup1" in out and "16 objects" in out
    rows = {(r["object"], r["algorithm"]): r["scores"] for r in json.loads((tmp_path / "s.json").read_text())["rows"]}
    assert rows[("box", "external")]["intrinsic_lmse"] < 1e-6
    assert rows[("box", "baseline:image_is_reflectance")]["intrinsic_lmse"] > rows[("box", "blake1985")]["intrinsic_lmse"]
    assert set(rows[("box", "blake1985")]) == {"intrinsic_lmse", "lmse_reflectance", "lmse_shading"}
    assert rows[("cup1", "external")] == {}


def test_infer_retinex_on_an_mit_folder_and_on_image_files(tmp_path, capsys):
    from pbrbench.io import read_image, write_png_exact

    mit_object(tmp_path / "box")
    assert main(["infer", "retinex", str(tmp_path / "box"), "--out", str(tmp_path / "o1")]) == 0
    r = read_image(tmp_path / "o1" / "reflectance.exr")
    s = read_image(tmp_path / "o1" / "shading.exr")
    obj = load_mit_object(tmp_path / "box")
    m = obj.mask
    assert np.allclose((r * s)[m], obj.image[m], rtol=1e-4)
    img8 = (np.clip(obj.diffuse, 0, 1) ** (1 / 2.2) * 255).round().astype(np.uint8)
    write_png_exact(tmp_path / "photo.png", img8)
    assert main(["infer", "retinex", str(tmp_path / "photo.png"), "--out", str(tmp_path / "o2"), "--threshold", "0.1"]) == 0
    res = json.loads((tmp_path / "o2" / "result.json").read_text())
    assert res["encoding"] == "8-bit, sRGB decoded" and res["options"] == {"threshold": 0.1}
    assert read_image(tmp_path / "o2" / "reflectance.exr").shape == (64, 64, 3)
    assert main(["infer", "retinex", str(tmp_path / "none.png"), "--out", str(tmp_path / "o3")]) == 1
    assert "none.png: no such file" in capsys.readouterr().err


def test_infer_retinex_reaches_the_colour_method_and_its_chromaticity_threshold(tmp_path, capsys):
    from pbrbench.infer.lightness import estimate_lightness
    from pbrbench.io import read_image

    mit_object(tmp_path / "box")
    obj = load_mit_object(tmp_path / "box")
    args = ["infer", "retinex", str(tmp_path / "box"), "--method", "grosse2009", "--colour"]
    assert main(args + ["--out", str(tmp_path / "c"), "--chromaticity-threshold", "0.2"]) == 0
    res = json.loads((tmp_path / "c" / "result.json").read_text())
    assert res["encoding"] == "MIT layout (colour diffuse image, linear)"
    assert res["options"] == {"chromaticity_threshold": 0.2}
    r = read_image(tmp_path / "c" / "reflectance.exr")
    assert r.shape == obj.diffuse.shape
    # the option reached the method: the command's reflectance is the method's with that threshold,
    # and another threshold gives another one
    m = obj.mask
    img = np.where(m[..., None], obj.diffuse, 0.0)
    want, _ = estimate_lightness(img, method="grosse2009", mask=m & (obj.diffuse > 0).all(axis=-1),
                                 chromaticity_threshold=0.2)
    other, _ = estimate_lightness(img, method="grosse2009", mask=m & (obj.diffuse > 0).all(axis=-1),
                                  chromaticity_threshold=np.inf)
    assert np.allclose(r[m], want[m], rtol=1e-5) and not np.allclose(want[m], other[m], rtol=1e-3)
    # a method without the option, a negative threshold and --colour on a file: one line, exit 1
    capsys.readouterr()
    assert main(["infer", "retinex", str(tmp_path / "box"), "--out", str(tmp_path / "x"),
                 "--chromaticity-threshold", "0.2"]) == 1
    err = capsys.readouterr().err
    errors = [ln for ln in err.splitlines() if ln.startswith("pbrbench: error:")]
    assert len(errors) == 1 and "chromaticity_threshold" in errors[0] and "Traceback" not in err
    for bad in ("-1", "nan"):
        assert main(args + ["--out", str(tmp_path / "y"), "--chromaticity-threshold", bad]) == 1
        err = capsys.readouterr().err
        errors = [ln for ln in err.splitlines() if ln.startswith("pbrbench: error:")]
        assert len(errors) == 1 and "chromaticity_threshold: must be a number >= 0" in errors[0] and "Traceback" not in err
    (tmp_path / "photo.exr").write_bytes((tmp_path / "c" / "reflectance.exr").read_bytes())
    assert main(["infer", "retinex", str(tmp_path / "photo.exr"), "--colour", "--out", str(tmp_path / "z")]) == 1
    assert "drop --colour" in capsys.readouterr().err
