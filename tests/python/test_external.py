"""External scenes: crom's own ironing-coarse study (128 training and 127 test snapshots of 6 164
+ 101 rows; about 15 s offline) exported to plain .npy / CSV and HDF5 / Parquet files, imported
back as an external scene, must give the native study's metric tables and bases bit for bit (the
import copies f64 values exactly and every metric is a deterministic function of the training
and test sets). ironing-coarse's 128 training points are no nested grid, so its nested levels
are not compared here; a rope at train_level = 3 is. Bad data files (on the rope's arrays, which
are small) are refused with exit 2, the file, the dataset or field and the fix, and nothing
stored. With a mesh, coordinates or a comparison, the views, the report and the comparison are
checked against the native study's too."""
import os
import pathlib
import subprocess

import h5py
import numpy as np
import pandas as pd
import pytest

from conftest import REPO, crom_bin

def study(scene_name):
    """The [study] table of a shipped scene, as the external scene must repeat it."""
    text = (REPO / "data" / "scenes" / f"{scene_name}.toml").read_text()
    table = text[text.index("[study]"):]
    # The contact quadrature needs the full-order operator: not for an external scene.
    return "\n".join(line for line in table.splitlines() if not line.startswith(("contact_sampling", "#")))

TABLES = ["compactness", "generalization", "specificity"]


def crom(store, *args):
    return subprocess.run([str(crom_bin()), "--store", str(store), *args], cwd=REPO, capture_output=True, text=True)


def native_study(tmp_path_factory, name, scene_file=None):
    """A native study (offline; of the shipped scene `name`, or of `scene_file` naming scene
    `name`) and its training and test sets as arrays."""
    store = tmp_path_factory.mktemp(f"native-{name}")
    done = crom(store, "--quiet", "run", str(scene_file or name), "--offline")
    assert done.returncode == 0, done.stderr
    sets = {}
    for s in ["train", "test"]:
        with h5py.File(store / "scenes" / name / f"{s}.h5") as f:
            sets[s] = (f["primal"][()], f["dual"][()], f["parameters"][()])
    return store, sets


def variant(tmp_path, base, name, replacements):
    """The shipped scene `base` renamed `name`, with each (old, new) of `replacements` made
    (each old text must be in it), written to tmp_path."""
    text = (REPO / "data" / "scenes" / f"{base}.toml").read_text()
    for old, new in [(f'name = "{base}"', f'name = "{name}"'), *replacements]:
        assert old in text, f"{base}.toml changed: update this test ({old!r})"
        text = text.replace(old, new)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def native(tmp_path_factory):
    return native_study(tmp_path_factory, "rope")


@pytest.fixture(scope="module")
def ironing(tmp_path_factory):
    return native_study(tmp_path_factory, "ironing-coarse")


def scene(dir: pathlib.Path, name: str, body: str, like: str = "rope") -> pathlib.Path:
    path = dir / f"{name}.toml"
    path.write_text(f'[scene]\nname = "{name}"\ndescription = "{like} read back"\n\n[model.external]\n{body}\n'
                    f'{study(like)}\n')
    return path


def all_columns(sets):
    """Training then test columns side by side, and the parameter values."""
    (tp, td, tm), (sp, sd, sm) = sets["train"], sets["test"]
    return np.hstack([tp, sp]), np.hstack([td, sd]), np.concatenate([tm, sm]), tp.shape[1]


def assert_same_tables(native_store, store, name, like):
    for t in TABLES:
        a = pd.read_parquet(native_store / "scenes" / like / f"{t}.parquet").drop(columns="scene")
        b = pd.read_parquet(store / "scenes" / name / f"{t}.parquet").drop(columns="scene")
        # Exact: the same f64 inputs through the same deterministic algorithms.
        pd.testing.assert_frame_equal(a, b, check_exact=True)
    with h5py.File(native_store / "scenes" / like / "basis.h5") as a, h5py.File(store / "scenes" / name / "basis.h5") as b:
        def walk(g, h, path=""):
            for k in g:
                if isinstance(g[k], h5py.Dataset):
                    assert np.array_equal(g[k][()], h[k][()]), f"basis {path}/{k}"
                else:
                    walk(g[k], h[k], f"{path}/{k}")
        walk(a, b)


def test_npy_and_csv_with_column_lists_round_trip_bit_for_bit(ironing, tmp_path):
    native_store, sets = ironing
    primal, dual, mu, n_train = all_columns(sets)
    np.save(tmp_path / "primal.npy", np.asfortranarray(primal))  # one snapshot per column, Fortran order
    np.save(tmp_path / "dual.npy", np.ascontiguousarray(dual.T))  # one snapshot per row
    # repr() of a float64 is its shortest round-trip decimal: the CSV holds the exact values.
    pd.DataFrame({"d_x": mu}).to_csv(tmp_path / "mu.csv", index=False, float_format=lambda v: repr(float(v)))
    n = dual.shape[1]
    path = scene(tmp_path, "ironing-npy", f"""dual = {{ file = "dual.npy", layout = "rows" }}
primal = {{ file = "primal.npy" }}
parameters = {{ file = "mu.csv", names = ["d_x"] }}
train = {list(range(n_train))}
test = {list(range(n_train, n))}""", like="ironing-coarse")
    store = tmp_path / "store"
    first = crom(store, "run", str(path))
    assert first.returncode == 0, first.stderr
    assert "external scene" in first.stderr and "skipped" in first.stderr
    assert_same_tables(native_store, store, "ironing-npy", "ironing-coarse")
    # A re-run with unchanged files imports nothing and computes nothing.
    again = crom(store, "run", str(path))
    assert again.returncode == 0, again.stderr
    assert f"0 imported, {n} reused" in again.stderr, again.stderr
    assert "computed" not in again.stderr, again.stderr
    # A changed dual file is imported again (new keys), and the sets are rebuilt.
    d2 = dual.copy()
    d2[:, 0] *= 2.0
    np.save(tmp_path / "dual.npy", np.ascontiguousarray(d2.T))
    changed = crom(store, "run", str(path))
    assert changed.returncode == 0, changed.stderr
    assert f"{n} imported, 0 reused" in changed.stderr, changed.stderr


def test_hdf5_with_a_second_pair_of_files_round_trips(ironing, tmp_path):
    native_store, sets = ironing
    (tp, td, tm), (sp, sd, sm) = sets["train"], sets["test"]
    with h5py.File(tmp_path / "train.h5", "w") as f:
        f["fields/primal"] = tp
        f["fields/dual"] = td
        f["mu"] = tm
    with h5py.File(tmp_path / "test.h5", "w") as f:
        f["fields/primal"] = sp.T  # rows
        f["fields/dual"] = sd
    pd.DataFrame({"d_x": sm}).to_parquet(tmp_path / "test_mu.parquet")
    path = scene(tmp_path, "ironing-h5", """dual = { file = "train.h5", dataset = "fields/dual" }
primal = { file = "train.h5", dataset = "fields/primal" }
parameters = { file = "train.h5", dataset = "mu", names = ["d_x"] }

[model.external.test_files]
dual = { file = "test.h5", dataset = "fields/dual" }
primal = { file = "test.h5", dataset = "fields/primal", layout = "rows" }
parameters = { file = "test_mu.parquet", names = ["d_x"] }""", like="ironing-coarse")
    store = tmp_path / "store"
    done = crom(store, "run", str(path))
    assert done.returncode == 0, done.stderr
    assert_same_tables(native_store, store, "ironing-h5", "ironing-coarse")
    # The Python reader opens the external scene like a native one.
    import crom_data
    sc = crom_data.open_store(store).scene("ironing-h5")
    ts = sc.trainset("test")
    assert np.array_equal(ts.dual, sd) and np.array_equal(ts.primal, sp)
    assert ts.parameter_names == ["d_x"] and np.array_equal(ts.parameters, sm)
    assert sorted(sc.compactness().columns) == sorted(pd.read_parquet(store / "scenes" / "ironing-h5" / "compactness.parquet").columns)


# --- bad input: exit 2, the file and the dataset or field named, a fix, nothing stored ---------


@pytest.fixture()
def files(native, tmp_path):
    """Writable copies of the rope's arrays as .npy (snapshots as columns) and a CSV."""
    _, sets = native
    primal, dual, mu, n_train = all_columns(sets)
    return tmp_path, primal.copy(), dual.copy(), mu.copy(), n_train


def write(tmp_path, primal, dual, mu):
    np.save(tmp_path / "primal.npy", primal)
    np.save(tmp_path / "dual.npy", dual)
    pd.DataFrame({"gamma": mu}).to_csv(tmp_path / "mu.csv", index=False)


def body(n_train, n, extra="", train=None, dual='{ file = "dual.npy" }'):
    train = list(range(n_train)) if train is None else train
    return f"""dual = {dual}
primal = {{ file = "primal.npy" }}
parameters = {{ file = "mu.csv", names = ["gamma"] }}
train = {train}
test = {list(range(n_train, n))}
{extra}"""


def refused(tmp_path, scene_body, *needles, env=None):
    store = tmp_path / "store"
    done = subprocess.run([str(crom_bin()), "--store", str(store), "run", str(scene(tmp_path, "bad", scene_body))],
                          cwd=REPO, capture_output=True, text=True, env=env)
    assert done.returncode == 2, (done.returncode, done.stderr)
    for needle in [*needles, "fix:"]:
        assert needle in done.stderr, (needle, done.stderr)
    # Nothing was stored: no column family, no set.
    assert not (store / "columns").exists() or not any((store / "columns").iterdir()), done.stderr
    assert not (store / "trainset").exists() or not any((store / "trainset").iterdir()), done.stderr
    return done.stderr


def test_a_missing_file_and_a_missing_dataset_are_named(files):
    tmp_path, primal, dual, mu, n_train = files
    write(tmp_path, primal, dual, mu)
    n = dual.shape[1]
    refused(tmp_path, body(n_train, n, dual='{ file = "nowhere.npy" }'), "nowhere.npy", "model.external.dual",
            "does not exist")
    with h5py.File(tmp_path / "d.h5", "w") as f:
        f["dual"] = dual
    refused(tmp_path, body(n_train, n, dual='{ file = "d.h5", dataset = "pressure" }'), "d.h5", "dataset pressure",
            "does not exist", "model.external.dual.dataset")
    # A compressed archive cut short: refused, naming the archive.
    np.savez_compressed(tmp_path / "d.npz", dual=dual)
    whole = (tmp_path / "d.npz").read_bytes()
    (tmp_path / "d.npz").write_bytes(whole[: len(whole) // 2])
    refused(tmp_path, body(n_train, n, dual='{ file = "d.npz", dataset = "dual" }'), "d.npz", "the .npz archive",
            "numpy.savez")
    # An archive without the member named, and one without a member given at all.
    np.savez(tmp_path / "d.npz", pressure=dual)
    refused(tmp_path, body(n_train, n, dual='{ file = "d.npz", dataset = "dual" }'), "d.npz", "member dual",
            "is not in the archive (it holds: pressure)", "model.external.dual.dataset")
    refused(tmp_path, body(n_train, n, dual='{ file = "d.npz" }'), "d.npz", "names no member",
            "model.external.dual.dataset")


@pytest.mark.parametrize("save", [np.savez, np.savez_compressed], ids=["stored", "deflated"])
def test_an_npz_round_trips_bit_for_bit(native, tmp_path, save):
    """np.savez stores its members uncompressed: each is read in blocks where it lies in the
    archive; np.savez_compressed deflates them: each is inflated into a temporary file first.
    Either way the study equals the native one, and no temporary file is left behind."""
    native_store, sets = native
    primal, dual, mu, n_train = all_columns(sets)
    save(tmp_path / "rope.npz", primal=primal, dual=np.ascontiguousarray(dual.T), mu=mu)
    tmp = tmp_path / "tmpdir"
    tmp.mkdir()
    n = dual.shape[1]
    path = scene(tmp_path, "rope-npz", f"""dual = {{ file = "rope.npz", dataset = "dual", layout = "rows" }}
primal = {{ file = "rope.npz", dataset = "primal" }}
parameters = {{ file = "rope.npz", dataset = "mu", names = ["gamma"] }}
train = {list(range(n_train))}
test = {list(range(n_train, n))}""")
    store = tmp_path / "store"
    done = subprocess.run([str(crom_bin()), "--store", str(store), "--quiet", "run", str(path)], cwd=REPO, capture_output=True,
                          text=True, env={**os.environ, "TMPDIR": str(tmp)})
    assert done.returncode == 0, done.stderr
    assert_same_tables(native_store, store, "rope-npz", "rope")
    assert list(tmp.iterdir()) == []


def test_mismatched_column_counts_are_refused(files):
    tmp_path, primal, dual, mu, n_train = files
    n = dual.shape[1]
    write(tmp_path, primal[:, :-1], dual, mu)
    refused(tmp_path, body(n_train, n), "primal.npy", f"holds {n - 1} snapshots", f"holds {n}")
    write(tmp_path, primal, dual, mu[:-1])
    refused(tmp_path, body(n_train, n), "mu.csv", f"holds {n - 1} parameter values")


def test_a_nonfinite_value_is_reported_with_its_column_and_row(files):
    tmp_path, primal, dual, mu, n_train = files
    dual[7, 3] = np.nan
    dual[2, 5] = np.inf  # a later column: not the first
    write(tmp_path, primal, dual, mu)
    refused(tmp_path, body(n_train, dual.shape[1]), "dual.npy", "column 3, row 7 is NaN")


def test_a_nonfinite_primal_value_takes_back_the_blocks_already_stored(files):
    tmp_path, primal, dual, mu, n_train = files
    n = dual.shape[1]
    store = tmp_path / "store"
    # A good import first: the bad one below goes to the same column family, which must be left
    # exactly as it was.
    write(tmp_path, primal, dual, mu)
    good = crom(store, "--quiet", "run", str(scene(tmp_path, "good", body(n_train, n))))
    assert good.returncode == 0, good.stderr
    before = sorted(p.relative_to(store) for p in (store / "columns").rglob("*"))
    primal[5, n_train + 2] = -np.inf  # a test column: the training set's blocks are stored first
    np.save(tmp_path / "primal.npy", primal)
    # Two columns per block, so that several blocks are committed before the bad value is read.
    env = {**os.environ, "CROM_BLOCK_COLUMNS": "2"}
    done = subprocess.run([str(crom_bin()), "--store", str(store), "run", str(scene(tmp_path, "bad", body(n_train, n)))],
                          cwd=REPO, capture_output=True, text=True, env=env)
    assert done.returncode == 2, done.stderr
    assert f"column {n_train + 2}, row 5 is -inf" in done.stderr and "primal.npy" in done.stderr, done.stderr
    assert sorted(p.relative_to(store) for p in (store / "columns").rglob("*")) == before


def test_a_nonfinite_primal_value_in_a_fresh_store_leaves_no_column_family(files):
    tmp_path, primal, dual, mu, n_train = files
    primal[3, 1] = np.nan
    write(tmp_path, primal, dual, mu)
    env = {**os.environ, "CROM_BLOCK_COLUMNS": "1"}
    refused(tmp_path, body(n_train, dual.shape[1]), "primal.npy", "column 1, row 3 is NaN", env=env)


def test_negative_pressures_are_refused_unless_clipped(files):
    tmp_path, primal, dual, mu, n_train = files
    scale = np.abs(dual[:, 4]).max()
    dual[10, 4] = -1e-3 * scale  # far beyond the default tolerance 1e-10
    dual[11, 6] = -1e-14 * np.abs(dual[:, 6]).max()  # within it: kept as is
    write(tmp_path, primal, dual, mu)
    n = dual.shape[1]
    err = refused(tmp_path, body(n_train, n), "dual.npy", "1 column(s)", "columns (most negative value) 4 (",
                  "clip_negative")
    assert " 6 (" not in err
    store = tmp_path / "store"
    done = crom(store, "--quiet", "run", str(scene(tmp_path, "clipped", body(n_train, n, "clip_negative = true"))))
    assert done.returncode == 0, done.stderr
    with h5py.File(store / "scenes" / "clipped" / "train.h5") as f:
        stored = f["dual"][()]
    assert stored[10, 4] == 0.0
    expect = dual[:, :n_train].copy()
    expect[expect < 0] = 0.0
    assert np.array_equal(stored, expect)


def test_duplicate_parameter_values_and_a_single_snapshot_are_refused(files):
    tmp_path, primal, dual, mu, n_train = files
    mu[n_train + 1] = mu[2]
    write(tmp_path, primal, dual, mu)
    n = dual.shape[1]
    refused(tmp_path, body(n_train, n), "mu.csv", f"test column {n_train + 1}", "as train column 2")
    mu[n_train + 1] = 0.123456
    write(tmp_path, primal, dual, mu)
    refused(tmp_path, body(n_train, n, train=[0]), "model.external.train", "1 snapshot(s)", "at least 2")


def test_crom_import_writes_a_scene_that_runs_and_refuses_bad_arrays(files):
    tmp_path, primal, dual, mu, n_train = files
    with h5py.File(tmp_path / "s.h5", "w") as f:
        f["fields/dual"] = dual.T  # one snapshot per row
        f["fields/primal"] = primal.T
    pd.DataFrame({"gamma": mu}).to_parquet(tmp_path / "mu.parquet")
    out = tmp_path / "imported.toml"
    args = ["import", "--name", "imported", "--dual", f"{tmp_path / 's.h5'}:fields/dual", "--primal",
            f"{tmp_path / 's.h5'}:fields/primal", "--rows", "--parameters", str(tmp_path / "mu.parquet"), "--names",
            "gamma", "--test-every", "3", "-o", str(out)]
    done = crom(tmp_path / "unused-store", *args)
    assert done.returncode == 0, done.stderr
    assert not (tmp_path / "unused-store").exists(), "crom import stores nothing"
    n = dual.shape[1]
    text = out.read_text()
    assert f"test = [{', '.join(str(j) for j in range(2, n, 3))}]" in text, text
    store = tmp_path / "store"
    run = crom(store, "--quiet", "run", str(out))
    assert run.returncode == 0, run.stderr
    with h5py.File(store / "scenes" / "imported" / "test.h5") as f:
        assert np.array_equal(f["dual"][()], dual[:, 2::3])
    # A non-finite value anywhere: exit 2, no scene file.
    primal[4, 7] = np.nan
    with h5py.File(tmp_path / "s.h5", "w") as f:
        f["fields/dual"] = dual.T
        f["fields/primal"] = primal.T
    out.unlink()
    bad = crom(tmp_path / "unused-store", *args)
    assert bad.returncode == 2, bad.stderr
    assert "row 7, column 4 is NaN" in bad.stderr and "fields/primal" in bad.stderr, bad.stderr
    assert not out.exists()


def test_crom_import_can_train_on_every_column(files):
    """`--test-every 0`: every column trains (`test = []`), the metrics are computed on all N
    columns (the training set holds them all, and G(m) has N folds), the comparison has no test
    rows, the run says what it skipped, and `--test-every 1` is refused (no training column)."""
    tmp_path, primal, dual, mu, n_train = files
    np.save(tmp_path / "dual.npy", dual)
    pd.DataFrame({"gamma": mu}).to_csv(tmp_path / "mu.csv", index=False, float_format=lambda v: repr(float(v)))
    out = tmp_path / "all.toml"
    args = ["import", "--name", "all", "--dual", str(tmp_path / "dual.npy"), "--parameters", str(tmp_path / "mu.csv"),
            "--names", "gamma", "-o", str(out)]
    done = crom(tmp_path / "unused-store", *args, "--test-every", "0")
    assert done.returncode == 0, done.stderr
    n = dual.shape[1]
    text = out.read_text()
    assert "test = []" in text and f"train = [{', '.join(str(j) for j in range(n))}]" in text, text
    # a small comparison, to see that it has no test rows
    out.write_text(text + '\n[comparison]\nmax_m = 3\nloo_folds = 4\napproximations = [{ kind = "pod" }]\n')
    store = tmp_path / "store"
    run = crom(store, "run", str(out))
    assert run.returncode == 0, run.stderr
    assert "every column trains" in run.stdout + run.stderr
    with h5py.File(store / "scenes" / "all" / "train.h5") as f:
        assert np.array_equal(f["dual"][()], dual)
    assert not (store / "scenes" / "all" / "test.h5").exists()
    g = pd.read_parquet(store / "scenes" / "all" / "generalization.parquet")
    assert (g[g.field == "dual"]["count"] + g[g.field == "dual"]["n_zero"]).max() == n
    cmp = pd.read_parquet(next((store / "approximation").glob("*/comparison.parquet")))
    assert set(cmp.metric) == {"compactness", "generalization", "specificity"}, set(cmp.metric)
    one = crom(tmp_path / "unused-store", *args, "--test-every", "1")
    assert one.returncode == 2 and "--test-every" in one.stderr, one.stderr


def test_without_primal_snapshots_the_dual_study_is_the_native_one(native, tmp_path):
    native_store, sets = native
    primal, dual, mu, n_train = all_columns(sets)
    np.save(tmp_path / "dual.npy", dual)
    pd.DataFrame({"gamma": mu}).to_csv(tmp_path / "mu.csv", index=False, float_format=lambda v: repr(float(v)))
    n = dual.shape[1]
    path = scene(tmp_path, "dual-only", f"""dual = {{ file = "dual.npy" }}
parameters = {{ file = "mu.csv", names = ["gamma"] }}
train = {list(range(n_train))}
test = {list(range(n_train, n))}""")
    store = tmp_path / "store"
    done = crom(store, "--quiet", "run", str(path))
    assert done.returncode == 0, done.stderr
    for t in TABLES:
        a = pd.read_parquet(native_store / "scenes" / "rope" / f"{t}.parquet").drop(columns="scene")
        b = pd.read_parquet(store / "scenes" / "dual-only" / f"{t}.parquet").drop(columns="scene")
        # The dual rows exactly as the native study's (same inputs, deterministic algorithms).
        pd.testing.assert_frame_equal(a[a.field == "dual"].reset_index(drop=True),
                                      b[b.field == "dual"].reset_index(drop=True), check_exact=True)


def test_an_external_scene_has_no_reduced_model_to_query(files):
    """An external scene's study is its bases and metrics: `crom query` says so (exit 2), rather
    than asking for a `crom run` that would not make a model."""
    tmp_path, primal, dual, mu, n_train = files
    write(tmp_path, primal, dual, mu)
    path = scene(tmp_path, "ext-query", body(n_train, dual.shape[1]))
    store = tmp_path / "store"
    assert crom(store, "--quiet", "run", str(path)).returncode == 0
    done = crom(store, "query", str(path), "--at", f"gamma={mu[0]!r}")
    assert done.returncode == 2, (done.returncode, done.stderr)
    assert "is external" in done.stderr and "fix:" in done.stderr, done.stderr
    assert "crom run" not in done.stderr.split("fix:")[1], done.stderr


def rope_mesh(native_store, tmp_path):
    """The native rope's mesh as an external mesh file: nodes, 2-node cells and the node of each
    dual entry (its contact nodes)."""
    with h5py.File(native_store / "scenes" / "rope" / "mesh.h5") as f:
        nodes, cells, contact = f["nodes"][()], f["cells"][()], f["contact_nodes"][()]
    with h5py.File(tmp_path / "mesh.h5", "w") as f:
        f["nodes"] = nodes[:, :1]  # 1-D coordinates: the mesh artifact pads y = 0
        f["cells"] = cells.astype(np.int32)
        f["dual_nodes"] = contact.astype(np.int64)
    return nodes, cells, contact


def test_without_a_mesh_the_report_has_the_curves_and_says_pictures_need_one(files):
    tmp_path, primal, dual, mu, n_train = files
    write(tmp_path, primal, dual, mu)
    store = tmp_path / "store"
    done = crom(store, "run", str(scene(tmp_path, "no-mesh", body(n_train, dual.shape[1]))))
    assert done.returncode == 0, done.stderr
    assert "need a mesh (model.external.mesh)" in done.stderr, done.stderr
    report = store / "scenes" / "no-mesh" / "report"
    index = (report / "index.html").read_text()
    for stem in ["fig_dual_snapshots", "fig04_singular_values", "fig09_compactness", "fig10_generalization",
                 "fig10_specificity"]:
        assert f'src="{stem}.png"' in index and (report / f"{stem}.png").exists(), stem
    assert "fig_pressure_mesh" not in index and "fig_tradeoff" not in index
    assert "they need a mesh" in index and "full-order operators" in index
    assert not (store / "scenes" / "no-mesh" / "train.xdmf").exists()


def test_a_mesh_gives_the_views_of_the_native_scene(native, files):
    """The rope's snapshots on the rope's own mesh, read back: the external scene's views hold
    the native views' values (the deflection as y, the pressure at the contact nodes)."""
    native_store, _ = native
    tmp_path, primal, dual, mu, n_train = files
    write(tmp_path, primal, dual, mu)
    rope_mesh(native_store, tmp_path)
    mesh = 'mesh = { file = "mesh.h5", nodes = "nodes", cells = "cells", dual_nodes = "dual_nodes" }'
    store = tmp_path / "store"
    done = crom(store, "run", str(scene(tmp_path, "rope-mesh", body(n_train, dual.shape[1], extra=mesh))))
    assert done.returncode == 0, done.stderr
    import meshio
    read = lambda p: meshio.xdmf.TimeSeriesReader(str(p))
    with read(native_store / "scenes" / "rope" / "train.xdmf") as a, \
            read(store / "scenes" / "rope-mesh" / "train.xdmf") as b:
        pa, ca = a.read_points_cells()
        pb, cb = b.read_points_cells()
        np.testing.assert_array_equal(pa, pb)
        np.testing.assert_array_equal(ca[0].data, cb[0].data)
        assert a.num_steps == b.num_steps == n_train
        for k in range(n_train):
            fa, fb = a.read_data(k)[1], b.read_data(k)[1]
            for field in ["displacement", "pressure"]:
                np.testing.assert_array_equal(fa[field], fb[field])
    index = (store / "scenes" / "rope-mesh" / "report" / "index.html").read_text()
    assert "they need a mesh" not in index and "full-order operators" in index


def test_a_bad_mesh_is_refused_naming_the_file_and_the_dataset(native, files):
    native_store, _ = native
    tmp_path, primal, dual, mu, n_train = files
    write(tmp_path, primal, dual, mu)
    nodes, cells, contact = rope_mesh(native_store, tmp_path)
    n = dual.shape[1]
    mesh = 'mesh = {{ file = "mesh.h5", nodes = "{}", cells = "cells"{} }}'
    # No map, and fewer dual entries than nodes (the rope's every node is a contact node: one
    # node more).
    with h5py.File(tmp_path / "mesh.h5", "a") as f:
        f["more_nodes"] = np.vstack([nodes[:, :1], [[2.0]]])
    refused(tmp_path, body(n_train, n, extra=mesh.format("more_nodes", "")), "mesh.h5",
            "model.external.mesh.dual_nodes", "is missing", f"{len(contact)} entries for {len(nodes) + 1} nodes")
    # A map of the wrong length.
    with h5py.File(tmp_path / "mesh.h5", "a") as f:
        f["short"] = contact[:-1]
    refused(tmp_path, body(n_train, n, extra=mesh.format("nodes", ', dual_nodes = "short"')), "mesh.h5",
            "dataset short", f"the dual snapshots have {len(contact)} entries")
    # A dataset that is not there.
    refused(tmp_path, body(n_train, n, extra=mesh.format("nodes", ', dual_nodes = "map"')), "mesh.h5", "dataset map",
            "does not exist")
    # A cell that names a node the mesh does not have.
    bad = cells.copy()
    bad[3, 1] = len(nodes) + 5
    with h5py.File(tmp_path / "mesh.h5", "a") as f:
        del f["cells"]
        f["cells"] = bad
    refused(tmp_path, body(n_train, n, extra=mesh.format("nodes", ', dual_nodes = "dual_nodes"')), "mesh.h5",
            "dataset cells", f"row 3, column 1 is {len(nodes) + 5}", "not a node index")
    # Two dual entries on one node.
    twice = contact.copy()
    twice[1] = twice[0]
    with h5py.File(tmp_path / "mesh.h5", "a") as f:
        del f["cells"], f["dual_nodes"]
        f["cells"] = cells
        f["dual_nodes"] = twice
    refused(tmp_path, body(n_train, n, extra=mesh.format("nodes", ', dual_nodes = "dual_nodes"')), "mesh.h5",
            "dataset dual_nodes", f"gives node {contact[0]} to dual entries 0 and 1")


@pytest.fixture(scope="module")
def hertz(tmp_path_factory):
    return native_study(tmp_path_factory, "hertz")


def test_the_comparison_runs_on_an_external_scene_with_coordinates(hertz, tmp_path):
    """Hertz's training and test sets with its contact nodes' coordinates, imported with Hertz's
    [comparison] (registered moments maps included): every approximation's curves equal the
    native study's bit for bit. Without coordinates the registered ones are skipped with their
    reason, and the others still equal the native ones."""
    native_store, sets = hertz
    primal, dual, mu, n_train = all_columns(sets)
    with h5py.File(native_store / "scenes" / "hertz" / "mesh.h5") as f:
        xy = f["nodes"][()][f["contact_nodes"][()]]
    with h5py.File(tmp_path / "hertz.h5", "w") as f:
        f["primal"], f["dual"], f["mu"], f["xy"] = primal, dual, mu, xy
    n = dual.shape[1]
    files = f"""dual = {{ file = "hertz.h5", dataset = "dual" }}
primal = {{ file = "hertz.h5", dataset = "primal" }}
parameters = {{ file = "hertz.h5", dataset = "mu", names = ["d"] }}
train = {list(range(n_train))}
test = {list(range(n_train, n))}"""
    native = pd.read_parquet(native_store / "scenes" / "hertz" / "comparison" / "comparison.parquet")
    native = native.drop(columns="scene")
    for name, extra, skipped in [("hertz-xy", 'coordinates = { file = "hertz.h5", dataset = "xy" }', False),
                                 ("hertz-no-xy", "", True)]:
        store = tmp_path / f"store-{name}"
        done = crom(store, "run", str(scene(tmp_path, name, files + "\n" + extra, like="hertz")))
        assert done.returncode == 0, done.stderr
        ours = pd.read_parquet(store / "scenes" / name / "comparison" / "comparison.parquet").drop(columns="scene")
        expected = native[~native.approximation.str.startswith("registered")] if skipped else native
        pd.testing.assert_frame_equal(expected.reset_index(drop=True), ours.reset_index(drop=True), check_exact=True)
        index = (store / "scenes" / name / "report" / "index.html").read_text()
        assert "fig_comparison_test" in index
        reason = "the registered maps need the contact entries' coordinates"
        assert (reason in done.stderr) == skipped and (reason in index) == skipped, done.stderr


def test_a_training_set_that_is_a_nested_grid_gets_the_native_nested_error(tmp_path, tmp_path_factory):
    """The rope at train_level = 3 with nested levels 1 to 3 (level 3 is its training set),
    exported and imported: the external scene finds the levels in its 9 equally spaced training
    points, and its H(n) table equals the native one bit for bit."""
    native_scene = variant(tmp_path, "rope", "rope-l3", [("n_train = 10", "train_level = 3\nnested_levels = 3")])
    native_store, sets = native_study(tmp_path_factory, "rope-l3", native_scene)
    primal, dual, mu, n_train = all_columns(sets)
    assert n_train == 9
    np.save(tmp_path / "primal.npy", primal)
    np.save(tmp_path / "dual.npy", dual)
    np.save(tmp_path / "mu.npy", mu)
    path = scene(tmp_path, "rope-nested", f"""dual = {{ file = "dual.npy" }}
primal = {{ file = "primal.npy" }}
parameters = {{ file = "mu.npy", names = ["gamma"] }}
train = {list(range(n_train))}
test = {list(range(n_train, dual.shape[1]))}""")
    store = tmp_path / "store"
    done = crom(store, "--quiet", "run", str(path))
    assert done.returncode == 0, done.stderr
    a = pd.read_parquet(native_store / "scenes" / "rope-l3" / "nested.parquet").drop(columns="scene")
    b = pd.read_parquet(store / "scenes" / "rope-nested" / "nested.parquet").drop(columns="scene")
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    assert sorted(p.name for p in (store / "scenes" / "rope-nested" / "nested").glob("level-*.h5")) == \
        ["level-1.h5", "level-2.h5", "level-3.h5"]
    assert "fig15_nested" in (store / "scenes" / "rope-nested" / "report" / "index.html").read_text()


def test_a_two_component_nested_grid_gets_the_native_nested_error(tmp_path, tmp_path_factory):
    """ironing-coarse with two components (d_x at train_level 3, d_y at train_level 2: 9 x 5
    training points) and nested levels 1 and 2, exported with its training columns reversed and
    imported: the external scene finds levels 1 and 2 as tensor grids in the shuffled columns,
    and its H(n) table equals the native one bit for bit."""
    native_scene = variant(tmp_path, "ironing-coarse", "ic-2d", [
        ("[model.ironing]\nd_y = 0.04\n", "[model.ironing]\n"),
        ("n_train = 128\nnested_levels = 7",
         'train_level = 3\nnested_levels = 2\n\n[[parameter.axes]]\nname = "d_y"\n'
         'description = "downward displacement of the iron"\nmin = 0.02\nmax = 0.06\ntrain_level = 2')])
    native_store, sets = native_study(tmp_path_factory, "ic-2d", native_scene)
    # The training columns in reverse order: the levels must come from the values, not the order.
    p, d, m = sets["train"]
    sets["train"] = (p[:, ::-1], d[:, ::-1], m[::-1])
    primal, dual, mu, n_train = all_columns(sets)
    assert n_train == 45 and mu.shape == (77, 2)
    np.save(tmp_path / "primal.npy", primal)
    np.save(tmp_path / "dual.npy", dual)
    np.save(tmp_path / "mu.npy", mu)
    path = scene(tmp_path, "ic-2d-ext", f"""dual = {{ file = "dual.npy" }}
primal = {{ file = "primal.npy" }}
parameters = {{ file = "mu.npy", names = ["d_x", "d_y"] }}
train = {list(range(n_train))}
test = {list(range(n_train, dual.shape[1]))}""", like="ironing-coarse")
    store = tmp_path / "store"
    done = crom(store, "--quiet", "run", str(path), "--offline")
    assert done.returncode == 0, done.stderr
    a = pd.read_parquet(native_store / "scenes" / "ic-2d" / "nested.parquet").drop(columns="scene")
    b = pd.read_parquet(store / "scenes" / "ic-2d-ext" / "nested.parquet").drop(columns="scene")
    assert len(a) > 0
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    for level, count in [(1, 9), (2, 25)]:
        with h5py.File(store / "scenes" / "ic-2d-ext" / "nested" / f"level-{level}.h5") as f:
            assert f["parameters"].shape[0] == count
