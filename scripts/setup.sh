#!/usr/bin/env bash
# One-time (idempotent) set-up on a fresh machine: virtual environment, the package, and the
# system libraries the renderer and the browser test need.  Called by `make` only when
# pyproject.toml or this script changed (stamp file), so a second `make test` installs nothing.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
PYTHON=${PYTHON:-python3}

say() { printf 'setup: %s\n' "$*" >&2; }

# --- system packages: libLLVM >= 16 for Mitsuba's LLVM variant, chromium for the report test
have_llvm16() {
  local f
  for f in /usr/lib/*/libLLVM*.so* /usr/lib/libLLVM*.so* /usr/lib/llvm-*/lib/libLLVM*.so*; do
    [ -e "$f" ] || continue
    case "$(basename "$f")" in
      libLLVM-1[6-9]*|libLLVM-[2-9][0-9]*|libLLVM.so.1[6-9]*|libLLVM.so.[2-9][0-9]*) return 0 ;;
    esac
  done
  return 1
}

apt_updated=0
apt_install() {
  if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then return 1; fi
  if [ "$apt_updated" = 0 ]; then
    DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null && apt_updated=1 || return 1
  fi
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}

if have_llvm16; then
  say "libLLVM >= 16 present"
elif apt_install libllvm19; then
  say "installed Debian's libllvm19 (Mitsuba llvm_ad_rgb)"
else
  say "NOTICE: no libLLVM >= 16 and cannot install it (not root or no apt): pbrbench will render with scalar_rgb (slow)"
fi

if [ "${PBRBENCH_SKIP_CHROMIUM:-0}" != 1 ] && ! command -v chromium >/dev/null; then
  if apt_install chromium; then say "installed chromium (headless report test)";
  else say "NOTICE: chromium not installed: the browser half of the report test will be skipped"; fi
fi

# --- Python environment
if [ ! -x "$VENV/bin/python" ]; then
  say "creating $VENV"
  "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip >/dev/null
say "installing pbrbench and its dependencies into $VENV"
"$VENV/bin/python" -m pip install -q --disable-pip-version-check -e ".[dev,distributed]"
"$VENV/bin/python" -c "import pbrbench, numpy, scipy, mitsuba, drjit, OpenEXR" \
  || { say "ERROR: the installed environment does not import"; exit 1; }
say "done"
