#!/usr/bin/env python3
"""The 3-D contact issue's two level-10 rows, release build, printed as a Markdown table. Part of
`just bench-3d-level10` (not of `just bench`: about 25 minutes on 2 cores); not a test.

  1  ironing-3d at train_level = 10 (1 025 + 1 024 snapshots), `crom run --offline` on the
     single-node Slurm (`--executor slurm`; `scripts/slurm-up.sh start` brings it up): wall
     time and peak memory (`/usr/bin/time -v`)
  2  the same study run locally on a second store, and the two stores compared file by file:
     every result file and every snapshot block must be byte-identical. Set aside: manifests,
     the catalog, the published names, timing files, and the `seconds` column of the columns'
     index (each solve's wall time). Any other difference is listed and fails the row.

Usage: scripts/bench_3d_level10.py [--keep DIR]   (DIR keeps both stores for inspection)
"""
import hashlib
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

import pyarrow.parquet as pq

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from scene_variant import variant  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[1]
BIN = REPO / "target" / "release" / "crom"
SKIP_NAMES = {"manifest.json", "catalog.parquet", "study.json"}


def timed(store, *args):
    """`crom --store STORE -q ARGS` under /usr/bin/time -v: (wall seconds, peak RSS in GB)."""
    p = subprocess.run(["/usr/bin/time", "-v", str(BIN), "--store", str(store), "-q", *map(str, args)], cwd=REPO,
                       capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"crom {' '.join(map(str, args))} failed:\n{p.stdout}\n{p.stderr}")
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", p.stderr).group(1)
    secs = sum(float(x) * 60 ** i for i, x in enumerate(reversed(wall.split(":"))))
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr).group(1))
    return secs, rss * 1024 / 1e9


def digests(root):
    """sha256 of every file that must match, by path relative to the store."""
    out = {}
    for dp, _, files in os.walk(root):
        rel = os.path.relpath(dp, root)
        top = rel.split(os.sep)[0]
        if top in ("scenes", "runs") or top.startswith("."):
            continue
        for f in files:
            if f in SKIP_NAMES or "timing" in f or (top == "columns" and f == "index.parquet"):
                continue
            out[os.path.join(rel, f)] = hashlib.sha256((pathlib.Path(dp) / f).read_bytes()).hexdigest()
    return out


def index_without_seconds(root):
    """Each column family's compacted index without its `seconds` column."""
    out = {}
    for p in sorted(pathlib.Path(root, "columns").glob("*/index.parquet")):
        t = pq.read_table(p)
        out[p.parent.name] = t.drop(["seconds"]) if "seconds" in t.column_names else t
    return out


def main():
    keep = sys.argv[sys.argv.index("--keep") + 1] if "--keep" in sys.argv else None
    subprocess.run(["just", "build"], cwd=REPO, check=True)
    up = subprocess.run(["bash", "scripts/slurm-up.sh", "start"], cwd=REPO, capture_output=True, text=True)
    if up.returncode != 0:
        sys.exit(f"slurm-up.sh start failed:\n{up.stdout}\n{up.stderr}")
    tmp = pathlib.Path(keep or tempfile.mkdtemp(prefix="crom-3d-level10-"))
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        scene = variant(tmp, "ironing-3d", "ironing-3d-level10", [("train_level = 7", "train_level = 10")])
        slurm, local = tmp / "slurm", tmp / "local"
        for s in (slurm, local):
            shutil.rmtree(s, ignore_errors=True)
        s_wall, s_rss = timed(slurm, "run", scene, "--offline", "--executor", "slurm", "--shard-size", 256,
                              "--max-parallel", 2, "--cpus-per-task", 1)
        l_wall, l_rss = timed(local, "run", scene, "--offline")
        a, b = digests(slurm), digests(local)
        differ = sorted(set(a) ^ set(b)) + sorted(k for k in set(a) & set(b) if a[k] != b[k])
        ia, ib = index_without_seconds(slurm), index_without_seconds(local)
        if ia.keys() != ib.keys() or any(not ia[k].equals(ib[k]) for k in ia):
            differ.append("columns/*/index.parquet (beyond its seconds column)")
        print("| what | target | measured | met |\n|---|---|---|---|")
        print(f"| level 10 offline on the single-node Slurm (8 array tasks of 256 points) | - | "
              f"{s_wall / 60:.1f} min, {s_rss:.2f} GB peak | - |")
        print(f"| level 10 offline, local | <= 15 min, <= 4 GiB | {l_wall / 60:.1f} min, {l_rss:.2f} GB peak | "
              f"{'yes' if l_wall <= 900 and l_rss <= 4 * 2 ** 30 / 1e9 else '**no**'} |")
        print(f"| Slurm and local stores, {len(a)} files compared | same bytes | "
              f"{'identical' if not differ else 'differ: ' + ', '.join(differ[:5])} | "
              f"{'yes' if not differ else '**no**'} |")
    finally:
        if not keep:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
