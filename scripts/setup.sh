#!/usr/bin/env bash
# Create .venv (Python 3.11), install the pinned environment, compile numba's kernels.
# Idempotent; quiet when up to date.
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
installed=0
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  .venv/bin/python -m pip install -q -r environment.txt
  echo "$want" > "$stamp"
  installed=1
fi
# numba's cached kernels compiled here, once, not by the first jobs (several at once):
# src/avoa_pipeline/warmup.py; --check (no numba import) fails when a source, the environment or
# the caches changed since the last warm-up
if [ "$installed" = 1 ] || ! .venv/bin/python -m avoa_pipeline.warmup --check; then
  .venv/bin/python -m avoa_pipeline.warmup ||
    echo "setup: the warm-up failed (above); the first jobs compile the kernels instead" >&2
fi
# a named Jupyter kernel for the papermill notebooks
if [ ! -d .venv/share/jupyter/kernels/avoa-pipeline ]; then
  .venv/bin/python -m ipykernel install --sys-prefix --name avoa-pipeline \
    --display-name "avoa-pipeline" >/dev/null
fi
