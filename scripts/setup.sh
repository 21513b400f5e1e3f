#!/usr/bin/env bash
# Everything crom needs on a fresh Debian machine with Rust and Python 3.11 (as root or sudo):
# the HDF5 C library, `just`, the Python validation environment, the reader crom_data and its
# native extension crom_native (built with maturin). Idempotent and quick when everything is
# already there.
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
if ! command -v just >/dev/null 2>&1 || ! "$PY" -c "import h5py, pandas, pyarrow, numpy, scipy, pytest, matplotlib, nbclient, nbformat, ipykernel, meshio, blake3, skfem, maturin" >/dev/null 2>&1; then
  echo "setup: installing just and the Python environment (PyPI)"
  "${PIP[@]}" rust-just h5py pandas pyarrow numpy scipy pytest matplotlib nbclient nbformat ipykernel meshio blake3 scikit-fem maturin
  hash -r
fi

# The Python reader (`import crom_data`), installed editable from this checkout; reinstalled
# when the installed one belongs to another checkout.
REPO=$(cd "$(dirname "$0")/.." && pwd -P)
if ! "$PY" -c "import crom_data, pathlib, sys; sys.exit(pathlib.Path(crom_data.__file__).resolve().is_relative_to('$REPO/python') is False)" >/dev/null 2>&1; then
  echo "setup: installing the Python reader crom_data from $REPO/python"
  "${PIP[@]}" -e "$REPO/python"
fi

# The native extension crom_native (python/native: PyO3, abi3 for Python >= 3.11), which
# `crom_data`'s `Scene.rom()` solves with. Built with the dev profile into the workspace's target
# directory, where `just test` finds the dependencies already compiled (dependencies are
# optimised in that profile; `scripts/bench_rom.py` builds its own release wheel). Cargo makes
# the build a no-op when nothing changed; the wheel is reinstalled only when it differs from the
# installed one.
TARGET=${CARGO_TARGET_DIR:-$REPO/target}
WHEELS="$TARGET/wheels-dev"
echo "setup: building the native extension crom_native (maturin, dev profile)"
rm -f "$WHEELS"/crom_native-*.whl
"$PY" -m maturin build --quiet --profile dev --compatibility linux --auditwheel skip -m "$REPO/python/native/Cargo.toml" -i "$PY" -o "$WHEELS" >/dev/null
WHEEL=$(ls "$WHEELS"/crom_native-*.whl)
SUM=$(sha256sum "$WHEEL" | cut -d' ' -f1)
if [ "$(cat "$WHEELS/.installed" 2>/dev/null)" != "$SUM" ] || ! "$PY" -c "import crom_native" >/dev/null 2>&1; then
  "${PIP[@]}" --force-reinstall --no-deps "$WHEEL"
  echo "$SUM" > "$WHEELS/.installed"
fi

if ! command -v cargo-nextest >/dev/null 2>&1; then
  echo "setup: cargo-nextest not found; tests will run with cargo test"
fi
echo "setup: ok ($(just --version), $("$PY" --version))"
