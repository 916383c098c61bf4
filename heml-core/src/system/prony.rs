//! Prony-series visco-hyperelasticity (DESIGN §1).
//!
//! The relaxation function is α(t) = 1 − Σ α_i (1 − e^(−t/τ_i)). Each term keeps one
//! state vector γ_i (a `Vec3` per node of its region), updated once per new time by
//! the backward-Euler scheme of the internal-variable equation τ_i γ̇_i + γ_i = α_i f:
//!
//! γ_i ← A_i f + B_i γ_i, A_i = Δt α_i / (Δt + τ_i), B_i = τ_i / (Δt + τ_i),
//!
//! where f is the region's elastic force at the new time and Δt the time since the
//! previous update; the region then contributes the viscous-elastic force
//! f̂ = f − Σ γ_i. The scheme is first order in Δt: a step strain applied at t = 0 and
//! held gives f̂(t_n) = f · [1 − Σ α_i (1 − (1 + Δt/τ_i)^(−n))], whose distance to
//! f·α(t_n) is ≈ Σ α_i e^(−t/τ_i) t Δt / (2 τ_i²).

use crate::error::{HemlError, Result};
use crate::Vec3;

/// One term of a Prony series: relative modulus `alpha` relaxing with time constant
/// `tau` (seconds).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PronyTerm {
    /// Relative weight α_i of the term, in [0, 1).
    pub alpha: f64,
    /// Relaxation time τ_i > 0.
    pub tau: f64,
}

impl PronyTerm {
    /// A term of weight `alpha` and time constant `tau`.
    pub fn new(alpha: f64, tau: f64) -> Self {
        PronyTerm { alpha, tau }
    }
}

/// The relaxation function α(t) = 1 − Σ α_i (1 − e^(−t/τ_i)) (1 for t ≤ 0).
pub fn relaxation(terms: &[PronyTerm], t: f64) -> f64 {
    let t = t.max(0.0);
    1.0 - terms.iter().map(|p| p.alpha * (1.0 - (-t / p.tau).exp())).sum::<f64>()
}

/// Most terms of a Prony series: each keeps 9 numbers per tet (its internal
/// stress), so 20 000 terms on 15 000 tets asked for 3.7 GB and aborted; fitted
/// tissue series use 1–5 terms, one per decade of relaxation time.
pub const MAX_PRONY_TERMS: usize = 32;

/// Checks a Prony series: at most [`MAX_PRONY_TERMS`] terms, every α_i finite and
/// ≥ 0, Σ α_i < 1 (the long-term modulus must stay positive), every τ_i finite and
/// > 0.
///
/// ```
/// use heml_core::system::{validate_prony, PronyTerm, MAX_PRONY_TERMS};
/// assert!(validate_prony(&[PronyTerm::new(0.3, 0.1)]).is_ok());
/// let many = vec![PronyTerm::new(1e-6, 0.1); MAX_PRONY_TERMS + 1];
/// assert!(validate_prony(&many).unwrap_err().to_string().contains("at most 32"));
/// ```
pub fn validate_prony(terms: &[PronyTerm]) -> Result<()> {
    if terms.len() > MAX_PRONY_TERMS {
        return Err(HemlError::Invalid(format!(
            "Prony series: {} terms, at most {MAX_PRONY_TERMS} are supported (each keeps an internal \
             stress per tet; fitted series need a few, one per decade of relaxation time)",
            terms.len()
        )));
    }
    for (i, p) in terms.iter().enumerate() {
        if !(p.alpha.is_finite() && p.alpha >= 0.0) {
            return Err(HemlError::Invalid(format!(
                "Prony term {i}: alpha = {} must be a finite number >= 0",
                p.alpha
            )));
        }
        if !(p.tau.is_finite() && p.tau > 0.0) {
            return Err(HemlError::Invalid(format!(
                "Prony term {i}: tau = {} must be a finite number > 0",
                p.tau
            )));
        }
    }
    let sum: f64 = terms.iter().map(|p| p.alpha).sum();
    if sum >= 1.0 {
        return Err(HemlError::Invalid(format!(
            "Prony series: the alphas sum to {sum}, which must be < 1 (the long-term modulus 1 - sum must stay positive)"
        )));
    }
    Ok(())
}

/// The internal variables of one region's Prony series.
///
/// Two copies are kept: `base`, the state at the last time strictly before the
/// current one, and `cur`, the state at the current time. Evaluating the forces twice
/// at the same time (e.g. after the user edits positions) recomputes `cur` from `base`
/// instead of advancing the series twice.
#[derive(Debug, Clone)]
pub(crate) struct PronyState {
    pub(crate) terms: Vec<PronyTerm>,
    /// Global ids of the region's nodes; γ is stored compactly over them.
    nodes: Vec<usize>,
    base: Vec<Vec<Vec3>>,
    cur: Vec<Vec<Vec3>>,
    t_base: f64,
    t_cur: Option<f64>,
}

impl PronyState {
    pub(crate) fn new(terms: Vec<PronyTerm>, nodes: Vec<usize>) -> Self {
        let zero = vec![vec![Vec3::zeros(); nodes.len()]; terms.len()];
        PronyState {
            terms,
            nodes,
            base: zero.clone(),
            cur: zero,
            t_base: 0.0,
            t_cur: None,
        }
    }

    /// Advances the series to time `t` with the region's elastic force `f` (indexed by
    /// global node id) and replaces `f` by f̂ = f − Σ γ_i on the region's nodes.
    pub(crate) fn apply(&mut self, t: f64, f: &mut [Vec3]) -> Result<()> {
        match self.t_cur {
            None => {
                // First evaluation: no history, γ = 0 (Δt = 0 gives A = 0, B = 1).
                self.t_base = t;
                self.t_cur = Some(t);
            }
            Some(tc) if t > tc => {
                std::mem::swap(&mut self.base, &mut self.cur);
                self.t_base = tc;
                self.t_cur = Some(t);
            }
            Some(tc) if t == tc => {}
            Some(tc) => {
                return Err(HemlError::Invalid(format!(
                    "Prony series evaluated at t = {t}, before its last update at t = {tc}"
                )))
            }
        }
        let dt = self.t_cur.unwrap_or(t) - self.t_base;
        for (k, term) in self.terms.iter().enumerate() {
            let a = dt * term.alpha / (dt + term.tau);
            let b = term.tau / (dt + term.tau);
            let (base, cur) = (&self.base[k], &mut self.cur[k]);
            for (j, &i) in self.nodes.iter().enumerate() {
                cur[j] = f[i] * a + base[j] * b;
            }
        }
        for cur in &self.cur {
            for (j, &i) in self.nodes.iter().enumerate() {
                f[i] -= cur[j];
            }
        }
        Ok(())
    }

    /// Takes a removed tet's share out of the history: its nodal forces `f` (at the
    /// current positions) on `nodes`, weighted by each term's α — the share γ_i
    /// holds once the force has been steady for a few τ_i (the per-node history
    /// cannot tell the tet's exact share, so faster loading leaves an error that
    /// relaxes in τ_i). Each tet's forces sum to zero, so the history's sum over
    /// the body is kept.
    pub(crate) fn remove_share(&mut self, nodes: &[usize; 4], f: &[Vec3; 4]) {
        for (i, fi) in nodes.iter().zip(f) {
            if let Ok(j) = self.nodes.binary_search(i) {
                for (k, term) in self.terms.iter().enumerate() {
                    self.base[k][j] -= fi * term.alpha;
                    self.cur[k][j] -= fi * term.alpha;
                }
            }
        }
    }

    /// Copies this state into `dst` (reusing its allocations).
    pub(crate) fn save_into(&self, dst: &mut PronyState) {
        dst.terms.clone_from(&self.terms);
        dst.nodes.clone_from(&self.nodes);
        dst.base.clone_from(&self.base);
        dst.cur.clone_from(&self.cur);
        dst.t_base = self.t_base;
        dst.t_cur = self.t_cur;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_names_the_problem() {
        assert!(validate_prony(&[PronyTerm::new(0.3, 1.0), PronyTerm::new(0.5, 0.1)]).is_ok());
        let e = validate_prony(&[PronyTerm::new(0.6, 1.0), PronyTerm::new(0.5, 0.1)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("sum to 1.1"), "{e}");
        let e = validate_prony(&[PronyTerm::new(0.1, 0.0)]).unwrap_err().to_string();
        assert!(e.contains("term 0") && e.contains("tau"), "{e}");
        let e = validate_prony(&[PronyTerm::new(0.1, 1.0), PronyTerm::new(f64::NAN, 1.0)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("term 1") && e.contains("alpha"), "{e}");
    }

    #[test]
    fn discrete_series_matches_its_closed_form() {
        // f̂_n = f (1 − α (1 − B^n)) exactly for a constant f (geometric series).
        let term = PronyTerm::new(0.4, 0.5);
        let mut st = PronyState::new(vec![term], vec![0]);
        let dt = 0.01;
        for n in 0..200 {
            let mut f = [Vec3::new(2.0, 0.0, 0.0)];
            st.apply(n as f64 * dt, &mut f).unwrap();
            let b: f64 = term.tau / (dt + term.tau);
            let expected = 2.0 * (1.0 - term.alpha * (1.0 - b.powi(n)));
            assert!((f[0].x - expected).abs() < 1e-13, "n = {n}: {} vs {expected}", f[0].x);
            // re-evaluating at the same time does not advance the series
            let mut g = [Vec3::new(2.0, 0.0, 0.0)];
            st.apply(n as f64 * dt, &mut g).unwrap();
            assert_eq!(f[0], g[0]);
        }
        assert!(st.apply(0.0, &mut [Vec3::zeros()]).is_err());
    }
}
