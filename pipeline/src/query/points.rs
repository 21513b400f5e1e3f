//! The points of a query: `--at NAME=VALUE[,NAME=VALUE…]` or a points file (CSV with a header
//! line, or Parquet), checked against the model's parameter before anything is solved.
//!
//! Every component of the parameter must be given exactly once, by its name, as a finite
//! number; a points file's columns must be exactly the parameter's names (in any order). A
//! point outside the training domain `[min, max]` of a component is refused, unless the user
//! asks for extrapolation (`--allow-extrapolation`): then it is solved and its row says
//! `extrapolated = true`. Every refusal is a usage error (exit 2) that names the point, the
//! component or column, and the fix.

use std::path::Path;

use crate::error::CromError;
use crate::io::table::{read_parquet, Column};

/// The parameter a model answers for: component names and the training domain.
#[derive(Debug, Clone, PartialEq)]
pub struct Domain {
    /// Component names, in the model's order.
    pub names: Vec<String>,
    /// Lower bounds.
    pub min: Vec<f64>,
    /// Upper bounds.
    pub max: Vec<f64>,
}

fn usage(message: String, fix: String) -> CromError {
    CromError::Usage { message, fix }
}

impl Domain {
    fn listing(&self) -> String {
        self.names
            .iter()
            .zip(self.min.iter().zip(&self.max))
            .map(|(n, (a, b))| format!("{n} in [{a}, {b}]"))
            .collect::<Vec<_>>()
            .join(", ")
    }

    fn example(&self) -> String {
        let parts: Vec<String> = self
            .names
            .iter()
            .zip(self.min.iter().zip(&self.max))
            .map(|(n, (a, b))| format!("{n}={}", 0.5 * (a + b)))
            .collect();
        parts.join(",")
    }

    /// The point of `--at` (e.g. `d_x=1.2345` or `d_x=1.2,d_y=0.03`).
    pub fn parse_at(&self, at: &str) -> Result<Vec<f64>, CromError> {
        let fix = format!("give every parameter once as NAME=VALUE, comma-separated, e.g. --at {}", self.example());
        let mut point = vec![None; self.names.len()];
        for item in at.split(',') {
            let Some((name, value)) = item.split_once('=') else {
                return Err(usage(format!("--at `{at}`: `{item}` is not NAME=VALUE"), fix));
            };
            let name = name.trim();
            let Some(c) = self.names.iter().position(|n| n == name) else {
                return Err(usage(
                    format!("--at `{at}`: the model has no parameter `{name}` (its parameters: {})", self.listing()),
                    fix,
                ));
            };
            if point[c].is_some() {
                return Err(usage(format!("--at `{at}`: `{name}` is given twice"), fix));
            }
            let v: f64 = value.trim().parse().map_err(|_| {
                usage(format!("--at `{at}`: `{name}` = `{}` is not a number", value.trim()), fix.clone())
            })?;
            point[c] = Some(v);
        }
        let missing: Vec<&str> =
            self.names.iter().zip(&point).filter(|(_, v)| v.is_none()).map(|(n, _)| n.as_str()).collect();
        if !missing.is_empty() {
            return Err(usage(format!("--at `{at}`: no value for {}", missing.join(", ")), fix));
        }
        Ok(point.into_iter().flatten().collect())
    }

    /// The points of a file: `.csv` (a header line of names, then one point per line) or
    /// `.parquet` (one float or integer column per component).
    pub fn read_points(&self, path: &Path) -> Result<Vec<Vec<f64>>, CromError> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        let columns: Vec<(String, Vec<f64>)> = match ext {
            "csv" => read_csv(path)?,
            "parquet" => {
                let t = read_parquet(path).map_err(|e| {
                    let why = match e {
                        CromError::Artifact { message, .. } => message,
                        other => other.to_string(),
                    };
                    usage(format!("--points {}: {why}", path.display()), "give a Parquet file of float columns".into())
                })?;
                t.columns
                    .into_iter()
                    .map(|(n, c)| match c {
                        Column::F64(v) => Ok((n, v)),
                        Column::U64(v) => Ok((n, v.into_iter().map(|x| x as f64).collect())),
                        Column::Str(_) => Err(usage(
                            format!("{}: column `{n}` holds strings, not numbers", path.display()),
                            "give the parameter values as float columns".into(),
                        )),
                    })
                    .collect::<Result<_, _>>()?
            }
            _ => {
                return Err(usage(
                    format!("--points {}: not a .csv or .parquet file", path.display()),
                    "give a CSV file with a header line, or a Parquet file".into(),
                ))
            }
        };
        let names: Vec<&str> = columns.iter().map(|(n, _)| n.trim()).collect();
        let fix = format!(
            "give exactly one column per parameter, named {} (file columns: {})",
            self.names.join(", "),
            names.join(", ")
        );
        let mut order = Vec::with_capacity(self.names.len());
        for n in &self.names {
            match names.iter().filter(|m| *m == n).count() {
                1 => order.push(names.iter().position(|m| m == n).unwrap_or(0)),
                0 => return Err(usage(format!("{}: no column `{n}`", path.display()), fix)),
                _ => return Err(usage(format!("{}: column `{n}` appears twice", path.display()), fix)),
            }
        }
        for n in &names {
            if !self.names.iter().any(|m| m == n) {
                return Err(usage(format!("{}: column `{n}` is not a parameter of the model", path.display()), fix));
            }
        }
        let rows = columns.first().map_or(0, |(_, v)| v.len());
        if rows == 0 {
            return Err(usage(format!("{}: no points", path.display()), "give at least one row".into()));
        }
        Ok((0..rows).map(|r| order.iter().map(|&c| columns[c].1[r]).collect()).collect())
    }

    /// Check a point: finite values inside the domain (outside: refused, or `true` when
    /// `extrapolate` allows it). `at` names the point in messages.
    pub fn check(&self, point: &[f64], at: &str, extrapolate: bool) -> Result<bool, CromError> {
        let mut outside = false;
        for (c, &v) in point.iter().enumerate() {
            let (name, lo, hi) = (&self.names[c], self.min[c], self.max[c]);
            if !v.is_finite() {
                return Err(usage(format!("{at}: {name} = {v} is not a finite number"), "give finite values".into()));
            }
            if v < lo || v > hi {
                if !extrapolate {
                    return Err(usage(
                        format!("{at}: {name} = {v} is outside the training domain [{lo}, {hi}] of the model"),
                        format!(
                            "give {name} in [{lo}, {hi}], or add --allow-extrapolation to solve it anyway (its row is flagged extrapolated)"
                        ),
                    ));
                }
                outside = true;
            }
        }
        Ok(outside)
    }
}

/// A CSV file of numbers with a header line: (column name, values).
fn read_csv(path: &Path) -> Result<Vec<(String, Vec<f64>)>, CromError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        usage(format!("--points {}: cannot read it: {e}", path.display()), "give an existing, readable file".into())
    })?;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        return Err(usage(format!("{}: empty file", path.display()), "give a header line of parameter names".into()));
    };
    let mut cols: Vec<(String, Vec<f64>)> = header.split(',').map(|n| (n.trim().to_string(), Vec::new())).collect();
    for (i, line) in lines {
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != cols.len() {
            return Err(usage(
                format!("{}:{}: {} values, the header has {} columns", path.display(), i + 1, cells.len(), cols.len()),
                "give one value per column on every line".into(),
            ));
        }
        for ((name, col), cell) in cols.iter_mut().zip(cells) {
            let v: f64 = cell.trim().parse().map_err(|_| {
                usage(
                    format!("{}:{}: column `{name}`: `{}` is not a number", path.display(), i + 1, cell.trim()),
                    "give numbers (e.g. 1.25 or 3e-2)".into(),
                )
            })?;
            col.push(v);
        }
    }
    Ok(cols)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn domain() -> Domain {
        Domain { names: vec!["d_x".into(), "d_y".into()], min: vec![0.0, -0.1], max: vec![3.0, 0.1] }
    }

    fn message(e: CromError) -> String {
        assert_eq!(e.exit_code(), 2, "{e}");
        e.to_string()
    }

    #[test]
    fn at_takes_every_component_once_by_name() {
        let d = domain();
        assert_eq!(d.parse_at("d_y=0.03, d_x=1.2345").expect("ok"), vec![1.2345, 0.03]);
        assert!(message(d.parse_at("d_x=1").expect_err("missing")).contains("no value for d_y"));
        assert!(message(d.parse_at("d_x=1,d_z=2").expect_err("unknown")).contains("no parameter `d_z`"));
        assert!(message(d.parse_at("d_x=1,d_x=2").expect_err("twice")).contains("given twice"));
        assert!(message(d.parse_at("d_x:1,d_y=0").expect_err("malformed")).contains("not NAME=VALUE"));
        assert!(message(d.parse_at("d_x=abc,d_y=0").expect_err("nan")).contains("not a number"));
    }

    #[test]
    fn points_outside_the_domain_are_refused_or_flagged() {
        let d = domain();
        assert!(!d.check(&[1.0, 0.0], "p", false).expect("inside"));
        assert!(!d.check(&[0.0, 0.1], "p", false).expect("on the boundary"));
        assert!(message(d.check(&[3.5, 0.0], "p", false).expect_err("outside")).contains("outside the training domain"));
        assert!(d.check(&[3.5, 0.0], "p", true).expect("allowed"));
        assert!(message(d.check(&[f64::NAN, 0.0], "p", true).expect_err("nan")).contains("not a finite number"));
        assert!(message(d.check(&[f64::INFINITY, 0.0], "p", true).expect_err("inf")).contains("not a finite number"));
    }

    #[test]
    fn points_files_need_exactly_the_parameter_columns() {
        let d = domain();
        let tmp = crate::scratch::tempdir().expect("tempdir");
        let write = |name: &str, text: &str| {
            let p = tmp.path().join(name);
            std::fs::write(&p, text).expect("write");
            p
        };
        let ok = write("ok.csv", "d_y,d_x\n0.01,1.5\n-0.02,2.5\n");
        assert_eq!(d.read_points(&ok).expect("ok"), vec![vec![1.5, 0.01], vec![2.5, -0.02]]);
        let missing = write("m.csv", "d_x\n1.5\n");
        assert!(message(d.read_points(&missing).expect_err("missing")).contains("no column `d_y`"));
        let extra = write("e.csv", "d_x,d_y,id\n1.5,0,1\n");
        assert!(message(d.read_points(&extra).expect_err("extra")).contains("column `id`"));
        let short = write("s.csv", "d_x,d_y\n1.5\n");
        assert!(message(d.read_points(&short).expect_err("short")).contains("s.csv:2"));
        let text = write("t.csv", "d_x,d_y\n1.5,x\n");
        assert!(message(d.read_points(&text).expect_err("text")).contains("column `d_y`"));
        let other = write("p.txt", "d_x,d_y\n");
        assert!(message(d.read_points(&other).expect_err("ext")).contains("not a .csv or .parquet"));
    }
}
