"""examples/explore.ipynb: committed without outputs, and it runs against a real store, drawing
its two figures (Fig. 16 and the speed/accuracy Pareto front)."""
import os

import h5py
import nbclient
import nbformat
import pandas as pd

from conftest import PYTHON_PACKAGE, REPO

NOTEBOOK = REPO / "examples" / "explore.ipynb"


def code_cells(nb):
    return [c for c in nb.cells if c.cell_type == "code"]


def test_committed_notebook_has_no_outputs():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    assert code_cells(nb), "the notebook has code"
    for cell in code_cells(nb):
        assert cell.outputs == [], f"committed outputs in cell {cell.source[:60]!r}"
        assert cell.execution_count is None, f"execution count in cell {cell.source[:60]!r}"


def test_notebook_runs_and_draws_two_figures(ironing_fine_store, tmp_path, monkeypatch):
    monkeypatch.setenv("CROM_STORE", str(ironing_fine_store))
    # The kernel imports the repository's crom_data, installed or not, and draws inline.
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(PYTHON_PACKAGE),
                                                                    os.environ.get("PYTHONPATH")])))
    monkeypatch.delenv("MPLBACKEND", raising=False)
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(nb, timeout=600, kernel_name=nb.metadata.kernelspec.name,
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    nbformat.write(nb, tmp_path / "explore.executed.ipynb")  # for inspection when a check fails

    outputs = [o for c in code_cells(nb) for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    figures = [o for o in outputs if o.output_type in ("display_data", "execute_result")
               and "image/png" in o.get("data", {})]
    assert len(figures) == 2, f"{len(figures)} figures drawn"

    # The printed training-set shape is the artifact's, read independently.
    cat = pd.read_parquet(ironing_fine_store / "catalog.parquet")
    train = cat[(cat["stage"] == "trainset") & (cat["set"] == "train")]
    assert len(train) == 1
    with h5py.File(ironing_fine_store / train["path"].iloc[0] / "snapshots.h5", "r") as f:
        shape = f["primal"].shape
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert f"training set primal {shape}" in text, text
