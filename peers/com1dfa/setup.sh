#!/usr/bin/env bash
# Create (or reuse) a virtualenv OUTSIDE the project's .venv and install the
# pinned AvaFrame release (peer model com1DFA).  Idempotent: re-running only
# installs if the pinned version is missing.
#
#   PEERS_VENV   venv location (default: $HOME/.cache/fem_runout/peers/avaframe)
#   PEERS_PYTHON interpreter used to create the venv (default: first of
#                ~/.pyenv/versions/3.12.*/bin/python, python3.12, python3)
set -euo pipefail

AVAFRAME_VERSION="2.1"          # version verified with run_avakot.py (cp312 manylinux wheel)
PEERS_VENV="${PEERS_VENV:-$HOME/.cache/fem_runout/peers/avaframe}"

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=../common.sh
source "$HERE/../common.sh"
peers_make_venv "$PEERS_VENV"

have="$("$PEERS_VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("avaframe"))' 2>/dev/null || true)"
if [[ "$have" != "$AVAFRAME_VERSION" ]]; then
  # constraints.txt pins the dependency versions of the verified environment
  "$PEERS_VENV/bin/python" -m pip install "avaframe==$AVAFRAME_VERSION" -c "$HERE/constraints.txt"
fi
"$PEERS_VENV/bin/python" -c 'import importlib.metadata as m, avaframe.com1DFA.com1DFA; print("avaframe", m.version("avaframe"), "OK")'
echo "PEERS_VENV=$PEERS_VENV"
