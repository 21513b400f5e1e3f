//! HDF5 arrays with attributes. Matrices are written with shape `(rows, cols)`, one snapshot per
//! column (so `f["primal"][:, j]` in h5py is snapshot j), chunked, shuffled and deflated.
//!
//! The hdf5 crate serialises every call behind a global lock: call these from one thread.

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;

use crate::error::CromError;

const FIX_WRITE: &str = "check free space and permissions of the store directory";
const FIX_READ: &str = "the artifact is damaged or from another tool; delete its directory and rerun to recompute it";

/// A dense matrix stored column-major in memory (`data[i + j * rows]`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ColMatrix {
    /// Rows (dofs).
    pub rows: usize,
    /// Columns (snapshots / modes).
    pub cols: usize,
    /// Column-major data.
    pub data: Vec<f64>,
}

impl ColMatrix {
    /// Column `j`.
    pub fn col(&self, j: usize) -> &[f64] {
        &self.data[j * self.rows..(j + 1) * self.rows]
    }

    /// From columns of equal length.
    pub fn from_columns(rows: usize, columns: &[&[f64]]) -> Self {
        let mut data = Vec::with_capacity(rows * columns.len());
        for c in columns {
            assert_eq!(c.len(), rows, "column length");
            data.extend_from_slice(c);
        }
        Self { rows, cols: columns.len(), data }
    }
}

/// An HDF5 file being written, or a group in it.
#[derive(Debug)]
pub struct H5Out {
    path: PathBuf,
    group: hdf5::Group,
}

fn werr(path: &Path, what: &str, e: hdf5::Error) -> CromError {
    CromError::artifact(path, format!("HDF5 write of {what}: {e}"), FIX_WRITE)
}

fn rerr(path: &Path, what: &str, e: impl std::fmt::Display) -> CromError {
    CromError::artifact(path, format!("HDF5 read of {what}: {e}"), FIX_READ)
}

impl H5Out {
    /// Create a new file.
    pub fn create(path: &Path) -> Result<Self, CromError> {
        let file = hdf5::File::create(path).map_err(|e| werr(path, "file", e))?;
        let group = file.as_group().map_err(|e| werr(path, "root group", e))?;
        Ok(Self { path: path.to_path_buf(), group })
    }

    /// Create a child group.
    pub fn group(&self, name: &str) -> Result<Self, CromError> {
        let group = self.group.create_group(name).map_err(|e| werr(&self.path, name, e))?;
        Ok(Self { path: self.path.clone(), group })
    }

    /// A string attribute on this group.
    pub fn attr_str(&self, name: &str, value: &str) -> Result<(), CromError> {
        let v: VarLenUnicode =
            value.parse().map_err(|e| CromError::artifact(&self.path, format!("attribute {name}: {e}"), FIX_WRITE))?;
        let a = self.group.new_attr::<VarLenUnicode>().create(name).map_err(|e| werr(&self.path, name, e))?;
        a.write_scalar(&v).map_err(|e| werr(&self.path, name, e))
    }

    /// A float attribute on this group.
    pub fn attr_f64(&self, name: &str, value: f64) -> Result<(), CromError> {
        let a = self.group.new_attr::<f64>().create(name).map_err(|e| werr(&self.path, name, e))?;
        a.write_scalar(&value).map_err(|e| werr(&self.path, name, e))
    }

    /// An integer attribute on this group.
    pub fn attr_u64(&self, name: &str, value: u64) -> Result<(), CromError> {
        let a = self.group.new_attr::<u64>().create(name).map_err(|e| werr(&self.path, name, e))?;
        a.write_scalar(&value).map_err(|e| werr(&self.path, name, e))
    }

    /// A dataset of `shape`: from 64 elements chunked, and shuffled and deflated if `deflate`.
    fn dataset_with<T: hdf5::H5Type>(
        &self,
        name: &str,
        shape: &[usize],
        deflate: bool,
    ) -> Result<hdf5::Dataset, CromError> {
        let builder = self.group.new_dataset::<T>();
        let empty = shape.contains(&0);
        let ds = if empty || shape.iter().product::<usize>() < 64 {
            builder.shape(shape).create(name)
        } else {
            let chunk: Vec<usize> = match shape {
                [r] => vec![(*r).min(1 << 16)],
                [r, c] => vec![(*r).min(1 << 14), (*c).min(8)],
                _ => shape.to_vec(),
            };
            let b = builder.shape(shape).chunk(chunk);
            if deflate {
                b.shuffle().deflate(4).create(name)
            } else {
                b.create(name)
            }
        };
        ds.map_err(|e| werr(&self.path, name, e))
    }

    /// A chunked, shuffled and deflated dataset of `shape` ([`Self::dataset_with`]).
    fn dataset<T: hdf5::H5Type>(&self, name: &str, shape: &[usize]) -> Result<hdf5::Dataset, CromError> {
        self.dataset_with::<T>(name, shape, true)
    }

    /// A 1-D float dataset with a `units` attribute.
    pub fn vec_f64(&self, name: &str, data: &[f64], units: &str) -> Result<(), CromError> {
        let ds = self.dataset::<f64>(name, &[data.len()])?;
        ds.write_raw(data).map_err(|e| werr(&self.path, name, e))?;
        set_units(&ds, &self.path, name, units)
    }

    /// A 1-D float dataset of `n` equal values, stored as its fill value only: no chunk is
    /// written, and every reader (HDF5, h5py, ParaView) reads `value` everywhere. The views'
    /// per-step constants (a parameter component over all nodes) were written and deflated
    /// in full, about 0.3 s of one core on ironing-fine's 508 steps.
    pub fn constant_f64(&self, name: &str, n: usize, value: f64, units: &str) -> Result<(), CromError> {
        let ds = self.group.new_dataset::<f64>().shape([n]).fill_value(value).create(name);
        let ds = ds.map_err(|e| werr(&self.path, name, e))?;
        set_units(&ds, &self.path, name, units)
    }

    /// A 1-D integer dataset.
    pub fn vec_u64(&self, name: &str, data: &[u64]) -> Result<(), CromError> {
        let ds = self.dataset::<u64>(name, &[data.len()])?;
        ds.write_raw(data).map_err(|e| werr(&self.path, name, e))
    }

    /// A 2-D row-major integer dataset `(rows, cols)`.
    pub fn table_u64(&self, name: &str, rows: usize, cols: usize, row_major: &[u64]) -> Result<(), CromError> {
        let ds = self.dataset::<u64>(name, &[rows, cols])?;
        ds.write_raw(row_major).map_err(|e| werr(&self.path, name, e))
    }

    /// A 2-D row-major float dataset `(rows, cols)`.
    pub fn table_f64(
        &self,
        name: &str,
        rows: usize,
        cols: usize,
        row_major: &[f64],
        units: &str,
    ) -> Result<(), CromError> {
        self.table_f64_with(name, (rows, cols), row_major, units, true)
    }

    /// [`Self::table_f64`], deflated or not.
    fn table_f64_with(
        &self,
        name: &str,
        (rows, cols): (usize, usize),
        row_major: &[f64],
        units: &str,
        deflate: bool,
    ) -> Result<(), CromError> {
        let ds = self.dataset_with::<f64>(name, &[rows, cols], deflate)?;
        ds.write_raw(row_major).map_err(|e| werr(&self.path, name, e))?;
        set_units(&ds, &self.path, name, units)
    }

    /// A virtual `(rows, N)` dataset whose column k is column `src[k].1` of dataset `dataset` in
    /// the HDF5 file `src[k].0` (a path relative to this file's directory); `width(file)` is
    /// the column count of that source. Consecutive columns of one source become one mapping.
    pub fn virtual_columns(
        &self,
        name: &str,
        dataset: &str,
        rows: usize,
        src: &[(String, usize)],
        width: &dyn Fn(&str) -> usize,
        units: &str,
    ) -> Result<(), CromError> {
        let n = src.len();
        let mut runs: Vec<(&str, usize, usize, usize)> = Vec::new(); // (file, src col, vds col, len)
        for (k, (file, j)) in src.iter().enumerate() {
            match runs.last_mut() {
                Some(r) if r.0 == file.as_str() && r.1 + r.3 == *j && r.2 + r.3 == k => r.3 += 1,
                _ => runs.push((file.as_str(), *j, k, 1)),
            }
        }
        let builder = self.group.new_dataset::<f64>().shape((rows, n));
        let ds = if rows == 0 || n == 0 {
            builder.create(name)
        } else {
            builder
                .with_dcpl(|p| {
                    for &(file, j, k, len) in &runs {
                        p.virtual_map(
                            file,
                            dataset,
                            (rows, width(file)),
                            (.., j..j + len),
                            (rows, n),
                            (.., k..k + len),
                        );
                    }
                    p
                })
                .create(name)
        };
        let ds = ds.map_err(|e| werr(&self.path, name, e))?;
        set_units(&ds, &self.path, name, units)
    }

    /// A virtual float dataset of shape `shape` assembled from hyperslabs of other datasets
    /// ([`VirtualPiece`]); elements no piece maps read as 0 (the fill value).
    pub fn virtual_dataset(&self, name: &str, shape: &[usize], pieces: &[VirtualPiece]) -> Result<(), CromError> {
        use hdf5::{Hyperslab, SliceOrIndex};
        let slab = |sel: &[(usize, usize, usize)]| -> Hyperslab {
            sel.iter()
                .map(|&(start, step, count)| SliceOrIndex::SliceCount { start, step: step.max(1), count, block: 1 })
                .collect::<Vec<_>>()
                .into()
        };
        let builder = self.group.new_dataset::<f64>().shape(shape.to_vec()).fill_value(0.0);
        let ds = if pieces.is_empty() || shape.contains(&0) {
            builder.create(name)
        } else {
            builder
                .with_dcpl(|p| {
                    for piece in pieces {
                        p.virtual_map(
                            &piece.file,
                            &piece.dataset,
                            piece.source_shape.clone(),
                            slab(&piece.source),
                            shape.to_vec(),
                            slab(&piece.target),
                        );
                    }
                    p
                })
                .create(name)
        };
        ds.map(|_| ()).map_err(|e| werr(&self.path, name, e))
    }

    /// A `(rows, cols)` float dataset written one column at a time ([`ColumnWriter`]), for
    /// matrices too large to hold in memory; chunked by column, not compressed (solution and
    /// error fields deflate by only a quarter, at about a second per 50 MB).
    pub fn column_writer(&self, name: &str, rows: usize, cols: usize, units: &str) -> Result<ColumnWriter, CromError> {
        let builder = self.group.new_dataset::<f64>().shape((rows, cols));
        let ds = if rows == 0 || cols == 0 {
            builder.create(name)
        } else {
            builder.chunk((rows.min(1 << 16), 1)).create(name)
        };
        let ds = ds.map_err(|e| werr(&self.path, name, e))?;
        set_units(&ds, &self.path, name, units)?;
        Ok(ColumnWriter { path: self.path.clone(), name: name.to_string(), ds })
    }

    /// A matrix, one column per snapshot / mode.
    pub fn matrix(&self, name: &str, m: &ColMatrix, units: &str) -> Result<(), CromError> {
        self.matrix_with(name, m, units, true)
    }

    /// [`Self::matrix`] without compression, for dense modes over the dofs (a primal basis):
    /// deflate takes them to only about 0.6 of their size, at about 20 MB/s on one core
    /// (ironing-fine's 23 924 x 128 POD modes: 0.45 s of the basis stage to write, 0.14 s more
    /// at every read), as the snapshot blocks and the online fields are stored already.
    pub fn matrix_raw(&self, name: &str, m: &ColMatrix, units: &str) -> Result<(), CromError> {
        self.matrix_with(name, m, units, false)
    }

    fn matrix_with(&self, name: &str, m: &ColMatrix, units: &str, deflate: bool) -> Result<(), CromError> {
        let mut row_major = vec![0.0; m.data.len()];
        for j in 0..m.cols {
            for i in 0..m.rows {
                row_major[i * m.cols + j] = m.data[i + j * m.rows];
            }
        }
        self.table_f64_with(name, (m.rows, m.cols), &row_major, units, deflate)
    }
}

/// A matrix dataset being written column by column ([`H5Out::column_writer`]).
#[derive(Debug)]
pub struct ColumnWriter {
    path: PathBuf,
    name: String,
    ds: hdf5::Dataset,
}

impl ColumnWriter {
    /// Write column `j`. The column goes in as a `(rows, 1)` view onto the selection `(.., j..j + 1)`:
    /// memory and file selections of the same shape let HDF5 copy it in one piece, where a
    /// 1-D view onto `(.., j)` made it map the column element by element (ironing-fine's
    /// online.h5, 508 columns: 0.23 s of one core; the file's bytes are the same).
    pub fn write(&self, j: usize, column: &[f64]) -> Result<(), CromError> {
        let view = ndarray::ArrayView2::from_shape((column.len(), 1), column)
            .map_err(|e| CromError::artifact(&self.path, format!("{}: column {j}: {e}", self.name), FIX_WRITE))?;
        self.ds.write_slice(view, (.., j..j + 1)).map_err(|e| werr(&self.path, &self.name, e))
    }
}

/// One mapping of a virtual dataset: the hyperslab `source` of `dataset` (shape
/// `source_shape`) in the file `file` (relative to the virtual dataset's file) is seen at the
/// hyperslab `target`. Each selection is one `(start, step, count)` per dimension; both select
/// the same number of elements.
#[derive(Debug, Clone, PartialEq)]
pub struct VirtualPiece {
    /// Source file, relative to the virtual dataset's directory (or `.` for the same file).
    pub file: String,
    /// Source dataset path.
    pub dataset: String,
    /// Shape of the source dataset.
    pub source_shape: Vec<usize>,
    /// Selection in the source.
    pub source: Vec<(usize, usize, usize)>,
    /// Selection in the virtual dataset.
    pub target: Vec<(usize, usize, usize)>,
}

fn set_units(ds: &hdf5::Dataset, path: &Path, name: &str, units: &str) -> Result<(), CromError> {
    let v: VarLenUnicode =
        units.parse().map_err(|e| CromError::artifact(path, format!("units of {name}: {e}"), FIX_WRITE))?;
    let a = ds.new_attr::<VarLenUnicode>().create("units").map_err(|e| werr(path, name, e))?;
    a.write_scalar(&v).map_err(|e| werr(path, name, e))
}

/// An HDF5 file opened for reading.
#[derive(Debug)]
pub struct H5In {
    path: PathBuf,
    file: hdf5::File,
}

impl H5In {
    /// Open for reading.
    pub fn open(path: &Path) -> Result<Self, CromError> {
        let file = hdf5::File::open(path).map_err(|e| rerr(path, "file", e))?;
        Ok(Self { path: path.to_path_buf(), file })
    }

    fn ds(&self, name: &str) -> Result<hdf5::Dataset, CromError> {
        self.file.dataset(name).map_err(|e| rerr(&self.path, name, e))
    }

    /// Whether the root group has an attribute `name`.
    pub fn contains_attr(&self, name: &str) -> bool {
        self.file.attr_names().is_ok_and(|names| names.iter().any(|n| n == name))
    }

    /// Whether a dataset or group `name` exists.
    pub fn contains(&self, name: &str) -> bool {
        self.file.link_exists(name)
    }

    /// A 1-D float dataset.
    pub fn vec_f64(&self, name: &str) -> Result<Vec<f64>, CromError> {
        self.ds(name)?.read_raw::<f64>().map_err(|e| rerr(&self.path, name, e))
    }

    /// A 2-D float dataset as a column-major matrix.
    pub fn matrix(&self, name: &str) -> Result<ColMatrix, CromError> {
        let ds = self.ds(name)?;
        let shape = ds.shape();
        let [rows, cols] = shape[..] else {
            return Err(rerr(&self.path, name, format!("expected a 2-D dataset, found shape {shape:?}")));
        };
        let rm = ds.read_raw::<f64>().map_err(|e| rerr(&self.path, name, e))?;
        let mut data = vec![0.0; rows * cols];
        for i in 0..rows {
            for j in 0..cols {
                data[i + j * rows] = rm[i * cols + j];
            }
        }
        Ok(ColMatrix { rows, cols, data })
    }

    /// A 1-D integer dataset.
    pub fn vec_u64(&self, name: &str) -> Result<Vec<u64>, CromError> {
        self.ds(name)?.read_raw::<u64>().map_err(|e| rerr(&self.path, name, e))
    }

    /// Shape of a dataset.
    pub fn shape(&self, name: &str) -> Result<Vec<usize>, CromError> {
        Ok(self.ds(name)?.shape())
    }

    /// An integer attribute of a dataset or group at `path` (e.g. `primal_pod` / `rank`).
    pub fn attr_u64_at(&self, path: &str, name: &str) -> Result<u64, CromError> {
        let g = self.file.group(path).map_err(|e| rerr(&self.path, path, e))?;
        let a = g.attr(name).map_err(|e| rerr(&self.path, name, e))?;
        a.read_scalar::<u64>().map_err(|e| rerr(&self.path, name, e))
    }

    /// A string attribute of the root group.
    pub fn attr_str(&self, name: &str) -> Result<String, CromError> {
        let a = self.file.attr(name).map_err(|e| rerr(&self.path, name, e))?;
        let v = a.read_scalar::<VarLenUnicode>().map_err(|e| rerr(&self.path, name, e))?;
        Ok(v.as_str().to_string())
    }

    /// A float attribute of the root group.
    pub fn attr_f64(&self, name: &str) -> Result<f64, CromError> {
        let a = self.file.attr(name).map_err(|e| rerr(&self.path, name, e))?;
        a.read_scalar::<f64>().map_err(|e| rerr(&self.path, name, e))
    }

    /// An integer attribute of the root group.
    pub fn attr_u64(&self, name: &str) -> Result<u64, CromError> {
        let a = self.file.attr(name).map_err(|e| rerr(&self.path, name, e))?;
        a.read_scalar::<u64>().map_err(|e| rerr(&self.path, name, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The earlier column write, a 1-D view onto `(.., j)`, kept as the reference of
    /// [`ColumnWriter::write`].
    fn write_reference(w: &ColumnWriter, j: usize, column: &[f64]) {
        w.ds.write_slice(column, (.., j)).expect("reference write");
    }

    /// Columns written in any order read back bit for bit, and the file is byte for byte the one
    /// the reference write makes (the byte-identity of every stored online.h5 rests on it).
    #[test]
    fn a_column_writer_writes_the_reference_bytes() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let (rows, cols) = (37, 5);
        let col = |j: usize| -> Vec<f64> { (0..rows).map(|i| (i as f64 + 0.1).sqrt() * (j as f64 - 1.7)).collect() };
        let order = [3usize, 0, 4, 1, 2];
        let mut bytes = Vec::new();
        for reference in [false, true] {
            let path = dir.path().join(format!("c{reference}.h5"));
            {
                let f = H5Out::create(&path).expect("create");
                let w = f.column_writer("m", rows, cols, "test").expect("writer");
                for j in order {
                    if reference {
                        write_reference(&w, j, &col(j));
                    } else {
                        w.write(j, &col(j)).expect("write");
                    }
                }
            }
            let m = H5In::open(&path).expect("open").matrix("m").expect("read");
            for j in 0..cols {
                let back: Vec<u64> = m.col(j).iter().map(|v| v.to_bits()).collect();
                assert_eq!(back, col(j).iter().map(|v| v.to_bits()).collect::<Vec<_>>(), "column {j}");
            }
            bytes.push(std::fs::read(&path).expect("bytes"));
        }
        assert_eq!(bytes[0], bytes[1], "the file differs from the reference write's");
    }
}
