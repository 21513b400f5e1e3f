//! Small arrays read whole (an external scene's mesh: nodes, cells, the dual entries' nodes):
//! an HDF5 dataset (`file` + dataset path) or a `.npy` file (`file` absent, the name a path
//! relative to the scene file's directory), 1-D or 2-D, returned row-major as `f64` (integer
//! arrays are converted; indices are exact below 2^53).

use std::path::{Path, PathBuf};

use super::npy::Npy;
use super::source::{is_h5, is_npy, is_npz, locate, open_h5};
use crate::error::CromError;

/// An array read whole.
#[derive(Debug, Clone, PartialEq)]
pub struct WholeArray {
    /// The file.
    pub path: PathBuf,
    /// `dataset /x` or `the array`, for messages.
    pub what: String,
    /// Its shape (1 or 2 entries).
    pub shape: Vec<usize>,
    /// Its elements, row-major.
    pub data: Vec<f64>,
}

impl WholeArray {
    /// Rows (the first dimension).
    pub fn rows(&self) -> usize {
        self.shape.first().copied().unwrap_or(0)
    }

    /// Columns (1 for a 1-D array).
    pub fn cols(&self) -> usize {
        self.shape.get(1).copied().unwrap_or(1)
    }
}

/// Read the array `name` (a dataset of the HDF5 file `file`, or a `.npy` file when `file` is
/// None) named in the scene as `field`.
pub fn read_whole(base: &Path, file: Option<&Path>, name: &str, field: &str) -> Result<WholeArray, CromError> {
    let (path, what, shape, data) = match file {
        Some(f) => {
            let path = locate(base, f);
            if !path.exists() {
                return Err(missing(&path, &format!("{field} (file)")));
            }
            if is_npz(&path) {
                let a = super::npz::open_member(&path, name, field)?;
                let (data, shape) = row_major(&a)?;
                return check(WholeArray { path, what: format!("member {name}"), shape, data }, field);
            }
            if !is_h5(&path) {
                return Err(CromError::input(
                    &path,
                    field,
                    "is neither an HDF5 file (.h5, .hdf5) nor a .npz archive, so it has no dataset to read",
                    "give an HDF5 file and dataset paths, a .npz archive and member names, or leave `file` out and name one .npy file per array",
                ));
            }
            let ds = open_h5(&path, field, name)?;
            let shape = ds.shape();
            let data = ds.read_raw::<f64>().map_err(|e| {
                CromError::input(
                    &path,
                    format!("dataset {name}"),
                    format!("cannot be read as numbers: {e}"),
                    "store a numeric array",
                )
            })?;
            (path, format!("dataset {name}"), shape, data)
        }
        None => {
            let path = locate(base, Path::new(name));
            if !is_npy(&path) {
                return Err(CromError::input(
                    &path,
                    field,
                    "is not a .npy file, and the mesh names no HDF5 file",
                    "give model.external.mesh.file = \"mesh.h5\" with dataset paths, or one .npy file per array",
                ));
            }
            if !path.exists() {
                return Err(missing(&path, field));
            }
            let (data, shape) = row_major(&Npy::open(&path)?)?;
            (path, "the array".to_string(), shape, data)
        }
    };
    check(WholeArray { path, what, shape, data }, field)
}

/// The elements of `a` in row-major order, and its shape.
fn row_major(a: &Npy) -> Result<(Vec<f64>, Vec<usize>), CromError> {
    let mut data = a.read_all()?;
    if a.fortran && a.shape.len() == 2 {
        let (r, c) = (a.shape[0], a.shape[1]);
        data = (0..r * c).map(|k| data[(k % c) * r + k / c]).collect();
    }
    Ok((data, a.shape.clone()))
}

/// `a` if it is 1-D or 2-D.
fn check(a: WholeArray, field: &str) -> Result<WholeArray, CromError> {
    if a.shape.is_empty() || a.shape.len() > 2 {
        return Err(CromError::input(
            &a.path,
            a.what,
            format!("has shape {:?}; {field} is a 1-D or 2-D array", a.shape),
            "store it as documented in docs/user-guide.md, \"Bring your own snapshots\"",
        ));
    }
    Ok(a)
}

fn missing(path: &Path, field: &str) -> CromError {
    CromError::input(
        path,
        field,
        "the file does not exist",
        "correct the path in the scene file (relative paths are relative to the scene file's directory)",
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::npy::tests::write_npy;

    #[test]
    fn a_fortran_npy_reads_row_major() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        // [[0, 1, 2], [3, 4, 5]] stored column by column.
        write_npy(&dir.path().join("a.npy"), &[2, 3], true, &[0.0, 3.0, 1.0, 4.0, 2.0, 5.0]);
        let a = read_whole(dir.path(), None, "a.npy", "model.external.mesh.nodes").expect("read");
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
    }

    #[test]
    fn a_missing_dataset_names_the_file_and_the_dataset() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let path = dir.path().join("m.h5");
        hdf5::File::create(&path).expect("create");
        let e = read_whole(dir.path(), Some(Path::new("m.h5")), "/cells", "model.external.mesh.cells")
            .expect_err("no dataset");
        assert_eq!(e.exit_code(), 2);
        let text = e.to_string();
        assert!(text.contains("m.h5") && text.contains("/cells"), "{text}");
    }
}
