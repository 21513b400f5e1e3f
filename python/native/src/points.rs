//! The points a Python caller gives, checked before anything is solved: every component a
//! finite number, inside the training domain `[min, max]` unless extrapolation is allowed (then
//! the answer is flagged `extrapolated`). Whether every component is given once by name is
//! checked by `Model::solve`, which reports a mismatch to the Python layer (`crom_data.rom`) to
//! word, as it knows the keyword arguments as given; here a point is a list of values in the
//! model's order. The rules are `crom query`'s (`crom_pipeline::query::points`);
//! the messages name the Python argument to change instead of the command-line flag.

/// A refused point: the message, and whether it is refused for lying outside the domain
/// (`OutsideDomain`) rather than for being malformed (`InvalidPoint`).
#[derive(Debug)]
pub(crate) struct PointError {
    pub(crate) message: String,
    pub(crate) outside: bool,
}

/// The model's parameter: component names and training domain.
#[derive(Debug, Clone)]
pub(crate) struct Bounds {
    pub(crate) names: Vec<String>,
    pub(crate) min: Vec<f64>,
    pub(crate) max: Vec<f64>,
}

fn at(row: Option<usize>) -> String {
    row.map_or_else(|| "the point".to_string(), |j| format!("row {j} of the points"))
}

impl Bounds {
    /// `value` (its repr) of component `c` is not a number.
    pub(crate) fn not_a_number(&self, c: usize, value: &str) -> PointError {
        let name = self.names.get(c).map_or("?", String::as_str);
        PointError {
            message: format!("{name} = {value} is not a number; give {name} as a float, e.g. {name}={}", self.mid(c)),
            outside: false,
        }
    }

    /// A points buffer whose length does not fit `n` rows of the components.
    pub(crate) fn bad_buffer(&self, bytes: usize, n: usize) -> PointError {
        PointError {
            message: format!(
                "{bytes} bytes of points for {n} rows of {} float64 components ({}); pass an (n, {}) float64 array",
                self.names.len(),
                self.names.join(", "),
                self.names.len()
            ),
            outside: false,
        }
    }

    fn mid(&self, c: usize) -> f64 {
        0.5 * (self.min.get(c).copied().unwrap_or(0.0) + self.max.get(c).copied().unwrap_or(0.0))
    }

    /// Check one point (`row`: its row in a batch, for messages): `Ok(extrapolated)`.
    pub(crate) fn check(
        &self,
        point: &[f64],
        row: Option<usize>,
        allow_extrapolation: bool,
    ) -> Result<bool, PointError> {
        if point.len() != self.names.len() {
            return Err(PointError {
                message: format!(
                    "{} has {} components, the model has {} ({}); give one value per component",
                    at(row),
                    point.len(),
                    self.names.len(),
                    self.names.join(", ")
                ),
                outside: false,
            });
        }
        let mut outside = false;
        for (c, &v) in point.iter().enumerate() {
            let (name, lo, hi) = (&self.names[c], self.min[c], self.max[c]);
            if !v.is_finite() {
                return Err(PointError {
                    message: format!(
                        "{}: {name} = {v} is not a finite number; give a finite {name} in [{lo}, {hi}]",
                        at(row)
                    ),
                    outside: false,
                });
            }
            if v < lo || v > hi {
                if !allow_extrapolation {
                    return Err(PointError {
                        message: format!(
                            "{}: {name} = {v} is outside the training domain [{lo}, {hi}] of the model; give {name} in \
                             [{lo}, {hi}], or pass allow_extrapolation=True to solve it anyway (the answer is flagged \
                             extrapolated)",
                            at(row)
                        ),
                        outside: true,
                    });
                }
                outside = true;
            }
        }
        Ok(outside)
    }
}
