#!/usr/bin/env python3
"""The targets for the dual approximations, measured, with the target beside each value.

Runs `crom run` for ironing-fine and hertz (release build) into a fresh temporary store and
reads the comparison artifacts (`comparison.parquet`, `comparison_timings.parquet`) and the
online comparison (`online_comparison.parquet` and its timings). The error of the targets is the
mean relative dual error over the scene's test set, each snapshot at its own parameter, in the
physical frame (the `test` metric); G(m) (leave-one-out) is printed beside it. Times are this
2-core VM's; they vary by up to ~30 % between runs, so ironing-fine's study is run
`BENCH_REPEATS` times (default 3, each into a fresh store) and the speed-up target is judged on
the median of the runs, every run's value printed beside it; the other rows are the first run's
(their numbers are byte-identical from run to run).

The dictionary row runs `stages/examples/bench_dictionary.rs` (its own table is printed after).

Usage: scripts/bench_comparison.py
"""

import os
import pathlib
import statistics
import subprocess
import tempfile

import pandas as pd

REPO = pathlib.Path(__file__).resolve().parent.parent
# The release binary `cargo build --release` writes (under CARGO_TARGET_DIR when that is set).
CROM = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target")) / "release" / "crom"
# Cold runs of ironing-fine's study whose speed-ups the speed-up target is judged on (median).
REPEATS = int(os.environ.get("BENCH_REPEATS", "3"))


def row(what, target, measured, met):
    print(f"| {what} | {target} | {measured} | {'yes' if met else '**no**'} |")


def only(store, kind):
    dirs = [d for d in (store / kind).iterdir() if d.is_dir()]
    assert len(dirs) == 1, f"{kind}: {len(dirs)} artifacts"
    return dirs[0]


def best_within(curves, metric, max_m, level):
    """The approximation reaching `level` with the fewest modes (at most max_m), or None."""
    t = curves[(curves.metric == metric) & (curves.m <= max_m) & (curves["mean"] <= level)]
    if t.empty:
        return None
    r = t.sort_values(["m", "mean"]).iloc[0]
    return r.approximation, int(r.m), float(r["mean"])


def registered_online(curves, online, timings, max_m=10, goal=0.001, speedup=100.0):
    """The targets for the registered approximation online (ironing-fine): median dual
    error <= 0.1 % with <= 10 modes, >= 100x the full-order solve timed in the same process,
    every test point converged; and the offline curve: the projection error of the registered
    bases at those sizes, which the online solve's pressure (a member of the same span or cone)
    cannot beat in the unweighted norm."""
    reg = online[online.approximation.str.startswith("registered") & (online.m <= max_m)
                 & (online.converged == online.points)]
    if reg.empty:
        row(f"ironing-fine online, registered, <= {max_m} modes: median dual error", "<= 0.1 %",
            "no registered approximation converged everywhere", False)
        return
    # The setting: the fewest modes that meet the error target (then the least error), or the
    # most accurate where none does. Chosen by errors, which are the same bytes in every run.
    meeting = reg[reg.median_dual_error <= goal]
    b = (meeting.sort_values(["m", "median_dual_error"]) if not meeting.empty
         else reg.sort_values(["median_dual_error", "m"])).iloc[0]
    row(f"ironing-fine online, registered, <= {max_m} modes: median dual error", "<= 0.1 %",
        f"{100 * b.median_dual_error:.3f} % ({b.approximation}, m = {int(b.m)}; at m = 32: "
        + ", ".join(f"{r.approximation} {100 * r.median_dual_error:.2f} %" for _, r in
                    online[online.approximation.str.startswith("registered") & (online.m == 32)].iterrows())
        + ")", b.median_dual_error <= goal)
    # The same row in every run (the errors are byte-identical across runs, the times are not).
    same = [t[(t.approximation == b.approximation) & (t.m == b.m)].iloc[0] for t in timings]
    median = statistics.median(float(t.speedup) for t in same)
    runs = "; ".join(f"{t.speedup:.1f}x ({t.median_online_ms:.3f} ms against {t.median_full_order_ms:.2f} ms)"
                     for t in same)
    # "That setting" is one that meets the error target: a speed-up measured where the error
    # misses it is shown, and not counted as met.
    accurate = b.median_dual_error <= goal
    caveat = "" if accurate else (f"; measured at the most accurate registered setting, whose "
                                  f"{100 * b.median_dual_error:.2f} % misses {100 * goal:g} %")
    row(f"... at that setting: speed-up over the full-order solve (same process), median of {len(same)} cold runs",
        f">= {speedup:.0f}x", f"{median:.1f}x (runs: {runs}){caveat}", accurate and median >= speedup)
    row("... at that setting: test points converged", "all", f"{int(b.converged)}/{int(b.points)}",
        int(b.converged) == int(b.points))
    off = curves[(curves.metric == "test") & curves.approximation.str.startswith("registered") & (curves.m <= max_m)]
    best = off.sort_values(["mean", "m"]).iloc[0]
    first = off[off["mean"] <= goal].sort_values(["m", "mean"])
    reach = (f"; reaches 0.1 % first at m = {int(first.iloc[0].m)} ({first.iloc[0].approximation})"
             if len(first) else "; no registered basis reaches 0.1 %")
    row(f"ironing-fine offline, registered, <= {max_m} modes: mean test error (the projection, before the online solve)", "<= 0.1 %",
        f"{100 * best['mean']:.3f} % ({best.approximation}, m = {int(best.m)}){reach}", best["mean"] <= goal)


def main():
    subprocess.run(["just", "build"], cwd=REPO,
                   check=True)
    print("| target | goal | measured | met |")
    print("|---|---|---|---|")
    for scene, max_m in [("ironing-fine", 5), ("hertz", 3)]:
        timings = []
        for run in range(max(1, REPEATS) if scene == "ironing-fine" else 1):
            with tempfile.TemporaryDirectory() as tmp:
                store = pathlib.Path(tmp) / "store"
                subprocess.run([str(CROM), "--store", str(store), "--quiet", "run", scene], cwd=REPO, check=True,
                               stdout=subprocess.DEVNULL)
                online_dir = only(store, "online-comparison")
                timings.append(pd.read_parquet(online_dir / "online_comparison_timings.parquet"))
                if run == 0:
                    cmp_dir = only(store, "comparison")
                    curves = pd.read_parquet(cmp_dir / "comparison.parquet")
                    builds = pd.read_parquet(cmp_dir / "comparison_timings.parquet")
                    online = pd.read_parquet(online_dir / "online_comparison.parquet").merge(
                        timings[0], on=["scene", "approximation", "m"], validate="one_to_one")
        best = best_within(curves, "test", max_m, 0.01)
        if best:
            name, m, err = best
            g = curves[(curves.approximation == name) & (curves.metric == "generalization") & (curves.m == m)]
            measured = f"{name}: {100 * err:.2f} % at m = {m} (G({m}) = {100 * float(g['mean'].iloc[0]):.2f} %)"
        else:
            measured = "none"
        row(f"{scene}: mean test error <= 1 % with <= {max_m} modes", f"<= {max_m} modes", measured, best is not None)
        # An approximation the online solve can use (a non-negative basis) that reaches 1 % with
        # at most max_m modes and whose online solve converges at every test point at that m.
        cone = curves[(curves.metric == "test") & curves.approximation.isin(set(online.approximation))
                      & (curves.m <= max_m) & (curves["mean"] <= 0.01)].sort_values(["m", "mean"])
        found = None
        for _, c in cone.iterrows():
            o = online[(online.approximation == c.approximation) & (online.m == c.m)]
            if len(o) and int(o.converged.iloc[0]) == int(o.points.iloc[0]):
                found = (c, o.iloc[0])
                break
        if found:
            c, o = found
            measured = (f"{c.approximation}, test error {100 * c['mean']:.2f} % at m = {int(c.m)}; online: "
                        f"{int(o.converged)}/{int(o.points)} converged, median dual error "
                        f"{100 * o.median_dual_error:.2f} %, {o.median_online_ms:.3f} ms ({o.speedup:.0f}x)")
        else:
            measured = "no non-negative approximation reaches 1 % and converges everywhere"
        goal = "all points" if scene == "ironing-fine" else "all points (not an issue target)"
        row(f"{scene}: ... with a non-negative basis whose online solve converges everywhere", goal, measured,
            found is not None)
        if scene == "ironing-fine":
            registered_online(curves, online, timings)
            worst = builds.sort_values("build_seconds").iloc[-1]
            row("ironing-fine: every approach's offline build at N = 128", "<= 2 s",
                f"{worst.build_seconds:.2f} s ({worst.approximation}, the slowest)", worst.build_seconds <= 2.0)
    # The dictionary online at 4 097 atoms (stages/examples/bench_dictionary.rs: solves the nested
    # level 12 of ironing-fine, ~20 s, and times the online solve with both dictionaries).
    out = subprocess.run(["just", "example", "bench_dictionary"], cwd=REPO, check=True, capture_output=True, text=True).stdout
    # Columns: method, dictionary, atoms, median ms, ratio, target, active, converged, error, rounds.
    lines = [l.split("|")[1:-1] for l in out.splitlines() if l.startswith("| working set |")]
    big = [c.strip() for c in lines[-1]]
    ratio = float(big[4])
    row("dictionary online (working set), 4 097 atoms vs 128 (median time)", "<= 2x",
        f"{ratio:.2f}x ({big[3]} ms; {big[7]} converged, median dual error {big[8]}, rounds / atoms {big[9]})",
        ratio <= 2.0)
    print()
    print(out)


if __name__ == "__main__":
    main()
