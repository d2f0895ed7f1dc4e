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

# refuse to install into the project's tree (in particular its .venv)
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
VENV_ABS="$(realpath -m "$PEERS_VENV")"
case "$VENV_ABS/" in
  "$REPO_ROOT"/*) echo "refusing: PEERS_VENV ($VENV_ABS) must be outside the repository $REPO_ROOT" >&2; exit 2;;
esac

pick_python() {
  if [[ -n "${PEERS_PYTHON:-}" ]]; then echo "$PEERS_PYTHON"; return; fi
  for p in "$HOME"/.pyenv/versions/3.12.*/bin/python; do
    [[ -x "$p" ]] && { echo "$p"; return; }
  done
  for p in python3.12 python3; do
    if command -v "$p" >/dev/null 2>&1 && "$p" -c 'import sys' >/dev/null 2>&1; then
      command -v "$p"; return
    fi
  done
  echo "no usable python found (set PEERS_PYTHON)" >&2; exit 1
}

if [[ ! -x "$PEERS_VENV/bin/python" ]]; then
  PY="$(pick_python)"
  echo "creating venv $PEERS_VENV with $PY ($("$PY" --version 2>&1))"
  mkdir -p "$(dirname "$PEERS_VENV")"
  "$PY" -m venv "$PEERS_VENV"
  "$PEERS_VENV/bin/python" -m pip install --upgrade pip
fi

have="$("$PEERS_VENV/bin/python" -c 'import importlib.metadata as m; print(m.version("avaframe"))' 2>/dev/null || true)"
if [[ "$have" != "$AVAFRAME_VERSION" ]]; then
  # constraints.txt pins the dependency versions of the verified environment
  "$PEERS_VENV/bin/python" -m pip install "avaframe==$AVAFRAME_VERSION" -c "$(dirname "${BASH_SOURCE[0]}")/constraints.txt"
fi
"$PEERS_VENV/bin/python" -c 'import importlib.metadata as m, avaframe.com1DFA.com1DFA; print("avaframe", m.version("avaframe"), "OK")'
echo "PEERS_VENV=$PEERS_VENV"
