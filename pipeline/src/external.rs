//! Loading an external scene (`[model.external]`, [`crom_schemas::external`]): open its data
//! files, check what can be checked without reading the snapshots (the files and datasets
//! exist, the arrays are 2-D, the column counts of primal, dual and parameters agree, the column
//! lists are in range, no two points share a parameter value, at least two training
//! snapshots), hash the snapshot files (blake3 of their bytes: the snapshots' keys), and record
//! it all in the scene ([`ResolvedExternal`], the parameter's explicit points), so that the plan
//! is known before anything is imported. The values themselves (NaN, infinities, negative
//! pressures) are checked by the import ([`crate::dag`]'s import stage) before it stores
//! anything. Every refusal is [`CromError::Input`] (exit 2) naming the file, the dataset or
//! field, and the fix.

use std::path::Path;

use crom_schemas::external::{ExternalSpec, ResolvedArray, ResolvedExternal, ResolvedSet};
use crom_schemas::parameter::{AxisSpec, ExplicitPoints};
use crom_schemas::{Model, SceneConfig};

use crate::error::CromError;
use crate::io::source::{locate, read_parameters, SnapshotArray};

/// Resolve `scene`'s external data (a native scene is left as it is); `path` is the scene file.
pub fn resolve(scene: &mut SceneConfig, path: &Path) -> Result<(), CromError> {
    let Model::External(ext) = &scene.model else { return Ok(()) };
    let base = path.parent().unwrap_or(Path::new("."));
    let resolved = resolve_spec(ext, base)?;
    let names = &ext.parameters.names;
    let p = &mut scene.parameter;
    p.name = names[0].clone();
    p.description = ext.parameters.description.clone();
    p.axes = names[1..]
        .iter()
        .map(|n| AxisSpec {
            name: n.clone(),
            description: String::new(),
            min: 0.0,
            max: 0.0,
            n_train: None,
            train_level: None,
        })
        .collect();
    p.explicit = Some(ExplicitPoints { train: resolved.train.points.clone(), test: resolved.test.points.clone() });
    if let Model::External(e) = &mut scene.model {
        e.resolved = Some(resolved);
    }
    Ok(())
}

/// One pair of arrays (dual, optional primal) and their parameter values, checked against each
/// other.
struct Files {
    dual: ResolvedArray,
    primal: Option<ResolvedArray>,
    points: Vec<Vec<f64>>,
}

/// blake3 of a file's bytes, each file hashed once per load (primal and dual are often one
/// HDF5 file).
#[derive(Default)]
struct Hashes(std::collections::HashMap<std::path::PathBuf, String>);

impl Hashes {
    fn of(&mut self, path: &Path) -> Result<String, CromError> {
        if let Some(h) = self.0.get(path) {
            return Ok(h.clone());
        }
        let h = hash_file(path).map_err(|e| CromError::io(path, "hashing a data file", e))?;
        self.0.insert(path.to_path_buf(), h.clone());
        Ok(h)
    }
}

/// blake3 of the bytes of the file at `path`, read in large pieces.
fn hash_file(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    let mut f = std::fs::File::open(path)?;
    let mut h = blake3::Hasher::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().to_hex().to_string())
}

fn array(
    base: &Path,
    src: &crom_schemas::external::ArraySource,
    field: &str,
    hashes: &mut Hashes,
) -> Result<ResolvedArray, CromError> {
    let a = SnapshotArray::open(base, src, field)?;
    let blake3 = hashes.of(a.path())?;
    Ok(ResolvedArray {
        path: a.path().to_path_buf(),
        dataset: src.dataset.clone(),
        layout: src.layout,
        blake3,
        rows: a.rows,
        cols: a.cols,
    })
}

fn files(
    base: &Path,
    at: &str,
    dual: &crom_schemas::external::ArraySource,
    primal: Option<&crom_schemas::external::ArraySource>,
    params: &crom_schemas::external::ParameterSource,
    hashes: &mut Hashes,
) -> Result<Files, CromError> {
    let dual = array(base, dual, &format!("{at}.dual"), hashes)?;
    let primal = primal.map(|p| array(base, p, &format!("{at}.primal"), hashes)).transpose()?;
    let points = read_parameters(base, params, &format!("{at}.parameters"))?;
    let fix = "give primal, dual and parameters one snapshot each, in the same order";
    if let Some(p) = &primal {
        if p.cols != dual.cols {
            return Err(CromError::input(
                &p.path,
                p.dataset.clone().unwrap_or_else(|| format!("{at}.primal")),
                format!("holds {} snapshots, and {} holds {}", p.cols, dual.path.display(), dual.cols),
                fix,
            ));
        }
    }
    if points.len() != dual.cols {
        return Err(CromError::input(
            locate(base, &params.file),
            format!("{at}.parameters"),
            format!(
                "holds {} parameter values, and {} holds {} snapshots",
                points.len(),
                dual.path.display(),
                dual.cols
            ),
            fix,
        ));
    }
    if let Some((i, c)) =
        points.iter().enumerate().find_map(|(i, p)| p.iter().position(|v| !v.is_finite()).map(|c| (i, c)))
    {
        return Err(CromError::input(
            locate(base, &params.file),
            format!("{at}.parameters, row {i}, component {}", params.names[c]),
            format!("is {}, not a finite number", points[i][c]),
            "give every snapshot a finite parameter value",
        ));
    }
    if dual.rows == 0 {
        return Err(CromError::input(
            &dual.path,
            format!("{at}.dual"),
            "has no rows",
            "give one row per contact entry",
        ));
    }
    Ok(Files { dual, primal, points })
}

/// A set: the columns `columns` of `f` (each checked to be in range; `field` names the list).
fn set(f: &Files, columns: Vec<usize>, field: &str) -> Result<ResolvedSet, CromError> {
    if let Some(j) = columns.iter().find(|&&j| j >= f.dual.cols) {
        return Err(CromError::input(
            &f.dual.path,
            field.to_string(),
            format!(
                "lists column {j}, and the file holds {} snapshots (columns 0 to {})",
                f.dual.cols,
                f.dual.cols.saturating_sub(1)
            ),
            format!("list columns below {} in {field}", f.dual.cols),
        ));
    }
    let points = columns.iter().map(|&j| f.points[j].clone()).collect();
    Ok(ResolvedSet { dual: f.dual.clone(), primal: f.primal.clone(), columns, points })
}

fn resolve_spec(ext: &ExternalSpec, base: &Path) -> Result<ResolvedExternal, CromError> {
    let at = "model.external";
    let mut hashes = Hashes::default();
    let main = files(base, at, &ext.dual, ext.primal.as_ref(), &ext.parameters, &mut hashes)?;
    let (train, test) = match (&ext.test, &ext.test_files) {
        (Some(test), _) => {
            let train = ext.train.clone().unwrap_or_default();
            (set(&main, train, &format!("{at}.train"))?, set(&main, test.clone(), &format!("{at}.test"))?)
        }
        (None, Some(tf)) => {
            let other =
                files(base, &format!("{at}.test_files"), &tf.dual, tf.primal.as_ref(), &tf.parameters, &mut hashes)?;
            for (a, b, what) in
                [(Some(&main.dual), Some(&other.dual), "dual"), (main.primal.as_ref(), other.primal.as_ref(), "primal")]
            {
                if let (Some(a), Some(b)) = (a, b) {
                    if a.rows != b.rows {
                        return Err(CromError::input(
                            &b.path,
                            format!("{at}.test_files.{what}"),
                            format!(
                                "has {} entries per snapshot, the training file {} has {}",
                                b.rows,
                                a.path.display(),
                                a.rows
                            ),
                            "give both sets snapshots of the same discretisation",
                        ));
                    }
                }
            }
            let train = ext.train.clone().unwrap_or_else(|| (0..main.dual.cols).collect());
            let all = (0..other.dual.cols).collect();
            (set(&main, train, &format!("{at}.train"))?, set(&other, all, &format!("{at}.test_files"))?)
        }
        (None, None) => {
            return Err(CromError::input(
                locate(base, &ext.dual.file),
                format!("{at}.test"),
                "no test points: neither `test` columns nor `test_files` are given",
                "give `test = [columns]` or a [model.external.test_files] table",
            ))
        }
    };
    if train.columns.len() < 2 {
        return Err(CromError::input(
            &train.dual.path,
            format!("{at}.train"),
            format!(
                "makes a training set of {} snapshot(s); a reduced basis and its leave-one-out need at least 2",
                train.columns.len()
            ),
            "give at least two training snapshots",
        ));
    }
    if test.columns.is_empty() && ext.test_files.is_some() {
        return Err(CromError::input(
            &test.dual.path,
            format!("{at}.test_files"),
            "holds no snapshot",
            "give at least one test snapshot",
        ));
    }
    check_distinct(ext, base, &train, &test)?;
    let n_dof = train.primal.as_ref().map_or(0, |p| p.rows);
    let mesh = ext.mesh.as_ref().map(|m| crate::external_mesh::resolve(base, m, main.dual.rows, n_dof)).transpose()?;
    let coordinates = match (&ext.coordinates, &mesh) {
        (Some(src), _) => Some(coordinates(base, src, main.dual.rows)?),
        // Without coordinates of their own, the dual entries are at their mesh nodes.
        (None, Some(m)) => {
            Some(m.dual_nodes.iter().map(|&i| m.nodes[i as usize * m.dim..(i as usize + 1) * m.dim].to_vec()).collect())
        }
        (None, None) => None,
    };
    let levels = nested_levels(&train.points);
    Ok(ResolvedExternal { n_dof, mesh, levels, n_contact: train.dual.rows, train, test, coordinates })
}

/// No two snapshots of the study may share a parameter value (bit for bit): a duplicate
/// makes the leave-one-out and the nested levels meaningless, and is most often a column
/// listed twice or a parameter file out of step with the snapshots.
fn check_distinct(ext: &ExternalSpec, base: &Path, train: &ResolvedSet, test: &ResolvedSet) -> Result<(), CromError> {
    let mut seen: std::collections::HashMap<Vec<u64>, (&str, usize)> = std::collections::HashMap::new();
    for (name, s) in [("train", train), ("test", test)] {
        for (k, p) in s.points.iter().enumerate() {
            let bits: Vec<u64> = p.iter().map(|v| v.to_bits()).collect();
            if let Some((other, j)) = seen.insert(bits, (name, s.columns[k])) {
                let file = if name == "test" && ext.test_files.is_some() {
                    &ext.test_files.as_ref().map(|t| t.parameters.file.clone()).unwrap_or_default()
                } else {
                    &ext.parameters.file
                };
                return Err(CromError::input(
                    locate(base, file),
                    "the parameter values",
                    format!(
                        "{name} column {} has the parameter value {p:?}, as {other} column {j} does",
                        s.columns[k]
                    ),
                    "give every snapshot its own parameter value (drop the duplicate column from the set lists, or correct the parameter file)",
                ));
            }
        }
    }
    Ok(())
}

/// The contact nodes' coordinates: an `(n_contact, d)` array, one row per dual entry (with
/// `layout = "rows"`, its transpose `(d, n_contact)`).
fn coordinates(
    base: &Path,
    src: &crom_schemas::external::ArraySource,
    n_contact: usize,
) -> Result<Vec<Vec<f64>>, CromError> {
    let field = "model.external.coordinates";
    // One node per row of the file: read it as `d` entries x `n_contact` "snapshots" transposed.
    let flipped = crom_schemas::external::ArraySource {
        layout: match src.layout {
            crom_schemas::external::Layout::Columns => crom_schemas::external::Layout::Rows,
            crom_schemas::external::Layout::Rows => crom_schemas::external::Layout::Columns,
        },
        ..src.clone()
    };
    let a = SnapshotArray::open(base, &flipped, field)?;
    if a.cols != n_contact {
        return Err(CromError::input(
            a.path(),
            a.what().to_string(),
            format!("holds {} nodes, the dual snapshots have {n_contact} entries", a.cols),
            "give one row of coordinates per contact entry, in the dual snapshots' order",
        ));
    }
    let d = a.rows;
    let block = a.block(0, n_contact)?;
    Ok((0..n_contact).map(|i| block[i * d..(i + 1) * d].to_vec()).collect())
}

/// The nested levels of a training set whose points form them: a tensor grid whose axis a
/// (parameter component a) takes `2^(k_a) + 1` equally spaced values (to 1e-9 of its spacing),
/// every combination exactly once, with `k = min_a k_a >= 2`. Level n (1 to k) is the points
/// whose index along every axis a is a multiple of `2^(k_a - n)` — `2^n + 1` values per axis,
/// as a native scene's level n of the same ranges — ordered as a native tensor grid (the first
/// component varying fastest). With one component, level k is the whole set in ascending order.
/// Returned as positions in the training set; empty when the points are no such grid.
pub fn nested_levels(points: &[Vec<f64>]) -> Vec<Vec<usize>> {
    let n = points.len();
    let d = points.first().map_or(0, Vec::len);
    if n < 5 || d == 0 || points.iter().any(|p| p.len() != d) {
        return Vec::new();
    }
    // Per axis: its exponent k_a, and each point's index along it.
    let mut ks = Vec::with_capacity(d);
    let mut index = vec![vec![0usize; d]; n];
    for a in 0..d {
        let mut values: Vec<f64> = points.iter().map(|p| p[a]).collect();
        values.sort_by(f64::total_cmp);
        values.dedup_by(|x, y| x.to_bits() == y.to_bits());
        let m = values.len();
        if m < 3 || !(m - 1).is_power_of_two() {
            return Vec::new();
        }
        let (lo, hi) = (values[0], values[m - 1]);
        let h = (hi - lo) / (m - 1) as f64;
        let grid = crom_stages::float_cmp::Tol { abs: 1e-9 * h, rel: 0.0 };
        let even = h > 0.0
            && values.iter().enumerate().all(|(i, &v)| crom_stages::float_cmp::close(v, lo + i as f64 * h, grid));
        if !even {
            return Vec::new();
        }
        ks.push((m - 1).trailing_zeros());
        for (p, idx) in points.iter().zip(index.iter_mut()) {
            idx[a] = values.partition_point(|v| v.total_cmp(&p[a]).is_lt());
        }
    }
    // Every combination exactly once: as many points as combinations, and no two alike.
    let combinations = ks.iter().try_fold(1usize, |acc, &k| acc.checked_mul((1usize << k) + 1));
    if combinations != Some(n) {
        return Vec::new();
    }
    // Native tensor order: the last axis slowest, the first fastest.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| index[i].iter().rev().cmp(index[j].iter().rev()));
    if order.windows(2).any(|w| index[w[0]] == index[w[1]]) {
        return Vec::new();
    }
    let top = ks.iter().copied().min().unwrap_or(0);
    if top < 2 {
        return Vec::new();
    }
    (1..=top)
        .map(|level| {
            order
                .iter()
                .copied()
                .filter(|&j| index[j].iter().zip(&ks).all(|(&i, &k)| i % (1usize << (k - level)) == 0))
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_equally_spaced_level_k_set_has_levels_1_to_k() {
        // 9 points of [0, 2] given out of order: levels 1 (3 points), 2 (5) and 3 (all 9).
        let values = [1.0, 0.0, 0.25, 2.0, 0.5, 0.75, 1.25, 1.5, 1.75];
        let points: Vec<Vec<f64>> = values.iter().map(|&v| vec![v]).collect();
        let levels = nested_levels(&points);
        let at = |l: &[usize]| l.iter().map(|&i| values[i]).collect::<Vec<_>>();
        assert_eq!(levels.len(), 3);
        assert_eq!(at(&levels[0]), vec![0.0, 1.0, 2.0]);
        assert_eq!(at(&levels[1]), vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        assert_eq!(levels[2].len(), 9);
        // Not a grid: one value moved, a count that is not 2^k + 1, a second component that
        // takes one value only.
        let mut moved = points.clone();
        moved[2][0] = 0.3;
        assert!(nested_levels(&moved).is_empty());
        assert!(nested_levels(&points[..8]).is_empty());
        let two: Vec<Vec<f64>> = values.iter().map(|&v| vec![v, 0.0]).collect();
        assert!(nested_levels(&two).is_empty());
    }

    /// A two-component tensor grid (9 x 5 values, given in a shuffled order) has the levels of a
    /// native scene with the same axes: level n is the tensor grid of `nested_points(n)`, in the
    /// same order, point for point; a grid with a point missing or listed twice has none.
    #[test]
    fn a_tensor_grid_has_the_native_scenes_levels() {
        use crom_schemas::parameter::tensor;
        let x = |k: u32| (0..=(1usize << k)).map(|i| i as f64 * 3.0 / (1usize << k) as f64).collect::<Vec<_>>();
        let y = |k: u32| (0..=(1usize << k)).map(|i| 0.02 + i as f64 * 0.04 / (1usize << k) as f64).collect::<Vec<_>>();
        let grid = tensor(&[x(3), y(2)]);
        // A fixed shuffle (reversed, then every third first): the levels must not depend on it.
        let mut points: Vec<Vec<f64>> = grid
            .iter()
            .rev()
            .step_by(3)
            .chain(grid.iter().rev().skip(1).step_by(3))
            .chain(grid.iter().rev().skip(2).step_by(3))
            .cloned()
            .collect();
        assert_eq!(points.len(), grid.len());
        let levels = nested_levels(&points);
        assert_eq!(levels.len(), 2, "levels 1 and 2 (the second axis has 2^2 + 1 values)");
        for (n, level) in levels.iter().enumerate() {
            let expected = tensor(&[x(n as u32 + 1), y(n as u32 + 1)]);
            let got: Vec<Vec<f64>> = level.iter().map(|&j| points[j].clone()).collect();
            assert_eq!(got.len(), expected.len(), "level {}", n + 1);
            for (g, e) in got.iter().zip(&expected) {
                assert!(g.iter().zip(e).all(|(a, b)| (a - b).abs() <= 1e-12), "level {}: {g:?} vs {e:?}", n + 1);
            }
        }
        let last = points.pop().expect("a point");
        assert!(nested_levels(&points).is_empty(), "one combination missing");
        points.push(points[0].clone());
        assert!(nested_levels(&points).is_empty(), "one combination twice, one missing");
        points.pop();
        points.push(last);
        assert_eq!(nested_levels(&points).len(), 2);
    }
}
