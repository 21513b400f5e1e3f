//! The data files of an external scene, read in blocks of snapshots: an HDF5 dataset or a
//! `.npy` array holding one snapshot per column (`layout = "columns"`, shape `(rows, N)`) or
//! per row (`layout = "rows"`, shape `(N, rows)`); and the parameter values from CSV,
//! Parquet, `.npy` or HDF5.
//!
//! A block of snapshots `j0..j1` is returned column-major (`rows x (j1 - j0)`), so its memory
//! is the block's, never the file's. In a `.npy` file the element `(entry d, snapshot j)` is at
//!
//! | layout  | C order     | Fortran order |
//! |---------|-------------|---------------|
//! | columns | `d N + j`   | `d + j rows`  |
//! | rows    | `j rows + d`| `j + d N`     |
//!
//! so a block is one contiguous read (`d + j rows` and `j rows + d`) or one read per entry
//! (the other two). HDF5 reads the block as one hyperslab.

use std::path::{Path, PathBuf};

use crom_schemas::external::{ArraySource, Layout, ParameterSource};

use super::npy::Npy;
use crate::error::CromError;

/// An open array of snapshots.
#[derive(Debug)]
pub struct SnapshotArray {
    path: PathBuf,
    what: String,
    layout: Layout,
    /// Entries per snapshot.
    pub rows: usize,
    /// Snapshots.
    pub cols: usize,
    inner: Inner,
}

#[derive(Debug)]
enum Inner {
    H5(hdf5::Dataset),
    Npy(Npy),
}

/// Whether `path` names an HDF5 file (by its extension).
pub(crate) fn is_h5(path: &Path) -> bool {
    matches!(path.extension().and_then(|e| e.to_str()), Some("h5" | "hdf5" | "he5" | "hdf"))
}

/// Whether `path` names a `.npy` file (by its extension).
pub(crate) fn is_npy(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()) == Some("npy")
}

/// Whether `path` names a `.npz` archive (by its extension).
pub(crate) fn is_npz(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()) == Some("npz")
}

/// `file` relative to `base` (absolute paths stay).
pub fn locate(base: &Path, file: &Path) -> PathBuf {
    if file.is_absolute() {
        file.to_path_buf()
    } else {
        base.join(file)
    }
}

fn missing(path: &Path, field: &str) -> CromError {
    CromError::input(
        path,
        field,
        "the file does not exist",
        format!("correct {field}.file in the scene file (relative paths are relative to the scene file's directory)"),
    )
}

/// HDF5's sieve buffer for contiguous datasets (its default is 64 KiB).
const SIEVE_BYTES: usize = 0;
/// Chunk cache of a chunked dataset: slots (a prime, as HDF5 advises) and bytes.
const CACHE_SLOTS: usize = 10_007;
const CACHE_BYTES: usize = 128 << 20;

/// Open an HDF5 dataset, naming the dataset and the fix when it is not there.
fn h5_dataset(path: &Path, field: &str, dataset: Option<&str>) -> Result<hdf5::Dataset, CromError> {
    let Some(name) = dataset else {
        return Err(CromError::input(
            path,
            field,
            "is an HDF5 file, and the scene names no dataset in it",
            format!("add {field}.dataset = \"/path/to/dataset\""),
        ));
    };
    // A column block of a contiguous (rows, N) dataset is one short run per row: without the
    // sieve buffer HDF5 reads each run as it is (with it, 64 KiB around every run). A chunked
    // dataset gets a chunk cache that holds a block's chunks across rows.
    let file = hdf5::File::with_options()
        .with_fapl(|p| p.sieve_buf_size(SIEVE_BYTES).chunk_cache(CACHE_SLOTS, CACHE_BYTES, 1.0))
        .open(path)
        .map_err(|e| {
            CromError::input(
                path,
                field,
                format!("cannot be opened as HDF5: {e}"),
                "check that the file is an HDF5 file",
            )
        })?;
    open_dataset(&file, path, field, name)
}

/// Open the HDF5 file `path` (with the reading options of a snapshot file) and its dataset
/// `name`, named in the scene as `field`.
pub(crate) fn open_h5(path: &Path, field: &str, name: &str) -> Result<hdf5::Dataset, CromError> {
    h5_dataset(path, field, Some(name))
}

fn open_dataset(file: &hdf5::File, path: &Path, field: &str, name: &str) -> Result<hdf5::Dataset, CromError> {
    if !file.link_exists(name) {
        let top: Vec<String> = file.member_names().unwrap_or_default();
        return Err(CromError::input(
            path,
            format!("dataset {name}"),
            format!("does not exist (the file's top level holds: {})", top.join(", ")),
            format!("correct {field}.dataset in the scene file"),
        ));
    }
    file.dataset(name).map_err(|e| {
        CromError::input(
            path,
            format!("dataset {name}"),
            format!("is not a dataset: {e}"),
            format!("correct {field}.dataset"),
        )
    })
}

impl SnapshotArray {
    /// Open the array `src` (relative to `base`) named in the scene as `field`
    /// (e.g. `model.external.dual`), checking that it is 2-D.
    pub fn open(base: &Path, src: &ArraySource, field: &str) -> Result<Self, CromError> {
        let path = locate(base, &src.file);
        if !path.exists() {
            return Err(missing(&path, field));
        }
        let (inner, shape, what) = if is_h5(&path) {
            let ds = h5_dataset(&path, field, src.dataset.as_deref())?;
            let shape = ds.shape();
            (Inner::H5(ds), shape, format!("dataset {}", src.dataset.as_deref().unwrap_or_default()))
        } else if is_npy(&path) {
            if src.dataset.is_some() {
                return Err(CromError::input(
                    &path,
                    field,
                    "is a .npy file, which has no datasets",
                    format!("remove {field}.dataset"),
                ));
            }
            let a = Npy::open(&path)?;
            let shape = a.shape.clone();
            (Inner::Npy(a), shape, "the array".to_string())
        } else if is_npz(&path) {
            let Some(member) = src.dataset.as_deref() else {
                return Err(CromError::input(
                    &path,
                    field,
                    "is a .npz archive, and the scene names no member of it",
                    format!("add {field}.dataset = \"NAME\" (the keyword given to np.savez)"),
                ));
            };
            let a = super::npz::open_member(&path, member, field)?;
            let shape = a.shape.clone();
            (Inner::Npy(a), shape, format!("member {member}"))
        } else {
            return Err(CromError::input(
                &path,
                field,
                "has an extension this reader does not know",
                "give an HDF5 file (.h5, .hdf5) with a dataset, a NumPy .npy file, or a .npz archive (np.savez or np.savez_compressed) with the member as dataset",
            ));
        };
        let [a, b] = shape[..] else {
            return Err(CromError::input(
                &path,
                what,
                format!("has shape {shape:?}; snapshots are a 2-D array"),
                "store one snapshot per column (shape (rows, N)) or per row with layout = \"rows\"",
            ));
        };
        let (rows, cols) = match src.layout {
            Layout::Columns => (a, b),
            Layout::Rows => (b, a),
        };
        Ok(Self { path, what, layout: src.layout, rows, cols, inner })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// `dataset /x` or `the array`, for messages.
    pub fn what(&self) -> &str {
        &self.what
    }

    /// Where entry `d` of snapshot `j` is in the file, for messages: `column j, row d` (or
    /// `row j, column d` for `layout = "rows"`).
    pub fn position(&self, j: usize, d: usize) -> String {
        match self.layout {
            Layout::Columns => format!("column {j}, row {d}"),
            Layout::Rows => format!("row {j}, column {d}"),
        }
    }

    /// Snapshots `j0..j1` as a column-major `rows x (j1 - j0)` block.
    pub fn block(&self, j0: usize, j1: usize) -> Result<Vec<f64>, CromError> {
        let (rows, n, b) = (self.rows, self.cols, j1 - j0);
        let rerr = |e: &dyn std::fmt::Display| {
            CromError::input(&self.path, self.what.clone(), format!("cannot be read: {e}"), "check the file")
        };
        match &self.inner {
            Inner::H5(ds) => {
                let mut out = vec![0.0; rows * b];
                if rows == 0 || b == 0 {
                    return Ok(out);
                }
                match self.layout {
                    Layout::Columns => {
                        let a = ds.read_slice_2d::<f64, _>((.., j0..j1)).map_err(|e| rerr(&e))?;
                        for ((d, k), v) in a.indexed_iter() {
                            out[d + k * rows] = *v;
                        }
                    }
                    Layout::Rows => {
                        let a = ds.read_slice_2d::<f64, _>((j0..j1, ..)).map_err(|e| rerr(&e))?;
                        for ((k, d), v) in a.indexed_iter() {
                            out[d + k * rows] = *v;
                        }
                    }
                }
                Ok(out)
            }
            Inner::Npy(a) => {
                let contiguous = matches!((self.layout, a.fortran), (Layout::Columns, true) | (Layout::Rows, false));
                if contiguous {
                    let mut out = Vec::with_capacity(rows * b);
                    a.read_into(j0 * rows, b * rows, &mut out)?;
                    return Ok(out);
                }
                // One run of b snapshots per entry d, at d N + j0, transposed into the block.
                let mut out = vec![0.0; rows * b];
                let mut run = Vec::with_capacity(b);
                for d in 0..rows {
                    run.clear();
                    a.read_into(d * n + j0, b, &mut run)?;
                    for (k, v) in run.iter().enumerate() {
                        out[d + k * rows] = *v;
                    }
                }
                Ok(out)
            }
        }
    }
}

/// The parameter values of `src` (relative to `base`): one row per snapshot, one value per
/// name, in the order of `src.names`. `field` names the table in the scene (for messages).
pub fn read_parameters(base: &Path, src: &ParameterSource, field: &str) -> Result<Vec<Vec<f64>>, CromError> {
    let path = locate(base, &src.file);
    if !path.exists() {
        return Err(missing(&path, field));
    }
    let p = src.names.len();
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase();
    let by_columns = |cols: Vec<Vec<f64>>| -> Vec<Vec<f64>> {
        let n = cols.first().map_or(0, Vec::len);
        (0..n).map(|i| cols.iter().map(|c| c[i]).collect()).collect()
    };
    match ext.as_str() {
        "csv" => read_csv(&path, &src.names).map(by_columns),
        "parquet" | "pq" => {
            let t = crate::io::table::read_parquet(&path).map_err(|e| {
                CromError::input(&path, field, format!("is not a readable Parquet file: {e}"), "check the file")
            })?;
            let cols = src
                .names
                .iter()
                .map(|n| {
                    t.f64s(n).map(<[f64]>::to_vec).ok_or_else(|| {
                        let have: Vec<&str> = t.columns.iter().map(|(c, _)| c.as_str()).collect();
                        CromError::input(
                            &path,
                            format!("column {n}"),
                            format!("is not a float64 column of the table (its columns: {})", have.join(", ")),
                            format!("name the float64 columns in {field}.names, or store the values as float64"),
                        )
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            Ok(by_columns(cols))
        }
        _ => {
            let (data, shape, fortran) = if is_npy(&path) {
                let a = Npy::open(&path)?;
                (a.read_all()?, a.shape.clone(), a.fortran)
            } else if is_npz(&path) {
                let member = src.dataset.as_deref().unwrap_or("mu");
                let a = super::npz::open_member(&path, member, field)?;
                (a.read_all()?, a.shape.clone(), a.fortran)
            } else if is_h5(&path) {
                let ds = h5_dataset(&path, field, src.dataset.as_deref())?;
                let v = ds.read_raw::<f64>().map_err(|e| {
                    CromError::input(
                        &path,
                        field,
                        format!("cannot be read as float64: {e}"),
                        "store the values as numbers",
                    )
                })?;
                (v, ds.shape(), false)
            } else {
                return Err(CromError::input(
                    &path,
                    field,
                    "has an extension this reader does not know",
                    "give a .csv (header row with the names), .parquet, .npy, .npz (member as dataset) or HDF5 file",
                ));
            };
            let n = match shape[..] {
                [n] if p == 1 => n,
                [n, q] if q == p => n,
                _ => return Err(CromError::input(
                    &path,
                    field,
                    format!("has shape {shape:?}, and the scene names {p} component(s) {:?}", src.names),
                    "store an array of shape (N,) for one component or (N, p) for p components, one row per snapshot",
                )),
            };
            Ok((0..n)
                .map(|i| (0..p).map(|c| if fortran { data[i + c * n] } else { data[i * p + c] }).collect())
                .collect())
        }
    }
}

/// The named columns of a CSV file with a header row (comma-separated, optional quotes).
fn read_csv(path: &Path, names: &[String]) -> Result<Vec<Vec<f64>>, CromError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| CromError::input(path, "the file", format!("cannot be read as text: {e}"), "check the file"))?;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let cell = |s: &str| s.trim().trim_matches('"').trim().to_string();
    let Some((_, head)) = lines.next() else {
        return Err(CromError::input(
            path,
            "the header row",
            "is missing (the file is empty)",
            "write a header row with the names",
        ));
    };
    let header: Vec<String> = head.split(',').map(cell).collect();
    let at = names
        .iter()
        .map(|n| {
            header.iter().position(|h| h == n).ok_or_else(|| {
                CromError::input(
                    path,
                    format!("column {n}"),
                    format!("is not in the header row ({})", header.join(", ")),
                    "name the header's columns in model.external.parameters.names",
                )
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut cols = vec![Vec::new(); names.len()];
    for (line, l) in lines {
        let cells: Vec<String> = l.split(',').map(cell).collect();
        for (c, &k) in at.iter().enumerate() {
            let v = cells.get(k).and_then(|s| s.parse::<f64>().ok()).ok_or_else(|| {
                CromError::input(
                    path,
                    format!("line {}, column {}", line + 1, names[c]),
                    format!("is {:?}, not a number", cells.get(k).map(String::as_str).unwrap_or("")),
                    "give one number per cell",
                )
            })?;
            cols[c].push(v);
        }
    }
    Ok(cols)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_layout_and_order_gives_the_same_block() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let (rows, n) = (3usize, 5usize);
        let x = |d: usize, j: usize| (10 * d + j) as f64;
        // The logical matrix (entry d, snapshot j) in each storage.
        let c_cols: Vec<f64> = (0..rows).flat_map(|d| (0..n).map(move |j| x(d, j))).collect();
        let f_cols: Vec<f64> = (0..n).flat_map(|j| (0..rows).map(move |d| x(d, j))).collect();
        let cases = [
            ("a.npy", [rows, n], false, Layout::Columns, &c_cols),
            ("b.npy", [rows, n], true, Layout::Columns, &f_cols),
            ("c.npy", [n, rows], false, Layout::Rows, &f_cols),
            ("d.npy", [n, rows], true, Layout::Rows, &c_cols),
        ];
        for (name, shape, fortran, layout, data) in cases {
            let p = dir.path().join(name);
            crate::io::npy::tests::write_npy(&p, &shape, fortran, data);
            let src = ArraySource { file: p.clone(), dataset: None, layout };
            let a = SnapshotArray::open(dir.path(), &src, "model.external.dual").expect("open");
            assert_eq!((a.rows, a.cols), (rows, n), "{name}");
            let block = a.block(1, 4).expect("block");
            let want: Vec<f64> = (1..4).flat_map(|j| (0..rows).map(move |d| x(d, j))).collect();
            // Copies of f64 values: exact.
            assert_eq!(block, want, "{name}");
        }
    }

    #[test]
    fn csv_columns_are_found_by_name() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let p = dir.path().join("mu.csv");
        std::fs::write(&p, "id,\"d_x\",d_y\n0,0.5,1e-2\n1,1.5,2e-2\n").expect("write");
        let src = ParameterSource {
            file: p.clone(),
            dataset: None,
            names: vec!["d_y".into(), "d_x".into()],
            description: String::new(),
        };
        let v = read_parameters(dir.path(), &src, "model.external.parameters").expect("read");
        assert_eq!(v, vec![vec![1e-2, 0.5], vec![2e-2, 1.5]]);
        let bad = ParameterSource { names: vec!["mu".into()], ..src };
        let e = read_parameters(dir.path(), &bad, "model.external.parameters").expect_err("no such column");
        assert!(e.to_string().contains("column mu") && e.to_string().contains("id, d_x, d_y"), "{e}");
    }
}
