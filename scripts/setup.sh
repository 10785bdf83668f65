#!/usr/bin/env bash
# Create .venv (Python 3.11) and install the pinned environment. Idempotent; quiet when up to date.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-$(command -v python3.11 || command -v python3)}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
  .venv/bin/python -m pip install -q --upgrade pip
fi
# The stamp covers environment.txt and pyproject.toml only: the cluster extra
# (environment-slurm.txt, installed by scripts/slurm-local.sh start or by hand) is neither
# installed nor removed here (pip install -r leaves a package it does not list alone).
stamp=.venv/.environment.sha256
want=$(sha256sum environment.txt pyproject.toml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  .venv/bin/python -m pip install -q -r environment.txt
  echo "$want" > "$stamp"
fi
# a named Jupyter kernel for the papermill notebooks
if [ ! -d .venv/share/jupyter/kernels/avoa-pipeline ]; then
  .venv/bin/python -m ipykernel install --sys-prefix --name avoa-pipeline \
    --display-name "avoa-pipeline" >/dev/null
fi
