#!/usr/bin/env python3
"""Time `crom run SCENE` cold (empty store) and warm (everything cached), release build, and
print a Markdown table with the wall time of every stage read from the artifact manifests.

Usage: scripts/bench_pipeline.py [SCENE ...]   (default: ironing-fine)
"""
import json
import pathlib
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[1]
BIN = REPO / "target" / "release" / "crom"


def run(store, scene):
    t = time.perf_counter()
    subprocess.run([str(BIN), "--store", str(store), "--quiet", "run", scene], cwd=REPO, check=True,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def main():
    scenes = sys.argv[1:] or ["ironing-fine"]
    subprocess.run(["just", "build"], cwd=REPO,
                   check=True)
    for scene in scenes:
        with tempfile.TemporaryDirectory() as tmp:
            store = pathlib.Path(tmp)
            cold = run(store, scene)
            warm = run(store, scene)
            stages = {}
            for m in store.glob("*/*/manifest.json"):
                man = json.loads(m.read_text())
                s = stages.setdefault(man["stage"], [0, 0.0])
                s[0] += 1
                s[1] += man["wall_seconds"]
        print(f"\n### crom run {scene}\n")
        print("| what | artifacts | seconds |\n|---|---:|---:|")
        for name, (n, secs) in stages.items():
            note = " (sum of per-snapshot solve times, solved 2 at a time)" if name == "snapshot" else ""
            print(f"| stage `{name}`{note} | {n} | {secs:.2f} |")
        print(f"| **cold run, wall** | | **{cold:.2f}** |")
        print(f"| **warm run (all cached), wall** | | **{warm:.2f}** |")


if __name__ == "__main__":
    main()
