//! The memory a scene needs, estimated from its file before anything is allocated or written
//! (a scene with `nx = 1000000000` must be refused with a message, not abort).
//!
//! The estimate is the sum of what one run holds at its peak, each term from the scene's sizes
//! (`n` displacement dofs, `c` contact dofs, `s` slaves, `N` training and `T` test points, `L`
//! the largest nested level, `8` bytes per value):
//!
//! - stiffness matrix and its sparse Cholesky factor: `12 * 18 n + 16 f n` (value and index
//!   per entry; 18 entries per row of a 2-D Q1 stiffness; a factor entry is an 8-byte value
//!   and an 8-byte row index), with the factor's fill `f = 10 log2 n` entries per row — a
//!   fill-reducing factor of a 2-D mesh grows as `n log n`, and the constant is measured: the
//!   ironing-fine mesh refined 2, 4 and 8 times per direction (95 000, 380 000 and 1.5 million
//!   dofs, `crom solve`, two threads) peaked at 0.33, 1.27 and 5.13 GiB, about 163 bytes per
//!   `n log2 n` beyond the process's own 0.15 GiB. The first version took `f = 4 log2 n` and
//!   12 bytes per entry, 2.5 times too little at 1.5 million dofs: a mesh that could not fit
//!   would have been let through (found by the stress matrix's finest-mesh row,
//!   docs/design-notes.md#resource-limits-are-checked-from-the-scene-file);
//!   A 3-D (hexahedral) stiffness has 81 entries per row and a fill-reducing factor of a 3-D
//!   mesh grows as `n^(4/3)`: `f = 15 n^(1/3)`, measured on ironing3d at 109 431 dofs (a peak of
//!   1.53 GB with the Delassus operator, `stages/examples/bench_contact3d.rs`);
//! - the Delassus operator on the contact dofs, `8 c^2`, and one solver's condensed work
//!   `8 (c s + s^2)` per thread (two threads);
//! - the largest stage's snapshot matrices: the online stage's training and test sets plus
//!   three `n x N` bases (`8 n (N + T + 3 N)`), or the nested-error stage's two levels
//!   (`8 n (2^L + 2^(L-1) + 2)`), or the offline metrics, whichever is largest. The metrics form
//!   `N x N` Gram matrices (`32 N^2`) up to 1 025 training snapshots. Above, no `N x N` matrix
//!   is formed and the primal snapshots are streamed from the store (`pipeline::dag::inputs::streamed`):
//!   the offline stages hold the dual set and its POD's working copy, `16 c N`, and of the
//!   primal either
//!   - the blockwise frame and what is built on it, `8 n (q + B) + 24 q N`: the frame `Q`
//!     (`n x q`), one block of `B = 512` columns (the modal pass's; the frame's are 256), and
//!     three `q x N` matrices (the frame's coordinates `R`, the leave-one-out's right singular
//!     vectors, the modal pass's coordinates on the POD modes), where `q = min(n, N)` is at most
//!     `frame_pays_up_to(N)`: the primal's rank cannot exceed `q`, so the frame always pays; or
//!   - the whole primal and the POD's working copy of it, `16 n N`, where it is not: a frame
//!     that grows past `frame_pays_up_to(N)` is abandoned and the POD reads the whole matrix
//!     (`pod_blocks` falls back to `ColumnBlocks::whole`). The rank is known only once the
//!     snapshots are, so the estimate takes the case the scene cannot rule out (the ironing
//!     scenes: their displacements' rank is about 200, but `n` is above the frame's limit).
//!
//!   The first version counted `16 (n + c) N` in both cases, the in-memory path's training set
//!   and working copy; the streamed path holds less where `q` is small against `n` and more,
//!   three `q x N` matrices, where `q` is near `N`.
//!
//! It is an estimate, not a bound: it is meant to catch a scene that cannot fit, by orders of
//! magnitude, before it starts. A scene is refused when the estimate exceeds the limit: the
//! `--max-memory` setting, else the machine's `MemAvailable` (`/proc/meminfo`); where neither is
//! known nothing is refused.

use crom_schemas::scene::{Model, SceneConfig};

/// Training snapshots up to which the metrics form N x N Gram matrices (above, the CPG
/// selection works without its Gram matrix and the metrics in column blocks).
const GRAM_LIMIT: f64 = crom_stages::basis::DENSE_CURVE_MAX as f64;

/// One term of an estimate: the scene field that drives it, what it is, and its bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    /// Dotted path of the scene field that sets its size.
    pub field: &'static str,
    /// What is allocated.
    pub what: &'static str,
    /// Estimated bytes.
    pub bytes: f64,
}

/// The estimated peak memory of a run of `scene`, term by term (floats: sizes of absurd scenes
/// overflow integers).
pub fn estimate(scene: &SceneConfig) -> Vec<Term> {
    if let Model::External(_) = &scene.model {
        return external_estimate(scene);
    }
    let (n, c, s, mesh_field, contact_field) = sizes(scene);
    let p = &scene.parameter;
    let n_train: f64 = p.train_points().len() as f64;
    let n_test: f64 = p.test_points().len() as f64;
    let level = p.nested_levels as f64;
    // a 3-D hexahedral stiffness: 81 entries per row, and a factor that grows as n^(4/3)
    let (row, fill) =
        if scene.model.is_3d() { (81.0, 15.0 * n.max(2.0).cbrt()) } else { (18.0, 10.0 * n.max(2.0).log2()) };
    let mut terms = vec![
        Term {
            field: mesh_field,
            what: "stiffness matrix and its sparse factor",
            bytes: (12.0 * row + 16.0 * fill) * n,
        },
        Term { field: contact_field, what: "Delassus operator on the contact dofs", bytes: 8.0 * c * c },
        Term { field: contact_field, what: "contact solver work (2 threads)", bytes: 2.0 * 8.0 * (c * s + s * s) },
    ];
    let online = 8.0 * n * (n_train + n_test + 3.0 * n_train);
    let nested = 8.0 * n * (2f64.powf(level) + 2f64.powf(level - 1.0) + 2.0);
    let (metrics_what, metrics) = metrics_term(n, c, n_train);
    let train = train_field(scene);
    let (field, what, bytes) = if online >= nested && online >= metrics {
        (train, "snapshot sets and bases of the online stage", online)
    } else if nested >= metrics {
        ("parameter.nested_levels", "two nested levels of snapshots", nested)
    } else {
        (train, metrics_what, metrics)
    };
    terms.push(Term { field, what, bytes });
    terms
}

/// What the offline metrics hold for `n_train` training snapshots of `n` dofs and `c` contact
/// dofs (module docs): up to the Gram limit the `N x N` Gram matrices; above it, with the primal
/// streamed, the dual set and its working copy plus the primal's frame and coordinates where
/// the frame surely pays, else the whole primal and its working copy.
fn metrics_term(n: f64, c: f64, n_train: f64) -> (&'static str, f64) {
    if n_train <= GRAM_LIMIT {
        return ("Gram matrices of the metrics", 8.0 * 4.0 * n_train * n_train);
    }
    let dual = 8.0 * 2.0 * c * n_train;
    let q = n.min(n_train);
    let pays = crom_stages::basis::frame_pays_up_to(n_train as usize) as f64;
    if q <= pays {
        let block = crom_stages::basis::FRAME_BLOCK.max(crom_stages::blocks::MODAL_BLOCK) as f64;
        (
            "dual training set and the primal's frame and coordinates",
            dual + 8.0 * n * (q + block) + 8.0 * 3.0 * q * n_train,
        )
    } else {
        ("training set and the POD's working copy", dual + 8.0 * 2.0 * n * n_train)
    }
}

/// The scene field that sets the training set's size: `parameter.train_level` where the scene
/// gives the training points as a nested level, else `parameter.n_train`.
fn train_field(scene: &SceneConfig) -> &'static str {
    if scene.parameter.train_level.is_some() {
        "parameter.train_level"
    } else {
        "parameter.n_train"
    }
}

/// An external scene holds no operator: the metrics' share of [`estimate`], on the sizes its
/// files' headers give. The import itself holds one block at a time.
fn external_estimate(scene: &SceneConfig) -> Vec<Term> {
    let (n, c, ..) = sizes(scene);
    external_terms(n, c, scene.parameter.train_points().len() as f64)
}

/// Up to the Gram limit the whole training set and the POD's working copy of it
/// (`16 (n + c) N`) and the metrics' Gram matrices (`32 N^2`); above it the primal is streamed
/// as for a native scene, and the term is [`metrics_term`]'s.
fn external_terms(n: f64, c: f64, n_train: f64) -> Vec<Term> {
    let field = "model.external.train";
    if n_train > GRAM_LIMIT {
        let (what, bytes) = metrics_term(n, c, n_train);
        return vec![Term { field, what, bytes }];
    }
    vec![
        Term { field, what: "training set and the POD's working copy", bytes: 8.0 * 2.0 * (n + c) * n_train },
        Term { field, what: "Gram matrices of the metrics", bytes: 32.0 * n_train * n_train },
    ]
}

/// Rows of one snapshot column from the scene alone (no meshing): displacement dofs and
/// contact dofs as [`estimate`] counts them. Used to size snapshot blocks before any solve.
pub fn snapshot_rows(scene: &SceneConfig) -> (f64, f64) {
    let (n, c, ..) = sizes(scene);
    (n, c)
}

/// Dofs, contact dofs, slaves, and the fields that set the mesh size and the contact size.
fn sizes(scene: &SceneConfig) -> (f64, f64, f64, &'static str, &'static str) {
    match &scene.model {
        Model::Rope(r) => {
            let nodes = r.n_elements as f64 + 1.0;
            (nodes, nodes, nodes, "model.rope.n_elements", "model.rope.n_elements")
        }
        Model::Hertz(h) => {
            let arc = h.n_arc as f64;
            let side = (7.0 * arc / 78.0).round().max(1.0);
            let nodes = 2.0 * (arc - 2.0 * side + 1.0).max(1.0) * (side + 1.0);
            (2.0 * nodes, 2.0 * 2.0 * (arc + 1.0), arc + 1.0, "model.hertz.n_arc", "model.hertz.n_arc")
        }
        Model::Ironing(i) => {
            let (snx, sny, inx, iny) = (i.slab.nx as f64, i.slab.ny as f64, i.iron.nx as f64, i.iron.ny as f64);
            let (slab, iron) = ((snx + 1.0) * (sny + 1.0), (inx + 1.0) * (iny + 1.0));
            let mesh_field = match (slab >= iron, snx >= sny, inx >= iny) {
                (true, true, _) => "model.ironing.slab.nx",
                (true, false, _) => "model.ironing.slab.ny",
                (false, _, true) => "model.ironing.iron.nx",
                (false, _, false) => "model.ironing.iron.ny",
            };
            let contact_field = if snx >= inx { "model.ironing.slab.nx" } else { "model.ironing.iron.nx" };
            (2.0 * (slab + iron), 2.0 * (snx + inx + 2.0), snx + 1.0, mesh_field, contact_field)
        }
        Model::Hertz3d(h) => {
            // two octant blocks of (n + 1)^3 nodes; slaves and masters at most a cap each
            let side = h.n as f64 + 1.0;
            let cap = side * side * (h.contact_radius / h.radius).min(1.0).powi(2).max(1.0 / (side * side));
            (2.0 * 3.0 * side.powi(3), 3.0 * 2.0 * cap, cap, "model.hertz3d.n", "model.hertz3d.contact_radius")
        }
        Model::Ironing3d(i) => {
            let (b, d, s) = (&i.block, &i.die, &i.slaves);
            let block = (b.nx as f64 + 1.0) * (b.ny as f64 + 1.0) * (b.nz as f64 + 1.0);
            let die = (d.nx as f64 + 1.0) * (d.ny as f64 + 1.0) * (d.nz as f64 + 1.0);
            let fx = ((s.x_max.min(b.length) - s.x_min.max(0.0)) / b.length).clamp(0.0, 1.0);
            let fy = (s.y_max / b.depth).clamp(0.0, 1.0);
            let slaves = ((b.nx as f64 + 1.0) * fx).ceil() * ((b.ny as f64 + 1.0) * fy).ceil();
            let masters = (d.nx as f64 + 1.0) * (d.ny as f64 + 1.0);
            let mesh_field = if block >= die { "model.ironing3d.block.nx" } else { "model.ironing3d.die.nx" };
            (3.0 * (block + die), 3.0 * (slaves + masters), slaves, mesh_field, "model.ironing3d.slaves")
        }
        Model::External(e) => {
            // From the files' headers (read when the scene was loaded).
            let (n, c) = e.resolved.as_ref().map_or((0.0, 0.0), |r| (r.n_dof as f64, r.n_contact as f64));
            (n, c, c, "model.external.primal", "model.external.dual")
        }
    }
}

/// Bytes available to a run: `MemAvailable` from `/proc/meminfo`, if readable.
pub fn available_bytes() -> Option<f64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// Parse a memory size: bytes, or a number with a `K`, `M`, `G` or `T` suffix (powers of 1024,
/// an optional trailing `B` or `iB`), e.g. `8G`, `512MiB`, `1.5g`.
pub fn parse_size(s: &str) -> Result<f64, String> {
    let t = s.trim();
    let lower = t.to_ascii_lowercase();
    let stripped = lower.trim_end_matches("ib").trim_end_matches('b');
    let (num, mult) = match stripped.chars().last() {
        Some('k') => (&stripped[..stripped.len() - 1], 1024f64),
        Some('m') => (&stripped[..stripped.len() - 1], 1024f64.powi(2)),
        Some('g') => (&stripped[..stripped.len() - 1], 1024f64.powi(3)),
        Some('t') => (&stripped[..stripped.len() - 1], 1024f64.powi(4)),
        _ => (stripped, 1.0),
    };
    match num.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * mult),
        _ => Err(format!("'{s}' is not a memory size; give e.g. 8G, 512M or a number of bytes")),
    }
}

/// Human-readable bytes.
pub fn human(bytes: f64) -> String {
    let gib = bytes / 1024f64.powi(3);
    if gib >= 1.0 {
        format!("{gib:.3} GiB")
    } else {
        format!("{:.1} MiB", bytes / 1024f64.powi(2))
    }
}

/// The environment variable that bounds glibc's malloc arenas.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const ARENA_VAR: &str = "MALLOC_ARENA_MAX";

/// The arenas `crom` runs with unless the user sets [`ARENA_VAR`] (one per core of the
/// development machine).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const ARENAS: &str = "2";

/// Start the process again (the same program, arguments and PID, `exec`) with glibc's malloc
/// arenas bounded to `ARENAS`, unless `MALLOC_ARENA_MAX` is already set; returns only when
/// nothing was started (already bounded, or the program cannot be found again: then the run goes
/// on with glibc's default).
///
/// glibc gives each thread that allocates while another holds the lock its own arena, up to
/// eight per core, and an arena keeps what was freed in it for its own thread. The study's
/// stages run on the main thread, a worker beside it and the parallel pool, so the memory one
/// stage frees on one thread is not reused by the next stage on another. Measured on the
/// ironing-coarse level-13 study (`crom run --offline`, 2 cores, peak RSS from
/// `/usr/bin/time -v`): 1.84 GB with glibc's default, 1.44 GB with 2 arenas, 1.33 GB with 1, and
/// the same wall time (58–63 s) for all three. The value is read by glibc at start-up, so it has
/// to be in the environment before the process starts; the results do not depend on it.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn bound_malloc_arenas() {
    if std::env::var_os(ARENA_VAR).is_some() {
        return;
    }
    let Ok(exe) = std::env::current_exe() else { return };
    let mut args = std::env::args_os();
    let mut command = std::process::Command::new(exe);
    if let Some(name) = args.next() {
        std::os::unix::process::CommandExt::arg0(&mut command, name);
    }
    // `exec` returns only when it failed.
    let _ = std::os::unix::process::CommandExt::exec(command.args(args).env(ARENA_VAR, ARENAS));
}

/// Other platforms' allocators: nothing to bound.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn bound_malloc_arenas() {}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped(name: &str) -> SceneConfig {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes");
        SceneConfig::load(&dir.join(format!("{name}.toml"))).expect("shipped scene")
    }

    fn total(scene: &SceneConfig) -> f64 {
        estimate(scene).iter().map(|t| t.bytes).sum()
    }

    /// Every shipped scene is estimated below 4 GiB (so a machine like CI's never refuses
    /// them), ironing-fine's online term is the hand count `8 n (N + T + 3 N)` with
    /// n = 23 924 dofs (docs/scenes.md), N = 128, T = 127, and refining a mesh raises the estimate.
    #[test]
    fn shipped_scenes_fit_and_refinement_needs_more() {
        for name in ["rope", "hertz", "hertz-fine", "ironing-coarse", "ironing-fine", "ironing-fine-2d"] {
            let t = total(&shipped(name));
            assert!(t > 0.0 && t < 4.0 * 1024f64.powi(3), "{name}: {}", human(t));
        }
        let fine = estimate(&shipped("ironing-fine"));
        let online = fine.iter().find(|t| t.what.contains("online")).expect("online term");
        // exact: integer-valued products far below 2^53
        assert_eq!(online.bytes.to_bits(), (8.0f64 * 23924.0 * (128.0 + 127.0 + 3.0 * 128.0)).to_bits());
        let mut coarse = shipped("ironing-coarse");
        let before = total(&coarse);
        if let Model::Ironing(i) = &mut coarse.model {
            i.slab.nx *= 4;
        }
        assert!(total(&coarse) > before);
    }

    /// Above 1 025 training snapshots no Gram term: the estimate of ironing-coarse at level 16
    /// (65 537 training points; n = 6 164 dofs and c = 264 contact dofs counted from the scene
    /// as `sizes` does) is led by the online term `8 n (N + T + 3 N)` and stays below 24 GiB
    /// (the Gram term alone was 137 GB and refused the study on any machine).
    #[test]
    fn large_training_sets_are_estimated_without_gram_matrices() {
        let mut scene = shipped("ironing-coarse");
        scene.parameter.n_train = None;
        scene.parameter.train_level = Some(16);
        scene.parameter.nested_levels = 0;
        let (n, c) = snapshot_rows(&scene);
        assert_eq!((n, c), (2.0 * (101.0 * 21.0 + 31.0 * 31.0), 2.0 * (100.0 + 30.0 + 2.0)));
        let n_train = 65537.0;
        let terms = estimate(&scene);
        let online = terms.iter().find(|t| t.what.contains("online")).expect("online term");
        assert_eq!(online.bytes.to_bits(), (8.0 * n * (n_train + 65536.0 + 3.0 * n_train)).to_bits());
        assert!(total(&scene) < 24.0 * 1024f64.powi(3), "{}", human(total(&scene)));
        assert!(terms.iter().all(|t| !t.what.contains("Gram")));
    }

    /// Above 1 025 training snapshots the primal is streamed. The rope at level 11 (n = c = 201
    /// nodes, N = 2 049): min(n, N) = 201 is within `frame_pays_up_to(2 049)` = 468 (the
    /// frame's rank cannot pass it), so the metrics hold the dual set and its copy
    /// (`16 c N`), the frame and one block of 512 columns (`8 n (201 + 512)`) and three
    /// 201 x 2 049 coordinate matrices (`24 n N`): 17.6 MB, above the online stage's
    /// `8 n (N + T + 3 N)` = 16.5 MB, so the term leads and names `parameter.train_level`.
    /// Ironing-coarse at level 16 (n = 6 164 above `frame_pays_up_to(65 537)` = 3 840: a
    /// frame may not pay, and then the whole primal is read) keeps the whole primal and the
    /// POD's working copy, `16 (n + c) N`.
    #[test]
    fn streamed_sets_count_the_frame_where_it_surely_pays_and_the_whole_primal_elsewhere() {
        assert_eq!(
            (crom_stages::basis::frame_pays_up_to(2049), crom_stages::basis::frame_pays_up_to(65537)),
            (468, 3840)
        );
        let mut rope = shipped("rope");
        rope.parameter.n_train = None;
        rope.parameter.train_level = Some(11);
        assert_eq!(snapshot_rows(&rope), (201.0, 201.0));
        let terms = estimate(&rope);
        let last = terms.last().expect("terms");
        let (n, big_n) = (201.0f64, 2049.0f64);
        // exact: integer-valued sums far below 2^53
        let expected = 16.0 * n * big_n + 8.0 * n * (n + 512.0) + 24.0 * n * big_n;
        assert_eq!(last.bytes.to_bits(), expected.to_bits(), "{last:?}");
        assert!(last.what.contains("frame") && last.field == "parameter.train_level", "{last:?}");
        assert!(expected > 8.0 * n * (big_n + 2048.0 + 3.0 * big_n));
        let (what, bytes) = metrics_term(6164.0, 264.0, 65537.0);
        assert_eq!(bytes.to_bits(), (16.0f64 * (6164.0 + 264.0) * 65537.0).to_bits());
        assert!(what.contains("working copy"), "{what}");
        // At and below the Gram limit, unchanged: 32 N^2.
        assert_eq!(metrics_term(201.0, 201.0, 1025.0).1.to_bits(), (32.0f64 * 1025.0 * 1025.0).to_bits());
    }

    /// An external scene is estimated like a native one with the same sizes: the whole set, its
    /// working copy and the Gram matrices up to 1 025 training snapshots; above, the streamed
    /// primal's frame (bench G's 16 385 columns of 6 164 + 101 rows, 8 193 of them training:
    /// 6 164 is above `frame_pays_up_to(8 193)`, so the whole primal and its working copy are
    /// counted, `16 (n + c) N`) and, for the rope's sizes at level 11, the frame and coordinates.
    #[test]
    fn external_scenes_count_the_streamed_primal_as_native_ones_do() {
        let small = external_terms(617.0, 11.0, 513.0);
        assert_eq!(small.len(), 2);
        let sum: f64 = small.iter().map(|t| t.bytes).sum();
        assert_eq!(sum.to_bits(), (16.0f64 * 628.0 * 513.0 + 32.0 * 513.0 * 513.0).to_bits());
        for (n, c, big_n) in [(201.0, 201.0, 2049.0), (6164.0, 101.0, 8193.0)] {
            let terms = external_terms(n, c, big_n);
            assert_eq!(terms.len(), 1);
            assert_eq!(terms[0].bytes.to_bits(), metrics_term(n, c, big_n).1.to_bits());
            assert_eq!(terms[0].field, "model.external.train");
        }
        let rope = external_terms(201.0, 201.0, 2049.0);
        assert!(rope[0].what.contains("frame"), "{:?}", rope[0]);
    }

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("1024"), Ok(1024.0));
        assert_eq!(parse_size("8G"), Ok(8.0 * 1024f64.powi(3)));
        assert_eq!(parse_size("512MiB"), Ok(512.0 * 1024f64.powi(2)));
        assert_eq!(parse_size("1.5g"), Ok(1.5 * 1024f64.powi(3)));
        assert!(parse_size("lots").is_err() && parse_size("-1G").is_err() && parse_size("0").is_err());
    }
}
