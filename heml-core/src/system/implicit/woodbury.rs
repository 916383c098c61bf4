//! Low-rank corrections of a held Cholesky factor for the tool contacts that
//! changed since it was made (Sherman–Morrison–Woodbury).
//!
//! Why: a contact spring adds (k + c c_v) n nᵀ to one node's diagonal block, a
//! rank-one term, and under a pressing tool the contact set changes at most steps;
//! refactoring for each change (tangent update, assembly, numeric factorisation)
//! was 28 of the liver's 43 factorisations in `heml bench --implicit`'s long run.
//! A factor of A0 (the matrix with the contacts of the factorisation) solves
//! A = A0 + U D Uᵀ exactly: u_i = e_node ⊗ n_i over the free coordinates, d_i = +k
//! for a contact made since, −k0 for one released (along its old normal; a turned
//! normal is a release and a make). With Z = A0⁻¹U (one pair of triangular solves
//! per column, kept while the column is) and S = D⁻¹ + UᵀZ (m × m, symmetric,
//! indefinite when some d_i < 0, so factored by LU with partial pivoting):
//! A⁻¹b = y − Z S⁻¹ Uᵀy with y = A0⁻¹b. The contact terms are then inverted exactly
//! over the factor's (stale) elastic part, the chord situation the refactor rule
//! already judges. Every operation runs in a fixed order on one thread: the same
//! bits for any thread count.

use super::cholesky::Cholesky;
use crate::system::statics::dofs::DofMap;
use crate::Vec3;
use nalgebra::{DMatrix, DVector, Dyn, LU};

/// A contact's matrix term (node, k + c·c_v, unit normal): its spring adds
/// (k + c·c_v)·n nᵀ to the node's diagonal block.
pub(super) type ContactTerm = (usize, f64, Vec3);

/// Smallest |pivot| of S's LU relative to its largest: below it S counts as
/// singular and the caller refactors. S's entries are ~1/k (k the contact
/// stiffness); a release (d = −k0) against a node whose remaining stiffness b⁻¹
/// is small leaves a pivot −1/(k0 (1 + k0 b)), ~20× below 1/k0 on the organ meshes
/// (k0 b ≈ 20), so 1e-10 only rejects a numerically singular S (a column
/// repeated, a spring cancelled against nothing), where the correction's
/// round-off would grow beyond what the chord rule can see.
const MIN_PIVOT_RATIO: f64 = 1e-10;

/// One column u of U, its weight d and z = A0⁻¹u.
#[derive(Debug)]
struct Column {
    node: usize,
    /// The unit direction of u on the node (the contact normal).
    dir: Vec3,
    d: f64,
    /// (free coordinate, component of u) of the node's free axes.
    entries: Vec<(usize, f64)>,
    z: Vec<f64>,
}

impl Column {
    /// uᵀv for `v` by free coordinate.
    fn dot(&self, v: &[f64]) -> f64 {
        self.entries.iter().map(|&(i, u)| u * v[i]).sum()
    }
}

/// The low-rank correction held with a factor: the columns serving the current
/// contacts and the LU of S.
#[derive(Debug, Default)]
pub(super) struct Correction {
    columns: Vec<Column>,
    s: Option<LU<f64, Dyn, Dyn>>,
    /// Column solves (z = A0⁻¹u) made on the current factor: the cost the caller's
    /// budget bounds before a refactorisation is cheaper.
    pub solves: usize,
}

/// Whether two normals are within the cosine a held factor tolerates.
fn close(a: &Vec3, b: &Vec3, cosine: f64) -> bool {
    a.dot(b) >= cosine
}

impl Correction {
    /// Forgets every column (after a refactorisation, whose factor holds the
    /// contacts it was made with).
    pub(super) fn clear(&mut self) {
        self.columns.clear();
        self.s = None;
        self.solves = 0;
    }

    /// Number of columns held (the rank of the correction).
    #[cfg(test)]
    pub(super) fn rank(&self) -> usize {
        self.columns.len()
    }

    /// The columns (node, direction, d) that make a factor of A0 (made with the
    /// contacts `base`) serve the contacts `now`: a contact of `now` matching one of
    /// `base` (same node and stiffness, normals within `cosine`, the tolerance of an
    /// uncorrected factor) needs nothing; else it is made (+k), along the direction
    /// of a make column already held for it when within `cosine` (so that a normal
    /// turning slowly does not ask for a new solve per step), else its own normal. A
    /// contact of `base` matched by none is released (−k0 along its old normal).
    /// Columns of the same node and direction are merged (weights summed; dropped
    /// when they cancel), and columns without a free coordinate dropped.
    fn plan(&self, base: &[ContactTerm], now: &[ContactTerm], cosine: f64) -> Vec<(usize, Vec3, f64)> {
        let mut matched = vec![false; base.len()];
        let mut want: Vec<(usize, Vec3, f64)> = Vec::new();
        for &(node, k, n) in now {
            let hit = (0..base.len()).find(|&j| {
                let b = &base[j];
                !matched[j] && b.0 == node && b.1 == k && close(&b.2, &n, cosine)
            });
            if let Some(j) = hit {
                matched[j] = true;
                continue;
            }
            let dir = self
                .columns
                .iter()
                .find(|c| c.node == node && c.d == k && close(&c.dir, &n, cosine))
                .map_or(n, |c| c.dir);
            want.push((node, dir, k));
        }
        for (j, &(node, k, n)) in base.iter().enumerate() {
            if !matched[j] {
                want.push((node, n, -k));
            }
        }
        let mut merged: Vec<(usize, Vec3, f64)> = Vec::with_capacity(want.len());
        for (node, dir, d) in want {
            match merged.iter_mut().find(|w| w.0 == node && w.1 == dir) {
                Some(w) => w.2 += d,
                None => merged.push((node, dir, d)),
            }
        }
        merged.retain(|w| w.2 != 0.0);
        merged
    }

    /// Makes the correction serve the contacts `now` on `factor` (made with `base`),
    /// solving for the columns not held yet. `None` when that would take the
    /// factor's column solves beyond `budget` or S is numerically singular: the
    /// caller refactors. Otherwise whether the corrected matrix changed.
    pub(super) fn update(
        &mut self,
        factor: &mut Cholesky,
        dofs: &DofMap,
        base: &[ContactTerm],
        now: &[ContactTerm],
        cosine: f64,
        budget: usize,
    ) -> Option<bool> {
        let mut want = self.plan(base, now, cosine);
        want.retain(|w| (0..3).any(|a| dofs.get(w.0, a).is_some()));
        let same = want.len() == self.columns.len()
            && want
                .iter()
                .zip(&self.columns)
                .all(|(w, c)| w.0 == c.node && w.1 == c.dir && w.2 == c.d);
        if same {
            return Some(false);
        }
        let new = want
            .iter()
            .filter(|w| !self.columns.iter().any(|c| c.node == w.0 && c.dir == w.1))
            .count();
        if self.solves + new > budget {
            return None;
        }
        let mut held = std::mem::take(&mut self.columns);
        let n = dofs.len();
        let mut columns = Vec::with_capacity(want.len());
        for (node, dir, d) in want {
            let column = match held.iter().position(|c| c.node == node && c.dir == dir) {
                Some(i) => Column {
                    d,
                    ..held.swap_remove(i)
                },
                None => {
                    let entries: Vec<(usize, f64)> =
                        (0..3).filter_map(|a| dofs.get(node, a).map(|i| (i, dir[a]))).collect();
                    let mut z = vec![0.0; n];
                    entries.iter().for_each(|&(i, u)| z[i] = u);
                    factor.solve(&mut z);
                    self.solves += 1;
                    Column {
                        node,
                        dir,
                        d,
                        entries,
                        z,
                    }
                }
            };
            columns.push(column);
        }
        self.columns = columns;
        self.s = None;
        if self.columns.is_empty() {
            return Some(true);
        }
        let m = self.columns.len();
        let cols = &self.columns;
        // S = D⁻¹ + UᵀZ, symmetrised (UᵀA0⁻¹U is symmetric up to round-off)
        let s = DMatrix::from_fn(m, m, |i, j| {
            let uz = 0.5 * (cols[i].dot(&cols[j].z) + cols[j].dot(&cols[i].z));
            if i == j {
                uz + 1.0 / cols[i].d
            } else {
                uz
            }
        });
        let lu = s.lu();
        let pivots = lu.u().diagonal().map(f64::abs);
        let (lo, hi) = (pivots.min(), pivots.max());
        if !(lo.is_finite() && hi.is_finite() && lo > MIN_PIVOT_RATIO * hi) {
            self.columns.clear();
            return None;
        }
        self.s = Some(lu);
        Some(true)
    }

    /// Solves (A0 + U D Uᵀ) x = `rhs` in place (by free coordinate) with the factor
    /// of A0 the columns were solved on.
    pub(super) fn solve(&self, factor: &mut Cholesky, rhs: &mut [f64]) {
        factor.solve(rhs);
        let Some(s) = &self.s else { return };
        let w = DVector::from_iterator(self.columns.len(), self.columns.iter().map(|c| c.dot(rhs)));
        let t = s.solve(&w).expect("S was checked nonsingular");
        for (c, &t) in self.columns.iter().zip(t.iter()) {
            rhs.iter_mut().zip(&c.z).for_each(|(x, z)| *x -= z * t);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::{box_mesh, HexSplit};
    use crate::system::implicit::matrix::tests::{add_to_diagonal, rnd, setup};
    use crate::system::implicit::matrix::BlockMatrix;
    use crate::system::implicit::ordering::CholeskyOrdering;

    /// The cosine of the tests: the factor's tolerance for a turned normal.
    const COSINE: f64 = 0.995;

    /// The box of [`setup`] (node 0 held, node 1 held in y) and its free coordinates.
    fn dofs() -> DofMap {
        let mesh = box_mesh([3.0, 2.0, 2.0], [3, 2, 2], HexSplit::Six).unwrap();
        let (_, _, mask) = setup();
        let held: Vec<[bool; 3]> = mask.chunks_exact(3).map(|c| [!c[0], !c[1], !c[2]]).collect();
        DofMap::new(&held, mesh.tets())
    }

    /// [`setup`]'s matrix plus the springs k n nᵀ of `contacts`.
    fn with_contacts(contacts: &[ContactTerm]) -> BlockMatrix {
        let (mut m, _, _) = setup();
        for &(node, k, n) in contacts {
            add_to_diagonal(&mut m, node, n * n.transpose() * k);
        }
        m
    }

    fn unit(s: &mut u64) -> Vec3 {
        Vec3::new(rnd(s), rnd(s), rnd(s)).normalize()
    }

    /// A solve of a fresh factor of [`with_contacts`]`(now)`.
    fn fresh_solve(now: &[ContactTerm], dofs: &DofMap, b: &[f64]) -> Vec<f64> {
        let m = with_contacts(now);
        let mut fresh = Cholesky::new(&m, dofs, usize::MAX, CholeskyOrdering::Auto).unwrap();
        fresh.factor(&m, false).unwrap();
        let mut x = b.to_vec();
        fresh.solve(&mut x);
        x
    }

    fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
        let d = a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        d / b.iter().map(|b| b.abs()).fold(0.0, f64::max)
    }

    /// A factor made with some contacts, corrected by low rank for contacts made,
    /// released and turned (beyond the cosine), solves like a fresh factor of the
    /// current matrix — also after a second, incremental change, which solves only
    /// its new columns — and a budget too small for the change refuses it.
    ///
    /// Bound: both are backward-stable solves of the same well-conditioned SPD
    /// matrix (random Gram stiffnesses + a mass shift, entries O(1), springs k =
    /// 20–60): the fresh factor errs by ~1e-15 relative; the Woodbury form loses
    /// the cancellation in S for releases, ~(1 + k b) ≤ 60× (b = uᵀ(A0 − k u uᵀ)⁻¹u
    /// ≤ 1 here), so ~1e-13; 1e-11 leaves 100× margin, while a missing or doubled
    /// spring errs by O(0.1) (k n nᵀ is larger than the node's other entries).
    #[test]
    fn woodbury_solve_equals_a_fresh_factor_of_the_current_matrix() {
        let dofs = dofs();
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let k = |s: &mut u64| 40.0 + 40.0 * rnd(s);
        // base: nodes 3, 5, 7, 9, 1 (held in y) and 0 (held: no free coordinate)
        let base: Vec<ContactTerm> = [3, 5, 7, 9, 1, 0]
            .iter()
            .map(|&i| (i, k(&mut s), unit(&mut s)))
            .collect();
        let m0 = with_contacts(&base);
        let mut factor = Cholesky::new(&m0, &dofs, usize::MAX, CholeskyOrdering::Auto).unwrap();
        factor.factor(&m0, false).unwrap();
        // now: 3 kept, 5 released, 7 turned by ~60°, 9 kept with another stiffness,
        // 1 kept, 0 released, 11, 13 and 1 (a second contact there) made
        let turned = (base[2].2 + unit(&mut s) * 1.5).normalize();
        assert!(turned.dot(&base[2].2) < COSINE);
        let now: Vec<ContactTerm> = vec![
            base[0],
            (7, base[2].1, turned),
            (9, base[3].1 * 0.5, base[3].2),
            base[4],
            (11, k(&mut s), unit(&mut s)),
            (13, k(&mut s), unit(&mut s)),
            (1, k(&mut s), unit(&mut s)),
        ];
        let mut correction = Correction::default();
        assert_eq!(
            correction.update(&mut factor, &dofs, &base, &now, COSINE, 6),
            None,
            "budget"
        );
        assert_eq!(
            correction.update(&mut factor, &dofs, &base, &now, COSINE, 7),
            Some(true)
        );
        // columns: release 5 and 7, make 7, 9's release and make merged (same
        // node and direction, d = k/2 − k), make 11, 13 and 1 (0 has no free
        // coordinate)
        assert_eq!((correction.rank(), correction.solves), (7, 7));
        let b: Vec<f64> = (0..dofs.len()).map(|_| rnd(&mut s)).collect();
        let mut x = b.clone();
        correction.solve(&mut factor, &mut x);
        let err = relative_difference(&x, &fresh_solve(&now, &dofs, &b));
        assert!(err < 1e-11, "relative difference {err:e}");
        // the same contacts again: nothing changes; one more made and 11 released:
        // one new column, the others kept
        assert_eq!(
            correction.update(&mut factor, &dofs, &base, &now, COSINE, 7),
            Some(false)
        );
        let mut later = now.clone();
        later.remove(4);
        later.push((17, k(&mut s), unit(&mut s)));
        assert_eq!(
            correction.update(&mut factor, &dofs, &base, &later, COSINE, 8),
            Some(true)
        );
        assert_eq!((correction.rank(), correction.solves), (7, 8));
        let mut x = b.clone();
        correction.solve(&mut factor, &mut x);
        let err = relative_difference(&x, &fresh_solve(&later, &dofs, &b));
        assert!(err < 1e-11, "relative difference after the incremental change {err:e}");
        // back to the base contacts: no column, the plain factor
        assert_eq!(
            correction.update(&mut factor, &dofs, &base, &base, COSINE, 8),
            Some(true)
        );
        assert_eq!(correction.rank(), 0);
        let mut x = b.clone();
        correction.solve(&mut factor, &mut x);
        let err = relative_difference(&x, &fresh_solve(&base, &dofs, &b));
        assert!(err < 1e-13, "without columns the factor's own solve: {err:e}");
    }
}
