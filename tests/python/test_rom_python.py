"""The reduced model from Python (`crom_data`'s `Scene.rom()`, the native extension crom_native).

Independent source of truth: the `crom` binary's own `crom query` process at the same points,
its table (`--out`, Parquet: the outcome, iterations, indicator) and its fields (`--fields`, HDF5:
the pressure on every node and the reconstructed displacement). Every float is compared bit for
bit (`tobytes()` / `float.hex`): the extension calls the query's code, so no tolerance applies.
`solve_many` is compared, bit for bit, with a loop of `solve` on 1 and 2 threads and on rayon's
default pool. Every refused input raises the exception class of `crom_data.errors` whose message
names the component and the fix.
"""
import json
import math
import shutil
import subprocess

import h5py
import numpy as np
import pandas as pd
import pytest

import crom_data
from crom_data.errors import (ArtifactMissing, CromDataError, InvalidPoint, InvalidSetting, OutsideDomain,
                              SceneNotFound, SchemaTooNew)
from conftest import REPO, crom_bin

STORES = {"rope": "rope_store", "hertz": "hertz_store"}


def _values(rom, k=5):
    """k points across the domain of a one-component model, ends included, not on a grid."""
    (lo, hi), = rom.domain.values()
    return [lo] + [lo + (hi - lo) * f for f in (0.1234567, 0.5, 0.7071067811865476)][:k - 2] + [hi]


def _query(store, scene, name, values, tmp_path):
    points = tmp_path / "points.csv"
    points.write_text(name + "\n" + "\n".join(repr(v) for v in values) + "\n")
    out, fields = tmp_path / "answers.parquet", tmp_path / "fields.h5"
    subprocess.run([str(crom_bin()), "--store", str(store), "query", scene, "--points", str(points), "--out", str(out),
                    "--fields", str(fields)], cwd=REPO, check=True, capture_output=True)
    return pd.read_parquet(out), fields


@pytest.mark.parametrize("scene", sorted(STORES))
def test_solve_is_the_query_bit_for_bit(scene, request, tmp_path):
    store = request.getfixturevalue(STORES[scene])
    sc = crom_data.open_store(store).scene(scene)
    rom = sc.rom()
    name, = rom.names
    values = _values(rom)
    table, fields = _query(store, scene, name, values, tmp_path)
    mesh = sc.mesh()
    in_contact = 0
    with h5py.File(fields, "r") as f:
        for j, v in enumerate(values):
            r = rom.solve(**{name: v})
            row = table.iloc[j]
            assert r.outcome == row["outcome"] and r.converged == (row["outcome"] == "converged")
            assert (r.iterations, r.linearizations, r.nonzero_dual) == (row["iterations"], row["linearizations"],
                                                                         row["nonzero_dual"])
            assert not r.extrapolated and row["extrapolated"] == "false"
            for mine, theirs in [(r.indicator, row["indicator"]),
                                 (r.indicator_terms["penetration"], row["penetration"]),
                                 (r.indicator_terms["complementarity"], row["complementarity"]),
                                 (r.indicator_terms["unpaired_force"], row["unpaired_force"])]:
                assert float(mine).hex() == float(theirs).hex(), (v, mine, theirs)
            pressure = f[f"steps/{j:05d}/pressure"][:][mesh.contact_nodes]
            assert r.pressure.tobytes() == pressure.tobytes(), v
            in_contact += r.pressure.max() > 0
            assert float(r.pressure.max()).hex() == float(row["max_pressure"]).hex()
            u = f[f"steps/{j:05d}/displacement"][:]  # n_nodes x 3
            d = mesh.dofs_per_node
            mine = r.displacement.reshape(-1, d)
            theirs = u[:, 1:2] if d == 1 else u[:, :d]
            assert mine.tobytes() == np.ascontiguousarray(theirs).tobytes(), v
            assert r.coefficients.shape == (rom.ranks[0],) and r.dual_coefficients.shape == (rom.ranks[1],)
    assert rom.n_contact == len(mesh.contact_nodes)
    assert in_contact >= 2, "the compared pressures are not all zero"


def _same(batch, j, r):
    """Row j of a batch is the single answer r, bit for bit."""
    assert batch.pressure[j].tobytes() == r.pressure.tobytes()
    assert batch.coefficients[j].tobytes() == r.coefficients.tobytes()
    assert batch.dual_coefficients[j].tobytes() == r.dual_coefficients.tobytes()
    assert batch.outcome[j] == r.outcome and bool(batch.converged[j]) == r.converged
    assert (batch.iterations[j], batch.linearizations[j], batch.nonzero_dual[j]) == (r.iterations, r.linearizations,
                                                                                       r.nonzero_dual)
    assert float(batch.indicator[j]).hex() == float(r.indicator).hex()
    for k, v in r.indicator_terms.items():
        assert float(getattr(batch, k)[j]).hex() == float(v).hex()
    assert bool(batch.extrapolated[j]) == r.extrapolated


def test_solve_many_is_a_loop_of_solve_on_one_and_two_threads(hertz_store):
    rom = crom_data.open_store(hertz_store).scene("hertz").rom()
    name, = rom.names
    (lo, hi), = rom.domain.values()
    rng = np.random.default_rng(7)
    points = np.concatenate([[lo, hi, 0.5 * (lo + hi)], rng.uniform(lo, hi, 37)])
    single = [rom.solve(**{name: float(v)}) for v in points]
    for threads in (1, 2, None):
        batch = rom.solve_many(points[:, None], threads=threads)
        assert len(batch) == len(points) and batch.pressure.shape == (len(points), rom.n_contact)
        for j, r in enumerate(single):
            _same(batch, j, r)
    # a 1-D array for a one-component model; the displacement of a row is the single answer's
    batch = rom.solve_many(points, threads=2)
    _same(batch, 5, single[5])
    assert batch.displacement(5).tobytes() == single[5].displacement.tobytes()
    frame = batch.to_frame()
    assert list(frame[name]) == list(points) and (frame["outcome"] == batch.outcome).all()


def test_a_model_opened_with_u_tol_is_the_query_with_u_tol_bit_for_bit(hertz_store, tmp_path):
    """`Scene.rom(u_tol=...)` solves as `crom query --u-tol` (the binary, the independent
    source): the same linearisations and the same pressure bits at points across the domain,
    fewer linearisations in all than the model's own tolerance (the setting reaches the solve),
    and `rom.u_tol` says which tolerance the solves use. Out-of-range values raise
    `InvalidSetting` naming u_tol."""
    sc = crom_data.open_store(hertz_store).scene("hertz")
    own, loose = sc.rom(), sc.rom(u_tol=1e-4)
    assert own.u_tol == own.info["u_tol"] == 1e-10 and loose.u_tol == 1e-4 and loose.info["u_tol"] == 1e-10
    name, = loose.names
    (lo, hi), = loose.domain.values()
    values = [lo + (hi - lo) * float(f) for f in np.linspace(0.03, 0.97, 12)]
    points = tmp_path / "points.csv"
    points.write_text(name + "\n" + "\n".join(repr(v) for v in values) + "\n")
    out = tmp_path / "answers.parquet"
    p = subprocess.run([str(crom_bin()), "--store", str(hertz_store), "query", "hertz", "--points", str(points),
                    "--out", str(out), "--u-tol", "1e-4"], cwd=REPO, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    table = pd.read_parquet(out)
    lin_own = lin_loose = 0
    for j, v in enumerate(values):
        r = loose.solve(**{name: v})
        assert r.converged and r.linearizations == table.iloc[j]["linearizations"], v
        assert float(r.pressure.max()).hex() == float(table.iloc[j]["max_pressure"]).hex(), v
        lin_loose += r.linearizations
        lin_own += own.solve(**{name: v}).linearizations
    assert lin_loose < lin_own, (lin_loose, lin_own)
    assert sc.rom(u_tol=np.float32(1e-4)).u_tol == float(np.float32(1e-4))  # any real number
    for bad in (0.0, 1.0, -1e-6, math.nan, math.inf, "1e-6", True):
        with pytest.raises(InvalidSetting, match=r"u_tol=.* not a tolerance in \(0, 1\)"):
            sc.rom(u_tol=bad)
    assert issubclass(InvalidSetting, (CromDataError, ValueError))


def test_the_hertz_model_is_the_most_accurate_candidate_the_study_measured(hertz_store):
    """The stored model's choice, recomputed in pandas from the study's tables: among the
    trade-off's rows of the exact solve and the online comparison's rows of the registered CPG
    approximations that converged at every test point, the fewest points missed, then the least
    median dual error, then the least median primal error, then the fewest modes. On hertz that
    is a registered basis, and the model's `measured_*` values are that row's."""
    sc = crom_data.open_store(hertz_store).scene("hertz")
    rom = sc.rom()
    trade = sc.tradeoff(timings=False)
    trade = trade[trade.algorithm.isin(["exact", "exact-sampled"])]
    exact = pd.DataFrame({"dual_basis": trade.dual_basis, "r_primal": trade.r_primal, "r_dual": trade.r_dual,
                          "points": trade.points, "converged": trade.converged,
                          "dual": trade.median_dual_error, "primal": trade.median_primal_error})
    online = sc.comparison("online_comparison")
    online = online[online.approximation.str.match(r"registered-.*-cpg$") & (online.converged == online.points)]
    registered = pd.DataFrame({"dual_basis": online.approximation, "r_primal": online.r_primal, "r_dual": online.m,
                               "points": online.points, "converged": online.converged,
                               "dual": online.median_dual_error, "primal": online.median_primal_error})
    c = pd.concat([exact, registered], ignore_index=True)
    c["missed"], c["modes"] = c.points - c.converged, c.r_primal + c.r_dual
    best = c.sort_values(["missed", "dual", "primal", "modes"], kind="stable", na_position="last").iloc[0]
    info = rom.info
    assert info["dual_basis"] == best.dual_basis == "registered-moments-cpg"
    assert rom.ranks == (best.r_primal, best.r_dual)
    assert float(info["measured_median_dual_error"]).hex() == float(best.dual).hex()
    assert float(info["measured_median_primal_error"]).hex() == float(best.primal).hex()
    assert info["measured_converged"] == info["measured_points"] == best.points
    assert best.dual < exact.dual.min(), "the registered basis is more accurate than every CPG row"


def test_bad_points_raise_the_packages_exceptions(rope_store):
    rom = crom_data.open_store(rope_store).scene("rope").rom()
    (lo, hi), = rom.domain.values()
    with pytest.raises(InvalidPoint, match=r"no value for gamma.*rom\.solve\(gamma="):
        rom.solve()
    with pytest.raises(InvalidPoint, match=r"no parameter 'beta'.*rom\.solve\(gamma="):
        rom.solve(gamma=0.0, beta=1.0)
    with pytest.raises(InvalidPoint, match=r"no value for gamma; the model has no parameter 'g'"):
        rom.solve(g=0.0)
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(InvalidPoint, match=r"gamma = .* is not a finite number; give a finite gamma in"):
            rom.solve(gamma=bad)
    with pytest.raises(InvalidPoint, match=r"gamma = abc is not a number"):
        rom.solve(gamma="abc")
    with pytest.raises(OutsideDomain, match=r"gamma = .* outside the training domain .*allow_extrapolation=True"):
        rom.solve(gamma=hi + 0.25)
    # the point as given, in the model's order (an int is a number too)
    assert rom.solve(gamma=lo).point == [lo] and rom.solve(gamma=0).point == [0]
    r = rom.solve(gamma=hi + 0.25, allow_extrapolation=True)
    assert r.extrapolated and np.all(np.isfinite(r.pressure))
    assert not rom.solve(gamma=hi, allow_extrapolation=True).extrapolated  # the boundary is inside
    # batches: the first bad row is named, nothing is solved
    with pytest.raises(InvalidPoint, match=r"row 2 of the points: gamma = NaN is not a finite number"):
        rom.solve_many([lo, 0.0, math.nan, hi])
    with pytest.raises(OutsideDomain, match=r"row 1 of the points: gamma = .* outside"):
        rom.solve_many([0.0, lo - 1.0])
    b = rom.solve_many([0.0, lo - 1.0], allow_extrapolation=True)
    assert b.extrapolated.tolist() == [False, True]
    with pytest.raises(InvalidPoint, match=r"points of shape \(3, 2\), the model has 1 component \(gamma\)"):
        rom.solve_many(np.zeros((3, 2)))
    with pytest.raises(InvalidPoint, match=r"not an array of numbers"):
        rom.solve_many(["a", "b"])
    with pytest.raises(InvalidPoint, match=r"threads=0"):
        rom.solve_many([0.0], threads=0)
    assert issubclass(OutsideDomain, InvalidPoint) and issubclass(InvalidPoint, (CromDataError, ValueError))


def test_a_study_without_a_model_is_refused_with_the_fix(rope_store, tmp_path):
    with pytest.raises(SceneNotFound, match=r"scene 'hertz-fine' is not published.*run hertz-fine"):
        crom_data.open_store(rope_store).scene("hertz-fine").rom()
    offline = tmp_path / "offline"
    subprocess.run([str(crom_bin()), "--store", str(offline), "--quiet", "run", "rope", "--offline"], cwd=REPO,
                   check=True, capture_output=True)
    with pytest.raises(ArtifactMissing, match=r"'model\.h5'.*--offline.*without --offline"):
        crom_data.open_store(offline).scene("rope").rom()


def test_an_unsupported_model_schema_is_refused(rope_store, tmp_path):
    copy = tmp_path / "store"
    shutil.copytree(rope_store, copy, symlinks=True)
    manifest, = (copy / "model").glob("*/manifest.json")
    m = json.loads(manifest.read_text())
    m["schema_version"] = m["schema_version"] + 1
    manifest.write_text(json.dumps(m))
    with pytest.raises(SchemaTooNew, match=r"entry 'model\.h5'.*schema version \d+ is newer.*upgrade crom_data"):
        crom_data.open_store(copy).scene("rope").rom()
