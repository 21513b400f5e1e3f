"""crom_data: read a crom store from Python by scene and set name, without knowing a hash.

    import crom_data as c
    s = c.open_store("data/store")          # default: $CROM_STORE, else data/store
    s.scenes()                              # ['ironing-fine', 'rope', ...]
    s.catalog()                             # catalog.parquet as a DataFrame
    sc = s.scene("ironing-fine")
    ts = sc.trainset("train")               # also "test", "nested-3"
    ts.primal.shape, ts.dual.shape          # (n_dof, N), (n_contact, N)
    sc.generalization(); sc.basis()["dual_cpg"].modes; sc.mesh().nodes; sc.report_dir
    rom = sc.rom()                          # the stored reduced model (native extension, crom_data.rom)
    rom.solve(d_x=1.2345).pressure; rom.solve_many(points).indicator

The store (written by the Rust binary `crom`; specified in full in docs/store-format.md):

    STORE/catalog.parquet               one row per artifact and snapshot column family: stage, scene,
                                        set, bases, key, inputs (JSON), schema_version, algorithm_version,
                                        crom_version, created_unix, created, bytes, files, path, published
    STORE/<stage>/<key>/                one artifact: its files + manifest.json (stage, key,
                                        schema_version, inputs, parameters, files [{name, bytes, blake3}],
                                        summary, ...); <key> is a blake3 content hash
    STORE/columns/<family>/             the snapshots themselves, in blocks (training sets are HDF5
                                        virtual datasets onto them; h5py reads them transparently)
    STORE/scenes/<scene>                relative link -> .versions/<scene>@<stamp>/, swapped atomically
                                        at the end of each successful `crom run <scene>`
    STORE/scenes/.versions/<scene>@<stamp>/
        study.json                      layout_version, scene, crom_version, created_unix, online,
                                        parameter_names, entries {name: {stage, key, target,
                                        schema_version}}, withdrawn {name: reason}
        mesh.h5, mesh.xdmf, train.h5, test.h5, {train,test}_solver_stats.parquet,
        nested/level-<k>.h5, nested/level-<k>_solver_stats.parquet, basis.h5, compactness.parquet,
        generalization.parquet, specificity.parquet, nested.parquet, rom_errors.parquet,
        tradeoff.parquet, report/       (links to the artifacts' files; rom and report only when
                                        the run was online, nested only for scenes with nested levels)
        comparison/comparison.parquet, comparison/comparison_{nested,cells,reached,facts,timings}.parquet,
        comparison/online_comparison{,_timings}.parquet
                                        (scenes with [comparison]; the online tables after online runs)

The reader follows `study.json`'s `target`s (relative to the store root), so a copy of the store
without symbolic links still reads, and verifies every artifact it opens against its manifest
(see `crom_data.scene`). Every error is a `CromDataError` naming the scene, the entry and the fix.
"""
from .errors import (ArtifactMissing, CorruptArtifact, CromDataError, InvalidPoint, NativeMissing, OutsideDomain,
                     SceneNotFound, SchemaTooNew, StaleArtifact, StoreNotFound)
from .scene import LAYOUT_VERSION, Basis, Mesh, Scene, SnapshotSet
from .store import Store, open_store

__version__ = "0.1.0"
__all__ = ["open_store", "Store", "Scene", "SnapshotSet", "Basis", "Mesh", "LAYOUT_VERSION",
           "CromDataError", "StoreNotFound", "SceneNotFound", "ArtifactMissing", "SchemaTooNew", "StaleArtifact",
           "CorruptArtifact", "InvalidPoint", "OutsideDomain", "NativeMissing"]
