//! Tables as Parquet (snappy), readable by `pandas.read_parquet`, and as CSV for humans.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, RecordBatch, StringArray, UInt64Array};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;

use crate::error::CromError;

/// One column of a [`Table`].
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// UTF-8 strings.
    Str(Vec<String>),
    /// Unsigned integers.
    U64(Vec<u64>),
    /// Floats (NaN allowed, e.g. for "not defined").
    F64(Vec<f64>),
}

impl Column {
    fn len(&self) -> usize {
        match self {
            Column::Str(v) => v.len(),
            Column::U64(v) => v.len(),
            Column::F64(v) => v.len(),
        }
    }
}

/// A table: named columns of equal length.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// (name, column) in order.
    pub columns: Vec<(String, Column)>,
}

impl Table {
    /// Append a column.
    pub fn with(mut self, name: &str, col: Column) -> Self {
        self.columns.push((name.to_string(), col));
        self
    }

    /// Number of rows (0 for no columns).
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, |(_, c)| c.len())
    }

    /// Write as Parquet at `path`.
    pub fn write_parquet(&self, path: &Path) -> Result<(), CromError> {
        let n = self.rows();
        assert!(self.columns.iter().all(|(_, c)| c.len() == n), "ragged table");
        let fields: Vec<Field> = self
            .columns
            .iter()
            .map(|(name, c)| {
                let t = match c {
                    Column::Str(_) => DataType::Utf8,
                    Column::U64(_) => DataType::UInt64,
                    Column::F64(_) => DataType::Float64,
                };
                Field::new(name, t, false)
            })
            .collect();
        let arrays: Vec<ArrayRef> = self
            .columns
            .iter()
            .map(|(_, c)| -> ArrayRef {
                match c {
                    Column::Str(v) => Arc::new(StringArray::from(v.clone())),
                    Column::U64(v) => Arc::new(UInt64Array::from(v.clone())),
                    Column::F64(v) => Arc::new(Float64Array::from(v.clone())),
                }
            })
            .collect();
        let fail = |e: &dyn std::fmt::Display| {
            CromError::artifact(
                path,
                format!("Parquet write: {e}"),
                "check free space and permissions of the store directory",
            )
        };
        let schema = Arc::new(Schema::new(fields));
        let batch = RecordBatch::try_new(schema.clone(), arrays).map_err(|e| fail(&e))?;
        let file = std::fs::File::create(path).map_err(|e| CromError::io(path, "creating a Parquet file", e))?;
        let props = WriterProperties::builder().set_compression(Compression::SNAPPY).build();
        let mut w = ArrowWriter::try_new(file, schema, Some(props)).map_err(|e| fail(&e))?;
        w.write(&batch).map_err(|e| fail(&e))?;
        w.close().map_err(|e| fail(&e))?;
        Ok(())
    }

    /// Write as CSV at `path` (floats in shortest round-trip form).
    pub fn write_csv(&self, path: &Path) -> Result<(), CromError> {
        let mut out = String::new();
        let names: Vec<&str> = self.columns.iter().map(|(n, _)| n.as_str()).collect();
        out.push_str(&names.join(","));
        out.push('\n');
        for r in 0..self.rows() {
            let cells: Vec<String> = self
                .columns
                .iter()
                .map(|(_, c)| match c {
                    Column::Str(v) => csv_quote(&v[r]),
                    Column::U64(v) => v[r].to_string(),
                    Column::F64(v) => v[r].to_string(),
                })
                .collect();
            out.push_str(&cells.join(","));
            out.push('\n');
        }
        std::fs::write(path, out).map_err(|e| CromError::io(path, "writing a CSV file", e))
    }
}

fn csv_quote(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}
