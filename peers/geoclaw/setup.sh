#!/usr/bin/env bash
# Create (or reuse) a virtualenv OUTSIDE the project's .venv with clawpack (GeoClaw) built
# from its sdist, so that GeoClaw's Fortran sources are available for `xgeoclaw`.
# Idempotent: re-running only downloads / installs / compiles what is missing.
#
#   PEERS_VENV   venv location (default: $HOME/.cache/fem_runout/peers/geoclaw)
#   PEERS_PYTHON interpreter used to create the venv (default: first of
#                ~/.pyenv/versions/3.12.*/bin/python, python3.12, python3)
#
# Layout inside the venv:
#   $PEERS_VENV/src/clawpack-5.14.0/   unpacked sdist = $CLAW (Fortran sources of GeoClaw)
#   $PEERS_VENV/geoclaw.env            `source` it to get CLAW and FC exported
#   $PEERS_VENV/share/geoclaw_build/   xgeoclaw binaries cached by run_dam_break.py
set -euo pipefail

CLAWPACK_VERSION="5.14.0"       # version verified with run_dam_break.py (sdist, built with meson)
PEERS_VENV="${PEERS_VENV:-$HOME/.cache/fem_runout/peers/geoclaw}"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

# shellcheck source=../common.sh
source "$HERE/../common.sh"
peers_refuse_inside_repo "$PEERS_VENV"

# GeoClaw is compiled by the user's Fortran compiler; this script never installs system packages
if ! command -v gfortran >/dev/null 2>&1; then
  echo "gfortran not found: install it with your package manager (e.g. apt-get install gfortran)" >&2
  exit 2
fi
export FC=gfortran

peers_make_venv "$PEERS_VENV"
VPY="$PEERS_VENV/bin/python"
export PATH="$PEERS_VENV/bin:$PATH"   # meson-python needs the venv's meson/ninja on PATH
CONSTRAINTS="$HERE/constraints.txt"
CFLAG=()
[[ -s "$CONSTRAINTS" ]] && CFLAG=(-c "$CONSTRAINTS")

# 1. the sdist (the PyPI wheel carries no GeoClaw Fortran sources), unpacked as $CLAW
CLAW="$PEERS_VENV/src/clawpack-$CLAWPACK_VERSION"
if [[ ! -f "$CLAW/geoclaw/src/2d/shallow/Makefile.geoclaw" ]]; then
  mkdir -p "$PEERS_VENV/src"
  sdist="$PEERS_VENV/src/clawpack-$CLAWPACK_VERSION.tar.gz"
  if [[ ! -f "$sdist" ]]; then
    if ! "$VPY" -m pip download "clawpack==$CLAWPACK_VERSION" --no-deps --no-binary clawpack \
         -d "$PEERS_VENV/src"; then
      echo "could not download the clawpack $CLAWPACK_VERSION sdist from the package index" >&2
      exit 3
    fi
    # pip may save the file as Clawpack-… on some indexes
    [[ -f "$sdist" ]] || mv "$PEERS_VENV"/src/[Cc]lawpack-"$CLAWPACK_VERSION".tar.gz "$sdist"
  fi
  tar -xzf "$sdist" -C "$PEERS_VENV/src"
fi

# 2. the Python side (setrun data classes, pyclaw readers), built from the same unpacked sdist
have="$("$VPY" -c 'import importlib.metadata as m; print(m.version("clawpack"))' 2>/dev/null || true)"
if [[ "$have" != "$CLAWPACK_VERSION" ]]; then
  "$VPY" -m pip install "${CFLAG[@]}" numpy meson-python meson ninja
  # meson compiles the f2py extensions with gfortran; no build isolation so the pinned numpy is used
  "$VPY" -m pip install "${CFLAG[@]}" --no-build-isolation "$CLAW"
fi

# 3. environment for make / run_dam_break.py
cat > "$PEERS_VENV/geoclaw.env" <<EOF
export CLAW="$CLAW"
export FC=gfortran
EOF

"$VPY" -c 'import importlib.metadata as m, clawpack.geoclaw.data, clawpack.pyclaw.solution; print("clawpack", m.version("clawpack"), "OK")'

# 4. make sure GeoClaw's Fortran compiles and links: build (and cache) the dam-break xgeoclaw
# (from the venv's folder: importing clawpack writes pyclaw.log into the current folder)
(cd "$PEERS_VENV" && CLAW="$CLAW" FC=gfortran "$VPY" "$HERE/run_dam_break.py" --build-only)
echo "PEERS_VENV=$PEERS_VENV"
echo "CLAW=$CLAW   (source $PEERS_VENV/geoclaw.env)"
