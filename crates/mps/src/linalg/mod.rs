//! Linear algebra for the pressure Poisson equation: sparse matrices, preconditioned
//! conjugate gradient, IC(0) and smoothed-aggregation AMG.
//!
//! A leaf: knows nothing of particles, kernels or schemes.
//! `sparse` is the leaf inside it; `pcg` defines the preconditioner interface that `ic0`
//! and `amg` implement.

pub mod amg;
pub mod dilu;
pub mod ic0;
pub mod pcg;
pub mod sparse;
pub mod team;
pub mod twisted;

pub use amg::{Amg, AmgParams};
pub use dilu::{dilu_cg, dilu_cg_in, Dilu, DiluCgVectors};
pub use ic0::{Ic0, Mic0Scratch, NEW_ROW};
pub use pcg::{pcg, pcg_in, CgVectors, Identity, Jacobi, NotConverged, Precondition, SolveStats};
pub use sparse::CsrMatrix;
pub use twisted::{twisted_cg_in, Twisted, TwistedCgVectors, TwistedPre};

use serde::{Deserialize, Serialize};

/// Linear solver choice for the PPE.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolverKind {
    /// Below [`AUTO_AMG_UNKNOWNS_2D`] unknowns MIC(0)-CG in 2D, below [`AUTO_AMG_UNKNOWNS`]
    /// modified D-ILU-CG in 3D, AMG-CG from there on.
    Auto,
    /// Unpreconditioned conjugate gradient.
    Cg,
    /// Jacobi (diagonal) preconditioned CG.
    JacobiCg,
    /// Incomplete-Cholesky IC(0) preconditioned CG.
    Ic0Cg,
    /// Modified incomplete-Cholesky MIC(0) preconditioned CG (relaxed by [`MIC_OMEGA`]).
    Mic0Cg,
    /// Smoothed-aggregation algebraic multigrid preconditioned CG.
    AmgCg,
    /// Modified D-ILU preconditioned CG by Eisenstat's trick (relaxed by [`DILU_OMEGA`]).
    DiluCg,
}

/// PPE size (unknowns) from which `auto` picks AMG-CG over D-ILU-CG in 3D
/// (docs/decisions.md, "Solver choice", "Modified D-ILU").
pub const AUTO_AMG_UNKNOWNS: usize = 8000;

/// PPE size (unknowns) from which `auto` picks AMG-CG over D-ILU-CG in 2D
/// (docs/decisions.md, "MIC(0) in the twisted numbering", "Modified D-ILU in the twisted
/// numbering").
pub const AUTO_AMG_UNKNOWNS_2D: usize = 12000;

/// Relaxation of MIC(0): the share of the dropped fill moved to the diagonal
/// (docs/decisions.md, "MIC(0)").
pub const MIC_OMEGA: f64 = 0.97;

/// Relaxation of the modified D-ILU pivots (docs/decisions.md, "Modified D-ILU").
pub const DILU_OMEGA: f64 = 0.99;

impl SolverKind {
    /// The solver `auto` stands for at `unknowns` rows in `dimension` 2 or 3; other kinds
    /// are themselves. Below the AMG sizes, D-ILU by Eisenstat's trick in the twisted
    /// numbering: no factor to build, half MIC(0)'s memory traffic per iteration, both
    /// substitutions on two threads (docs/decisions.md, "Modified D-ILU", "Modified D-ILU in
    /// the twisted numbering").
    pub fn for_size(self, unknowns: usize, dimension: usize) -> SolverKind {
        match self {
            SolverKind::Auto if dimension == 3 && unknowns < AUTO_AMG_UNKNOWNS => {
                SolverKind::DiluCg
            }
            SolverKind::Auto if dimension != 3 && unknowns < AUTO_AMG_UNKNOWNS_2D => {
                SolverKind::DiluCg
            }
            SolverKind::Auto => SolverKind::AmgCg,
            k => k,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::CsrMatrix;

    #[test]
    fn auto_takes_the_measured_solver_for_each_size() {
        use super::SolverKind::*;
        use super::{AUTO_AMG_UNKNOWNS, AUTO_AMG_UNKNOWNS_2D};
        let pick = |n, d| Auto.for_size(n, d);
        assert_eq!(pick(AUTO_AMG_UNKNOWNS_2D - 1, 2), DiluCg);
        assert_eq!(pick(AUTO_AMG_UNKNOWNS_2D, 2), AmgCg);
        assert_eq!(pick(AUTO_AMG_UNKNOWNS - 1, 3), DiluCg);
        assert_eq!(pick(AUTO_AMG_UNKNOWNS, 3), AmgCg);
        assert_eq!(Mic0Cg.for_size(10, 3), Mic0Cg);
    }

    /// Five-point Laplacian on an `m x m` grid with Dirichlet boundaries.
    pub(crate) fn laplace_2d(m: usize) -> CsrMatrix {
        let stencil = [
            (0, -1, -1.0),
            (-1, 0, -1.0),
            (0, 0, 4.0),
            (1, 0, -1.0),
            (0, 1, -1.0),
        ];
        CsrMatrix::from_rows((0..m * m).map(|i| {
            let (x, y) = ((i % m) as i64, (i / m) as i64);
            stencil
                .iter()
                .filter(|(dx, dy, _)| {
                    (0..m as i64).contains(&(x + dx)) && (0..m as i64).contains(&(y + dy))
                })
                .map(|&(dx, dy, v)| (((y + dy) * m as i64 + x + dx) as u32, v))
                .collect()
        }))
    }
}
