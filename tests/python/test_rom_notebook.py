"""examples/rom_sweep.ipynb: committed without outputs, and it runs against a real ironing-fine store
(the one the explore notebook's test builds; ironing-fine because it is the scene the notebook is
about, and its store is already built for that test, so this one adds only the sweep and a
16-point `crom query --check`): it sweeps 10^4 points with `solve_many`, draws three figures, and
finds the query's indicator identical to the sweep's at the checked sample."""
import os

import nbclient
import nbformat

from conftest import PYTHON_PACKAGE, REPO, crom_bin
from test_notebook import code_cells

NOTEBOOK = REPO / "examples" / "rom_sweep.ipynb"


def test_committed_notebook_has_no_outputs():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    for cell in code_cells(nb):
        assert cell.outputs == [] and cell.execution_count is None, cell.source[:60]


def test_notebook_sweeps_and_draws_three_figures(ironing_fine_store, tmp_path, monkeypatch):
    monkeypatch.setenv("CROM_STORE", str(ironing_fine_store))
    monkeypatch.setenv("CROM_BIN", str(crom_bin()))
    monkeypatch.setenv("CROM_SCENES", str(REPO / "data" / "scenes"))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(PYTHON_PACKAGE),
                                                                    os.environ.get("PYTHONPATH")])))
    monkeypatch.delenv("MPLBACKEND", raising=False)
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(nb, timeout=600, kernel_name=nb.metadata.kernelspec.name,
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    nbformat.write(nb, tmp_path / "rom_sweep.executed.ipynb")  # for inspection when a check fails

    outputs = [o for c in code_cells(nb) for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    figures = [o for o in outputs if o.output_type in ("display_data", "execute_result")
               and "image/png" in o.get("data", {})]
    assert len(figures) == 3, f"{len(figures)} figures drawn"
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "10000 points of d_x" in text, text
    assert "indicator identical to solve_many's: True" in text, text
