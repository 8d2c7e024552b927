"""The libLLVM guard trusts no file name: a symlink or a renamed file is resolved and its version
read from the library itself (its ELF SONAME, else LLVMGetVersion); ``DRJIT_LIBLLVM_PATH=/dev/null``
means "none" (no bogus notice), and each notice is printed once per process."""

from __future__ import annotations

import glob
import os
import shutil

import pytest

from pbrbench.errors import UserError
from pbrbench.render import variant as V

REAL = sorted({os.path.realpath(p) for p in glob.glob("/usr/lib/*/libLLVM*.so*") if os.path.isfile(p)})
OLD = [p for p in REAL if (V.elf_soname(p) or "").startswith(("libLLVM-14", "libLLVM-15"))]
NEW = [p for p in REAL if (V.llvm_major_from_name(V.elf_soname(p) or "") or 0) >= V.MIN_LLVM]


@pytest.mark.skipif(not REAL, reason="no libLLVM installed")
def test_soname_is_read_from_the_file():
    for p in REAL:
        so = V.elf_soname(p)
        assert so and so.startswith("libLLVM"), (p, so)


def test_soname_of_a_non_elf_file_is_none(tmp_path):
    f = tmp_path / "libLLVM-19.so"
    f.write_bytes(b"not an ELF file at all")
    assert V.elf_soname(str(f)) is None
    assert V.elf_soname(str(tmp_path / "missing.so")) is None


@pytest.mark.skipif(not OLD, reason="no libLLVM 14/15 to disguise")
def test_a_new_name_for_an_old_library_is_not_trusted(tmp_path):
    link = tmp_path / "libLLVM-19.so"
    os.symlink(OLD[-1], link)
    copy = tmp_path / "libLLVM.so.20.1"
    shutil.copyfile(OLD[-1], copy)
    assert V.llvm_major(str(link)) < V.MIN_LLVM
    assert V.llvm_major(str(copy)) < V.MIN_LLVM
    best, found = V.find_llvm([str(tmp_path)])
    assert best is None and all(v is not None and v < V.MIN_LLVM for _, v in found)


@pytest.mark.skipif(not OLD, reason="no libLLVM 14/15 to disguise")
def test_disguised_old_library_in_the_environment_is_refused_with_a_notice(tmp_path, monkeypatch, capsys):
    link = tmp_path / "libLLVM-19.so"
    os.symlink(OLD[-1], link)
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(link))
    monkeypatch.setattr(V, "_NOTICED", set())
    monkeypatch.setattr(V, "cuda_available", lambda: False)
    c = V.choose_variant()
    assert c.llvm_path != str(link) and os.environ.get("DRJIT_LIBLLVM_PATH") != str(link)
    assert "older than 16" in c.notice and "a link to" in c.notice
    V.choose_variant()  # chosen again in the same process: no second notice
    err = capsys.readouterr().err
    assert err.count("older than 16") == 1


def test_devnull_means_no_llvm_and_the_fallback_notice_is_said_once(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(V, "_NOTICED", set())
    monkeypatch.setattr(V, "cuda_available", lambda: False)
    monkeypatch.setattr(V, "find_llvm", lambda search_dirs=None: (None, []))
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", os.devnull)  # as pbrbench leaves it for child processes
    for _ in range(3):
        c = V.choose_variant()
        assert c.variant == "scalar_rgb"
        assert os.devnull not in c.notice and "does not exist" not in c.notice
    err = capsys.readouterr().err
    assert err.count("rendering with scalar_rgb") == 1 and "/dev/null" not in err


def test_unknown_variant_is_refused_without_importing_mitsuba(monkeypatch):
    import subprocess
    import sys

    # The check runs before mitsuba is imported (the command line makes it when it resolves its
    # settings).  An earlier test of this session may have imported mitsuba: then
    # sys.modules["mitsuba"] is mitsuba's alias extension module, whose spec has no package
    # directory, and known_variants() cannot find config.py (it returns None and the check lets
    # every name through).  Hide it, as in a process that has not imported mitsuba yet.
    monkeypatch.delitem(sys.modules, "mitsuba", raising=False)
    known = V.known_variants()
    assert known is not None, "mitsuba's config.py is not readable"
    assert "scalar_rgb" in known
    with pytest.raises(UserError, match="'foo_rgb'.*not a variant"):
        V.check_variant_name("foo_rgb")
    with pytest.raises(UserError):
        V.choose_variant("llvm_ad_rgbx")
    assert V.check_variant_name("scalar_rgb") == "scalar_rgb"
    probe = ("import sys; from pbrbench.render.variant import check_variant_name; check_variant_name('scalar_rgb'); "
             "print('mitsuba' in sys.modules, 'drjit' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert out.stdout.split() == ["False", "False"], out.stderr
