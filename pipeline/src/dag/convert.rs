//! Between the pipeline's [`ColMatrix`] (what HDF5 reads and writes) and faer matrices (what the
//! stages compute with). Both are column-major, so views are free.

use faer::MatRef;

use crate::io::h5::ColMatrix;

/// A faer view of a column-major matrix.
pub(crate) fn view(m: &ColMatrix) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(&m.data, m.rows, m.cols)
}

/// The pressure snapshots `dual` at the points `params` as what a dual approximation is built
/// from, with the contact entries' abscissae `surface` and coordinates across the travel
/// `across` (empty for a curve; the registration maps') and the basis sizes `ms`.
pub(crate) fn training<'a>(
    (dual, params): (&'a ColMatrix, &'a [Vec<f64>]),
    surface: &'a [f64],
    across: &'a [f64],
    ms: &'a [usize],
) -> crom_stages::dual::Training<'a> {
    crom_stages::dual::Training { snapshots: view(dual), params, surface, across, ms }
}

/// Copy a faer matrix into a [`ColMatrix`].
pub(crate) fn to_col(m: MatRef<'_, f64>) -> ColMatrix {
    let mut data = Vec::with_capacity(m.nrows() * m.ncols());
    for j in 0..m.ncols() {
        data.extend(m.col(j).iter().copied());
    }
    ColMatrix { rows: m.nrows(), cols: m.ncols(), data }
}
