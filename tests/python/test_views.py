"""The XDMF views: every step of every collection, read with meshio's XDMF
time-series reader (an independent XDMF reader), equals the same column read through h5py; the
views refer to the stored columns instead of copying them; a malformed or stale XDMF is caught.

Expectations come from the stored snapshot and basis matrices (h5py) and the mesh (dofs are
numbered `dofs_per_node * node + component`, dual row k is contact node `contact_nodes[k]`),
not from the code that writes the views. Comparisons are exact: the views are the same bytes.
"""
import pathlib
import shutil
import subprocess

import h5py
import meshio
import numpy as np
import pytest

import crom_data
from conftest import REPO, crom_bin


def expected_displacement(column: np.ndarray, n_nodes: int, dofs_per_node: int) -> np.ndarray:
    u = np.zeros((n_nodes, 3))
    if dofs_per_node == 1:
        u[:, 1] = column  # the rope's deflection is vertical
    else:
        u[:, :dofs_per_node] = column.reshape(n_nodes, dofs_per_node)
    return u


def expected_pressure(column: np.ndarray, n_nodes: int, contact: np.ndarray) -> np.ndarray:
    p = np.zeros(n_nodes)
    p[contact] = column
    return p


def read_series(path: pathlib.Path):
    with meshio.xdmf.TimeSeriesReader(str(path)) as r:
        points, cells = r.read_points_cells()
        steps = [r.read_data(k) for k in range(r.num_steps)]
    return points, cells, steps


@pytest.mark.parametrize("scene_fixture,scene", [("rope_store", "rope"), ("hertz_store", "hertz"),
                                                 ("ironing_fine_store", "ironing-fine")])
def test_every_step_of_every_set_equals_its_stored_column(request, scene_fixture, scene):
    store = request.getfixturevalue(scene_fixture)
    sc = crom_data.open_store(store).scene(scene)
    mesh = sc.mesh()
    n = len(mesh.nodes)
    for name in sc.sets():
        ts = sc.trainset(name)
        points, cells, steps = read_series(sc.xdmf(name))
        np.testing.assert_array_equal(points, mesh.nodes)
        np.testing.assert_array_equal(cells[0].data, mesh.cells)
        assert len(steps) == ts.primal.shape[1], name
        params = ts.parameters.reshape(len(steps), -1)
        names = ts.parameter_names
        times = [t for t, _, _ in steps]
        assert np.all(np.diff(times) > 0), f"{name}: times must increase for ParaView's slider"
        for k, (t, point_data, cell_data) in enumerate(steps):
            np.testing.assert_array_equal(point_data["displacement"],
                                          expected_displacement(ts.primal[:, k], n, mesh.dofs_per_node))
            np.testing.assert_array_equal(point_data["pressure"],
                                          expected_pressure(ts.dual[:, k], n, mesh.contact_nodes))
            np.testing.assert_array_equal(point_data["node_body"], mesh.node_body)
            np.testing.assert_array_equal(cell_data["cell_body"][0], mesh.cell_body)
            for c, pname in enumerate(names):
                assert np.all(point_data[pname] == params[k, c]), (name, k, pname)
            if len(names) == 1:
                assert t == params[k, 0], "a scalar parameter is the step's time"


@pytest.mark.parametrize("scene_fixture,scene", [("hertz_store", "hertz"), ("rope_store", "rope")])
def test_every_mode_of_every_basis_equals_its_stored_column(request, scene_fixture, scene):
    store = request.getfixturevalue(scene_fixture)
    sc = crom_data.open_store(store).scene(scene)
    mesh, bases = sc.mesh(), sc.basis()
    n = len(mesh.nodes)
    for group in ("primal_pod", "dual_pod", "dual_cpg"):
        modes = bases[group].modes
        _, _, steps = read_series(sc.xdmf(group))
        assert len(steps) == modes.shape[1], group
        for k, (t, point_data, _) in enumerate(steps):
            assert t == k + 1
            if group == "primal_pod":
                np.testing.assert_array_equal(point_data["displacement"],
                                              expected_displacement(modes[:, k], n, mesh.dofs_per_node))
            else:
                np.testing.assert_array_equal(point_data["pressure"],
                                              expected_pressure(modes[:, k], n, mesh.contact_nodes))


def test_views_refer_to_the_stored_columns_instead_of_copying_them(ironing_fine_store):
    sc = crom_data.open_store(ironing_fine_store).scene("ironing-fine")
    ts = sc.trainset("train")
    views = ironing_fine_store / pathlib.Path(sc.entries["train.xdmf"]["target"]).parent / "views.h5"
    with h5py.File(views, "r") as f:
        step = f["steps/00000"]
        assert step["displacement"].is_virtual and step["pressure"].is_virtual
        blocks = {pathlib.Path(s.file_name).name for s in step["displacement"].virtual_sources()}
        assert blocks == {pathlib.Path(b).name for b in ts.stats["block"][:1]}
    # The displacement alone is 8 * n_dof bytes per step; the file holds far less than one
    # step's worth per step (only the mappings and the compressed constant parameter fields).
    per_step = views.stat().st_size / ts.primal.shape[1]
    assert per_step < 8 * ts.primal.shape[0] / 4, per_step


def copy_store(src: pathlib.Path, dst: pathlib.Path) -> pathlib.Path:
    shutil.copytree(src, dst, symlinks=True)
    return dst


def test_a_malformed_or_stale_xdmf_is_caught(rope_store, tmp_path):
    store = copy_store(rope_store, tmp_path / "store")
    sc = crom_data.open_store(store).scene("rope")
    published = sc.xdmf("train")
    text = published.read_text()
    # Malformed: cut in the middle.
    published.write_text(text[: len(text) // 2])
    with pytest.raises(crom_data.CorruptArtifact, match="not a readable XDMF"):
        crom_data.open_store(store).scene("rope").xdmf("train")
    # Stale: a step refers to a dataset that is not there.
    published.write_text(text.replace("/steps/00003/pressure", "/steps/00099/pressure"))
    with pytest.raises(crom_data.CorruptArtifact, match="00099"):
        crom_data.open_store(store).scene("rope").xdmf("train")
    # Stale: the dimensions no longer match the dataset.
    published.write_text(text.replace('Dimensions="201 3"', 'Dimensions="202 3"', 1))
    with pytest.raises(crom_data.CorruptArtifact, match="shape"):
        crom_data.open_store(store).scene("rope").xdmf("train")
    published.write_text(text)
    assert crom_data.open_store(store).scene("rope").xdmf("train") == published


def test_a_changed_xdmf_in_the_store_fails_crom_verify(rope_store, tmp_path):
    store = copy_store(rope_store, tmp_path / "store")
    target = store / crom_data.open_store(store).scene("rope").entries["test.xdmf"]["target"]
    target.write_text(target.read_text().replace("00001", "00002"))
    out = subprocess.run([str(crom_bin()), "--store", str(store), "verify"], cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 1, out.stdout + out.stderr
    assert "views" in out.stdout
    with pytest.raises(crom_data.ArtifactMissing, match="withdrawn"):
        crom_data.open_store(store).scene("rope").xdmf("test")


def test_the_report_shows_the_deformed_bodies_of_2d_scenes_only(hertz_store, rope_store):
    hertz = crom_data.open_store(hertz_store).scene("hertz").report_dir
    html = (hertz / "index.html").read_text()
    assert (hertz / "fig_bodies.png").stat().st_size > 10_000 and "fig_bodies.png" in html
    # Three rows (first, middle, last training point), each row a pair of views and a profile.
    assert html.count("Deformed configuration at the first, middle and last training points") >= 1
    rope = crom_data.open_store(rope_store).scene("rope").report_dir
    assert not (rope / "fig_bodies.png").exists(), "the rope's set-up figure is fig02 (1-D)"


@pytest.mark.parametrize("scene_fixture,scene", [("rope_store", "rope"), ("ironing_fine_store", "ironing-fine"),
                                                 ("rope_large_store", "rope-large")])
def test_every_online_step_shows_the_online_solution_its_error_and_the_full_order_one(request, scene_fixture, scene):
    store = request.getfixturevalue(scene_fixture)
    sc = crom_data.open_store(store).scene(scene)
    mesh, test = sc.mesh(), sc.trainset("test")
    n, n_test = len(mesh.nodes), test.primal.shape[1]
    with h5py.File(sc.file("online.h5"), "r") as f:
        online = {k: f[k][()] for k in ("primal", "dual", "primal_error", "dual_error", "converged", "parameters")}
        # a large test set is measured on a sample of 1 024 of its points, stored with it
        cols = f["test_columns"][()] if "test_columns" in f else np.arange(n_test)
    if n_test > 1024:
        assert len(cols) == 1024 and np.all(np.diff(cols) > 0) and cols[-1] < n_test, cols
        # a uniform draw, not a stride or a prefix: it reaches into the last tenth of the set
        assert cols[-1] >= 0.9 * n_test and len(set(np.diff(cols))) > 1
    else:
        np.testing.assert_array_equal(cols, np.arange(n_test))
    primal, dual = test.primal[:, cols], test.dual[:, cols]
    np.testing.assert_array_equal(online["parameters"].reshape(len(cols), -1),
                                  test.parameters.reshape(n_test, -1)[cols])
    # The stored error is the online field minus the test snapshot (same IEEE subtraction).
    np.testing.assert_array_equal(online["primal_error"], online["primal"] - primal)
    np.testing.assert_array_equal(online["dual_error"], online["dual"] - dual)
    # Cross-check with the error table (an independent path: reduced coordinates, H1 norm):
    # converged queries with a zero table error have a zero field error and vice versa.
    errors = sc.rom_errors()
    rows = errors[(errors["set"] == "test") & (errors["algorithm"] == "exact") & (errors["dual_basis"] == "full")
                  & (errors["r_primal"] == errors["r_primal"].max())]
    assert len(rows) == len(cols)
    np.testing.assert_array_equal(rows["parameter"].to_numpy(), test.parameters.reshape(n_test, -1)[cols, 0])
    np.testing.assert_array_equal(online["converged"] == 1, (rows["outcome"] == "converged").to_numpy())
    field_zero = np.all(online["primal_error"] == 0, axis=0)
    table_zero = rows["primal_error"].to_numpy() == 0
    np.testing.assert_array_equal(field_zero, table_zero)
    _, _, steps = read_series(sc.xdmf("online"))
    assert len(steps) == len(cols)
    for k, (t, pd, _) in enumerate(steps):
        for field, matrix in (("displacement", online["primal"]), ("displacement_error", online["primal_error"]),
                              ("displacement_fom", primal)):
            np.testing.assert_array_equal(pd[field], expected_displacement(matrix[:, k], n, mesh.dofs_per_node))
        for field, matrix in (("pressure", online["dual"]), ("pressure_error", online["dual_error"]),
                              ("pressure_fom", dual)):
            np.testing.assert_array_equal(pd[field], expected_pressure(matrix[:, k], n, mesh.contact_nodes))
        assert np.all(pd["converged"] == online["converged"][k])


def test_a_vector_parameter_is_the_step_index_as_time_and_one_field_per_component(tmp_path):
    from test_vector_parameter import run, scene_2d
    store = tmp_path / "store"
    run(store, scene_2d(tmp_path))
    sc = crom_data.open_store(store).scene("ironing-2d-small")
    ts, mesh = sc.trainset("train"), sc.mesh()
    assert ts.parameter_names == ["d_x", "d_y"]
    _, _, steps = read_series(sc.xdmf("train"))
    assert len(steps) == ts.parameters.shape[0] == 9
    for k, (t, pd, _) in enumerate(steps):
        assert t == k, "the tensor grid is not monotone in one component: time is the step index"
        assert np.all(pd["d_x"] == ts.parameters[k, 0]) and np.all(pd["d_y"] == ts.parameters[k, 1])
        np.testing.assert_array_equal(pd["displacement"],
                                      expected_displacement(ts.primal[:, k], len(mesh.nodes), mesh.dofs_per_node))


def test_a_sampled_test_set_is_named_in_the_report(rope_store, rope_large_store):
    """The report says how many points a sampled large set shows (1 024 of each set of the
    1 100 + 1 099-point rope, counted from the error table), and a set measured whole is not
    said to be sampled."""
    large = (crom_data.open_store(rope_large_store).scene("rope-large").report_dir / "index.html").read_text()
    errors = crom_data.open_store(rope_large_store).scene("rope-large").rom_errors()
    exact = errors[(errors["dual_basis"] == "full") & (errors["algorithm"] == "exact")]
    n_train, n_test = (exact["set"] == "train").sum(), (exact["set"] == "test").sum()
    assert (n_train, n_test) == (1024, 1024)
    assert f"online solve, {n_test} of the 1099 test points (drawn at random), full dual basis" in large
    assert f"at {n_train} of the 1100 training and {n_test} of the 1099 test points, drawn at random" in large
    small = (crom_data.open_store(rope_store).scene("rope").report_dir / "index.html").read_text()
    assert "online solve, test points, full dual basis" in small and "drawn at random" not in small
