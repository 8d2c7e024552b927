"""Write the corpus of malformed scene files (``tests/corpus/scenes/``) and their data files.

Each file starts with comment lines that the tests read::

    # class: nonfinite            the class of mistake
    # expect: shapes[0].radius    substrings of the one-line error (all must appear)
    # stage: render               (optional) only a render can find it; the test renders it

Run ``python -m tests.corpus.make_scenes`` after changing the table; the files are committed.
"""

from __future__ import annotations

import io
import struct
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "scenes"

SPHERE = '[[shapes]]\ntype = "sphere"\nname = "ball"\n'
SUN = '[[lights]]\ntype = "directional"\ndirection = [0.0, 0.0, 1.0]\nirradiance = 3.0\n'
RENDER = "[render]\nresolution = 16\nspp = 4\n"


def scene(name="corpus", shapes=SPHERE, lights=SUN, render=RENDER, camera="", extra="", head=""):
    return (f'{head}name = "{name}"\ndescription = "corpus scene"\n{extra}\n{camera}\n{render}\n{shapes}\n{lights}\n')


def shape(body: str) -> str:
    return "[[shapes]]\n" + body.strip() + "\n"


def light(body: str, table="lights") -> str:
    return f"[[{table}]]\n" + body.strip() + "\n"


def cam(body: str) -> str:
    return "[camera]\n" + body.strip() + "\n"


def rnd(body: str) -> str:
    return "[render]\n" + body.strip() + "\n"


HF = 'type = "heightfield"\nname = "hf"\nresolution = 16\n'

# (file stem, class, toml text, expected substrings, stage)
CASES: list[tuple[str, str, str, list[str], str]] = [
    # ------------------------------------------------------------------ non-finite numbers
    ("sphere-radius-inf", "nonfinite", scene(shapes=shape('type = "sphere"\nradius = inf')), ["shapes[0].radius", "finite"], "load"),
    ("sphere-radius-nan", "nonfinite", scene(shapes=shape('type = "sphere"\nradius = nan')), ["shapes[0].radius", "finite"], "load"),
    ("sphere-center-nan", "nonfinite", scene(shapes=shape('type = "sphere"\ncenter = [nan, 0.0, 0.0]')), ["shapes[0].center", "finite"], "load"),
    ("sphere-center-huge", "nonfinite", scene(shapes=shape('type = "sphere"\ncenter = [1e300, 0.0, 0.0]')), ["shapes[0].center", "1e+06"], "load"),
    ("rotate-angle-nan", "nonfinite", scene(shapes=shape('type = "sphere"\nrotate = [{ axis = [0.0, 1.0, 0.0], angle = nan }]')),
     ["shapes[0].rotate[0].angle", "finite"], "load"),
    ("rotate-angle-inf", "nonfinite", scene(shapes=shape('type = "sphere"\nrotate = [{ axis = [0.0, 1.0, 0.0], angle = -inf }]')),
     ["shapes[0].rotate[0].angle", "finite"], "load"),
    ("rotate-axis-inf", "nonfinite", scene(shapes=shape('type = "sphere"\nrotate = [{ axis = [inf, 1.0, 0.0], angle = 10.0 }]')),
     ["shapes[0].rotate[0].axis", "finite"], "load"),
    ("point-position-inf", "nonfinite", scene(lights=light('type = "point"\nposition = [0.0, 0.0, inf]')),
     ["lights[0].position", "finite"], "load"),
    ("directional-direction-nan", "nonfinite", scene(lights=light('type = "directional"\ndirection = [nan, 0.0, 1.0]')),
     ["lights[0].direction", "finite"], "load"),
    ("area-center-inf", "nonfinite", scene(lights=light('type = "area"\ncenter = [0.0, inf, 2.0]')), ["lights[0].center", "finite"], "load"),
    ("area-size-inf", "nonfinite", scene(lights=light('type = "area"\ncenter = [0.0, 0.0, 2.0]\nsize = [inf, 1.0]')),
     ["lights[0].size", "finite"], "load"),
    ("area-normal-nan", "nonfinite", scene(lights=light('type = "area"\ncenter = [0.0, 0.0, 2.0]\nnormal = [0.0, nan, -1.0]')),
     ["lights[0].normal", "finite"], "load"),
    ("irradiance-inf", "nonfinite", scene(lights=light('type = "directional"\ndirection = [0.0, 0.0, 1.0]\nirradiance = inf')),
     ["lights[0].irradiance", "finite"], "load"),
    ("intensity-nan", "nonfinite", scene(lights=light('type = "point"\nposition = [0.0, 0.0, 3.0]\nintensity = [1.0, nan, 1.0]')),
     ["lights[0].intensity", "finite"], "load"),
    ("ambient-inf", "nonfinite", scene(lights=light('type = "ambient"\nradiance = inf')), ["lights[0].radiance", "finite"], "load"),
    ("camera-origin-inf", "nonfinite", scene(camera=cam("origin = [0.0, 0.0, inf]")), ["camera.origin", "finite"], "load"),
    ("camera-target-nan", "nonfinite", scene(camera=cam("target = [nan, 0.0, 0.0]")), ["camera.target", "finite"], "load"),
    ("camera-up-nan", "nonfinite", scene(camera=cam("up = [0.0, nan, 0.0]")), ["camera.up", "finite"], "load"),
    ("camera-half-width-1e308", "nonfinite", scene(camera=cam("half_width = 1e308")), ["camera.half_width", "1e+06"], "load"),
    ("camera-half-width-inf", "nonfinite", scene(camera=cam("half_width = inf")), ["camera.half_width", "finite"], "load"),
    ("camera-far-clip-inf", "nonfinite", scene(camera=cam("far_clip = inf")), ["camera.far_clip", "finite"], "load"),
    ("camera-near-clip-nan", "nonfinite", scene(camera=cam("near_clip = nan")), ["camera.near_clip", "finite"], "load"),
    ("camera-fov-nan", "nonfinite", scene(camera=cam('type = "perspective"\nfov = nan')), ["camera.fov", "finite"], "load"),
    ("box-size-nan", "nonfinite", scene(shapes=shape('type = "box"\nsize = [nan, 1.0, 1.0]')), ["shapes[0].size", "finite"], "load"),
    ("box-center-inf", "nonfinite", scene(shapes=shape('type = "box"\ncenter = [0.0, -inf, 0.0]')), ["shapes[0].center", "finite"], "load"),
    ("cylinder-p0-nan", "nonfinite", scene(shapes=shape('type = "cylinder"\np0 = [nan, 0.0, 0.0]')), ["shapes[0].p0", "finite"], "load"),
    ("cylinder-radius-inf", "nonfinite", scene(shapes=shape('type = "cylinder"\nradius = inf')), ["shapes[0].radius", "finite"], "load"),
    ("disk-radius-nan", "nonfinite", scene(shapes=shape('type = "disk"\nradius = nan')), ["shapes[0].radius", "finite"], "load"),
    ("rectangle-center-inf", "nonfinite", scene(shapes=shape('type = "rectangle"\ncenter = [inf, 0.0, 0.0]')),
     ["shapes[0].center", "finite"], "load"),
    ("heightfield-z-scale-nan", "nonfinite", scene(shapes=shape(HF + 'surface = "sphere"\nz_scale = nan')),
     ["shapes[0].z_scale", "finite"], "load"),
    ("heightfield-z-scale-inf", "nonfinite", scene(shapes=shape(HF + 'surface = "sphere"\nz_scale = inf')),
     ["shapes[0].z_scale", "finite"], "load"),
    ("heightfield-half-width-inf", "nonfinite", scene(shapes=shape(HF + 'surface = "sphere"\nhalf_width = inf')),
     ["shapes[0].half_width", "finite"], "load"),
    ("heightfield-center-nan", "nonfinite", scene(shapes=shape(HF + 'surface = "sphere"\ncenter = [0.0, 0.0, nan]')),
     ["shapes[0].center", "finite"], "load"),
    ("heightfield-param-nan", "nonfinite", scene(shapes=shape(HF + 'surface = "sphere"\nparams = { radius = nan }')),
     ["shapes[0].params.radius", "finite"], "load"),
    ("plastic-ior-nan", "nonfinite", scene(extra='[materials.m]\ntype = "plastic"\nint_ior = nan\n',
                                            shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.int_ior", "finite"], "load"),
    ("roughplastic-alpha-nan", "nonfinite", scene(extra='[materials.m]\ntype = "roughplastic"\nalpha = nan\n',
                                                   shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.alpha", "finite"], "load"),
    ("checker-scale-inf", "nonfinite", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "checker", scale = inf }\n',
                                              shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.scale", "finite"], "load"),
    ("mondrian-low-nan", "nonfinite", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "mondrian", low = nan }\n',
                                             shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.low", "finite"], "load"),
    ("albedo-nan", "nonfinite", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = nan\n',
                                       shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo", "finite"], "load"),
    ("point-position-huge", "nonfinite", scene(lights=light('type = "point"\nposition = [0.0, 0.0, 1e30]')),
     ["lights[0].position", "1e+06"], "load"),
    ("irradiance-huge", "nonfinite", scene(lights=light('type = "directional"\ndirection = [0.0, 0.0, 1.0]\nirradiance = 1e30')),
     ["lights[0].irradiance", "<= 1e+12"], "load"),
    # ------------------------------------------------------------------ degenerate geometry
    ("rectangle-size-zero", "degenerate", scene(shapes=shape('type = "rectangle"\nsize = [0.0, 1.0]')), ["shapes[0].size", ">= 1e-06"], "load"),
    ("rectangle-size-negative", "degenerate", scene(shapes=shape('type = "rectangle"\nsize = [-2.0, 1.0]')), ["shapes[0].size", ">= 1e-06"], "load"),
    ("box-size-negative", "degenerate", scene(shapes=shape('type = "box"\nsize = [1.0, -1.0, 1.0]')), ["shapes[0].size", ">= 1e-06"], "load"),
    ("box-size-zero", "degenerate", scene(shapes=shape('type = "box"\nsize = [1.0, 1.0, 0.0]')), ["shapes[0].size", ">= 1e-06"], "load"),
    ("cylinder-equal-ends", "degenerate", scene(shapes=shape('type = "cylinder"\np0 = [0.0, 0.0, 0.5]\np1 = [0.0, 0.0, 0.5]')),
     ["shapes[0]", "p0", "p1"], "load"),
    ("sphere-radius-tiny", "degenerate", scene(shapes=shape('type = "sphere"\nradius = 1e-300')), ["shapes[0].radius", "1e-06"], "load"),
    ("sphere-radius-zero", "degenerate", scene(shapes=shape('type = "sphere"\nradius = 0.0')), ["shapes[0].radius", "1e-06"], "load"),
    ("disk-radius-negative", "degenerate", scene(shapes=shape('type = "disk"\nradius = -1.0')), ["shapes[0].radius", "1e-06"], "load"),
    ("camera-half-width-tiny", "degenerate", scene(camera=cam("half_width = 1e-300")), ["camera.half_width", "1e-06"], "load"),
    ("area-normal-parallel-up", "degenerate", scene(lights=light('type = "area"\ncenter = [0.0, 0.0, 2.0]\nnormal = [0.0, 1.0, 0.0]\nup = [0.0, 2.0, 0.0]')),
     ["lights[0]", "up", "parallel"], "load"),
    ("rotation-axis-zero", "degenerate", scene(shapes=shape('type = "sphere"\nrotate = [{ axis = [0.0, 0.0, 0.0], angle = 10.0 }]')),
     ["shapes[0].rotate[0].axis", "non-zero"], "load"),
    ("camera-clip-order", "degenerate", scene(camera=cam("near_clip = 10.0\nfar_clip = 1.0")), ["camera", "near_clip"], "load"),
    ("camera-origin-is-target", "degenerate", scene(camera=cam("origin = [0.0, 0.0, 0.0]")), ["camera", "target - origin"], "load"),
    ("camera-up-parallel", "degenerate", scene(camera=cam("up = [0.0, 0.0, 1.0]")), ["camera", "parallel"], "load"),
    ("directional-direction-tiny", "degenerate", scene(lights=light('type = "directional"\ndirection = [0.0, 0.0, 1e-300]')),
     ["lights[0].direction", "non-zero"], "load"),
    ("area-size-zero", "degenerate", scene(lights=light('type = "area"\ncenter = [0.0, 0.0, 2.0]\nsize = [0.0, 1.0]')),
     ["lights[0].size", ">= 1e-06"], "load"),
    ("fov-180", "degenerate", scene(camera=cam('type = "perspective"\nfov = 180.0')), ["camera.fov"], "load"),
    # ---------------------------------------------------- black ground truth (found by rendering)
    ("black-light-behind", "black", scene(lights=light('type = "directional"\ndirection = [0.0, 0.0, -1.0]\nirradiance = 3.0')),
     ["corpus", "radiance is zero"], "render"),
    ("black-camera-away", "black", scene(camera=cam("origin = [0.0, 0.0, 5.0]\ntarget = [0.0, 0.0, 10.0]")),
     ["corpus", "sees no geometry"], "render"),
    ("black-beyond-far-clip", "black", scene(camera=cam("far_clip = 2.0")), ["corpus", "sees no geometry"], "render"),
    # ------------------------------------------------------------------ heightfield params
    ("params-misspelt", "params", scene(shapes=shape(HF + 'surface = "sphere"\nparams = { radiuss = 0.9 }')),
     ["shapes[0].params.radiuss", "did you mean 'radius'"], "load"),
    ("params-string", "params", scene(shapes=shape(HF + 'surface = "sphere"\nparams = { radius = "big" }')),
     ["shapes[0].params.radius"], "load"),
    ("params-list-for-scalar", "params", scene(shapes=shape(HF + 'surface = "sphere"\nparams = { radius = [1.0, 2.0] }')),
     ["shapes[0].params.radius", "a number"], "load"),
    ("params-scalar-for-list", "params", scene(shapes=shape(HF + 'surface = "bumps"\nparams = { amplitudes = 0.3 }')),
     ["shapes[0].params.amplitudes", "list"], "load"),
    ("params-bumps-centers-3d", "params", scene(shapes=shape(HF + 'surface = "bumps"\nparams = { centers = [[0.0, 0.0, 0.0]], amplitudes = [0.3], sigmas = [0.2] }')),
     ["shapes[0].params.centers", "[x, y]"], "load"),
    ("params-bumps-lengths", "params", scene(shapes=shape(HF + 'surface = "bumps"\nparams = { amplitudes = [0.3, 0.2] }')),
     ["shapes[0].params", "bumps"], "load"),
    ("params-empty-domain", "params", scene(shapes=shape(HF + 'surface = "sphere"\nparams = { radius = 0.0 }')),
     ["shapes[0].params", "no triangle"], "load"),
    ("params-n-waves-huge", "params", scene(shapes=shape(HF + 'surface = "random_smooth"\nparams = { n_waves = 1000000000 }')),
     ["shapes[0].params.n_waves", "<= 1000"], "load"),
    ("params-seed-negative", "params", scene(shapes=shape(HF + 'surface = "random_smooth"\nparams = { seed = -3 }')),
     ["shapes[0].params.seed", ">= 0"], "load"),
    ("params-bool", "params", scene(shapes=shape(HF + 'surface = "sphere"\nparams = { radius = true }')),
     ["shapes[0].params.radius"], "load"),
    ("params-with-path", "params", scene(shapes=shape(HF + 'path = "data/height_ok.npy"\nparams = { radius = 1.0 }')),
     ["shapes[0].params", "surface"], "load"),
    ("params-float-for-int", "params", scene(shapes=shape(HF + 'surface = "random_smooth"\nparams = { n_waves = 2.5 }')),
     ["shapes[0].params.n_waves", "integer"], "load"),
    ("params-huge-value", "params", scene(shapes=shape(HF + 'surface = "plane"\nparams = { fx = 1e300 }')),
     ["shapes[0].params.fx", "1e+06"], "load"),
    # ------------------------------------------------------------------ data files
    ("npy-text", "datafile", scene(shapes=shape(HF + 'path = "data/text.npy"')), ["shapes[0].path", "data/text.npy", "not a NumPy .npy file"], "load"),
    ("npy-pickle", "datafile", scene(shapes=shape(HF + 'path = "data/pickle.npy"')), ["shapes[0].path", "pickle"], "load"),
    ("npy-object", "datafile", scene(shapes=shape(HF + 'path = "data/object.npy"')), ["shapes[0].path", "object"], "load"),
    ("npy-header-lies", "datafile", scene(shapes=shape(HF + 'path = "data/lying_header.npy"')), ["shapes[0].path", "header"], "load"),
    ("npy-too-large", "datafile", scene(shapes=shape(HF + 'path = "data/huge_header.npy"')), ["shapes[0].path", "limit"], "load"),
    ("npy-complex", "datafile", scene(shapes=shape(HF + 'path = "data/complex.npy"')), ["shapes[0].path", "complex"], "load"),
    ("npy-nan", "datafile", scene(shapes=shape(HF + 'path = "data/nan.npy"')), ["shapes[0].path", "non-finite"], "load"),
    ("npy-3d", "datafile", scene(shapes=shape(HF + 'path = "data/cube.npy"')), ["shapes[0].path", "2-D"], "load"),
    ("npy-empty", "datafile", scene(shapes=shape(HF + 'path = "data/empty.npy"')), ["shapes[0].path", "at least 2 x 2"], "load"),
    ("npy-structured", "datafile", scene(shapes=shape(HF + 'path = "data/structured.npy"')), ["shapes[0].path", "dtype"], "load"),
    ("npy-truncated", "datafile", scene(shapes=shape(HF + 'path = "data/truncated.npy"')), ["shapes[0].path", "truncated"], "load"),
    ("npy-missing", "datafile", scene(shapes=shape(HF + 'path = "data/nope.npy"')), ["shapes[0].path", "does not exist"], "load"),
    ("npy-directory", "datafile", scene(shapes=shape(HF + 'path = "data"')), ["shapes[0].path", "not a file"], "load"),
    ("npy-parent-dir", "datafile", scene(shapes=shape(HF + 'path = "../outside.npy"')), ["shapes[0].path", "outside"], "load"),
    ("npy-absolute", "datafile", scene(shapes=shape(HF + 'path = "/etc/passwd"')), ["shapes[0].path", "outside"], "load"),
    ("npy-huge-values", "datafile", scene(shapes=shape(HF + 'path = "data/huge_values.npy"')), ["shapes[0].path", "1e+06"], "load"),
    ("texture-above-one", "datafile", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "image", path = "data/albedo_bright.npy" }\n',
                                             shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.path", "[0, 1]"], "load"),
    ("texture-four-channels", "datafile", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "image", path = "data/albedo_rgba.npy" }\n',
                                                 shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.path", "(H, W, 3)"], "load"),
    ("texture-text", "datafile", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "image", path = "data/text.npy" }\n',
                                        shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.path", "not a NumPy .npy file"], "load"),
    ("texture-nan", "datafile", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "image", path = "data/nan.npy" }\n',
                                       shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.path", "non-finite"], "load"),
    ("texture-absolute", "datafile", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "image", path = "/etc/hostname" }\n',
                                            shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.path", "outside"], "load"),
    ("texture-parent-dir", "datafile", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "image", path = "data/../../outside.npy" }\n',
                                              shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.path", "outside"], "load"),
    ("texture-inline-material", "datafile", scene(shapes=shape('type = "sphere"\nmaterial = { type = "diffuse", albedo = { type = "image", path = "data/pickle.npy" } }')),
     ["shapes[0].material.albedo.path", "pickle"], "load"),
    ("texture-empty-path", "datafile", scene(extra='[materials.m]\ntype = "diffuse"\nalbedo = { type = "image", path = "" }\n',
                                              shapes=shape('type = "sphere"\nmaterial = "m"')), ["materials.m.albedo.path"], "load"),
    # ------------------------------------------------------------------ names
    ("name-dotdot", "name", scene(name=".."), ["name", "'..'"], "load"),
    ("name-dot", "name", scene(name="."), ["name", "'.'"], "load"),
    ("name-dots", "name", scene(name="...."), ["name"], "load"),
    ("name-space", "name", scene(name=" "), ["name"], "load"),
    ("name-empty", "name", scene(name=""), ["name"], "load"),
    ("name-leading-dot", "name", scene(name=".hidden"), ["name", "start"], "load"),
    ("name-too-long", "name", scene(name="x" * 300), ["name", "characters"], "load"),
    ("name-slash", "name", scene(name="a/b"), ["name"], "load"),
    ("name-control-char", "name", scene(name="bad\\u001b[31mred"), ["name"], "load"),
    ("sweep-duplicate-values", "name", scene(extra='[sweep]\n"lights[0].irradiance" = [1.0, 2.0, 1.0]\n'), ["sweep", "twice"], "load"),
    # ------------------------------------------------------------------ render numbers
    ("seed-64bit", "render", scene(render=rnd("resolution = 16\nspp = 4\nseed = 9223372036854775807")), ["render.seed", "<= 2097151"], "load"),
    ("seed-negative", "render", scene(render=rnd("resolution = 16\nspp = 4\nseed = -1")), ["render.seed", ">= 0"], "load"),
    ("max-resolution-max-spp", "expansion", scene(render=rnd("resolution = 8192\nspp = 1048576")), ["render", "samples", "PBRBENCH_ALLOW_LARGE"], "load"),
    ("spp-zero", "render", scene(render=rnd("resolution = 16\nspp = 0")), ["render.spp"], "load"),
    ("spp-float", "render", scene(render=rnd("resolution = 16\nspp = 4.5")), ["render.spp"], "load"),
    ("resolution-float", "render", scene(render=rnd("resolution = 16.5\nspp = 4")), ["render.resolution"], "load"),
    ("resolution-three", "render", scene(render=rnd("resolution = [16, 16, 16]\nspp = 4")), ["render.resolution"], "load"),
    ("resolution-bool", "render", scene(render=rnd("resolution = true\nspp = 4")), ["render.resolution"], "load"),
    ("max-depth-negative", "render", scene(render=rnd("resolution = 16\nspp = 4\nmax_depth = -5")), ["render.max_depth"], "load"),
    ("max-depth-huge", "render", scene(render=rnd("resolution = 16\nspp = 4\nmax_depth = 9223372036854775807")), ["render.max_depth", "1024"], "load"),
    ("rr-depth-huge", "render", scene(render=rnd("resolution = 16\nspp = 4\nrr_depth = 4294967296")), ["render.rr_depth", "1024"], "load"),
    ("rr-depth-zero", "render", scene(render=rnd("resolution = 16\nspp = 4\nrr_depth = 0")), ["render.rr_depth"], "load"),
    ("sampler-unknown", "render", scene(render=rnd('resolution = 16\nspp = 4\nsampler = "sobol"')), ["render.sampler"], "load"),
    ("heightfield-resolution-huge", "render", scene(shapes=shape('type = "heightfield"\nsurface = "sphere"\nresolution = 100000')),
     ["shapes[0].resolution"], "load"),
    # ------------------------------------------------------------------ expansion limits
    ("sweep-1500", "expansion", scene(extra="[sweep]\n\"lights[0].irradiance\" = [" + ", ".join(str(i + 1) for i in range(1500)) + "]\n"),
     ["sweep", "1500 scenes", "PBRBENCH_ALLOW_LARGE"], "load"),
    ("sweep-10000", "expansion", scene(extra="[materials.m]\ntype = \"diffuse\"\nalbedo = 0.5\n[sweep]\n"
                                       + "\"materials.m.albedo\" = [" + ", ".join(f"{i / 100:.2f}" for i in range(100)) + "]\n"
                                       + "\"lights[0].irradiance\" = [" + ", ".join(str(i + 1) for i in range(100)) + "]\n",
                                       shapes=shape('type = "sphere"\nmaterial = "m"')), ["sweep", "10000 scenes", "PBRBENCH_ALLOW_LARGE"], "load"),
    ("light-set-1100", "expansion", scene(extra="light_set = [" + ", ".join('{ type = "directional", direction = [0, 0, 1] }' for _ in range(1100)) + "]\n"),
     ["light_set", "1100", "PBRBENCH_ALLOW_LARGE"], "load"),
    ("light-set-work", "expansion", scene(render=rnd("resolution = 1024\nspp = 4096"),
                                          lights="".join(light('type = "directional"\ndirection = [0.0, 0.0, 1.0]', "light_set") for _ in range(40))),
     ["samples", "PBRBENCH_ALLOW_LARGE"], "load"),
    # ------------------------------------------------------------------ file structure and types
    ("empty-file", "structure", "", ["required key is missing"], "load"),
    ("not-utf8", "structure", None, ["not a UTF-8 text file"], "load"),
    ("binary-garbage", "structure", None, ["scene files are TOML"], "load"),
    ("toml-syntax", "structure", scene().replace("spp = 4", "spp = = 4"), ["TOML syntax error"], "load"),
    ("shapes-empty", "structure", 'name = "corpus"\ndescription = "x"\nshapes = []\n' + SUN, ["shapes"], "load"),
    ("shapes-not-list", "structure", 'name = "corpus"\ndescription = "x"\nshapes = 5\n' + SUN, ["shapes"], "load"),
    ("lights-string", "structure", 'name = "corpus"\ndescription = "x"\nlights = "sun"\n' + SPHERE, ["lights"], "load"),
    ("radius-string", "types", scene(shapes=shape('type = "sphere"\nradius = "1.0"')), ["shapes[0].radius"], "load"),
    ("radius-bool", "types", scene(shapes=shape('type = "sphere"\nradius = true')), ["shapes[0].radius"], "load"),
    ("center-two", "types", scene(shapes=shape('type = "sphere"\ncenter = [0.0, 0.0]')), ["shapes[0].center"], "load"),
    ("center-string-item", "types", scene(shapes=shape('type = "sphere"\ncenter = [0.0, "a", 0.0]')), ["shapes[0].center"], "load"),
    ("radius-date", "types", scene(shapes=shape('type = "sphere"\nradius = 1979-05-27')), ["shapes[0].radius"], "load"),
    ("radius-int-max", "types", scene(shapes=shape('type = "sphere"\nradius = 9223372036854775807')), ["shapes[0].radius", "1e+06"], "load"),
    ("tags-string", "types", scene(extra='tags = "a"\n'), ["tags"], "load"),
    ("description-number", "types", scene().replace('description = "corpus scene"', "description = 5"), ["description"], "load"),
    ("description-missing", "types", scene().replace('description = "corpus scene"\n', ""), ["description: required key is missing"], "load"),
    ("name-number", "types", scene().replace('name = "corpus"', "name = 5"), ["name"], "load"),
    ("material-not-table", "types", scene(extra='materials = { m = 5 }\n', shapes=shape('type = "sphere"\nmaterial = "m"')),
     ["materials.m"], "load"),
    ("sweep-value-dict", "types", scene(extra='[sweep]\n"lights[0].irradiance" = [{ a = 1 }]\n'), ["lights[0].irradiance"], "load"),
    ("sweep-not-table", "types", scene(extra='sweep = 5\n'), ["sweep"], "load"),
    ("sweep-index-out-of-range", "types", scene(extra='[sweep]\n"lights[7].irradiance" = [1.0, 2.0]\n'), ["sweep", "lights[7]"], "load"),
    ("sweep-bad-key", "types", scene(extra='[sweep]\n"lights[0]..irradiance" = [1.0, 2.0]\n'), ["sweep", "key path"], "load"),
    ("light-type-missing", "types", scene(lights=light("direction = [0.0, 0.0, 1.0]")), ["lights[0]", "type"], "load"),
    ("light-type-number", "types", scene(lights=light("type = 3\ndirection = [0.0, 0.0, 1.0]")), ["lights[0]", "type"], "load"),
    ("shape-type-typo", "types", scene(shapes=shape('type = "sphear"')), ["shapes[0].type", "sphere"], "load"),
    ("unknown-key", "types", scene(shapes=shape('type = "sphere"\nradus = 1.0')), ["shapes[0].radus", "did you mean 'radius'"], "load"),
    ("max-depth-string", "types", scene(render=rnd('resolution = 16\nspp = 4\nmax_depth = "-1"')), ["render.max_depth"], "load"),
]


def npy_header(shape, dtype="<f8") -> bytes:
    """A valid .npy version 1.0 header for ``shape`` (no data)."""
    d = f"{{'descr': '{dtype}', 'fortran_order': False, 'shape': {tuple(shape)!r}, }}"
    pad = 64 - (10 + len(d) + 1) % 64
    d = d + " " * pad + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(d)) + d.encode("latin1")


def data_files(d: Path) -> None:
    d.mkdir(parents=True, exist_ok=True)
    yy, xx = np.mgrid[-1:1:16j, -1:1:16j]
    ok = 0.2 * np.exp(-(xx ** 2 + yy ** 2))
    np.save(d / "height_ok.npy", ok)
    np.save(HERE / "outside.npy", ok)
    (d / "text.npy").write_text("1.0 2.0 3.0\n4.0 5.0 6.0\n")
    buf = io.BytesIO()
    np.save(buf, np.array([{"a": 1}, None], dtype=object), allow_pickle=True)
    (d / "pickle.npy").write_bytes(buf.getvalue())
    buf = io.BytesIO()
    np.save(buf, np.array([[1, "x"], [2, "y"]], dtype=object), allow_pickle=True)
    (d / "object.npy").write_bytes(buf.getvalue())
    (d / "lying_header.npy").write_bytes(npy_header((1000000, 1000000)) + b"\x00" * 64)
    (d / "huge_header.npy").write_bytes(npy_header((1000000, 1000000)))
    np.save(d / "complex.npy", ok + 1j)
    nan = ok.copy()
    nan[3, 4] = np.nan
    np.save(d / "nan.npy", nan)
    np.save(d / "cube.npy", np.zeros((4, 4, 4)))
    np.save(d / "empty.npy", np.zeros((0, 0)))
    np.save(d / "structured.npy", np.zeros((4, 4), dtype=[("a", "<f4"), ("b", "<i4")]))
    full = io.BytesIO()
    np.save(full, ok)
    (d / "truncated.npy").write_bytes(full.getvalue()[:-100])
    np.save(d / "huge_values.npy", ok * 1e300)
    np.save(d / "albedo_bright.npy", np.full((8, 8, 3), 1.5))
    np.save(d / "albedo_rgba.npy", np.full((8, 8, 4), 0.5))


def main() -> None:
    OUT.mkdir(exist_ok=True)
    for old in OUT.glob("*.toml"):
        old.unlink()
    data_files(OUT / "data")
    for stem, cls, text, expect, stage in CASES:
        head = f"# class: {cls}\n" + "".join(f"# expect: {e}\n" for e in expect) + (f"# stage: {stage}\n" if stage != "load" else "")
        p = OUT / f"{cls}-{stem}.toml"
        if stem == "not-utf8":
            p.write_bytes(head.encode() + scene().encode().replace(b"corpus scene", b"corpus \xff\xfe scene"))
        elif stem == "binary-garbage":
            p.write_bytes(head.encode() + bytes(range(256)) * 4)
        else:
            p.write_text(head + text)
    print(f"{len(CASES)} scene files in {OUT}")


if __name__ == "__main__":
    main()
