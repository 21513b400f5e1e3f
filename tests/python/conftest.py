"""Shared fixtures: run the real `crom` binary into a temporary store once per session."""
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def crom_bin() -> pathlib.Path:
    path = pathlib.Path(os.environ.get("CROM_BIN", REPO / "target" / "debug" / "crom"))
    if not path.is_absolute():
        path = REPO / path
    if not path.exists():
        pytest.fail(f"crom binary not found at {path}: build it with `cargo build -p crom-pipeline --bin crom` "
                    "or set CROM_BIN")
    return path


@pytest.fixture(scope="session")
def rope_store(tmp_path_factory) -> pathlib.Path:
    store = tmp_path_factory.mktemp("store")
    subprocess.run([str(crom_bin()), "--store", str(store), "--quiet", "run", "rope"], cwd=REPO, check=True,
                   capture_output=True)
    return store


def only_artifact(store: pathlib.Path, stage: str, file: str, where=None) -> pathlib.Path:
    """The one artifact file of `stage` (optionally the one whose HDF5 `set` attribute matches)."""
    found = sorted((store / stage).glob(f"*/{file}"))
    if where is not None:
        found = [p for p in found if where(p)]
    assert len(found) == 1, f"expected one {stage}/{file}, found {found}"
    return found[0]
