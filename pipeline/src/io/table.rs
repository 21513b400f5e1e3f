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

    /// The columns of `other` appended to this table's, for two tables written row by row
    /// together (results and their timings): `None` unless both have the same number of rows
    /// and equal `keys` columns; `other`'s key columns are not repeated.
    pub fn join_rows(mut self, other: Table, keys: &[&str]) -> Option<Table> {
        if self.rows() != other.rows() {
            return None;
        }
        for k in keys {
            let a = self.columns.iter().find(|(n, _)| n == k).map(|(_, c)| c);
            let b = other.columns.iter().find(|(n, _)| n == k).map(|(_, c)| c);
            if a.is_none() || a != b {
                return None;
            }
        }
        self.columns.extend(other.columns.into_iter().filter(|(n, _)| !keys.contains(&n.as_str())));
        Some(self)
    }

    /// The rows of `other` appended below this table's, for tables of the same layout written
    /// apart (one per approximation): `Err` naming the first column whose name or type
    /// differs. An empty table (no columns) takes `other`'s layout.
    pub fn append(&mut self, other: Table) -> Result<(), String> {
        if self.columns.is_empty() {
            *self = other;
            return Ok(());
        }
        if self.columns.len() != other.columns.len() {
            return Err(format!("{} columns against {}", other.columns.len(), self.columns.len()));
        }
        // Check every column before changing any, so a refused table leaves this one whole.
        for ((name, col), (other_name, other_col)) in self.columns.iter().zip(&other.columns) {
            let same = matches!(
                (col, other_col),
                (Column::Str(_), Column::Str(_)) | (Column::U64(_), Column::U64(_)) | (Column::F64(_), Column::F64(_))
            );
            if name != other_name || !same {
                return Err(format!("column `{other_name}` does not match `{name}` (name or type)"));
            }
        }
        for ((_, col), (_, other_col)) in self.columns.iter_mut().zip(other.columns) {
            match (col, other_col) {
                (Column::Str(a), Column::Str(b)) => a.extend(b),
                (Column::U64(a), Column::U64(b)) => a.extend(b),
                (Column::F64(a), Column::F64(b)) => a.extend(b),
                _ => {} // types checked above
            }
        }
        Ok(())
    }

    /// Number of rows (0 for no columns).
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, |(_, c)| c.len())
    }

    /// Write as Parquet at `path`.
    pub fn write_parquet(&self, path: &Path) -> Result<(), CromError> {
        let file = std::fs::File::create(path).map_err(|e| CromError::io(path, "creating a Parquet file", e))?;
        self.write_parquet_to(file).map_err(|e| {
            CromError::artifact(
                path,
                format!("Parquet write: {e}"),
                "check free space and permissions of the store directory",
            )
        })
    }

    /// Write as Parquet (snappy) into any writer, e.g. stdout for `crom ls --format parquet`.
    pub fn write_parquet_to<W: std::io::Write + Send>(&self, out: W) -> Result<(), String> {
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
                // a float column may hold nulls: the undefined values (NaN, infinity) of crom's
                // tables are written as nulls, never as IEEE specials (documented per column in
                // crom_schemas::artifact)
                Field::new(name, t, matches!(c, Column::F64(_)))
            })
            .collect();
        let arrays: Vec<ArrayRef> = self
            .columns
            .iter()
            .map(|(_, c)| -> ArrayRef {
                match c {
                    Column::Str(v) => Arc::new(StringArray::from(v.clone())),
                    Column::U64(v) => Arc::new(UInt64Array::from(v.clone())),
                    Column::F64(v) => Arc::new(v.iter().map(|x| x.is_finite().then_some(*x)).collect::<Float64Array>()),
                }
            })
            .collect();
        let schema = Arc::new(Schema::new(fields));
        let batch = RecordBatch::try_new(schema.clone(), arrays).map_err(|e| e.to_string())?;
        let props = WriterProperties::builder().set_compression(Compression::SNAPPY).build();
        let mut w = ArrowWriter::try_new(out, schema, Some(props)).map_err(|e| e.to_string())?;
        w.write(&batch).map_err(|e| e.to_string())?;
        w.close().map_err(|e| e.to_string())?;
        Ok(())
    }

    /// Write as CSV at `path` (floats in shortest round-trip form).
    pub fn write_csv(&self, path: &Path) -> Result<(), CromError> {
        std::fs::write(path, self.to_csv()).map_err(|e| CromError::io(path, "writing a CSV file", e))
    }

    /// The table as CSV text: a header line, then one line per row.
    pub fn to_csv(&self) -> String {
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
                    // an undefined value is an empty cell, as pandas reads it
                    Column::F64(v) if !v[r].is_finite() => String::new(),
                    Column::F64(v) => v[r].to_string(),
                })
                .collect();
            out.push_str(&cells.join(","));
            out.push('\n');
        }
        out
    }

    /// The table as a JSON array of row objects (`pandas.read_json(..., orient="records")`);
    /// non-finite floats become `null`.
    pub fn to_json_records(&self) -> serde_json::Value {
        let rows = (0..self.rows())
            .map(|r| {
                let obj: serde_json::Map<String, serde_json::Value> = self
                    .columns
                    .iter()
                    .map(|(name, c)| {
                        let v = match c {
                            Column::Str(v) => serde_json::Value::from(v[r].clone()),
                            Column::U64(v) => serde_json::Value::from(v[r]),
                            Column::F64(v) => {
                                serde_json::Number::from_f64(v[r]).map_or(serde_json::Value::Null, Into::into)
                            }
                        };
                        (name.clone(), v)
                    })
                    .collect();
                serde_json::Value::Object(obj)
            })
            .collect();
        serde_json::Value::Array(rows)
    }
}

fn csv_quote(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Read a Parquet file written by [`Table::write_parquet`] (Utf8, UInt64 and Float64 columns; a
/// null float reads as NaN).
pub fn read_parquet(path: &Path) -> Result<Table, CromError> {
    use arrow_array::Array;
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let fail = |e: &dyn std::fmt::Display| {
        CromError::artifact(
            path,
            format!("Parquet read: {e}"),
            "delete the artifact directory and rerun to recompute it",
        )
    };
    let file = std::fs::File::open(path).map_err(|e| CromError::io(path, "opening a Parquet file", e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| fail(&e))?;
    // Columns come from the schema, so a table with no rows still has them.
    let mut table = Table::default();
    for field in builder.schema().fields() {
        let empty = match field.data_type() {
            arrow_schema::DataType::Utf8 => Column::Str(Vec::new()),
            arrow_schema::DataType::UInt64 => Column::U64(Vec::new()),
            arrow_schema::DataType::Float64 => Column::F64(Vec::new()),
            t => return Err(fail(&format!("column {} has unsupported type {t}", field.name()))),
        };
        table.columns.push((field.name().clone(), empty));
    }
    let reader = builder.build().map_err(|e| fail(&e))?;
    for batch in reader {
        let batch = batch.map_err(|e| fail(&e))?;
        let schema = batch.schema();
        for (i, field) in schema.fields().iter().enumerate() {
            let col = batch.column(i);
            let values = if let Some(a) = col.as_any().downcast_ref::<StringArray>() {
                Column::Str((0..a.len()).map(|k| a.value(k).to_string()).collect())
            } else if let Some(a) = col.as_any().downcast_ref::<UInt64Array>() {
                Column::U64(a.values().to_vec())
            } else if let Some(a) = col.as_any().downcast_ref::<Float64Array>() {
                Column::F64((0..a.len()).map(|k| if a.is_null(k) { f64::NAN } else { a.value(k) }).collect())
            } else {
                return Err(fail(&format!("column {} has unsupported type {}", field.name(), field.data_type())));
            };
            match table.columns.iter_mut().find(|(n, _)| n == field.name()) {
                Some((_, Column::Str(v))) => {
                    if let Column::Str(w) = values {
                        v.extend(w)
                    }
                }
                Some((_, Column::U64(v))) => {
                    if let Column::U64(w) = values {
                        v.extend(w)
                    }
                }
                Some((_, Column::F64(v))) => {
                    if let Column::F64(w) = values {
                        v.extend(w)
                    }
                }
                None => table.columns.push((field.name().clone(), values)),
            }
        }
    }
    Ok(table)
}

impl Table {
    /// A float column by name.
    pub fn f64s(&self, name: &str) -> Option<&[f64]> {
        self.columns.iter().find_map(|(n, c)| match c {
            Column::F64(v) if n == name => Some(v.as_slice()),
            _ => None,
        })
    }

    /// An integer column by name.
    pub fn u64s(&self, name: &str) -> Option<&[u64]> {
        self.columns.iter().find_map(|(n, c)| match c {
            Column::U64(v) if n == name => Some(v.as_slice()),
            _ => None,
        })
    }

    /// A string column by name.
    pub fn strs(&self, name: &str) -> Option<&[String]> {
        self.columns.iter().find_map(|(n, c)| match c {
            Column::Str(v) if n == name => Some(v.as_slice()),
            _ => None,
        })
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn append_stacks_rows_and_refuses_another_layout() {
        let t = |name: &str, v: Vec<f64>| {
            Table::default()
                .with("approximation", Column::Str(vec![name.to_string(); v.len()]))
                .with("m", Column::F64(v))
        };
        let mut all = Table::default();
        all.append(t("pod", vec![1.0, 2.0])).expect("first");
        all.append(t("cpg", vec![3.0])).expect("same layout");
        assert_eq!(all.rows(), 3);
        assert_eq!(all.strs("approximation").expect("column"), ["pod", "pod", "cpg"]);
        assert_eq!(all.f64s("m").expect("column"), [1.0, 2.0, 3.0]);
        let other =
            Table::default().with("approximation", Column::Str(vec!["x".into()])).with("m", Column::U64(vec![1]));
        assert!(all.append(other).expect_err("a u64 m").contains("`m`"));
        assert_eq!(all.rows(), 3);
    }

    use super::*;
    use arrow_array::Array;

    /// Undefined floats (NaN, ±infinity) are written as Parquet nulls — checked with the arrow
    /// reader itself, not with `read_parquet` — read back as NaN, and written as empty CSV
    /// cells; finite values round-trip exactly.
    #[test]
    fn undefined_floats_are_nulls() {
        let v = vec![1.5, f64::NAN, f64::INFINITY, -0.25, f64::NEG_INFINITY];
        let t = Table::default().with("x", Column::F64(v.clone())).with("n", Column::U64(vec![1, 2, 3, 4, 5]));
        let dir = crate::scratch::tempdir().expect("tempdir");
        let path = dir.path().join("t.parquet");
        t.write_parquet(&path).expect("write");
        let file = std::fs::File::open(&path).expect("open");
        let reader = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
            .expect("parquet")
            .build()
            .expect("reader");
        let batches: Vec<RecordBatch> = reader.map(|b| b.expect("batch")).collect();
        let col = batches[0].column(0).as_any().downcast_ref::<Float64Array>().expect("float column");
        let nulls: Vec<bool> = (0..col.len()).map(|k| col.is_null(k)).collect();
        assert_eq!(nulls, [false, true, true, false, true]);
        assert_eq!((col.value(0), col.value(3)), (1.5, -0.25));
        assert_eq!(batches[0].column(1).null_count(), 0);
        let back = read_parquet(&path).expect("read");
        let x = back.f64s("x").expect("x");
        assert_eq!((x[0], x[3]), (1.5, -0.25));
        assert!(x[1].is_nan() && x[2].is_nan() && x[4].is_nan());
        assert_eq!(t.to_csv(), "x,n\n1.5,1\n,2\n,3\n-0.25,4\n,5\n");
    }
}
