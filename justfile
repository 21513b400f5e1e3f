# crom task runner. `just --list` shows the recipes.
set shell := ["bash", "-euo", "pipefail", "-c"]

# Python used for the validation tests.
python := env_var_or_default("PYTHON", "python3")

default:
    @just --list

# Install system libraries, just and the Python validation environment.
setup:
    bash scripts/setup.sh

# The one compilation (release profile): the `crom` binary, every crate the tests use and the
# Python extension (python/native's cdylib), in one cargo invocation so that every crate is built
# once with one feature resolution; then the extension is put beside the reader crom_data (as
# python/crom_data/crom_native.abi3.so, replaced only when it changed). A no-op when nothing
# changed.
build:
    cargo build --release --workspace
    src="${CARGO_TARGET_DIR:-target}/release/libcrom_native.so"; dst=python/crom_data/crom_native.abi3.so; cmp -s "$src" "$dst" || { cp "$src" "$dst.tmp" && mv "$dst.tmp" "$dst"; }

# Run (or resume) the whole study of SCENE with the release build.
run SCENE *ARGS: build
    "${CARGO_TARGET_DIR:-target}/release/crom" run {{SCENE}} {{ARGS}}

# Run every scene that exists.
run-all: build
    for s in $("${CARGO_TARGET_DIR:-target}/release/crom" scenes); do "${CARGO_TARGET_DIR:-target}/release/crom" run "$s"; done

# Rust tests (unit, reference, end-to-end) and the Python artifact validation, on the release
# build that `just run` uses (one compilation per machine; only the test harnesses are added).
test: build
    if command -v cargo-nextest >/dev/null; then cargo nextest run --release --workspace --no-fail-fast; else cargo test --release --workspace --no-fail-fast; fi
    CROM_BIN="${CARGO_TARGET_DIR:-target}/release/crom" {{python}} -m pytest -q tests/python

# Formatting check.
fmt:
    cargo fmt --all -- --check

# Lints, warnings are errors.
clippy:
    # --release: the proc macros and build scripts are the build's own, not compiled again.
    cargo clippy --release --workspace --all-targets -- -D warnings

# What CI runs: fmt check, clippy, tests.
ci: fmt clippy test

# Benchmarks (release build), printed as tables: contact solver, metrics/NNLS, whole pipeline,
# the scale targets (large and growing snapshot sets, 2-D parameter, store size and reads) and
# the online reduced model (speed-ups, convergence, online time against the mesh).
bench:
    just example bench_contact
    just example bench_metrics
    {{python}} scripts/bench_pipeline.py ironing-fine ironing-coarse hertz rope
    {{python}} scripts/bench_scale.py
    {{python}} scripts/bench_rom.py
    {{python}} scripts/bench_cluster.py
    {{python}} scripts/bench_comparison.py
    just bench-3d

# Render one step of a scene's XDMF view with ParaView under Xvfb (installs Debian's paraview,
# ~440 MB, on first use; not part of CI), e.g. `just paraview ironing-fine test 1`.
paraview SCENE SET="train" WARP="1" OUT="paraview.png":
    command -v pvbatch >/dev/null || (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends paraview python3-paraview xvfb xauth)
    xvfb-run -a pvbatch scripts/render_paraview.py "${CROM_STORE:-data/store}/scenes/{{SCENE}}/{{SET}}.xdmf" {{OUT}} {{WARP}}

# The 3-D targets: hertz-3d against Hertz theory, the 10^5-dof ironing-3d model (factorisation,
# contact operators, a sweep's snapshots; peak memory), the whole cold ironing-3d study, and the
# stored 3-D models at random points (accuracy, convergence, speed-up; at the scene's online_u_tol and at --u-tol 1e-10).
bench-3d: build
    just example hertz3d_theory
    /usr/bin/time -f "bench_contact3d: peak memory %M KB" just example bench_contact3d
    tmp=$(mktemp -d) && /usr/bin/time -f "whole cold crom run ironing-3d: %e s, peak %M KB" "${CARGO_TARGET_DIR:-target}/release/crom" -q --store "$tmp/store" run ironing-3d > /dev/null && rm -rf "$tmp"
    CROM_BIN="${CARGO_TARGET_DIR:-target}/release/crom" {{python}} scripts/bench_3d_query.py

# The 3-D level-10 rows: ironing-3d at train_level = 10 offline on the single-node Slurm and
# locally, and the two stores compared byte for byte (about 25 minutes; not part of `just bench`).
bench-3d-level10:
    {{python}} scripts/bench_3d_level10.py

# Only the online reduced-model targets: speed-ups, convergence, mesh independence.
bench-rom:
    {{python}} scripts/bench_rom.py

# Only the scale benchmarks (A-G, see scripts/bench_scale.py), e.g. `just bench-scale G`.
bench-scale *WHICH:
    {{python}} scripts/bench_scale.py {{WHICH}}

# Only the sharded-sweep overheads: sbatch, worker start, block commit, index.
bench-cluster:
    {{python}} scripts/bench_cluster.py

# The dual approximations' targets, side by side.
bench-comparison:
    {{python}} scripts/bench_comparison.py

# A single-node Slurm on this machine from Debian's packages (root; see scripts/slurm-up.sh),
# for `crom run SCENE --executor slurm`; `just slurm-down` stops what it started.
slurm-up:
    bash scripts/slurm-up.sh start

slurm-down:
    bash scripts/slurm-up.sh stop

# The stress matrix: scenes pushed to the extremes, each answer verified or refused
# with a reason; one row per case. `just stress --fast` is the subset CI runs.
stress *ARGS:
    {{python}} scripts/stress.py {{ARGS}}

# Run one of stages/examples (the benchmarks' kernels) from the release build, e.g.
# `just example bench_contact`: built with the workspace's feature resolution, like everything
# else, so nothing is compiled twice.
example NAME *ARGS:
    cargo build --release --quiet --workspace --example {{NAME}}
    "${CARGO_TARGET_DIR:-target}/release/examples/{{NAME}}" {{ARGS}}
