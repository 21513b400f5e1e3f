//! The reduced constraints at the current linearisation as the QP sees them ([`Oracle`]):
//! Type-1 the precomputed `Ĉ` and `ĝ0(mu)`, Type-2 the gap rows of the paired supported slaves
//! summed under the dual basis, either as the assembly summed them (a small dual basis) or
//! from the rows kept per slave.

use super::linearise::LinState;
use super::{ReducedModel, SurfaceData};
use crate::rom::la::dot;
use crate::rom::qp::QpConstraints;

/// The reduced constraints at the current linearisation, for the QP.
pub(super) struct Oracle<'a> {
    pub(super) m: &'a ReducedModel,
    pub(super) lin: &'a mut LinState,
}

impl QpConstraints for Oracle<'_> {
    fn len(&self) -> usize {
        self.m.r_l
    }

    fn values(&mut self, x: &[f64], s: &mut [f64]) {
        let (m, ru) = (self.m, self.m.r_u);
        match &m.surf {
            SurfaceData::Fixed { chat, .. } => {
                for (a, sa) in s.iter_mut().enumerate() {
                    *sa = dot(&chat[a * ru..(a + 1) * ru], x) + self.lin.g_mu[a];
                }
            }
            SurfaceData::Nts { .. } | SurfaceData::Nts3(_) if m.sums_rows() => {
                let l = &*self.lin;
                // at x = 0 (the QP's warm start) the values are the constant parts
                let zero = x.iter().all(|&v| v == 0.0);
                for (a, sa) in s.iter_mut().enumerate() {
                    *sa = if zero { l.ghat0[a] } else { dot(&l.chat[a * ru..(a + 1) * ru], x) + l.ghat0[a] };
                }
            }
            SurfaceData::Nts { .. } | SurfaceData::Nts3(_) => {
                s.iter_mut().for_each(|v| *v = 0.0);
                let l = &*self.lin;
                // at x = 0 (the QP's warm start) the gaps are the constant parts
                let zero = x.iter().all(|&v| v == 0.0);
                for (k, &sl) in l.ps.iter().enumerate() {
                    let g = if zero { l.g0[k] } else { dot(&l.cphi[k * ru..(k + 1) * ru], x) + l.g0[k] };
                    let wg = m.gap_weight(sl) * g;
                    for e in m.by_node.0[sl]..m.by_node.0[sl + 1] {
                        s[m.by_node.1[e]] += m.by_node.2[e] * wg;
                    }
                }
            }
        }
    }

    fn row(&mut self, a: usize, out: &mut [f64]) {
        let (m, ru) = (self.m, self.m.r_u);
        match &m.surf {
            SurfaceData::Fixed { chat, .. } => out.copy_from_slice(&chat[a * ru..(a + 1) * ru]),
            SurfaceData::Nts { .. } | SurfaceData::Nts3(_) if m.sums_rows() => {
                out.copy_from_slice(&self.lin.chat[a * ru..(a + 1) * ru])
            }
            SurfaceData::Nts { .. } | SurfaceData::Nts3(_) => {
                out.iter_mut().for_each(|v| *v = 0.0);
                let l = &*self.lin;
                for e in m.by_col.0[a]..m.by_col.0[a + 1] {
                    let sl = m.by_col.1[e];
                    let k = l.ps_of[sl];
                    if k == usize::MAX {
                        continue;
                    }
                    let tw = m.by_col.2[e] * m.gap_weight(sl);
                    for (o, c) in out.iter_mut().zip(&l.cphi[k * ru..(k + 1) * ru]) {
                        *o += tw * c;
                    }
                }
            }
        }
    }
}
