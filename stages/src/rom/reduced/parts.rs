//! The reduced model as named flat arrays ([`ModelParts`]): what a file stores, and the model
//! rebuilt from them ([`ReducedModel::from_parts`]) exactly — the same bits in every array the
//! online solve reads, so a loaded model answers every query with the same bits as the model it
//! was written from.
//!
//! Layout (`r_u`, `r_l`: primal and dual ranks; `nc`: potential-contact nodes; `t = 1 + dim`:
//! affine terms of the lift, `dim` the parameter's components; matrices row- or column-major as
//! stated, flattened):
//!
//! | name | type | length | meaning |
//! |---|---|---|---|
//! | `khat_l` | f64 | `r_u²` | Cholesky factor `L` of `K̂ = Φᵀ K Φ`, column-major |
//! | `u_of_y` | f64 | `r_u²` | `L⁻ᵀ`, column-major: `û = L⁻ᵀ y` |
//! | `weights` | f64 | `nc` | tributary lengths of the contact nodes |
//! | `theta_start` | u64 | `nc + 1` | `Θ[:, :r_l]` by node (CSR): row starts |
//! | `theta_column`, `theta_value` | u64, f64 | nnz | its column indices and values |
//! | `warm_points` | f64 | `n_warm · dim` | warm-start sample parameters, row-major |
//! | `warm_set_start`, `warm_set` | u64 | `n_warm + 1`, … | their active sets (CSR) |
//! | `warm_y` | f64 | `n_warm · r_u` or 0 | Type-2: their answers `y` |
//!
//! Type-1 (`surface = 0`, fixed pairs): `cphi` (`nc · r_u`, `C Ψ` row-major), `cu0`
//! (`t · nc`, affine terms of `C u0(μ) + g0(μ)`), `paired` (u64 0/1, `nc`), `chat`
//! (`r_l · r_u`, `Ĉ` row-major), `ghat` (`t · r_l`, affine terms of `ĝ0(μ)`), `cwc`
//! (`nc²`, `C W Cᵀ`).
//!
//! Type-2 (`surface = 1`, node-to-segment; `nn = ns + nm` contact nodes, slaves first):
//! `x_ref` (`2 nn`, reference positions), `slave_fixed` (u64 0/1, `ns`), `phi_c` (`2 nn · r_u`,
//! `Ψ` on the contact dofs, row-major), `a_terms` (`t · 2 nn`, affine terms of the lift on the
//! contact dofs), `supp` (u64, the slaves the reduced constraints sum over), `quad` (`nc`, a
//! sampled surface's quadrature weights, absent — length 0 — for the full surface), `w_c`
//! (`(2 nn)²`, the compliance on the contact dofs, row-major).
//!
//! Type-2 in 3-D (`surface = 2`, node-to-surface; `nn = ns + nm` contact nodes, slaves first):
//! `x_ref` (`3 nn`), `slave_fixed`, `phi_c` (`3 nn · r_u`), `a_terms` (`t · 3 nn`), `supp` as for
//! node-to-segment; `facets` (u64, `4 · n_facets`, master-local node ids, outward), `plane_axis`
//! (u64) and `plane_at` (f64), one per symmetry plane, `plane_tol` (f64, 1 value: the distance
//! that puts a node on a plane); `w_c` (`(3 nn)²` or 0 values: the compliance on the contact
//! dofs, kept when at most 4M entries, else the indicator's residual is NaN); `quad` as for
//! node-to-segment, absent (not written) for the full surface.
//!
//! A registered dual basis rebuilt at each query point (`reg_map` > 0; then `r_dual` is 0, the
//! `theta_*` arrays are empty, the `warm_*` arrays hold primal starts only — every active set
//! empty, [`ReducedModel::with_primal_starts`] — and [`ReducedModel::dual_at`] sets `Θ(μ)` before
//! each query; [`crate::dual::registration::RegisteredArrays`] describes the arrays):
//!
//! | name | type | length | meaning |
//! |---|---|---|---|
//! | `reg_map` | scalar | | 1: translate by `μ_1`, whole-node shifts; 2: translate, linear interpolation; 3: moments map |
//! | `reg_refine` | scalar | | reference cells per finest node spacing (2, 3) |
//! | `reg_len`, `reg_generators`, `reg_m` | scalars | | reference grid length, generators stored, most generators per query |
//! | `reg_surface` | f64 | `nc` | abscissa of each contact node (reference configuration) |
//! | `reg_table` | f64 | `3 · count` or 0 | moments map: `(μ_j, c_j, a_j)` sorted by `μ_j`; over `reg_dims` components `(μ_j1, …, μ_jd, c_j, a_j)` in the fit's order, `(d + 2) · count` |
//! | `reg_dims` | scalar | | the moments map's parameter components, written only when more than one (absent: 1) |
//! | `reg_grid` | f64 | 2 | reference grid start and step |
//! | `reg_modes` | f64 | `reg_len · reg_generators` | reference generators, column-major |
//! | `reg_travels` | f64 | `reg_generators` or 0 | neighbours basis: each generator's travel `c_j` (absent for CPG) |
//! | `reg_weight` | f64 | 1 or 0 | neighbours basis: the weight `w` of the per-query order |
//! | `reg_second`, `reg_second_scale` | f64 | `reg_generators` and 1, or 0 | neighbours basis over a vector parameter: each generator's second parameter component, and the scale of their distances (absent over one component) |
//! | `reg_across` | f64 | `nc` or 0 | a 3-D contact area: each contact node's coordinate across the travel (y), whose lines the map acts along (absent for a contact curve) |
//! | `reg_quad` | f64 | `reg_len` or 0 | a reduced quadrature of the contact constraints in the reference frame: each reference node's weight, non-negative (absent: every supported slave) |
//!
//! Scalars: `surface`, `r_primal`, `r_dual`, `n_contact`, `lift_terms`, `warm_dim`, and for
//! Type-2 `n_slaves`, `n_masters`. `Θ` by column and the per-node norms of `phi_c` are derived
//! on load (by the same code that derives them offline). No array's length depends on the
//! number of dofs of the full-order model.

use super::build::{csr, node_norms, Compressed};
use super::{ReducedModel, RomError, SurfaceData, WarmStarts};
use crate::dual::registration::{Registered, RegisteredArrays};
use crate::dual::{Interpolation, MapKind};

/// A reduced model as named arrays (see the module doc for the names and shapes).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelParts {
    /// Integer scalars.
    pub scalars: Vec<(&'static str, u64)>,
    /// Float arrays.
    pub floats: Vec<(&'static str, Vec<f64>)>,
    /// Integer arrays.
    pub ints: Vec<(&'static str, Vec<u64>)>,
}

impl ModelParts {
    /// Names of the integer scalars, in the order [`ReducedModel::parts`] gives them.
    pub const SCALARS: [&str; 14] = [
        "surface",
        "r_primal",
        "r_dual",
        "n_contact",
        "lift_terms",
        "warm_dim",
        "n_slaves",
        "n_masters",
        "reg_map",
        "reg_refine",
        "reg_len",
        "reg_generators",
        "reg_m",
        "reg_dims",
    ];
    /// Names of the float arrays.
    pub const FLOATS: [&str; 28] = [
        "khat_l",
        "u_of_y",
        "weights",
        "theta_value",
        "warm_points",
        "warm_y",
        "cphi",
        "cu0",
        "chat",
        "ghat",
        "cwc",
        "x_ref",
        "phi_c",
        "a_terms",
        "quad",
        "w_c",
        "plane_at",
        "plane_tol",
        "reg_surface",
        "reg_table",
        "reg_grid",
        "reg_modes",
        "reg_travels",
        "reg_weight",
        "reg_across",
        "reg_second",
        "reg_second_scale",
        "reg_quad",
    ];
    /// Names of the integer arrays.
    pub const INTS: [&str; 9] = [
        "theta_start",
        "theta_column",
        "warm_set_start",
        "warm_set",
        "paired",
        "slave_fixed",
        SUPP,
        "facets",
        "plane_axis",
    ];

    /// The scalar `name` (0 when absent).
    pub fn scalar(&self, name: &str) -> u64 {
        self.scalars.iter().find(|(n, _)| *n == name).map_or(0, |(_, v)| *v)
    }

    /// The float array `name` (empty when absent).
    pub fn float(&self, name: &str) -> &[f64] {
        self.floats.iter().find(|(n, _)| *n == name).map_or(&[], |(_, v)| v.as_slice())
    }

    /// The integer array `name` (empty when absent).
    pub fn int(&self, name: &str) -> &[u64] {
        self.ints.iter().find(|(n, _)| *n == name).map_or(&[], |(_, v)| v.as_slice())
    }
}

/// Type-2's integer array of supported slaves.
const SUPP: &str = "supp";

fn flat(terms: &[Vec<f64>]) -> Vec<f64> {
    terms.iter().flatten().copied().collect()
}

fn flags(b: &[bool]) -> Vec<u64> {
    b.iter().map(|&x| u64::from(x)).collect()
}

fn idx(v: &[usize]) -> Vec<u64> {
    v.iter().map(|&x| x as u64).collect()
}

/// A refused part: which array, and what is wrong with it.
fn bad(name: &str, what: String) -> RomError {
    RomError::Parts(format!("`{name}`: {what}"))
}

/// `parts.float(name)`, checked to hold `len` values.
fn floats_of(p: &ModelParts, name: &str, len: usize) -> Result<Vec<f64>, RomError> {
    let v = p.float(name);
    if v.len() != len {
        return Err(bad(name, format!("{} values, expected {len}", v.len())));
    }
    Ok(v.to_vec())
}

/// `parts.float(name)` as one optional value: 0 where absent, refused with more than one.
fn optional_float(p: &ModelParts, name: &str) -> Result<f64, RomError> {
    match p.float(name) {
        [] => Ok(0.0),
        [v] => Ok(*v),
        v => Err(bad(name, format!("{} values, expected 1", v.len()))),
    }
}

/// `parts.int(name)` as indices, checked to hold `len` values (any length when `None`), each
/// below `bound`.
fn indices_of(p: &ModelParts, name: &str, len: Option<usize>, bound: usize) -> Result<Vec<usize>, RomError> {
    let v = p.int(name);
    if let Some(len) = len.filter(|&l| l != v.len()) {
        return Err(bad(name, format!("{} values, expected {len}", v.len())));
    }
    v.iter()
        .map(|&x| {
            usize::try_from(x).ok().filter(|&x| x < bound).ok_or_else(|| bad(name, format!("{x} is not below {bound}")))
        })
        .collect()
}

/// `parts.int(name)` as row starts of a compressed layout of `rows` rows over `entries`
/// entries: `rows + 1` non-decreasing values from 0 to `entries`.
fn starts_of(p: &ModelParts, name: &str, rows: usize, entries: usize) -> Result<Vec<usize>, RomError> {
    let s = indices_of(p, name, Some(rows + 1), entries + 1)?;
    if s[0] != 0 || s[rows] != entries || s.windows(2).any(|w| w[0] > w[1]) {
        return Err(bad(name, format!("not the row starts of {rows} rows over {entries} entries")));
    }
    Ok(s)
}

/// `terms · n` values split into `terms` rows of `n`.
fn split(v: Vec<f64>, terms: usize) -> Vec<Vec<f64>> {
    let n = v.len() / terms.max(1);
    if n == 0 {
        return vec![Vec::new(); terms];
    }
    v.chunks(n).map(<[f64]>::to_vec).collect()
}

impl ReducedModel {
    /// The model as named arrays (see the module doc).
    pub fn parts(&self) -> ModelParts {
        let lib = &self.warm_starts;
        let mut set_start = vec![0u64];
        let mut sets = Vec::new();
        for s in &lib.sets {
            sets.extend(idx(s));
            set_start.push(sets.len() as u64);
        }
        let mut scalars = vec![
            ("surface", 0),
            ("r_primal", self.r_u as u64),
            ("r_dual", self.r_l as u64),
            ("n_contact", self.n_contact as u64),
            ("lift_terms", 0),
            ("warm_dim", lib.dim as u64),
        ];
        let mut floats = vec![
            ("khat_l", self.khat_l.clone()),
            ("u_of_y", self.u_of_y.clone()),
            ("weights", self.weights.clone()),
            ("theta_value", self.by_node.2.clone()),
            ("warm_points", lib.points.clone()),
            ("warm_y", flat(&lib.ys)),
        ];
        let mut ints = vec![
            ("theta_start", idx(&self.by_node.0)),
            ("theta_column", idx(&self.by_node.1)),
            ("warm_set_start", set_start),
            ("warm_set", sets),
        ];
        match &self.surf {
            SurfaceData::Nts3(d) => {
                scalars[0].1 = 2;
                scalars[4].1 = d.a_terms.len() as u64;
                scalars.extend([("n_slaves", d.ns as u64), ("n_masters", d.nm as u64)]);
                let (planes, tol) = d.master.planes();
                floats.extend([
                    ("x_ref", d.x_ref.iter().flatten().copied().collect()),
                    ("phi_c", d.phi_c.clone()),
                    ("a_terms", flat(&d.a_terms)),
                    ("w_c", d.w_c.clone().unwrap_or_default()),
                    ("plane_at", planes.iter().map(|p| p.at).collect()),
                    ("plane_tol", vec![tol]),
                ]);
                if let Some(q) = &d.quad {
                    // absent for the full surface, so its file keeps its layout
                    floats.push(("quad", q.clone()));
                }
                ints.extend([
                    ("slave_fixed", flags(&d.slave_fixed)),
                    (SUPP, idx(&d.supp)),
                    ("facets", d.master.facets().iter().flatten().map(|&v| v as u64).collect()),
                    ("plane_axis", planes.iter().map(|p| p.axis as u64).collect()),
                ]);
            }
            SurfaceData::Fixed { cphi, cu0, paired, chat, ghat, cwc } => {
                scalars[4].1 = cu0.len() as u64;
                floats.extend([
                    ("cphi", cphi.clone()),
                    ("cu0", flat(cu0)),
                    ("chat", chat.clone()),
                    ("ghat", flat(ghat)),
                    ("cwc", cwc.clone()),
                ]);
                ints.push(("paired", flags(paired)));
            }
            SurfaceData::Nts { ns, nm, x_ref, slave_fixed, phi_c, a_terms, supp, quad, w_c, .. } => {
                scalars[0].1 = 1;
                scalars[4].1 = a_terms.len() as u64;
                scalars.extend([("n_slaves", *ns as u64), ("n_masters", *nm as u64)]);
                floats.extend([
                    ("x_ref", x_ref.iter().flatten().copied().collect()),
                    ("phi_c", phi_c.clone()),
                    ("a_terms", flat(a_terms)),
                    ("quad", quad.clone().unwrap_or_default()),
                    ("w_c", w_c.clone()),
                ]);
                ints.extend([("slave_fixed", flags(slave_fixed)), (SUPP, idx(supp))]);
            }
        }
        if let Some((a, m)) = self.registered_dual().and_then(|(b, m)| Some((b.arrays()?, m))) {
            let (map, refine) = match a.kind {
                MapKind::Translate { interpolation: Interpolation::Nodes } => (1, 0),
                MapKind::Translate { interpolation: Interpolation::Linear { refine } } => (2, refine),
                MapKind::Moments { refine } => (3, refine),
            };
            scalars.extend([
                ("reg_map", map),
                ("reg_refine", refine as u64),
                ("reg_len", a.len as u64),
                ("reg_generators", a.generators as u64),
                ("reg_m", m as u64),
            ]);
            if a.dims > 1 {
                // absent for one component, so a model over one keeps its layout
                scalars.push(("reg_dims", a.dims as u64));
            }
            if !a.across.is_empty() {
                floats.push(("reg_across", a.across));
            }
            floats.extend([
                ("reg_surface", a.surface),
                ("reg_table", a.table),
                ("reg_grid", a.grid.to_vec()),
                ("reg_modes", a.modes),
            ]);
            if !a.travels.is_empty() {
                floats.extend([("reg_travels", a.travels), ("reg_weight", vec![a.weight])]);
            }
            if !a.seconds.is_empty() {
                floats.extend([("reg_second", a.seconds), ("reg_second_scale", vec![a.second_scale])]);
            }
            if let Some(q) = self.per_query.as_ref().and_then(|d| d.quad.as_ref()) {
                floats.push(("reg_quad", q.to_vec()));
            }
        }
        ModelParts { scalars, floats, ints }
    }

    /// The registered dual basis stored in `p` (`reg_map` > 0) with its most generators per
    /// query, checked (a moments table over several components against the `warm_dim`
    /// components of the warm starts' points, where there are any); `None` where the dual basis
    /// is fixed.
    fn registered_of(p: &ModelParts, warm_dim: usize) -> Result<Option<(Registered, usize)>, RomError> {
        let size = |name: &str| -> Result<usize, RomError> {
            usize::try_from(p.scalar(name)).ok().filter(|&v| v <= 1 << 32).ok_or_else(|| bad(name, "too large".into()))
        };
        let refine = size("reg_refine")?;
        let kind = match p.scalar("reg_map") {
            0 => return Ok(None),
            1 => MapKind::Translate { interpolation: Interpolation::Nodes },
            2 => MapKind::Translate { interpolation: Interpolation::Linear { refine } },
            3 => MapKind::Moments { refine },
            k => return Err(bad("reg_map", format!("{k}: expected 0 to 3"))),
        };
        let grid = p.float("reg_grid");
        let [start, step] = grid else {
            return Err(bad("reg_grid", format!("{} values, expected 2", grid.len())));
        };
        let arrays = RegisteredArrays {
            kind,
            surface: p.float("reg_surface").to_vec(),
            across: p.float("reg_across").to_vec(),
            table: p.float("reg_table").to_vec(),
            dims: match p.scalar("reg_dims") {
                0 => 1,
                d => usize::try_from(d).map_err(|_| bad("reg_dims", format!("{d}: too large")))?,
            },
            grid: [*start, *step],
            len: size("reg_len")?,
            modes: p.float("reg_modes").to_vec(),
            generators: size("reg_generators")?,
            travels: p.float("reg_travels").to_vec(),
            weight: optional_float(p, "reg_weight")?,
            seconds: p.float("reg_second").to_vec(),
            second_scale: optional_float(p, "reg_second_scale")?,
        };
        let basis = Registered::from_arrays(&arrays).map_err(|e| bad("reg_modes", e.to_string()))?;
        // (a model without warm starts has no points to compare with: `warm_dim` 0)
        if arrays.dims > 1 && warm_dim > 0 && arrays.dims != warm_dim {
            return Err(bad(
                "reg_dims",
                format!(
                    "{} parameter components in the moments table, {warm_dim} in the warm starts' points",
                    arrays.dims
                ),
            ));
        }
        Ok(Some((basis, size("reg_m")?)))
    }

    /// The model stored as `parts` ([`Self::parts`]); every length and index is checked
    /// (refused: [`RomError::Parts`], naming the array), so damaged parts never make a model
    /// that panics in a query.
    pub fn from_parts(p: &ModelParts) -> Result<Self, RomError> {
        let size = |name: &str| -> Result<usize, RomError> {
            usize::try_from(p.scalar(name)).ok().filter(|&v| v <= 1 << 32).ok_or_else(|| bad(name, "too large".into()))
        };
        let (r_u, r_l, nc, terms, dim) =
            (size("r_primal")?, size("r_dual")?, size("n_contact")?, size("lift_terms")?, size("warm_dim")?);
        if terms == 0 {
            return Err(bad("lift_terms", "0: a lift has at least its constant term".into()));
        }
        let khat_l = floats_of(p, "khat_l", r_u * r_u)?;
        let u_of_y = floats_of(p, "u_of_y", r_u * r_u)?;
        let weights = floats_of(p, "weights", nc)?;
        let values = p.float("theta_value").to_vec();
        let start = starts_of(p, "theta_start", nc, values.len())?;
        let cols = indices_of(p, "theta_column", Some(values.len()), r_l)?;
        let mut theta = vec![0.0; nc * r_l];
        for i in 0..nc {
            for e in start[i]..start[i + 1] {
                theta[i + cols[e] * nc] = values[e];
            }
        }
        let (by_node, by_col): (Compressed, Compressed) = csr(&theta, nc, r_l);
        if by_node != (start, cols, values) {
            return Err(bad("theta_value", "zeros or repeated columns in the compressed rows".into()));
        }
        let points = p.float("warm_points").to_vec();
        let n_warm = points.len().checked_div(dim).unwrap_or(0);
        if n_warm * dim != points.len() {
            return Err(bad("warm_points", format!("{} values are not points of {dim} components", points.len())));
        }
        let set = indices_of(p, "warm_set", None, usize::MAX)?;
        let set_start = starts_of(p, "warm_set_start", n_warm, set.len())?;
        let sets = (0..n_warm).map(|k| set[set_start[k]..set_start[k + 1]].to_vec()).collect();
        let ys_flat = p.float("warm_y").to_vec();
        let ys = match ys_flat.len() {
            0 => Vec::new(),
            n if n == n_warm * r_u => ys_flat.chunks(r_u.max(1)).map(<[f64]>::to_vec).collect(),
            n => return Err(bad("warm_y", format!("{n} values, expected 0 or {}", n_warm * r_u))),
        };
        let mut warm_starts = WarmStarts { dim, points, sets, ys, ..WarmStarts::default() };
        let surf = match p.scalar("surface") {
            0 => SurfaceData::Fixed {
                cphi: floats_of(p, "cphi", nc * r_u)?,
                cu0: split(floats_of(p, "cu0", terms * nc)?, terms),
                paired: indices_of(p, "paired", Some(nc), 2)?.into_iter().map(|x| x == 1).collect(),
                chat: floats_of(p, "chat", r_l * r_u)?,
                ghat: split(floats_of(p, "ghat", terms * r_l)?, terms),
                cwc: floats_of(p, "cwc", nc * nc)?,
            },
            1 => {
                let (ns, nm) = (size("n_slaves")?, size("n_masters")?);
                if ns > nc {
                    return Err(bad("n_slaves", format!("{ns} slaves, more than the {nc} contact nodes")));
                }
                let ncd = 2 * (ns + nm);
                let x_ref = floats_of(p, "x_ref", ncd)?.chunks(2).map(|c| [c[0], c[1]]).collect();
                let phi_c = floats_of(p, "phi_c", ncd * r_u)?;
                let supp = indices_of(p, SUPP, None, ns)?;
                if supp.windows(2).any(|w| w[0] >= w[1]) {
                    return Err(bad(SUPP, "not strictly increasing".into()));
                }
                let quad = match p.float("quad").len() {
                    0 => None,
                    _ => Some(floats_of(p, "quad", nc)?),
                };
                let (node_norm, master_norm) = node_norms(&phi_c, r_u, ns);
                SurfaceData::Nts {
                    ns,
                    nm,
                    x_ref,
                    slave_fixed: indices_of(p, "slave_fixed", Some(ns), 2)?.into_iter().map(|x| x == 1).collect(),
                    phi_c,
                    a_terms: split(floats_of(p, "a_terms", terms * ncd)?, terms),
                    supp,
                    quad,
                    node_norm,
                    master_norm,
                    w_c: floats_of(p, "w_c", ncd * ncd)?,
                }
            }
            2 => SurfaceData::Nts3(Box::new(Self::nts3_of(p, nc, r_u, terms)?)),
            s => {
                return Err(bad(
                    "surface",
                    format!("{s}: expected 0 (fixed pairs), 1 (node-to-segment) or 2 (node-to-surface)"),
                ))
            }
        };
        match &surf {
            SurfaceData::Nts { phi_c, .. } => warm_starts.place(phi_c, r_u),
            SurfaceData::Nts3(d) => warm_starts.locate3(d, r_u),
            SurfaceData::Fixed { .. } => {}
        }
        let model = Self {
            r_u,
            r_l,
            n_contact: nc,
            khat_l,
            u_of_y,
            weights,
            by_node,
            by_col,
            surf,
            warm_starts,
            per_query: None,
        };
        match Self::registered_of(p, dim)? {
            None => Ok(model),
            Some((basis, m)) => {
                if r_l != 0 || model.warm_starts.sets.iter().any(|s| !s.is_empty()) {
                    return Err(bad(
                        "r_dual",
                        "a model with a registered dual basis stores no fixed one and no warm-start active sets".into(),
                    ));
                }
                let len = basis.map().len();
                let mut model = model.with_registered_dual(basis, m)?;
                let q = p.float("reg_quad");
                if !q.is_empty() {
                    if q.len() != len || q.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                        return Err(bad(
                            "reg_quad",
                            format!("{} values, expected {len} finite non-negative weights", q.len()),
                        ));
                    }
                    if let Some(d) = &mut model.per_query {
                        d.quad = Some(std::sync::Arc::new(q.to_vec()));
                    }
                }
                Ok(model)
            }
        }
    }

    /// The 3-D contact surface stored in `p` (`surface = 2`), checked.
    fn nts3_of(p: &ModelParts, nc: usize, r_u: usize, terms: usize) -> Result<super::nts3::Nts3, RomError> {
        let size = |name: &str| -> Result<usize, RomError> {
            usize::try_from(p.scalar(name)).ok().filter(|&v| v <= 1 << 32).ok_or_else(|| bad(name, "too large".into()))
        };
        let (ns, nm) = (size("n_slaves")?, size("n_masters")?);
        if ns > nc {
            return Err(bad("n_slaves", format!("{ns} slaves, more than the {nc} contact nodes")));
        }
        let ncd = 3 * (ns + nm);
        let x_ref: Vec<[f64; 3]> = floats_of(p, "x_ref", ncd)?.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        let supp = indices_of(p, SUPP, None, ns)?;
        if supp.windows(2).any(|w| w[0] >= w[1]) {
            return Err(bad(SUPP, "not strictly increasing".into()));
        }
        let quad = match p.float("quad").len() {
            0 => None,
            _ => Some(floats_of(p, "quad", nc)?),
        };
        let facets = indices_of(p, "facets", None, nm)?;
        if facets.len() % 4 != 0 {
            return Err(bad("facets", format!("{} node ids, not four per facet", facets.len())));
        }
        let facets: Vec<[usize; 4]> = facets.chunks(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
        let axes = indices_of(p, "plane_axis", None, 3)?;
        if axes.len() > 8 {
            return Err(bad("plane_axis", format!("{} planes, at most 8", axes.len())));
        }
        let at = floats_of(p, "plane_at", axes.len())?;
        let planes: Vec<crate::solid::symmetry::Plane> =
            axes.iter().zip(&at).map(|(&axis, &at)| crate::solid::symmetry::Plane { axis, at }).collect();
        let tol = floats_of(p, "plane_tol", 1)?[0];
        let w_c = match p.float("w_c").len() {
            0 => None,
            _ => Some(floats_of(p, "w_c", ncd * ncd)?),
        };
        let master = crate::contact3d::surface::MasterSurface::new(facets, &x_ref[ns..], &planes, tol);
        Ok(super::nts3::Nts3 {
            ns,
            nm,
            slave_fixed: indices_of(p, "slave_fixed", Some(ns), 2)?.into_iter().map(|x| x == 1).collect(),
            master,
            phi_c: floats_of(p, "phi_c", ncd * r_u)?,
            a_terms: split(floats_of(p, "a_terms", terms * ncd)?, terms),
            supp,
            quad,
            w_c,
            x_ref,
        })
    }

    /// Components of the parameter the model is affine in (its lift's terms minus one).
    pub fn parameter_dim(&self) -> usize {
        let terms = match &self.surf {
            SurfaceData::Nts3(d) => d.a_terms.len(),
            SurfaceData::Fixed { cu0, .. } => cu0.len(),
            SurfaceData::Nts { a_terms, .. } => a_terms.len(),
        };
        terms.saturating_sub(1)
    }

    /// The tributary lengths of the contact nodes (the weights of the pressure's L2 norm).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }
}

#[cfg(test)]
mod tests {
    use super::ModelParts;
    use crate::rom::reduced::test_support::{assert_round_trip, coarse_mus, coarse_tests, full_rom, points};
    use crate::rom::{ReducedModel, RomError, RomParams};
    use crate::testing::ironing_coarse;

    /// Type-2 (ironing-coarse, 17 training points, full bases): the full model, its leading
    /// (8, 6) block with warm starts, and a sampled surface (quadrature weights and a reduced
    /// support) each survive a round trip through their parts bit for bit at the 48 test
    /// points, with both algorithms.
    #[test]
    fn type2_models_round_trip_bit_for_bit() {
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (rom, _, _) = full_rom(fm, &mus);
        let p = RomParams::default();
        let samples = points(&mus);
        let at = points(&coarse_tests());
        let warm = rom.leading(8, 6).with_warm_starts(&samples, &p);
        let (sampled, _) = rom.with_sampled_surface(&samples, &p, 3e-2).expect("fit");
        let sampled = sampled.with_warm_starts(&samples, &p);
        assert!(sampled.sampled_slaves().is_some());
        for model in [&rom, &warm, &sampled] {
            assert_round_trip(model, &at);
        }
    }

    /// Damaged parts are refused with the array's name, never a panic: a wrong length, an
    /// index out of range, row starts that do not close, an unknown surface type.
    #[test]
    fn inconsistent_parts_are_refused_by_name() {
        let (rom, _, _) = full_rom(ironing_coarse(), &coarse_mus());
        let good = rom.with_warm_starts(&points(&coarse_mus()), &RomParams::default()).parts();
        let edit = |f: &dyn Fn(&mut ModelParts)| {
            let mut p = good.clone();
            f(&mut p);
            match ReducedModel::from_parts(&p) {
                Err(RomError::Parts(m)) => m,
                other => panic!("accepted: {other:?}"),
            }
        };
        let float = |name: &'static str, f: fn(&mut Vec<f64>)| {
            move |p: &mut ModelParts| f(&mut p.floats.iter_mut().find(|(n, _)| *n == name).expect("array").1)
        };
        let int = |name: &'static str, f: fn(&mut Vec<u64>)| {
            move |p: &mut ModelParts| f(&mut p.ints.iter_mut().find(|(n, _)| *n == name).expect("array").1)
        };
        assert!(edit(&float("khat_l", |v| v.truncate(1))).contains("`khat_l`"));
        assert!(edit(&float("w_c", |v| v.push(0.0))).contains("`w_c`"));
        assert!(edit(&int("theta_column", |v| v[0] = 10_000)).contains("`theta_column`"));
        assert!(edit(&int("theta_start", |v| v[1] = u64::MAX)).contains("`theta_start`"));
        assert!(edit(&int("supp", |v| v[0] = 1 << 40)).contains("`supp`"));
        assert!(edit(&int("warm_set_start", |v| v.truncate(2))).contains("`warm_set_start`"));
        assert!(edit(&|p: &mut ModelParts| p.scalars[0].1 = 7).contains("`surface`"));
        assert!(edit(&|p: &mut ModelParts| p.scalars[1].1 = u64::MAX).contains("`r_primal`"));
        // every scalar listed; a fixed dual basis has all but a registered one's (`reg_*`)
        let names: Vec<&str> = good.scalars.iter().map(|(n, _)| *n).collect();
        let fixed: Vec<&str> = ModelParts::SCALARS.iter().copied().filter(|n| !n.starts_with("reg_")).collect();
        assert_eq!(names, fixed);
        for (n, _) in &good.floats {
            assert!(ModelParts::FLOATS.contains(n), "{n} not listed");
        }
        for (n, _) in &good.ints {
            assert!(ModelParts::INTS.contains(n), "{n} not listed");
        }
    }
}
