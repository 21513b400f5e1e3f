"""Shared fixtures: run the real `crom` binary into a temporary store once per session."""
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def crom_bin() -> pathlib.Path:
    path = pathlib.Path(os.environ.get("CROM_BIN", REPO / "target" / "release" / "crom"))
    if not path.is_absolute():
        path = REPO / path
    if not path.exists():
        pytest.fail(f"crom binary not found at {path}: build it with `just build` "
                    "or set CROM_BIN")
    return path


def run_scene(tmp_path_factory, scene: str) -> pathlib.Path:
    store = tmp_path_factory.mktemp(f"store-{scene}")
    subprocess.run([str(crom_bin()), "--store", str(store), "--quiet", "run", scene], cwd=REPO, check=True,
                   capture_output=True)
    return store


@pytest.fixture(scope="session")
def rope_store(tmp_path_factory) -> pathlib.Path:
    return run_scene(tmp_path_factory, "rope")


@pytest.fixture(scope="session")
def hertz_store(tmp_path_factory) -> pathlib.Path:
    return run_scene(tmp_path_factory, "hertz")


def only_artifact(store: pathlib.Path, stage: str, file: str, where=None) -> pathlib.Path:
    """The one artifact file of `stage` (optionally the one whose HDF5 `set` attribute matches)."""
    found = sorted((store / stage).glob(f"*/{file}"))
    if where is not None:
        found = [p for p in found if where(p)]
    assert len(found) == 1, f"expected one {stage}/{file}, found {found}"
    return found[0]


# --- crom_data (python/): the reader under test is the repository's own, installed or not ------
import sys  # noqa: E402

PYTHON_PACKAGE = REPO / "python"
sys.path.insert(0, str(PYTHON_PACKAGE))


@pytest.fixture(scope="session")
def ironing_fine_store(tmp_path_factory) -> pathlib.Path:
    return run_scene(tmp_path_factory, "ironing-fine")


@pytest.fixture(scope="session")
def rope_large_store(tmp_path_factory) -> pathlib.Path:
    """The rope on 1 100 training and 1 099 test points: more test points than the online stage
    measures (1 024), so it measures a keyed sample of them."""
    scenes = tmp_path_factory.mktemp("rope-large-scene")
    text = (REPO / "data/scenes/rope.toml").read_text()
    for old, new in (('n_train = 10', 'n_train = 1100'), ('name = "rope"', 'name = "rope-large"')):
        assert old in text, old
        text = text.replace(old, new)
    scene = scenes / "rope-large.toml"
    scene.write_text(text)
    store = tmp_path_factory.mktemp("store-rope-large")
    subprocess.run([str(crom_bin()), "--store", str(store), "--quiet", "run", str(scene)], cwd=REPO, check=True,
                   capture_output=True)
    return store
