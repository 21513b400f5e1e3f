//! NumPy `.npy` arrays, read in pieces without loading the file.
//!
//! Format (numpy.lib.format, versions 1–3): the magic `\x93NUMPY`, a major and minor version
//! byte, the header length (`u16` little-endian in version 1, `u32` in versions 2 and 3), then an
//! ASCII header, a Python dict literal such as
//! `{'descr': '<f8', 'fortran_order': False, 'shape': (6164, 255), }`, then the data: the
//! elements in C order (last index fastest) or, with `fortran_order`, in Fortran order (first
//! index fastest). Element types read here: little-endian `f8`, `f4`, `i8`, `i4` (converted to
//! `f64`; `i8` values beyond 2^53 lose precision, as in NumPy's own cast).

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use crate::error::CromError;

/// An element type of a `.npy` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    /// `<f8`.
    F64,
    /// `<f4`.
    F32,
    /// `<i8`.
    I64,
    /// `<i4`.
    I32,
}

impl Dtype {
    fn size(self) -> usize {
        match self {
            Dtype::F64 | Dtype::I64 => 8,
            Dtype::F32 | Dtype::I32 => 4,
        }
    }

    fn decode(self, b: &[u8]) -> f64 {
        match self {
            Dtype::F64 => f64::from_le_bytes(b.try_into().unwrap_or([0; 8])),
            Dtype::F32 => f64::from(f32::from_le_bytes(b.try_into().unwrap_or([0; 4]))),
            Dtype::I64 => i64::from_le_bytes(b.try_into().unwrap_or([0; 8])) as f64,
            Dtype::I32 => f64::from(i32::from_le_bytes(b.try_into().unwrap_or([0; 4]))),
        }
    }
}

/// An open `.npy` file: its header, and the file to read elements from.
#[derive(Debug)]
pub struct Npy {
    path: PathBuf,
    file: File,
    /// Element type.
    pub dtype: Dtype,
    /// Fortran (column-major) order.
    pub fortran: bool,
    /// Shape.
    pub shape: Vec<usize>,
    offset: u64,
}

const FIX: &str = "save the array with numpy.save (a float64 array: np.save(path, a.astype(np.float64)))";

impl Npy {
    /// Open `path` and read its header; checks that the file holds as many bytes as the shape
    /// says.
    pub fn open(path: &Path) -> Result<Self, CromError> {
        let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
        Self::open_at(path, 0, size)
    }

    /// The same array, named `path` in every later error (an inflated archive member read from
    /// a temporary file is named by its archive).
    pub(crate) fn shown_as(mut self, path: &Path) -> Self {
        self.path = path.to_path_buf();
        self
    }

    /// The `.npy` data of `size` bytes at byte `at` of the file `path` (a whole file, or a member
    /// stored uncompressed in a `.npz` archive); checks that it holds as many bytes as the shape
    /// says.
    pub fn open_at(path: &Path, at: u64, size: u64) -> Result<Self, CromError> {
        let bad = |m: String| CromError::input(path, "the .npy header", m, FIX);
        let file = File::open(path).map_err(|e| {
            CromError::input(path, "the file", format!("cannot be opened: {e}"), "check the path in the scene file")
        })?;
        let mut pre = [0u8; 12];
        let got = file.read_at(&mut pre, at).map_err(|e| bad(format!("cannot be read: {e}")))?;
        if got < 10 || &pre[..6] != b"\x93NUMPY" {
            return Err(bad("is not a NumPy .npy file (no \\x93NUMPY magic)".into()));
        }
        let (len, start) = match pre[6] {
            1 => (usize::from(u16::from_le_bytes([pre[8], pre[9]])), 10usize),
            2 | 3 if got == 12 => (u32::from_le_bytes([pre[8], pre[9], pre[10], pre[11]]) as usize, 12usize),
            v => return Err(bad(format!("has format version {v}, which this reader does not know"))),
        };
        if len > 1 << 20 {
            return Err(bad(format!("claims a header of {len} bytes")));
        }
        let mut header = vec![0u8; len];
        file.read_exact_at(&mut header, at + start as u64).map_err(|e| bad(format!("is cut short: {e}")))?;
        let header = String::from_utf8_lossy(&header).into_owned();
        let (dtype, fortran, shape) = parse_header(&header).map_err(bad)?;
        let header_end = (start + len) as u64;
        let elements =
            shape.iter().try_fold(1usize, |a, &n| a.checked_mul(n)).ok_or_else(|| bad("overflows".into()))?;
        let need = (elements as u64).saturating_mul(dtype.size() as u64).saturating_add(header_end);
        let offset = at + header_end;
        if size != need {
            return Err(CromError::input(
                path,
                "the array data",
                format!("the header says shape {shape:?} ({need} bytes with the header), the file has {size} bytes"),
                FIX,
            ));
        }
        Ok(Self { path: path.to_path_buf(), file, dtype, fortran, shape, offset })
    }

    /// `count` elements from element `start` of the data, in storage order, appended to `out`.
    pub fn read_into(&self, start: usize, count: usize, out: &mut Vec<f64>) -> Result<(), CromError> {
        let size = self.dtype.size();
        let mut bytes = vec![0u8; count * size];
        self.file.read_exact_at(&mut bytes, self.offset + (start * size) as u64).map_err(|e| {
            CromError::input(&self.path, "the array data", format!("cannot be read: {e}"), "check the file")
        })?;
        out.extend(bytes.chunks_exact(size).map(|b| self.dtype.decode(b)));
        Ok(())
    }

    /// Every element, in storage order.
    pub fn read_all(&self) -> Result<Vec<f64>, CromError> {
        let n = self.shape.iter().product();
        let mut out = Vec::with_capacity(n);
        self.read_into(0, n, &mut out)?;
        Ok(out)
    }
}

/// `descr`, `fortran_order` and `shape` of a header dict.
fn parse_header(h: &str) -> Result<(Dtype, bool, Vec<usize>), String> {
    let value = |key: &str| -> Result<&str, String> {
        let at = h.find(&format!("'{key}'")).ok_or_else(|| format!("has no '{key}' entry ({h:?})"))?;
        let rest = &h[at + key.len() + 2..];
        let colon = rest.find(':').ok_or_else(|| format!("has no value for '{key}'"))?;
        Ok(rest[colon + 1..].trim_start())
    };
    let descr = value("descr")?;
    let descr = descr.trim_start_matches(['\'', '"']);
    let dtype = match descr.get(..3) {
        Some("<f8") => Dtype::F64,
        Some("<f4") => Dtype::F32,
        Some("<i8") => Dtype::I64,
        Some("<i4") => Dtype::I32,
        _ => {
            let shown: String = descr.chars().take_while(|c| *c != '\'' && *c != '"').collect();
            return Err(format!(
                "has element type {shown:?}; readable are little-endian float64, float32, int64, int32"
            ));
        }
    };
    let fortran = value("fortran_order")?.starts_with("True");
    let shape = value("shape")?;
    let inner = shape
        .strip_prefix('(')
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| format!("has a shape that is not a tuple: {shape:?}"))?;
    let dims = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.trim_end_matches('L').parse::<usize>().map_err(|_| format!("has a shape entry {s:?} that is not a count"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok((dtype, fortran, dims))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A version-1 `.npy` file of float64 `data` with `shape`, written by hand as numpy.save
    /// does (header padded with spaces to a multiple of 64 bytes, ending in a newline).
    /// The bytes of a float64 `.npy` of `shape` (version 1.0, as numpy.save writes them).
    pub(crate) fn npy_bytes(shape: &[usize], fortran: bool, data: &[f64]) -> Vec<u8> {
        let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
        let tuple = if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
        let order = if fortran { "True" } else { "False" };
        let mut h = format!("{{'descr': '<f8', 'fortran_order': {order}, 'shape': {tuple}, }}");
        while (10 + h.len() + 1) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend((h.len() as u16).to_le_bytes());
        bytes.extend(h.as_bytes());
        for v in data {
            bytes.extend(v.to_le_bytes());
        }
        bytes
    }

    pub(crate) fn write_npy(path: &Path, shape: &[usize], fortran: bool, data: &[f64]) {
        std::fs::write(path, npy_bytes(shape, fortran, data)).expect("write npy");
    }

    #[test]
    fn header_and_ranges_read_back_exactly() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let p = dir.path().join("a.npy");
        let data: Vec<f64> = (0..12).map(|i| i as f64 * 0.1).collect();
        write_npy(&p, &[3, 4], false, &data);
        let a = Npy::open(&p).expect("open");
        assert_eq!((a.shape.clone(), a.fortran, a.dtype), (vec![3, 4], false, Dtype::F64));
        let mut out = Vec::new();
        a.read_into(5, 3, &mut out).expect("range");
        // Stored and read as f64 bit patterns: exact.
        assert_eq!(out, data[5..8]);
        assert_eq!(a.read_all().expect("all"), data);
    }

    #[test]
    fn a_truncated_file_and_a_foreign_type_are_refused() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let p = dir.path().join("a.npy");
        write_npy(&p, &[3, 4], false, &[0.0; 11]);
        let e = Npy::open(&p).expect_err("short");
        assert!(e.to_string().contains("the header says shape [3, 4]"), "{e}");
        assert_eq!(e.exit_code(), 2);
        let (dtype, ..) = parse_header("{'descr': '<f8', 'fortran_order': True, 'shape': (2,), }").expect("ok");
        assert_eq!(dtype, Dtype::F64);
        let e = parse_header("{'descr': '>f8', 'fortran_order': False, 'shape': (2,), }").expect_err("big-endian");
        assert!(e.contains("\">f8\""), "{e}");
    }
}
