#!/usr/bin/env bash
# Print the path of a Python >= 3.12 that actually runs, or explain what to install.
for cand in python3.13 python3.12 $(ls -d "$HOME"/.pyenv/versions/3.1[2-9]*/bin/python3 2>/dev/null | sort -rV); do
  if "$cand" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 12) else 1)' >/dev/null 2>&1; then
    command -v "$cand" 2>/dev/null || echo "$cand"
    exit 0
  fi
done
echo "error: fem_runout needs Python >= 3.12 (DOLFINx 0.11 wheels); install python3.12 or python3.13 (e.g. 'pyenv install 3.12') and re-run 'make setup'" >&2
exit 1
