#!/usr/bin/env bash
# Everything crom needs on a fresh Debian machine with Rust and Python 3.11 (as root or sudo):
# the HDF5 C library, `just`, and the Python validation environment. Idempotent and quick when
# everything is already there.
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

if ! dpkg -s libhdf5-dev pkg-config >/dev/null 2>&1; then
  echo "setup: installing libhdf5-dev and pkg-config (Debian)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends libhdf5-dev pkg-config >/dev/null
fi

PY=${PYTHON:-python3}
if ! command -v just >/dev/null 2>&1 || ! "$PY" -c "import h5py, pandas, pyarrow, numpy, scipy, pytest" >/dev/null 2>&1; then
  echo "setup: installing just and the Python validation environment (PyPI)"
  "$PY" -m pip install -q --disable-pip-version-check --root-user-action=ignore \
    rust-just h5py pandas pyarrow numpy scipy pytest
  hash -r
fi

if ! command -v cargo-nextest >/dev/null 2>&1; then
  echo "setup: cargo-nextest not found; tests will run with cargo test"
fi
echo "setup: ok ($(just --version), $("$PY" --version))"
