//! The tangent linear solve both Newton problems share when the banded LDLᵀ is not
//! used: (c_k K + c_m M + K_g + K_contact) dx = rhs over the free coordinates of a
//! [`DofMap`], on the system matrix assembled in 3×3 blocks ([`BlockMatrix`]) from
//! the generated per-tet tangents, K_g the diagonal of the grasp springs and dampers
//! and K_contact the tool contacts' n nᵀ blocks; solved by preconditioned conjugate
//! gradients or by a sparse Cholesky factor ([`Cholesky`]) that may be reused.

use super::cg::{dot, pcg_fused, CgOperator, CgReport};
use super::cholesky::Cholesky;
use super::matrix::{BlockMatrix, GsOrdering};
use super::ordering::CholeskyOrdering;
use super::precision::FactorPrecision;
use super::problem::REFACTOR_COST_IN_CHORDS;
use super::settings::{CgPreconditioner, LinearSolver};
use super::timings::PhaseTimes;
use super::woodbury::Correction;
use crate::error::Result;
use crate::force::TangentOperator;
use crate::system::statics::dofs::DofMap;
use crate::system::System;
use crate::Vec3;
use nalgebra::Matrix3;
use std::time::Instant;

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
    /// CG preconditioner.
    pub preconditioner: CgPreconditioner,
    /// Conjugate gradients or a sparse Cholesky factor.
    pub linear_solver: LinearSolver,
    /// Cholesky: solve with the held factor, without updating the tangents or
    /// assembling, when it was made for the same matrix terms ([`FactorKey`]: chord
    /// Newton); otherwise (or when false) refactor first.
    pub reuse_factor: bool,
    /// Cholesky: a held factor made for other tool contacts (only) is corrected by
    /// low rank ([`Correction`]) instead of refactored, within [`CORRECTION_SOLVES`].
    pub contact_corrections: bool,
    /// Cholesky: the most nonzeros the factor may hold.
    pub max_factor_nonzeros: usize,
    /// Cholesky: the fill-reducing ordering of the factor.
    pub cholesky_ordering: CholeskyOrdering,
    /// Cholesky: the precision of the factor (f32 only with a mass term, `cm > 0`,
    /// under [`FactorPrecision::Auto`]).
    pub factor_precision: FactorPrecision,
}

/// What a held factor was made for: c_k, c_m, c_v, the grasps' diagonal terms
/// ((k + c c_v) per node, `None` without grasps) and the active tool contacts.
/// Runtime changes that leave the matrix alone (a grasp or tool moved without
/// changing the contact set, loads, gravity) keep the factor; a grasp made or
/// opened or other coefficients refactor; a contact made or released (or turned
/// beyond [`CONTACT_NORMAL_COSINE`]) is corrected by low rank on the kept factor
/// ([`Correction`]) until that has cost [`CORRECTION_SOLVES`], then refactors.
///
/// Why the contacts must enter the solve exactly: a contact spring k·n nᵀ is far stiffer than a
/// surface node's share of the rest of the matrix (k = 200 N/m against m/h² ≈ 0.3
/// N/m and an elastic stiffness of ~10 N/m on gen_kidney_20k at 10 ms). A factor
/// without the spring of a node that has since come into contact treats it
/// explicitly (a chord iteration is the forward step of the missing term), at
/// k·h²/m ≫ 1: the node is shot out of the tool and the motion diverges (the
/// long run's press phase diverged within 18 steps). The contraction rule could
/// not see it, as a fresh factor contracts little during contact anyway, which
/// loosens its bound to ~0.95.
#[derive(Debug, Clone, PartialEq)]
struct FactorKey {
    coefficients: [u64; 3],
    grasps: Option<Vec<f64>>,
    /// (node, k + c·c_v, normal) of each active contact, in the tool set's order.
    contacts: Vec<(usize, f64, Vec3)>,
}

/// A held factor stays valid while each contact normal is within this cosine of
/// the one it was factored with (5.7°): the spring's change |n nᵀ − n₀ n₀ᵀ| = sin θ
/// ≤ 0.1 of the contact stiffness, a perturbation the contraction rule judges
/// (a capsule sliding over the tissue turns its normals continuously, so equal
/// normals would refactor at every step of a contact).
const CONTACT_NORMAL_COSINE: f64 = 0.995;

impl FactorKey {
    /// The key of the system's current matrix terms for a solve with `cv`.
    fn of(sys: &System, ck: f64, cm: f64, cv: f64) -> Self {
        FactorKey {
            coefficients: [ck.to_bits(), cm.to_bits(), cv.to_bits()],
            grasps: sys.model.grasps.diagonal(sys.state.x.len(), cv),
            contacts: sys
                .model
                .tools
                .contacts()
                .iter()
                .filter(|c| c.stiffness + c.damping * cv > 0.0)
                .map(|c| (c.node, c.stiffness + c.damping * cv, c.normal))
                .collect(),
        }
    }

    /// Whether a factor made for `self` serves a matrix with the terms of `now` up to
    /// the tool contacts (the same coefficients and grasps): the contacts that
    /// changed are then corrected by low rank ([`Correction`]).
    fn same_but_contacts(&self, now: &FactorKey) -> bool {
        self.coefficients == now.coefficients && self.grasps == now.grasps
    }
}

/// The most column solves (A0⁻¹u, one pair of triangular solves each) a factor may
/// take for low-rank contact corrections before the next contact change refactors
/// instead: [`REFACTOR_COST_IN_CHORDS`], the fixed cost of a refactorisation in
/// chord iterations, each of which holds one pair of triangular solves besides its
/// force evaluations (so a column costs less than a chord iteration: the budget
/// errs towards refactoring, whose fresh tangent also helps the contraction). A
/// constant, not a timing: which steps refactor replays on every run.
const CORRECTION_SOLVES: usize = REFACTOR_COST_IN_CHORDS as usize;

/// What a tangent solve keeps between calls: the assembled matrix (its pattern is
/// built once per set of operators) and the wall-clock time of its phases.
#[derive(Debug, Default)]
pub(in crate::system) struct SolveCache {
    matrix: Option<BlockMatrix>,
    /// The sparse Cholesky analysis and factor (for the matrix's pattern) and what
    /// the factor was made for.
    direct: Option<(Cholesky, Option<FactorKey>)>,
    /// The low-rank correction of the factor for the contacts changed since it was
    /// made (cleared by each factorisation).
    correction: Correction,
    /// Changes of the correction (each a new matrix for the chord iterations, as a
    /// factorisation is) since the cache was made.
    pub corrections: usize,
    /// Numeric Cholesky factorisations since the cache was made.
    pub factorizations: usize,
    /// Cholesky: the next solve must refactor (set by the chord-Newton rules of the
    /// implicit step, cleared by the solve).
    pub refactor: bool,
    /// Cholesky: the residual contraction of the last iteration on a fresh factor
    /// (the reference the iterations on a kept one are held to).
    pub fresh_contraction: f64,
    /// Phase times accumulated since the owner last reset them.
    pub times: PhaseTimes,
    /// The residual's round-off scale at the last assembly ([`roundoff_floor`]; 0
    /// before the first): a residual below it is converged, whatever its ratio to
    /// the step's first residual.
    pub roundoff: f64,
}

/// Units of round-off in [`roundoff_floor`]: the residual of gen_kidney_20k at rest
/// (no load) was measured at 0.02–0.11 units, so 1024 leaves a wide margin (meshes
/// with more tets per node, other laws) while the floor stays 2·10⁻¹³ of the force
/// that would move every node by its own coordinates: a residual below it asks for
/// a correction of ~1000 ulps of the positions, and 10⁻⁵ of the Newton tolerance
/// of that kidney under gravity.
const ROUNDOFF_ULPS: f64 = 1024.0;

/// The scale of the residual's round-off at positions `x`: ROUNDOFF_ULPS·ε·‖(‖A_ii‖
/// |x_i|)_i‖ over the free nodes, A_ii the diagonal blocks of the assembled system
/// matrix. Each residual term is a sum of products of that size (the elastic
/// forces of the tets around a node are differences of positions of size |x| times
/// stiffnesses summing to K_ii, the inertia m c_a (x − x0 − h v0) likewise with
/// m c_a), so a body at rest, whose residual is that round-off, is converged: a
/// Newton solve there measures noise (a contraction noise/noise ≈ 1 that the chord
/// rule takes for a stale factor) and buys nothing.
fn roundoff_floor(matrix: &BlockMatrix, x: &[Vec3]) -> f64 {
    let blocks = matrix.blocks();
    let sum: f64 = (0..matrix.n_nodes())
        .filter(|&i| (0..3).any(|a| matrix.mask(3 * i + a) > 0.0))
        .filter_map(|i| matrix.row_blocks(i).find(|&(j, _)| j == i))
        .map(|(i, b)| (blocks[b].norm() * x[i].norm()).powi(2))
        .sum();
    ROUNDOFF_ULPS * f64::EPSILON * sum.sqrt()
}

impl SolveCache {
    /// Forgets the assembled matrix and any factor (e.g. after the mesh lost tets).
    pub(in crate::system) fn invalidate(&mut self) {
        self.matrix = None;
        self.direct = None;
        self.correction.clear();
    }

    /// Builds what depends on the mesh, the operators and the numbering of the
    /// unknowns only — the block pattern of the system matrix and, for `direct`, the
    /// Cholesky factor's pattern and symbolic analysis (ordering, elimination tree,
    /// supernodes, scratch) — when not held yet, so that a step pays only for
    /// numeric work. Contacts and grasps add diagonal blocks only, which the pattern
    /// always holds: they never invalidate it.
    pub(in crate::system) fn prepare(
        &mut self,
        n: usize,
        tets: &[[u32; 4]],
        tangents: &[Box<dyn TangentOperator>],
        dofs: &DofMap,
        direct: Option<(usize, CholeskyOrdering)>,
    ) -> Result<()> {
        if !self.matrix.as_ref().is_some_and(|m| m.fits(n, tangents)) {
            self.matrix = Some(BlockMatrix::new(n, tets, tangents));
            self.direct = None;
            self.correction.clear();
        }
        if let (Some((max_nonzeros, ordering)), None) = (direct, &self.direct) {
            let matrix = self.matrix.as_ref().expect("built above");
            self.direct = Some((Cholesky::new(matrix, dofs, max_nonzeros, ordering)?, None));
        }
        Ok(())
    }

    /// Nonzeros of the Cholesky factor held (0 without one).
    pub(in crate::system) fn factor_nonzeros(&self) -> usize {
        self.direct.as_ref().map_or(0, |(c, _)| c.factor_nonzeros())
    }

    /// Whether the Cholesky factor held is in f32 (false without one).
    pub(in crate::system) fn factor_is_single(&self) -> bool {
        self.direct
            .as_ref()
            .is_some_and(|(c, _)| c.is_factored() && c.is_single())
    }
}

impl TangentSolve {
    /// Updates `tangents` at the system's positions, assembles the system matrix and
    /// solves for `rhs` (by degree of freedom) in place, starting CG from `guess`
    /// (by degree of freedom; zero when `None`).
    pub(in crate::system) fn solve(
        &self,
        sys: &System,
        tangents: &mut [Box<dyn TangentOperator>],
        cache: &mut SolveCache,
        dofs: &DofMap,
        rhs: &mut [f64],
        guess: Option<&[f64]>,
    ) -> Result<CgReport> {
        if self.linear_solver == LinearSolver::Cholesky {
            return self.solve_direct(sys, tangents, cache, dofs, rhs);
        }
        let n = sys.state.x.len();
        let nl_diag = self.assemble(sys, tangents, cache, dofs)?;
        let tangents = &*tangents;
        let matrix = cache.matrix.as_ref().expect("assembled");
        let t2 = Instant::now();
        // CG on nodal vectors (3 per node, zero on held coordinates)
        let to_nodal = |v: &[f64]| {
            let mut out = vec![0.0; 3 * n];
            dofs.scatter(v, &mut out);
            out
        };
        let b = to_nodal(rhs);
        let mut x = vec![0.0; 3 * n];
        // the parallel sweeps' ordering: one pass over the pattern per solve
        let ordering =
            (self.preconditioner == CgPreconditioner::ParallelGaussSeidel).then(|| matrix.gauss_seidel_ordering(None));
        let mut op = Assembled {
            matrix,
            nonlocal: nl_diag.as_deref().map(|d| (tangents, self.ck, d)),
            preconditioner: self.preconditioner,
            ordering: ordering.as_ref(),
        };
        if let Some(g) = guess {
            // the guess scaled to minimise the quadratic model ½xᵀAx − bᵀx along it:
            // the model then starts below its value at 0, so CG's result stays a
            // descent direction of the line-search merit, however few iterations
            let g = to_nodal(g);
            let mut ag = vec![0.0; 3 * n];
            let (bg, gag) = (dot(&b, &g), op.apply_dot(&g, &mut ag));
            if bg > 0.0 && gag > 0.0 && (bg / gag).is_finite() {
                let alpha = bg / gag;
                x.iter_mut().zip(&g).for_each(|(x, g)| *x = alpha * g);
            }
        }
        let report = pcg_fused(&mut op, &b, &mut x, self.tol, self.max_iterations);
        dofs.gather_flat(&x, rhs);
        let t3 = Instant::now();
        cache.times.cg += (t3 - t2).as_secs_f64();
        cache.times.cg_residual = cache.times.cg_residual.max(report.relative_residual);
        Ok(report)
    }

    /// Updates `tangents` at the system's positions and fills the cached system
    /// matrix (building its pattern when the operators changed); returns the diagonal
    /// blocks of the nonlocal couplings the matrix holds (c_k-scaled), if any.
    fn assemble(
        &self,
        sys: &System,
        tangents: &mut [Box<dyn TangentOperator>],
        cache: &mut SolveCache,
        dofs: &DofMap,
    ) -> Result<Option<Vec<Matrix3<f64>>>> {
        let n = sys.state.x.len();
        let t0 = Instant::now();
        for t in tangents.iter_mut() {
            t.update(&sys.state.x)?;
        }
        let t1 = Instant::now();
        let tangents = &*tangents;
        if !cache.matrix.as_ref().is_some_and(|m| m.fits(n, tangents)) {
            cache.matrix = Some(BlockMatrix::new(n, sys.model.mesh.tets(), tangents));
            cache.direct = None;
            cache.correction.clear();
        }
        let matrix = cache.matrix.as_mut().expect("assembled");
        // grasp springs and dampers ((k + c c_v) I) and tool contacts ((k + c c_v) n nᵀ)
        // sit on the diagonal blocks of their nodes
        let grasps = sys.model.grasps.diagonal(n, self.cv);
        let nonlocal = tangents.iter().any(|t| t.has_nonlocal());
        // couplings beyond a tet (nodal volumes): their diagonal blocks go into the
        // matrix (so the preconditioners see them), the rest is added to its product
        // below (K_nl − D_nl)
        let nl_diag = nonlocal.then(|| {
            let mut nl = vec![Matrix3::zeros(); n];
            for t in tangents.iter().filter(|t| t.has_nonlocal()) {
                t.add_nonlocal_diagonal(&mut nl).expect("sizes match the system");
            }
            nl.iter_mut().for_each(|d| *d *= self.ck);
            nl
        });
        let extra = (grasps.is_some() || !sys.model.tools.contacts().is_empty() || nonlocal).then(|| {
            let mut blocks = nl_diag.clone().unwrap_or_else(|| vec![Matrix3::zeros(); n]);
            if let Some(g) = &grasps {
                for (b, d) in blocks.iter_mut().zip(g) {
                    *b += Matrix3::identity() * *d;
                }
            }
            sys.model.tools.add_diagonal_blocks(self.cv, &mut blocks);
            blocks
        });
        matrix.fill(tangents, self.ck, self.cm, &sys.model.mass, extra.as_deref(), |i, a| {
            dofs.get(i, a).is_some()
        });
        cache.roundoff = roundoff_floor(matrix, &sys.state.x);
        cache.times.tangent += (t1 - t0).as_secs_f64();
        cache.times.assembly += t1.elapsed().as_secs_f64();
        Ok(nl_diag)
    }

    /// The Cholesky path of [`Self::solve`]: reuses the held factor when allowed and
    /// made for the same coefficients and grasps ([`FactorKey`]), the tool contacts
    /// changed since corrected by low rank ([`Correction`]) within the budget
    /// [`CORRECTION_SOLVES`]; else updates the tangents, assembles, (analyses the
    /// pattern once and) factors. Then two triangular solves (and the correction's
    /// rank-m update). Couplings beyond a tet (nodal volumes) enter the factor
    /// through their diagonal blocks only, so with them the factor is an
    /// approximation (positive definite) and the Newton iteration converges as a
    /// chord iteration.
    fn solve_direct(
        &self,
        sys: &System,
        tangents: &mut [Box<dyn TangentOperator>],
        cache: &mut SolveCache,
        dofs: &DofMap,
        rhs: &mut [f64],
    ) -> Result<CgReport> {
        let key = FactorKey::of(sys, self.ck, self.cm, self.cv);
        let t0 = Instant::now();
        let served = self.reuse_factor
            && match cache.direct.as_mut() {
                Some((direct, Some(base))) if direct.is_factored() && base.same_but_contacts(&key) => {
                    // without corrections, only a factor whose contacts serve as they are
                    let budget = if self.contact_corrections { CORRECTION_SOLVES } else { 0 };
                    let solves = cache.correction.solves;
                    let out = cache.correction.update(
                        direct,
                        dofs,
                        &base.contacts,
                        &key.contacts,
                        CONTACT_NORMAL_COSINE,
                        budget,
                    );
                    cache.times.correction_columns += cache.correction.solves - solves;
                    cache.corrections += usize::from(out == Some(true));
                    out.is_some()
                }
                _ => false,
            };
        cache.times.factor += t0.elapsed().as_secs_f64();
        if !served {
            self.assemble(sys, tangents, cache, dofs)?;
            let t0 = Instant::now();
            let matrix = cache.matrix.as_ref().expect("assembled");
            let (direct, made_for) = match cache.direct.take() {
                Some(d) => d,
                None => (
                    Cholesky::new(matrix, dofs, self.max_factor_nonzeros, self.cholesky_ordering)?,
                    None,
                ),
            };
            let (direct, made_for) = cache.direct.insert((direct, made_for));
            *made_for = None;
            cache.correction.clear();
            let single = self.factor_precision.single(dofs.len(), self.cm > 0.0);
            direct.factor(matrix, single)?;
            *made_for = Some(key);
            cache.factorizations += 1;
            cache.times.factor += t0.elapsed().as_secs_f64();
        }
        let t0 = Instant::now();
        let (direct, _) = cache.direct.as_mut().expect("factored");
        cache.correction.solve(direct, rhs);
        cache.times.cg += t0.elapsed().as_secs_f64();
        Ok(CgReport {
            iterations: 0,
            relative_residual: 0.0,
            converged: true,
            breakdown: false,
        })
    }
}

/// The nonlocal couplings: the tangents, c_k and the diagonal blocks the matrix holds.
type Nonlocal<'a> = (&'a [Box<dyn TangentOperator>], f64, &'a [Matrix3<f64>]);

/// The assembled system matrix as a CG operator: its product (plus the nonlocal
/// couplings it does not hold: the tangents, c_k and the diagonal blocks already in
/// the matrix) and the chosen preconditioner.
struct Assembled<'a> {
    matrix: &'a BlockMatrix,
    nonlocal: Option<Nonlocal<'a>>,
    preconditioner: CgPreconditioner,
    /// The parallel Gauss–Seidel ordering (built when that preconditioner is used).
    ordering: Option<&'a GsOrdering>,
}

impl CgOperator for Assembled<'_> {
    fn apply_dot(&mut self, p: &[f64], out: &mut [f64]) -> f64 {
        let pap = self.matrix.apply(p, out);
        match self.nonlocal {
            None => pap,
            Some((tangents, ck, diag)) => {
                add_nonlocal(tangents, self.matrix, ck, diag, p, out);
                dot(p, out)
            }
        }
    }

    fn precondition_dot(&mut self, r: &[f64], z: &mut [f64]) -> f64 {
        match self.preconditioner {
            CgPreconditioner::BlockJacobi => self.matrix.block_jacobi(r, z),
            CgPreconditioner::SymmetricGaussSeidel => self.matrix.symmetric_gauss_seidel(r, z),
            CgPreconditioner::ParallelGaussSeidel => {
                let ord = self.ordering.expect("built for this preconditioner");
                self.matrix.parallel_gauss_seidel(ord, r, z)
            }
        }
    }
}

/// out += (c_k K_nonlocal − D) p on the free coordinates, with D = `diag` the
/// diagonal blocks of c_k K_nonlocal the matrix already holds (the couplings of the
/// tangents that the block matrix does not hold), p and out flat by node.
fn add_nonlocal(
    tangents: &[Box<dyn TangentOperator>],
    matrix: &BlockMatrix,
    ck: f64,
    diag: &[Matrix3<f64>],
    p: &[f64],
    out: &mut [f64],
) {
    let dx: Vec<crate::Vec3> = p.chunks_exact(3).map(|c| crate::Vec3::new(c[0], c[1], c[2])).collect();
    let mut y = vec![crate::Vec3::zeros(); dx.len()];
    for t in tangents.iter().filter(|t| t.has_nonlocal()) {
        t.add_nonlocal_product(&dx, &mut y).expect("sizes match the system");
    }
    for (i, (yi, (d, u))) in y.iter().zip(diag.iter().zip(&dx)).enumerate() {
        let v = yi * ck - d * u;
        for a in 0..3 {
            out[3 * i + a] += v[a] * matrix.mask(3 * i + a);
        }
    }
}
