//! The tangent linear solve both Newton problems share when no direct factorisation
//! is used: (c_k K + c_m M + K_g + K_contact) dx = rhs over the free coordinates of a [`DofMap`], by
//! conjugate gradients with a block-Jacobi preconditioner, K the matrix-free
//! generated tangent of every region and K_g the diagonal of the grasp springs and
//! dampers.

use super::cg::{pcg, CgReport};
use crate::error::Result;
use crate::force::TangentOperator;
use crate::system::statics::dofs::DofMap;
use crate::system::System;
use crate::Vec3;
use nalgebra::Matrix3;

/// Coefficients and stopping rule of one tangent solve.
pub(in crate::system) struct TangentSolve {
    /// Stiffness coefficient c_k.
    pub ck: f64,
    /// Mass coefficient c_m (0 for a static solve).
    pub cm: f64,
    /// Velocity coefficient c_v of the step (v⁺ = v + c_v d; 0 for a static solve):
    /// the grasp dampers c add c·c_v to the diagonal, the springs k; the tool
    /// contacts' damping enters the operator as c·c_v.
    pub cv: f64,
    /// CG relative tolerance.
    pub tol: f64,
    /// CG iteration cap.
    pub max_iterations: usize,
}

/// The per-node inverse of the system matrix's 3×3 diagonal block restricted to the
/// node's free coordinates (zero rows and columns on held ones); a block that cannot
/// be inverted falls back to the inverse of its diagonal (or 1 on a zero one).
fn preconditioner(blocks: &mut [Matrix3<f64>], free: impl Fn(usize, usize) -> bool) {
    for (i, b) in blocks.iter_mut().enumerate() {
        let f = [free(i, 0), free(i, 1), free(i, 2)];
        let all = f.iter().all(|&x| x);
        let inv = if all { b.try_inverse() } else { None };
        *b = inv.unwrap_or_else(|| {
            Matrix3::from_fn(|r, c| {
                if r == c && f[r] {
                    let d = b[(r, r)];
                    if d > 0.0 {
                        1.0 / d
                    } else {
                        1.0
                    }
                } else {
                    0.0
                }
            })
        });
        if !all {
            for r in 0..3 {
                for c in 0..3 {
                    if !(f[r] && f[c]) {
                        b[(r, c)] = 0.0;
                    }
                }
            }
        }
    }
}

impl TangentSolve {
    /// Updates `tangents` at the system's positions and solves for `rhs` (by degree
    /// of freedom) in place.
    pub(in crate::system) fn solve(
        &self,
        sys: &System,
        tangents: &mut [Box<dyn TangentOperator>],
        dofs: &DofMap,
        rhs: &mut [f64],
    ) -> Result<CgReport> {
        for t in tangents.iter_mut() {
            t.update(&sys.state.x)?;
        }
        let n = sys.state.x.len();
        let (ck, cm) = (self.ck, self.cm);
        let mut blocks = vec![Matrix3::zeros(); n];
        for t in tangents.iter() {
            t.add_diagonal_blocks(&mut blocks)?;
        }
        for (b, m) in blocks.iter_mut().zip(&sys.model.mass) {
            *b = *b * ck + Matrix3::identity() * (cm * m);
        }
        // grasp springs and dampers: (k + c c_v) I on their nodes
        let grasps = sys.model.grasps.diagonal(n, self.cv);
        if let Some(g) = &grasps {
            for (b, d) in blocks.iter_mut().zip(g) {
                *b += Matrix3::identity() * *d;
            }
        }
        sys.model.tools.add_diagonal_blocks(self.cv, &mut blocks);
        preconditioner(&mut blocks, |i, a| dofs.get(i, a).is_some());
        let mut px = vec![Vec3::zeros(); n];
        let mut kp = vec![Vec3::zeros(); n];
        let mut failure = None;
        let tangents = &*tangents;
        let apply = |p: &[f64], out: &mut [f64]| {
            dofs.scatter(p, &mut px);
            kp.fill(Vec3::zeros());
            for t in tangents {
                if let Err(e) = t.add_product(&px, &mut kp) {
                    failure = Some(e);
                }
            }
            for ((k, p), m) in kp.iter_mut().zip(&px).zip(&sys.model.mass) {
                *k = *k * ck + p * (cm * m);
            }
            if let Some(g) = &grasps {
                for ((k, p), d) in kp.iter_mut().zip(&px).zip(g) {
                    *k += p * *d;
                }
            }
            sys.model.tools.add_product(self.cv, &px, &mut kp);
            out.copy_from_slice(&dofs.gather(&kp));
        };
        let precond = |r: &[f64], out: &mut [f64]| {
            let mut nodal = vec![Vec3::zeros(); n];
            dofs.scatter(r, &mut nodal);
            for (v, b) in nodal.iter_mut().zip(&blocks) {
                *v = b * *v;
            }
            out.copy_from_slice(&dofs.gather(&nodal));
        };
        let mut x = vec![0.0; rhs.len()];
        let report = pcg(apply, precond, rhs, &mut x, self.tol, self.max_iterations);
        if let Some(e) = failure {
            return Err(e);
        }
        rhs.copy_from_slice(&x);
        Ok(report)
    }
}
