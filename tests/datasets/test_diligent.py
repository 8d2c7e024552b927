"""DiLiGenT layout: 16-bit PNGs read without loss, light files, masks and ground-truth normals in
their published forms and file-name variations, the frame check, one-line errors for malformed
folders, and `pbrbench infer photometric-stereo` / `pbrbench evaluate` on such folders."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pbrbench.cli.main import main
from pbrbench.datasets import diligent_objects, frame_check, load_diligent
from pbrbench.errors import UserError
from tests.datasets.layouts import DIRS, diligent_object


def test_an_object_loads_bit_exact_in_the_camera_frame(tmp_path):
    n, mask, dirs, ints, raw = diligent_object(tmp_path / "ballPNG")
    obj = load_diligent(tmp_path / "ballPNG")
    assert obj.images.shape == (12, 48, 48, 3) and obj.name == "ballPNG"
    # every 16-bit value survives: images x intensities x 65535 gives the written integers back
    assert np.array_equal(np.round(obj.images * ints[:, None, None, :] * 65535).astype(np.uint16), raw)
    assert np.allclose(obj.lights, DIRS, atol=1e-8) and np.allclose(np.linalg.norm(obj.lights, axis=1), 1)
    assert np.array_equal(obj.mask, mask)
    assert np.allclose(obj.normals[mask], n[mask], atol=1e-12) and not obj.normals[~mask].any()
    assert [f.name for f in obj.files] == [f"{k:03d}.png" for k in range(1, 13)]
    assert obj.grey.shape == (12, 48, 48)


def test_file_name_and_format_variations_give_the_same_object(tmp_path):
    diligent_object(tmp_path / "a")
    diligent_object(tmp_path / "b", normal_file="normal.txt", filenames=False, crlf=True, mask_rgb=True,
                    filters=(1,))
    diligent_object(tmp_path / "c", normal_file="Normal_gt.npy")
    diligent_object(tmp_path / "e", normal_file="Normal_gt.txt", column_major=True)   # MATLAB's N(:) order
    a, b, c = (load_diligent(tmp_path / x) for x in "abc")
    assert np.allclose(load_diligent(tmp_path / "e").normals, a.normals, atol=1e-7)
    assert np.array_equal(a.images, b.images) and np.array_equal(a.mask, b.mask)
    assert np.allclose(a.normals, b.normals, atol=1e-7) and np.allclose(a.normals, c.normals, atol=1e-12)
    assert np.allclose(a.lights, b.lights, atol=1e-8)
    d = tmp_path / "d"
    diligent_object(d, intensities=False)
    assert np.array_equal(load_diligent(d).intensities, np.ones((12, 3)))
    sub = load_diligent(tmp_path / "a", indices=range(2, 12))
    assert len(sub.lights) == 10 and np.array_equal(sub.images, a.images[2:])


def test_objects_are_found_below_a_dataset_root(tmp_path):
    for name in ("ballPNG", "catPNG"):
        diligent_object(tmp_path / "DiLiGenT" / "pmsData" / name, size=24)
    assert [p.name for p in diligent_objects(tmp_path / "DiLiGenT")] == ["ballPNG", "catPNG"]
    assert diligent_objects(tmp_path / "DiLiGenT" / "pmsData" / "catPNG")[0].name == "catPNG"


def test_the_frame_check_prefers_the_given_frame_and_catches_a_flipped_axis(tmp_path):
    diligent_object(tmp_path / "ok", surface="bumps")
    diligent_object(tmp_path / "flipped", surface="bumps", flip_normals_y=True)
    ok = frame_check(load_diligent(tmp_path / "ok"))
    assert max(ok, key=ok.get) == "as_given" and ok["as_given"] > 0.999
    bad = frame_check(load_diligent(tmp_path / "flipped"))
    assert max(bad, key=bad.get) == "flip_y"


@pytest.mark.parametrize("damage, message", [
    (lambda d: (d / "light_directions.txt").unlink(), "not a DiLiGenT object folder"),
    (lambda d: (d / "light_directions.txt").write_text("0 0 1\n1 0\n"), r"light_directions.txt, line 2: 2 values, expected 3"),
    (lambda d: (d / "light_intensities.txt").write_text("1 1 1\n" * 5), "12 images, 12 light directions and 5 intensities"),
    (lambda d: (d / "005.png").unlink(), "lists '005.png', which is not in"),
    (lambda d: (d / "mask.png").write_bytes(b"junk"), "mask.png: not a PNG file"),
    (lambda d: (d / "003.png").write_bytes((d / "003.png").read_bytes()[:200]), "003.png: truncated"),
    (lambda d: (d / "light_directions.txt").write_text("0 0 one\n"), "is not a row of numbers"),
])
def test_a_malformed_folder_is_a_one_line_error(tmp_path, damage, message):
    d = tmp_path / "obj"
    diligent_object(d, size=24)
    damage(d)
    with pytest.raises(UserError, match=message) as e:
        load_diligent(d)
    assert "\n" not in str(e.value)


def test_a_mat_file_with_another_variable_name_and_misshaped_normals(tmp_path):
    import scipy.io

    d = tmp_path / "obj"
    n, mask, *_ = diligent_object(d, size=24)
    scipy.io.savemat(d / "Normal_gt.mat", {"N_est_any": n * mask[..., None]})
    assert np.allclose(load_diligent(d).normals, n * mask[..., None])
    scipy.io.savemat(d / "Normal_gt.mat", {"Normal_gt": np.zeros((5, 5, 3))})
    with pytest.raises(UserError, match=r"normals of shape \(5, 5, 3\), the images are 24 x 24"):
        load_diligent(d)


def test_infer_photometric_stereo_on_a_diligent_folder(tmp_path, capsys):
    from pbrbench.infer.photometric_stereo import solve_photometric_stereo
    from pbrbench.io import read_image, read_png

    d = tmp_path / "bumpsPNG"
    diligent_object(d, surface="bumps")
    assert main(["infer", "photometric-stereo", str(d), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "bumpsPNG: woodham1980 on 12 images" in out and "angular error mean" in out
    res = json.loads((tmp_path / "out" / "result.json").read_text())
    assert res["angular_error_deg"]["mean"] < 0.05 and res["images"] == 12 and res["layout"] == "DiLiGenT layout"
    obj = load_diligent(d)
    want = solve_photometric_stereo(obj.grey, obj.lights, mask=obj.mask).normals.astype(np.float32)
    assert np.array_equal(read_image(tmp_path / "out" / "normals.exr"), want)
    for f in ("normals.png", "albedo.exr", "albedo.png", "height.exr", "height.png", "valid.png"):
        assert (tmp_path / "out" / f).is_file(), f
    assert read_png(tmp_path / "out" / "normals.png").shape[:2] == (48, 48)
    h = read_image(tmp_path / "out" / "height.exr")
    assert np.ptp(h[obj.mask]) > 0
    assert main(["infer", "photometric-stereo", str(d), "--out", str(tmp_path / "o2"), "--method", "ikehata2012_l1",
                 "--drop-first", "2"]) == 0
    assert json.loads((tmp_path / "o2" / "result.json").read_text())["images"] == 10
    assert main(["infer", "photometric-stereo", str(tmp_path), "--out", str(tmp_path / "o3")]) == 1
    assert "neither a DiLiGenT object folder" in capsys.readouterr().err


MINE = '''
import numpy as np
from pbrbench.infer.photometric_stereo import photometric_stereo_woodham1980

def flipped(images, lights, *, mask=None):
    r = photometric_stereo_woodham1980(images, lights, mask=mask)
    return r.normals * np.array([1.0, 1.0, -1.0]), r.albedo
'''


def test_evaluate_on_diligent_folders_reports_mean_and_median_angular_error(tmp_path, capsys):
    root = tmp_path / "DiLiGenT" / "pmsData"
    for name, surface in (("ballPNG", "sphere"), ("bumpsPNG", "bumps")):
        diligent_object(root / name, surface=surface)
    plugin = tmp_path / "mine.py"
    plugin.write_text(MINE)
    pred = tmp_path / "pred"
    (pred / "ballPNG").mkdir(parents=True)
    ball = load_diligent(root / "ballPNG")
    np.save(pred / "ballPNG" / "normals.npy", ball.normals)          # a perfect prediction; bumps has none
    args = ["evaluate", "photometric_stereo", str(tmp_path / "DiLiGenT"), "--method", "woodham1980",
            "--algorithm", f"photometric_stereo={plugin}:flipped", "--predictions", str(pred), "--name", "theirs",
            "--json", str(tmp_path / "s.json"), "--out", str(tmp_path / "rep"), "--store", str(tmp_path / "h.sqlite")]
    assert main(args) == 1                      # one prediction is missing
    cap = capsys.readouterr()
    assert "normal_mean_deg / normal_median_deg" in cap.out and "bumpsPNG" in cap.out and "mean" in cap.out
    assert "bumpsPNG: theirs: ValueError:" in cap.out and "normals.npy (or .exr, .mat, .txt): missing" in cap.out
    data = json.loads((tmp_path / "s.json").read_text())
    sc = {(r["object"], r["algorithm"]): r["scores"] for r in data["rows"]}
    assert sc[("ballPNG", "woodham1980")]["normal_mean_deg"] < 0.05
    assert sc[("ballPNG", "theirs")]["normal_mean_deg"] == 0.0 and sc[("bumpsPNG", "theirs")] == {}
    assert sc[("ballPNG", "flipped")]["normal_median_deg"] > 10
    from pbrbench.bench.store import Store

    with Store(tmp_path / "h.sqlite") as st:
        (run,) = st.runs()
        scores = st.scores(run["id"])
    assert run["quality"] == "real" and {s["condition"] for s in scores} == {"real"}
    assert {s["scene"] for s in scores} == {"diligent:ballPNG", "diligent:bumpsPNG"}
    assert main(["evaluate", "photometric_stereo", str(tmp_path / "pred"), "--no-report",
                 "--store", str(tmp_path / "h2.sqlite")]) == 1
    assert "no DiLiGenT object folder" in capsys.readouterr().err


def test_data_warnings_reach_the_evaluation_notes_and_result_json(tmp_path, capsys):
    """Light directions of length 2 are normalised with a warning: a note of `evaluate`, a
    `pbrbench: warning:` line and an entry of result.json for `infer`; the normals stay right."""
    from pbrbench.bench.realdata import evaluate_folder

    d = tmp_path / "ballPNG"
    diligent_object(d)
    (d / "light_directions.txt").write_text("\n".join(" ".join(f"{2 * v:.8f}" for v in r) for r in DIRS) + "\n")
    ev = evaluate_folder("photometric_stereo", d, methods=("woodham1980",), store_run=False, report=False)
    assert any("not of unit length" in n and "light_directions.txt" in n for n in ev.notes), ev.notes
    assert ev.rows[0]["scores"]["normal_mean_deg"] < 0.05
    assert main(["infer", "photometric-stereo", str(d), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "pbrbench: warning:" in err and "not of unit length" in err
    res = json.loads((tmp_path / "out" / "result.json").read_text())
    assert len(res["warnings"]) == 1 and "light_directions.txt" in res["warnings"][0]


def test_indices_out_of_range_are_a_one_line_error(tmp_path):
    diligent_object(tmp_path / "a")
    with pytest.raises(UserError, match="indices: 40 is not a light of the 12"):
        load_diligent(tmp_path / "a", indices=[0, 1, 40])
    assert len(load_diligent(tmp_path / "a", indices=range(2, 12)).files) == 10
