#!/usr/bin/env bash
# Shared by the peer models' setup scripts (sourced, not run): a virtualenv OUTSIDE the
# project's tree, created with Python 3.12 when available.
#
#   PEERS_PYTHON interpreter used to create a venv (default: first of
#                ~/.pyenv/versions/3.12.*/bin/python, python3.12, python3)

PEERS_REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

# refuse a venv inside the project's tree (in particular its .venv)
peers_refuse_inside_repo() {
  local venv_abs
  venv_abs="$(realpath -m "$1")"
  case "$venv_abs/" in
    "$PEERS_REPO_ROOT"/*)
      echo "refusing: PEERS_VENV ($venv_abs) must be outside the repository $PEERS_REPO_ROOT" >&2
      exit 2;;
  esac
}

peers_pick_python() {
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

# create the venv $1 unless it exists (idempotent)
peers_make_venv() {
  peers_refuse_inside_repo "$1"
  if [[ ! -x "$1/bin/python" ]]; then
    local py
    py="$(peers_pick_python)"
    echo "creating venv $1 with $py ($("$py" --version 2>&1))"
    mkdir -p "$(dirname "$1")"
    "$py" -m venv "$1"
    "$1/bin/python" -m pip install --upgrade pip
  fi
}
