"""Scene files: malformed files give one-line errors naming the file and the key path (exit 1, no
traceback); every scene of the library validates and follows the naming contract."""

from __future__ import annotations

import math

import pytest

from pbrbench.cli.main import main
from pbrbench.scene.load import library_files, load_library, load_scene_file

GOOD = """
name = "t"
description = "test scene"

[render]
resolution = 16
spp = 4

[materials.paint]
type = "diffuse"
albedo = 0.5

[[shapes]]
type = "sphere"
material = "paint"

[[lights]]
type = "directional"
direction = [0.0, 0.0, 1.0]

[[lights]]
type = "point"
position = [1.0, 1.0, 2.0]
"""

# (label, replacement of GOOD or full text, substrings the message must contain: the key path and the reason)
BAD = [
    ("typo in a light key", GOOD.replace("position = [1.0, 1.0, 2.0]", "position = [1.0, 1.0, 2.0]\ndrection = [0.0, 1.0, 0.0]"),
     ["lights[1].drection: unknown key (did you mean 'direction'?)"]),
    ("typo in the camera", GOOD + "\n[camera]\nhalf_widht = 2.0\n", ["camera.half_widht: unknown key (did you mean 'half_width'?)"]),
    ("unknown shape type", GOOD.replace('type = "sphere"', 'type = "sphear"'), ["shapes[0].type: unknown type 'sphear'", "sphere"]),
    ("albedo above 1", GOOD.replace("albedo = 0.5", "albedo = 1.5"), ["materials.paint.albedo", "[0, 1]"]),
    ("undefined material", GOOD.replace('material = "paint"', 'material = "pain"'), ["shapes[0].material", "'pain' is not defined"]),
    ("TOML syntax error", GOOD.replace("spp = 4", "spp = = 4"), ["TOML syntax error"]),
    ("bad resolution", GOOD.replace("resolution = 16", "resolution = -3"), ["render.resolution", "integer 4..8192"]),
    ("sweep over a missing key", GOOD + '\n[sweep]\n"materials.paint.albdo" = [0.1, 0.5]\n',
     ["sweep.materials.paint.albdo: key path does not exist"]),
    ("sweep value not a list", GOOD + '\n[sweep]\n"materials.paint.albedo" = 0.5\n', ["sweep.materials.paint.albedo: must be a non-empty list"]),
    ("no light", GOOD.split("[[lights]]")[0], ["the scene has no light"]),
    ("zero direction", GOOD.replace("direction = [0.0, 0.0, 1.0]", "direction = [0.0, 0.0, 0.0]"),
     ["lights[0].direction", "non-zero vector"]),
    ("missing required light key", GOOD.replace("position = [1.0, 1.0, 2.0]", ""), ["lights[1].position: required key is missing"]),
    ("unknown surface", GOOD.replace('type = "sphere"', 'type = "heightfield"\nsurface = "bumpz"'), ["shapes[0]", "unknown surface 'bumpz'"]),
    ("negative irradiance", GOOD.replace("direction = [0.0, 0.0, 1.0]", "direction = [0.0, 0.0, 1.0]\nirradiance = -1.0"),
     ["lights[0].irradiance", ">= 0"]),
    ("unknown top-level key", "descripton = 'x'\n" + GOOD, ["descripton: unknown key (did you mean 'description'?)"]),
    ("min_resolution above resolution", GOOD.replace("spp = 4", "spp = 4\nmin_resolution = 32"),
     ["render", "min_resolution (32) must not exceed", "[16, 16]"]),
    ("min_groups above spp", GOOD.replace("spp = 4", "spp = 4\nmin_groups = 8"),
     ["render", "min_groups (8) must not exceed spp (4)", "raise spp"]),
    ("min_groups above 16", GOOD.replace("spp = 4", "spp = 64\nmin_groups = 17"), ["render.min_groups", "16"]),
]


@pytest.mark.parametrize("label,text,expected", BAD, ids=[b[0] for b in BAD])
def test_malformed_scene_file_one_line_error(tmp_path, capsys, label, text, expected):
    path = tmp_path / "bad_scene.toml"
    path.write_text(text)
    rc = main(["render", str(path), "--quality", "draft", "--cache", str(tmp_path / "cache"), "--no-previews"])
    err = capsys.readouterr().err.strip()
    assert rc == 1, f"{label}: exit code {rc}, stderr {err!r}"
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, f"{label}: expected one line, got {lines}"
    assert str(path) in lines[0], f"{label}: the message does not name the file: {lines[0]}"
    for e in expected:
        assert e in lines[0], f"{label}: {e!r} not in {lines[0]!r}"


def test_good_file_loads(tmp_path):
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    (spec,) = load_scene_file(path)
    assert spec.name == "t" and len(spec.lights) == 2


def test_min_resolution_floors_the_draft_resolution_and_an_unset_one_leaves_the_hash(tmp_path):
    from pbrbench.quality import get_quality

    big = GOOD.replace("resolution = 16", "resolution = [256, 128]")
    plain = tmp_path / "plain.toml"
    plain.write_text(big)
    floored = tmp_path / "floored.toml"
    floored.write_text(big.replace("spp = 4", "spp = 4\nmin_resolution = 64"))
    (a,), (b,) = load_scene_file(plain), load_scene_file(floored)
    draft, standard = get_quality("draft"), get_quality("standard")
    assert draft.resolution(a.render.resolution, a.render.min_resolution) == (64, 32)     # / 4, at least 32 px
    assert draft.resolution(b.render.resolution, b.render.min_resolution) == (128, 64)    # the smaller side >= 64
    assert standard.resolution(b.render.resolution, b.render.min_resolution) == (256, 128)
    # a file without the key hashes as before the key existed (caches and baselines stay valid)
    assert "min_resolution" not in a.canonical()["render"]
    assert a.content_hash() != b.content_hash()


def test_min_groups_raises_the_sample_groups_at_every_profile_and_an_unset_one_leaves_the_hash(tmp_path):
    from pbrbench.quality import get_quality

    plain = tmp_path / "plain.toml"
    plain.write_text(GOOD.replace("spp = 4", "spp = 72"))
    more = tmp_path / "more.toml"
    more.write_text(GOOD.replace("spp = 4", "spp = 72\nmin_groups = 8"))
    (a,), (b,) = load_scene_file(plain), load_scene_file(more)
    draft, standard = get_quality("draft"), get_quality("standard")
    assert draft.groups_for(a.render.min_groups) == 4 and standard.groups_for(a.render.min_groups) == 4
    assert draft.groups_for(b.render.min_groups) == 8 and standard.groups_for(b.render.min_groups) == 8
    assert draft.groups_for(2) == 4                     # never fewer than the profile's
    # at least two samples per group at draft: 72 / 16 rounds to 4, raised to 8 for 4 groups, 16 for 8
    assert draft.spp(a.render.spp) == 8 and draft.spp(b.render.spp, 8) == 16
    assert standard.spp(b.render.spp, 8) == 72          # the file's count, split eight ways
    assert "min_groups" not in a.canonical()["render"]
    assert a.content_hash() != b.content_hash()


def test_a_scene_without_a_seed_gets_its_own_and_a_given_seed_is_kept(tmp_path):
    from pbrbench.render.groundtruth import SEED_MOD, SEED_STRIDE
    from pbrbench.scene.spec import SEED_SPAN, default_seed

    sweep = tmp_path / "sweep.toml"
    sweep.write_text(GOOD + '\n[sweep]\n"materials.paint.albedo" = [0.1, 0.5, 0.9]\n')
    members = load_scene_file(sweep)
    seeds = [m.render.seed for m in members]
    assert len(set(seeds)) == 3 and all(1 <= s <= SEED_SPAN for s in seeds)   # one noise stream per member
    assert seeds == [default_seed(m.name) for m in members]
    again = [m.render.seed for m in load_scene_file(sweep)]
    assert again == seeds                                       # deterministic: the same file, the same seeds
    for given in (0, 12345):
        f = tmp_path / f"given{given}.toml"
        f.write_text(GOOD.replace("spp = 4", f"spp = 4\nseed = {given}"))
        assert [m.render.seed for m in load_scene_file(f)] == [given]
    # the renderer's pass seeds 16 (1000 seed + offset) + group do not wrap around 2^32 for any
    # derived seed, --render-seed offset up to 4096, pass offset below 1000 and group below 16
    assert SEED_STRIDE * ((SEED_SPAN + 4096) * 1000 + 999) + 15 < SEED_MOD


# ------------------------------------------------------------------------------ library
def test_no_two_library_scenes_share_their_render_noise():
    # a mean over scenes adds their standard errors in quadrature: their noise must be independent
    # (sphere_5lights and ps_near_distant[radius=1] are the same scene; with one seed they gave the
    # same noise, and the mean of the two counted one measurement twice)
    lib = load_library()
    seeds = {}
    for name, spec in lib.items():
        assert spec.render.seed not in seeds, f"{name} and {seeds.get(spec.render.seed)} share render.seed"
        seeds[spec.render.seed] = name


def test_every_library_scene_validates():
    lib = load_library()
    assert len(lib) >= 60
    for name, spec in lib.items():
        assert spec.description.strip(), name
        assert spec.reference.strip(), f"{name}: no reference to the chapter"
        assert "§" in spec.reference, f"{name}: reference should cite a section: {spec.reference!r}"


CONTRACT = [
    "sphere_5lights", "sphere_12lights", "sphere_textured", "ps_bumps", "ps_vase", "ps_cup", "ps_groove",
    "shadow_near", "shadow_far", "shadow_small", "groove_reflex_parallel", "groove_reflex_bisector", "cylinder_bump",
    "room_black", "room_white", "colour_bleeding", "mondrian_grey", "mondrian_colour", "mondrian_shadow", "mondrian_folded",
    "hdr_scene", "sfs_sphere", "sfs_vase", "sfs_random", "specular_sphere", "specular_shapes",
]
AREA_TWINS = ["sphere_5lights", "sphere_12lights", "sphere_textured", "ps_bumps", "ps_vase", "ps_cup", "ps_groove",
              "sfs_sphere", "sfs_vase", "sfs_random"]


def test_naming_contract_families_exist():
    stems = {f.stem for f in library_files()}
    missing = [f for f in CONTRACT + [a + "_area" for a in AREA_TWINS] if f not in stems]
    assert not missing, f"missing scene files: {missing}"


def _norm(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


@pytest.mark.parametrize("family", AREA_TWINS[:7])
def test_area_twins_match_distant_lights(family):
    """Area twins: identical rectangles, centred along the distant directions, facing the origin."""
    d = load_scene_file(next(f for f in library_files() if f.stem == family))
    a = load_scene_file(next(f for f in library_files() if f.stem == family + "_area"))
    assert len(d) == len(a)
    for sd, sa in zip(d, a, strict=True):
        assert len(sd.light_set) == len(sa.light_set)
        dists, sizes, rads = set(), set(), set()
        for ld, la in zip(sd.light_set, sa.light_set, strict=True):
            assert ld.type == "directional" and la.type == "area"
            c = _norm(la.center)
            assert max(abs(x - y) for x, y in zip(c, _norm(ld.direction), strict=True)) < 1e-5
            assert max(abs(x + y) for x, y in zip(_norm(la.normal), c, strict=True)) < 1e-5
            dists.add(round(math.sqrt(sum(x * x for x in la.center)), 4))
            sizes.add(tuple(la.size))
            rads.add(tuple(la.radiance))
        assert len(dists) == len(sizes) == len(rads) == 1


@pytest.mark.parametrize("family", ["ps_bumps", "ps_vase", "ps_cup", "ps_groove"])
def test_albedo_sweeps(family):
    specs = load_scene_file(next(f for f in library_files() if f.stem == family))
    names = [s.name for s in specs]
    assert names == [f"{family}[albedo={a:g}]" for a in (0.1, 0.3, 0.5, 0.7, 0.9)]
    assert all("paint" in s.materials for s in specs)


@pytest.mark.parametrize("family", AREA_TWINS + ["mondrian_grey", "mondrian_colour", "mondrian_shadow", "mondrian_folded"])
def test_area_twins_differ_only_in_their_lights_and_render_direct_light(family):
    d = load_scene_file(next(f for f in library_files() if f.stem == family))
    a = load_scene_file(next(f for f in library_files() if f.stem == family + "_area"))
    assert len(d) == len(a)
    for sd, sa in zip(d, a, strict=True):
        assert sd.shapes == sa.shapes and sd.materials == sa.materials
        assert sd.camera.half_width == sa.camera.half_width and sd.render.resolution == sa.render.resolution
        assert sa.render.max_depth == 2 and {li.type for li in sa.lights + sa.light_set} == {"area"}
        assert ("convex" in sd.tags) == ("convex" in sa.tags) and ("concave" in sd.tags) == ("concave" in sa.tags)
