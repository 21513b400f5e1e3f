#!/usr/bin/env python3
"""Per-task overheads of sharded sweeps, release build, printed as a Markdown table. Part of
`just bench`; not a test. The numbers feed
docs/design-notes.md#what-limits-a-sweep-at-a-million-snapshots (what 10^5-10^6 snapshots on
100 nodes would cost).

  1  sbatch: one job array of 100 tasks submitted (needs Slurm: `scripts/slurm-up.sh start`)
  2  worker start with nothing to do: process start, scene, plan (every key), index read
     -- on ironing-coarse (381 points) and on 8 193 points (train_level = 12, level-13 tests)
  3  worker start with one point to solve: the above plus meshing and factorising
  4  block commit: a sweep with one snapshot per block against one with 128 per block
  5  index: reading F uncompacted fragments, and compacting them (`crom solve`, exclusive)

Usage: scripts/bench_cluster.py
"""
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from scene_variant import variant  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[1]
BIN = REPO / "target" / "release" / "crom"


def crom(store, *args, env=None, check=True):
    e = dict(os.environ)
    e.pop("CROM_BLOCK_COLUMNS", None)
    e.update(env or {})
    t = time.perf_counter()
    p = subprocess.run([str(BIN), "--store", str(store), "--quiet", *map(str, args)], cwd=REPO, capture_output=True,
                       text=True, env=e)
    wall = time.perf_counter() - t
    if check and p.returncode != 0:
        sys.exit(f"crom {' '.join(map(str, args))} failed:\n{p.stdout}\n{p.stderr}")
    return wall, p.stdout + p.stderr


def best(n, f):
    return min(f() for _ in range(n))


def main():
    subprocess.run(["just", "build"], cwd=REPO,
                   check=True)
    rows = []
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="crom-bench-cluster-"))
    try:
        # 1. sbatch of a 100-task array.
        if shutil.which("sbatch"):
            def submit():
                t = time.perf_counter()
                p = subprocess.run(["sbatch", "--parsable", "--array=0-99", "-o", "/dev/null", "--hold",
                                    "--wrap=true"], capture_output=True, text=True)
                wall = time.perf_counter() - t
                if p.returncode != 0:
                    sys.exit(f"sbatch failed: {p.stderr}")
                subprocess.run(["scancel", p.stdout.strip().split(";")[0]], check=False)
                return wall
            s = best(5, submit)
            rows.append(("sbatch, one array of 100 tasks (held, then cancelled)", f"{s * 1e3:.0f} ms",
                         f"{s / 100 * 1e3:.2f} ms per task"))
        else:
            rows.append(("sbatch, one array of 100 tasks", "n/a (no Slurm here: scripts/slurm-up.sh start)", ""))

        # 2./3. worker start on ironing-coarse.
        scene = "ironing-coarse"
        store = tmp / "coarse"
        crom(store, "solve", scene)
        w = best(5, lambda: crom(store, "work", scene, "--shard", "0/1")[0])
        rows.append(("worker start, nothing to do, 381 points stored", f"{w * 1e3:.0f} ms", "process + plan + index"))
        big = variant(tmp, "ironing-coarse", "coarse-8k", [("n_train = 128", "train_level = 12"),
                                                           ("nested_levels = 7", "nested_levels = 0")])
        store_big = tmp / "big"
        t_solve, _ = crom(store_big, "solve", big)
        wb = best(3, lambda: crom(store_big, "work", big, "--shard", "0/1")[0])
        rows.append(("worker start, nothing to do, 8 193 points stored", f"{wb * 1e3:.0f} ms",
                     f"sweep itself: {t_solve:.1f} s on 2 cores"))
        # one missing point: remove the newest block's fragment and file after a 1-column sweep
        one = tmp / "one"
        crom(one, "solve", scene, env={"CROM_BLOCK_COLUMNS": "1"})
        fam = next((one / "columns").iterdir())
        blk = sorted((fam / "blocks").iterdir())[0]
        # the compacted index still names the block; deleting the file drops its row on read
        blk.unlink()
        w1 = best(1, lambda: crom(one, "work", scene, "--shard", "0/1", env={"CROM_BLOCK_COLUMNS": "1"})[0])
        rows.append(("worker start with one point to solve (mesh, factor, solve, commit)", f"{w1 * 1e3:.0f} ms",
                     f"{(w1 - w) * 1e3:.0f} ms over nothing to do"))

        # 4. block commit overhead: 381 one-column blocks vs 3 blocks, workers only (no compaction).
        def sweep(cols):
            s = tmp / f"blocks-{cols}"
            shutil.rmtree(s, ignore_errors=True)
            crom(s, "solve", scene)  # mesh + a compacted store, then drop the columns
            shutil.rmtree(s / "columns")
            return crom(s, "work", scene, "--shard", "0/1", env={"CROM_BLOCK_COLUMNS": str(cols)})[0], s
        t128, _ = sweep(128)
        t1, s1 = sweep(1)
        per_block = (t1 - t128) / (381 - 3)
        rows.append(("block commit (write HDF5 + fsync + rename, fragment likewise)", f"{per_block * 1e3:.2f} ms",
                     f"381 blocks {t1:.2f} s vs 3 blocks {t128:.2f} s"))

        # 5. index: 381 fragments read by a worker, then compacted by `crom solve`.
        wf = best(3, lambda: crom(s1, "work", scene, "--shard", "0/1", env={"CROM_BLOCK_COLUMNS": "1"})[0])
        rows.append(("worker start, nothing to do, 381 uncompacted fragments", f"{wf * 1e3:.0f} ms",
                     f"{(wf - w) / 381 * 1e3:.2f} ms per fragment over a compacted index"))
        tc, _ = crom(s1, "solve", scene, env={"CROM_BLOCK_COLUMNS": "1"})
        rows.append(("compaction of 381 fragments (`crom solve`, mesh cached)", f"{tc * 1e3:.0f} ms",
                     "read fragments + write index.parquet + remove fragments"))
        frag = list((next((s1 / "columns").iterdir()) / "index").glob("*.parquet"))
        assert not frag, f"{len(frag)} fragments left after compaction"
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print("\n### Sharded sweeps: per-task overheads (`scripts/bench_cluster.py`, release, 2 cores)\n")
    print("| what | measured | note |")
    print("|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} |")


if __name__ == "__main__":
    main()
