#!/usr/bin/env bash
# One-time (idempotent) set-up on a fresh machine: virtual environment, the package, and the
# system libraries the renderer and the browser test need.  Called by `make` only when
# pyproject.toml, requirements.lock or this script changed (stamp file), so a second `make test`
# installs nothing.  `setup.sh --uv-only` only makes the virtual environment and its uv (for
# `make lock`).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
PYTHON=${PYTHON:-python3}
LOCK=requirements.lock
UV="$VENV/bin/uv"

say() { printf 'setup: %s\n' "$*" >&2; }

# --- the virtual environment and uv, at the version pinned (with its hashes) in the lock
bootstrap_uv() {
  [ -f "$LOCK" ] || { say "ERROR: $LOCK is missing (\`make lock\` writes it)"; exit 1; }
  if [ ! -x "$VENV/bin/python" ]; then
    say "creating $VENV"
    "$PYTHON" -m venv "$VENV"
  fi
  local want have req
  want=$(sed -n 's/^uv==\([^ ]*\).*/\1/p' "$LOCK")
  have=$("$UV" --version 2>/dev/null | cut -d' ' -f2 || true)
  [ "$have" = "$want" ] && return 0
  say "installing uv $want (pinned in $LOCK) into $VENV"
  req=$(mktemp)
  # uv's entry of the lock: its pin and its hash lines
  awk '/^uv==/ {p = 1} p {print} p && !/\\$/ {exit}' "$LOCK" >"$req"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps --require-hashes -r "$req" \
    || { rm -f "$req"; exit 1; }
  rm -f "$req"
}

if [ "${1:-}" = --uv-only ]; then
  bootstrap_uv
  exit 0
fi

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

# --- Python environment: exactly the versions of requirements.lock (hashes checked), installed
# by uv, compiled to bytecode as they are installed (uv does not compile by default: every
# interpreter, the test suite's child processes included, would compile NumPy, SciPy, Matplotlib
# ... anew where PYTHONDONTWRITEBYTECODE is set); then pbrbench itself, editable, without
# dependencies.  Refresh the lock with `make lock` (docs/install.md).
bootstrap_uv
uvp() { "$UV" pip "$@" --quiet --python "$VENV/bin/python"; }
say "installing the locked dependencies and pbrbench into $VENV"
uvp install --require-hashes --compile-bytecode -r "$LOCK"
uvp install --no-deps --no-build-isolation -e .
check=$("$UV" pip check --python "$VENV/bin/python" 2>&1) \
  || { printf '%s\n' "$check" >&2; say "ERROR: $LOCK does not satisfy pyproject.toml; refresh it with \`make lock\`"; exit 1; }
# the peers extra (OpenCV, colour-hdri: the peer rows of \`pbrbench perf\`, the OpenCV reader test) is
# in the lock too; found, not imported (colour-hdri takes seconds to import)
"$VENV/bin/python" -c "import pbrbench, numpy, scipy, mitsuba, drjit, OpenEXR, importlib.util as u
assert all(u.find_spec(m) for m in ('cv2', 'colour_hdri'))" \
  || { say "ERROR: the installed environment does not import"; exit 1; }
say "done"
