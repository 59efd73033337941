#!/usr/bin/env bash
# Sets up o3dheat on a Debian machine: system packages (only those missing), a virtual environment
# at .venv in the project root, and an editable install with the test extras. Idempotent: when
# nothing changed since the last run it returns in about a second.
#
#   bash scripts/setup.sh            # normal use (root installs missing system packages)
#   O3DHEAT_PIP_ONLY=1 bash scripts/setup.sh   # no apt, no scikit-sparse: cholespy/SuperLU only
#                                              # (remembered by later runs; O3DHEAT_PIP_ONLY=0 undoes it)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
venv="$root/.venv"
log() { printf '[setup] %s\n' "$*" >&2; }
if [ -z "${O3DHEAT_PIP_ONLY+set}" ] && grep -qs piponly "$venv/.o3dheat-setup"; then
  export O3DHEAT_PIP_ONLY=1  # an earlier pip-only set-up stays pip-only
fi
[ "${O3DHEAT_PIP_ONLY:-}" = 0 ] && unset O3DHEAT_PIP_ONLY

# --- system packages ---------------------------------------------------------------------------
# libsuitesparse-dev: CHOLMOD headers for scikit-sparse; libusb-1.0-0 and libgomp1: Open3D does not
# import without them; libgl1/libegl1/libopengl0: pymeshlab silently loses its plugins without them.
# libopenblas0-pthread: Debian's optimized BLAS, which becomes the system libblas.so.3 (through
# update-alternatives) and so CHOLMOD's: supernodal factorizations of large meshes about 1.8x faster.
# (The figures are drawn by o3dheat's own rasterizer: no Vulkan, display or GPU needed.)
pkgs=(libsuitesparse-dev libopenblas0-pthread libusb-1.0-0 libgomp1 libgl1 libegl1 libopengl0 libglu1-mesa)
python3 -c 'import venv, ensurepip' 2>/dev/null || pkgs+=(python3-venv)
python3 -c 'import sysconfig, os, sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' 2>/dev/null || pkgs+=(python3-dev)
command -v gcc >/dev/null || pkgs+=(build-essential)
missing=()
if [ -z "${O3DHEAT_PIP_ONLY:-}" ] && command -v dpkg-query >/dev/null; then
  for p in "${pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done
fi
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    log "installing system packages: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    log "missing system packages (not root, continuing pip-only): ${missing[*]}"
    log "  to install them: sudo apt-get install ${missing[*]}"
    export O3DHEAT_PIP_ONLY=1
  fi
fi

# --- virtual environment -----------------------------------------------------------------------
if [ ! -x "$venv/bin/python" ]; then
  log "creating $venv"
  python3 -m venv "$venv"
fi
py="$venv/bin/python"
stamp="$venv/.o3dheat-setup"
want=$(cat pyproject.toml scripts/setup.sh | sha256sum | cut -c1-16)${O3DHEAT_PIP_ONLY:+-piponly}
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && "$py" -c 'import o3dheat' 2>/dev/null; then
  exit 0
fi
log "installing o3dheat and its dependencies into $venv (a few minutes the first time)"
"$py" -m pip install -q --upgrade pip setuptools wheel
if [ -z "${O3DHEAT_PIP_ONLY:-}" ] && "$py" -m pip install -q -e ".[dev]"; then
  :
else
  # pip-only fallback: everything but scikit-sparse; CHOLMOD then comes from cholespy's wheel.
  log "scikit-sparse not installed: falling back to cholespy (bundled CHOLMOD) and SuperLU"
  deps=$("$py" - <<'PY'
import re
text = open("pyproject.toml").read()
block = re.search(r"^dependencies = \[(.*?)^\]", text, re.S | re.M).group(1)
deps = [d for d in re.findall(r'"([^"]+)"', block) if not d.startswith("scikit-sparse")]
dev = re.search(r"^dev = \[(.*?)\]\s*$", text, re.S | re.M).group(1)
print(" ".join(deps + re.findall(r'"([^"]+)"', dev)))
PY
)
  # shellcheck disable=SC2086
  "$py" -m pip install -q $deps
  "$py" -m pip install -q --no-deps -e .
fi
# Smoke tests of what silently breaks on a machine with missing system libraries.
"$py" - <<'PY'
import open3d, pymeshlab
ms = pymeshlab.MeshSet()
needed = ["meshing_isotropic_explicit_remeshing"]
have = set(pymeshlab.filter_list()) if hasattr(pymeshlab, "filter_list") else set(dir(ms))
lost = [n for n in needed if n not in have]
if lost:
    raise SystemExit(f"pymeshlab lost its plugins ({lost}): install libgl1 libegl1 libopengl0")
PY
echo "$want" > "$stamp"
log "ready: $("$py" -c 'import o3dheat, sys; print("o3dheat", o3dheat.__version__, "python", sys.version.split()[0])')"
