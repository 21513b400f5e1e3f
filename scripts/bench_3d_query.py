#!/usr/bin/env python3
"""The stored 3-D models online, printed as a Markdown table with each target beside the
measured value (release build, a cold store). Part of `just bench-3d`; not a test.

Each shipped 3-D scene is run cold (`crom run SCENE`), then its stored model is queried at random
points off the training grid with the full-order check (`crom query SCENE --points P.csv
--check`): ironing-3d at 64 travels uniform in [0, 3] (`random.Random(5)`), hertz-3d at 40
approaches uniform in [0.001, 0.01] (`random.Random(3)`); once with the model's own re-pairing
tolerance (the scene's `study.online_u_tol`: 1e-4 for both) and once with `--u-tol 1e-10`, the
default of a scene that sets none (docs/user-guide.md#querying-the-reduced-model; printed for
information, without a target). The targets of the 3-D contact issue, at the model's own
tolerance: median pressure error <= 0.1 %, every point converged, and >= 1000x over the
full-order solve (the ratio of the median times).

Usage: scripts/bench_3d_query.py [ironing-3d hertz-3d]   (default: both)
CROM_BIN=path/to/crom uses that binary and builds nothing.
"""
import os
import pathlib
import random
import subprocess
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_scale import REPO, crom, header, row  # noqa: E402

# scene: (parameter, lo, hi, points, seed)
SCENES = {"ironing-3d": ("d_x", 0.0, 3.0, 64, 5), "hertz-3d": ("d", 0.001, 0.01, 40, 3)}


def bench(tmp, scene):
    import pandas as pd
    name, lo, hi, n, seed = SCENES[scene]
    store = pathlib.Path(tmp) / "store"
    header(f"{scene}: the stored model at {n} random points (cold store)")
    wall, rss, _ = crom(store, "run", scene)
    row("whole cold study", "-", f"{wall:.0f} s, {rss / (1 << 30):.2f} GiB", True)
    rng = random.Random(seed)
    points = pathlib.Path(tmp) / "points.csv"
    points.write_text(f"{name}\n" + "".join(f"{rng.uniform(lo, hi)!r}\n" for _ in range(n)))
    for extra in ([], ["--u-tol", "1e-10"]):
        out = pathlib.Path(tmp) / "q.parquet"
        crom(store, "query", scene, "--points", points, "--check", "--out", out, *extra)
        q = pd.read_parquet(out)
        converged = int((q.outcome == "converged").sum())
        med = q.dual_error.median()
        speed = q.fom_seconds.median() / q.online_seconds.median()
        how = " ".join(extra) or "the model's u_tol"
        error = f"{100 * med:.4f} % (p95 {100 * q.dual_error.quantile(0.95):.2f} %), {converged}/{n}"
        speed_up = (f"{speed:.0f}x ({1e3 * q.online_seconds.median():.3f} ms against "
                    f"{1e3 * q.fom_seconds.median():.0f} ms; {q.linearizations.mean():.2f} linearisations)")
        if extra:
            # for information: the targets hold at the model's own re-pairing tolerance
            print(f"| {how}: median pressure error, converged | - | {error} | - |")
            print(f"| {how}: speed-up over the full-order solve | - | {speed_up} | - |")
        else:
            row(f"{how}: median pressure error, converged", f"<= 0.1 %, {n}/{n}", error,
                med <= 1e-3 and converged == n)
            row(f"{how}: speed-up over the full-order solve", ">= 1000x", speed_up, speed >= 1000)


def main():
    which = sys.argv[1:] or list(SCENES)
    if not os.environ.get("CROM_BIN"):
        subprocess.run(["just", "build"], cwd=REPO, check=True)
    for scene in which:
        if scene not in SCENES:
            sys.exit(f"unknown scene {scene!r}: give {' or '.join(SCENES)}")
        with tempfile.TemporaryDirectory() as tmp:
            bench(tmp, scene)


if __name__ == "__main__":
    main()
