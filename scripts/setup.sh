#!/usr/bin/env bash
# Everything crom needs on a fresh Debian machine with Rust and Python 3.11 (as root or sudo):
# the HDF5 C library, `just`, the Python validation environment and the reader crom_data.
# It compiles nothing: the one compilation of the workspace (the binary, the tests' crates and
# crom_data's native extension) is `just build`, which `just run` and `just test` start with.
# Idempotent and quick when everything is already there.
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

if ! dpkg -s libhdf5-dev pkg-config >/dev/null 2>&1; then
  echo "setup: installing libhdf5-dev and pkg-config (Debian)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends libhdf5-dev pkg-config >/dev/null
fi

PY=${PYTHON:-python3}
PIP=("$PY" -m pip install -q --disable-pip-version-check --root-user-action=ignore)
if ! command -v just >/dev/null 2>&1 || ! "$PY" -c "import h5py, pandas, pyarrow, numpy, scipy, pytest, matplotlib, nbclient, nbformat, ipykernel, meshio, blake3, skfem" >/dev/null 2>&1; then
  echo "setup: installing just and the Python environment (PyPI)"
  "${PIP[@]}" rust-just h5py pandas pyarrow numpy scipy pytest matplotlib nbclient nbformat ipykernel meshio blake3 scikit-fem
  hash -r
fi

# The Python reader (`import crom_data`), installed editable from this checkout; reinstalled
# when the installed one belongs to another checkout.
REPO=$(cd "$(dirname "$0")/.." && pwd -P)
if ! "$PY" -c "import crom_data, pathlib, sys; sys.exit(pathlib.Path(crom_data.__file__).resolve().is_relative_to('$REPO/python') is False)" >/dev/null 2>&1; then
  echo "setup: installing the Python reader crom_data from $REPO/python"
  "${PIP[@]}" -e "$REPO/python"
fi

if ! command -v cargo-nextest >/dev/null 2>&1; then
  echo "setup: cargo-nextest not found; tests will run with cargo test"
fi
echo "setup: ok ($(just --version), $("$PY" --version))"
