"""The reduced model artifact (`model/<key>/model.h5`) read by a third party with h5py alone, as
docs/user-guide.md ("The model artifact") describes it, and `crom query` driven from Python.

Checked independently of crom's reader: the dual basis rebuilt from its compressed rows is the
stored CPG basis's leading columns, exactly (a copy of the same doubles); a registered dual basis
(hertz's model; ironing-fine's, a neighbours basis whose order depends on the point) pushed forward to a point in NumPy from its `reg_*` arrays, as the store format
describes, gives the pressure the model answers there from its coefficients (to 1e-12: the same
products summed in another order); `u_of_y` is the inverse
transpose of the Cholesky factor `khat_l` to 1e-10 (a triangular inverse of a well-conditioned
factor, rounding only); every array has the length the layout gives; the training domain is the
scene file's.
"""
import subprocess
import tomllib

import h5py
import numpy as np
import pandas as pd

from conftest import REPO, crom_bin, only_artifact


def _registered_name(entry):
    """The tables' name of a registered `[comparison]` entry (`ApproximationSpec::name`)."""
    if entry.get("kind") != "registered":
        return None
    interpolation = entry.get("interpolation", "linear")
    kind = "moments" if entry["map"] == "moments" else f"translate-{interpolation}"
    return f"registered-{kind}-{entry['basis']}"


def _check_layout(store, scene):
    model = h5py.File(only_artifact(store, "model", "model.h5"), "r")
    a = model.attrs
    assert a["schema_version"] == 4 and a["scene"] == scene and a["kind"] == "model"
    # the corrected step: first-order (0) unless the model's registered basis is a comparison
    # entry with its own primal space (`primal_translates`), which stores 2
    scene_toml = tomllib.loads((REPO / "data" / "scenes" / f"{scene}.toml").read_text())
    entries = scene_toml.get("comparison", {}).get("approximations", [])
    own_primal = [e for e in entries if e.get("primal_translates") and _registered_name(e) == a["dual_basis"]]
    assert int(a["exact_step"]) == (2 if own_primal else 0), (a["dual_basis"], int(a["exact_step"]))
    ru, rl, nc, terms = (int(a[k]) for k in ("r_primal", "r_dual", "n_contact", "lift_terms"))
    # the dual basis, rebuilt from its compressed rows
    start, col, val = model["theta_start"][:], model["theta_column"][:], model["theta_value"][:]
    assert len(start) == nc + 1 and start[0] == 0 and start[-1] == len(val) == len(col)
    theta = np.zeros((nc, rl))
    for i in range(nc):
        theta[i, col[start[i]:start[i + 1]]] = val[start[i]:start[i + 1]]
    if int(a.get("reg_map", 0)) > 0:
        # no fixed dual basis; warm starts hold primal answers only (every active set empty)
        assert rl == 0 and len(val) == 0 and len(model["warm_set"]) == 0, "a registered basis has no fixed one"
        _check_registered(store, scene, model)
    else:
        basis = h5py.File(only_artifact(store, "basis", "basis.h5"), "r")
        cpg = basis["dual_cpg/modes"][:, :rl]
        assert np.array_equal(theta, cpg), "Theta is the stored CPG basis's leading columns"
    # the reduced stiffness' factor and its inverse transpose (column-major r x r)
    lower = model["khat_l"][:].reshape(ru, ru).T
    u_of_y = model["u_of_y"][:].reshape(ru, ru).T
    assert np.all(np.diag(lower) > 0)
    assert np.allclose(u_of_y @ np.tril(lower).T, np.eye(ru), atol=1e-10)
    assert len(model["weights"]) == nc
    # the training domain is the scene file's
    spec = tomllib.loads((REPO / "data" / "scenes" / f"{scene}.toml").read_text())["parameter"]
    assert a["parameter_names"] == spec["name"]
    assert model["parameter_min"][:].tolist() == [spec["min"]] and model["parameter_max"][:].tolist() == [spec["max"]]
    if int(a["surface"]) == 0:
        assert len(model["cphi"]) == nc * ru and len(model["chat"]) == rl * ru and len(model["cwc"]) == nc * nc
        assert len(model["cu0"]) == terms * nc and len(model["ghat"]) == terms * rl
    else:
        nn = int(a["n_slaves"]) + int(a["n_masters"])
        assert len(model["x_ref"]) == 2 * nn and len(model["phi_c"]) == 2 * nn * ru
        assert len(model["w_c"]) == (2 * nn) ** 2 and len(model["a_terms"]) == terms * 2 * nn
    # the optional reconstruction part: the primal basis on every dof, the lift's terms
    rec = h5py.File(only_artifact(store, "model", "reconstruction.h5"), "r")
    assert rec["phi"].shape[1] == ru and rec["lift"].shape == (rec["phi"].shape[0], terms)
    speed = pd.read_parquet(only_artifact(store, "model", "model_speed.parquet"))
    assert list(speed.columns) == ["median_online_seconds", "median_fom_seconds", "speedup"] and len(speed) == 1


def _levels(rows, mu, d):
    """(c, a) of the moments table `rows` (`d` components, then c and a) at `mu`, level by level
    along the last component as docs/store-format.md describes it."""
    t = mu[d - 1]
    values = np.unique(rows[:, d - 1])

    def at(v):
        on = rows[rows[:, d - 1] == v]
        return (on[0, -2], on[0, -1]) if d == 1 else _levels(on, mu, d - 1)

    k = np.searchsorted(values, t, side="right")
    if k == 0:
        return at(values[0])
    if k >= len(values):
        return at(values[-1])
    p, q = values[k - 1], values[k]
    (c0, a0), (c1, a1) = at(p), at(q)
    th = (t - p) / (q - p)
    return (1 - th) * c0 + th * c1, (1 - th) * a0 + th * a1


def _push(model, mu):
    """The registered generators pushed forward to the parameter point `mu` (a number, or one
    value per component), from the `reg_*` arrays as docs/store-format.md describes them:
    n_contact x (the first reg_m that are not zero there)."""
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    a = model.attrs
    kind, length, k, m = (int(a[n]) for n in ("reg_map", "reg_len", "reg_generators", "reg_m"))
    x, (start, step) = model["reg_surface"][:], model["reg_grid"][:]
    modes = model["reg_modes"][:].reshape(k, length).T
    out = np.zeros((len(x), k))
    if kind == 1:  # whole-node shifts: sorted node j takes reference value j - round(mu / h) + start
        order = np.argsort(x, kind="stable")
        t = np.sign(mu[0] / step) * np.floor(abs(mu[0] / step) + 0.5)
        q = np.arange(len(x)) - t + start
        inside = (q >= 0) & (q < length)
        out[order[inside]] = modes[q[inside].astype(int)]
    else:
        if kind == 2:
            c, w = mu[0], 1.0
        else:  # moments: (c, a) interpolated between the table's rows, clamped at its ends
            d = int(a["reg_dims"]) if "reg_dims" in a else 1
            c, w = _levels(model["reg_table"][:].reshape(-1, d + 2), mu, d)
        u = ((x - c) / w - start) / step
        inside = (u >= 0) & (u <= length - 1)
        k0 = np.minimum(np.floor(u[inside]).astype(int), length - 2)
        th = (u[inside] - k0)[:, None]
        out[inside] = (1 - th) * modes[k0] + th * modes[k0 + 1]
    if "reg_travels" in model:  # a neighbours basis: the generators in the order at mu
        out = out[:, _neighbour_order(model, mu[0], step)]
    keep = [j for j in range(out.shape[1]) if np.any(out[:, j] != 0)][:m]
    return out[:, keep]


def _round(t):
    """Rounding half away from zero (Rust's f64::round; NumPy's rounds half to even)."""
    return np.sign(t) * np.floor(np.abs(t) + 0.5)


def _neighbour_order(model, mu, h):
    """The generators of a neighbours basis in the order at `mu`, as docs/store-format.md gives
    it: scored by h |Δρ| + w |μ_1 − c_j| on the two sides of Δρ, taken alternately."""
    c, w = model["reg_travels"][:], float(model["reg_weight"][0])
    rho = lambda t: t / h - _round(t / h)
    d = rho(c) - rho(mu)
    d = d - _round(d)
    d[d <= -0.5] += 1.0
    score = h * np.abs(d) + w * np.abs(mu - c)
    sides = [sorted(np.flatnonzero(d <= 0), key=lambda j: (score[j], j)),
             sorted(np.flatnonzero(d > 0), key=lambda j: (score[j], j))]
    if sides[1] and (not sides[0] or score[sides[1][0]] < score[sides[0][0]]):
        sides.reverse()
    order = []
    for k in range(max(len(sides[0]), len(sides[1]))):
        order += [side[k] for side in sides if k < len(side)]
    return order


def _check_registered(store, scene, model):
    """A registered dual basis: its arrays' lengths, and Θ(μ) rebuilt in NumPy against the
    model's answers (pressure = Θ(μ) λ̂) at points across the domain."""
    import crom_data

    a = model.attrs
    length, k, m, nc = (int(a[n]) for n in ("reg_len", "reg_generators", "reg_m", "n_contact"))
    assert 1 <= m <= k and len(model["reg_modes"]) == length * k and len(model["reg_surface"]) == nc
    assert len(model["reg_grid"]) == 2 and len(model["reg_table"]) % 3 == 0
    if "reg_travels" in model:
        assert len(model["reg_travels"]) == k and len(model["reg_weight"]) == 1 and int(a["reg_map"]) == 1
    assert int(a["reg_map"]) != 3 or len(model["reg_table"]) > 0
    rom = crom_data.open_store(store).scene(scene).rom()
    (name, (lo, hi)), = rom.domain.items()
    for mu in np.linspace(lo, hi, 7):
        r = rom.solve(**{name: float(mu)})
        theta = _push(model, float(mu))
        assert theta.shape[1] == len(r.dual_coefficients) <= m
        p = theta @ r.dual_coefficients
        assert np.allclose(p, r.pressure, rtol=0, atol=1e-12 * max(np.abs(r.pressure).max(), 1e-300)), mu
        assert r.pressure.max() > 0, f"no contact at {mu}"


def test_model_layout_reads_with_h5py(rope_store, hertz_store, ironing_fine_store):
    _check_layout(rope_store, "rope")
    _check_layout(hertz_store, "hertz")
    _check_layout(ironing_fine_store, "ironing-fine")


def test_query_writes_one_row_per_point(rope_store, tmp_path):
    points = tmp_path / "points.csv"
    points.write_text("gamma\n-0.3\n0.0\n0.25\n")
    out = tmp_path / "answers.parquet"
    subprocess.run([str(crom_bin()), "--store", str(rope_store), "query", "rope", "--points", str(points), "--out",
                    str(out)], cwd=REPO, check=True, capture_output=True)
    t = pd.read_parquet(out)
    assert t["gamma"].tolist() == [-0.3, 0.0, 0.25]
    assert (t["outcome"] == "converged").all() and (t["extrapolated"] == "false").all()
    assert (t["max_pressure"] >= 0).all() and (t["indicator"] >= 0).all()
    bad = subprocess.run([str(crom_bin()), "--store", str(rope_store), "query", "rope", "--at", "gamma=9"], cwd=REPO,
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "outside the training domain" in bad.stderr


def test_query_fields_hold_the_dirichlet_data_and_the_queried_pressure(hertz_store, tmp_path):
    """`crom query --fields`: the reconstructed displacement imposes the scene's Dirichlet data
    exactly where it is imposed (the top face moves by -d: the lift carries it and the POD modes
    vanish there; 1e-12 relative for the rounding of one affine combination), the pressure field's
    largest value is the row's `max_pressure` (the same doubles), and meshio's XDMF reader (as
    ParaView's) opens the series."""
    import meshio

    fields = tmp_path / "out" / "hertz.h5"
    d = [0.05, 0.1234]
    rows = subprocess.run([str(crom_bin()), "--store", str(hertz_store), "query", "hertz", "--points",
                           str(_points(tmp_path, "d", d)), "--fields", str(fields)],
                          cwd=REPO, check=True, capture_output=True, text=True).stdout
    table = pd.read_csv(pd.io.common.StringIO(rows))
    with h5py.File(fields, "r") as f:
        nodes = f["nodes"][:]
        top = np.isclose(nodes[:, 1], nodes[:, 1].max(), rtol=0, atol=1e-12)
        assert top.sum() > 2
        np.testing.assert_array_equal(f["parameters"][:, 0], d)
        for j, dj in enumerate(d):
            u = f[f"steps/{j:05d}/displacement"][:]
            p = f[f"steps/{j:05d}/pressure"][:]
            assert u.shape == (len(nodes), 3) and p.shape == (len(nodes),)
            np.testing.assert_allclose(u[top, 1], -dj, rtol=1e-12, atol=0)
            assert p.max() == table["max_pressure"][j] and (p >= 0).all()
    with meshio.xdmf.TimeSeriesReader(str(fields.with_suffix(".xdmf"))) as reader:
        points, _ = reader.read_points_cells()
        np.testing.assert_array_equal(points[:, :2], nodes)
        _, point_data, _ = reader.read_data(1)
        with h5py.File(fields, "r") as f:
            np.testing.assert_array_equal(point_data["pressure"], f["steps/00001/pressure"][:])


def _points(tmp_path, name, values):
    path = tmp_path / "points.csv"
    path.write_text(name + "\n" + "\n".join(repr(v) for v in values) + "\n")
    return path
