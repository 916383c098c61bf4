//! The penalty contact law: a spring and a dashpot along the tool's normal on every
//! penetrating surface node, that only ever pushes.

use crate::error::{HemlError, Result};

/// Penalty contact with damping (per surface node).
///
/// A surface node at depth d > 0 inside a tool, moving with normal velocity
/// v_n = (v − v_tool)·n relative to the tool (n the tool's outward normal, v_n < 0
/// when the node moves further in), receives the force
///
/// f = max(0, k·d − c·v_n) · n
///
/// and no force when d ≤ 0. The clamp at zero keeps the dashpot from gluing a
/// separating node to the tool. The potential ½k·d² of the spring is what the
/// implicit integrators' line search sees.
///
/// **Penetration tolerance.** A tool carrying a normal load F (the sum of the
/// nodal contact force magnitudes; the tool force when the normals are aligned)
/// through n_c penetrating nodes sinks in, at rest, by d ≈ F/(n_c·k), and never
/// deeper than d ≤ F/k (one node carrying everything is the worst case), plus, while it moves at speed u, the ground it
/// covers in one step, u·dt, before the next force evaluation sees it. With an
/// explicit integrator k is bounded by stability: a node of mass m on a spring k is
/// stable for dt < 2√(m/k) (less with damping, see [`ContactLaw::critical_dt`]), so
/// k ≤ 4m/dt² and d ≥ F·dt²/(4m) — halve dt, and the reachable tolerance drops
/// fourfold. Implicit integrators add k to their operator
/// and take any k; d then is F/(n_c·k) + u·dt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactLaw {
    /// Penalty stiffness k (N/m per node), > 0.
    pub stiffness: f64,
    /// Normal damping c (N·s/m per node), ≥ 0.
    pub damping: f64,
}

impl ContactLaw {
    /// A law of stiffness `k` and no damping.
    pub fn stiff(k: f64) -> Self {
        ContactLaw {
            stiffness: k,
            damping: 0.0,
        }
    }

    /// Checks the coefficients: finite, stiffness > 0, damping ≥ 0.
    pub fn check(&self) -> Result<()> {
        if !(self.stiffness.is_finite() && self.stiffness > 0.0) {
            return Err(HemlError::Invalid(format!(
                "contact stiffness = {} must be a finite number > 0 (N/m)",
                self.stiffness
            )));
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return Err(HemlError::Invalid(format!(
                "contact damping = {} must be a finite number >= 0 (N·s/m)",
                self.damping
            )));
        }
        Ok(())
    }

    /// The normal force magnitude at depth `d` > 0 and relative normal velocity
    /// `vn`, and whether the dashpot is active (false when clamped at zero, where
    /// the force no longer depends on the state).
    pub fn normal_force(&self, d: f64, vn: f64) -> (f64, bool) {
        let f = self.stiffness * d - self.damping * vn;
        if f > 0.0 {
            (f, true)
        } else {
            (0.0, false)
        }
    }

    /// The largest stable explicit (symplectic Euler) time step for a node of mass
    /// `m` held only by this contact: (2/ω)(√(1 + ζ²) − ζ) with ω = √(k/m) and
    /// ζ = c/(2√(k·m)) — 2√(m/k) without damping, about 2m/c when the dashpot
    /// dominates (a light node on a strong dashpot is the tighter limit).
    pub fn critical_dt(&self, m: f64) -> f64 {
        let omega = (self.stiffness / m).sqrt();
        let zeta = self.damping / (2.0 * (self.stiffness * m).sqrt());
        2.0 / omega * ((1.0 + zeta * zeta).sqrt() - zeta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Symplectic Euler on m x'' = −k x − c v is stable just below
    /// [`ContactLaw::critical_dt`] and blows up just above it, undamped and with
    /// a dashpot that dominates.
    #[test]
    fn critical_dt_is_the_symplectic_euler_limit() {
        let m = 3e-7;
        for c in [0.0, 1e-4, 0.05] {
            let law = ContactLaw {
                stiffness: 200.0,
                damping: c,
            };
            let h0 = law.critical_dt(m);
            // the largest |x| over 20 000 steps from x = 1 mm at rest
            let run = |h: f64| {
                let (mut x, mut v, mut top) = (1e-3f64, 0.0, 0.0f64);
                for _ in 0..20_000 {
                    v += h * (-law.stiffness * x - c * v) / m;
                    x += h * v;
                    top = top.max(x.abs());
                }
                top
            };
            // 1 % either side: below, the undamped orbit is an ellipse whose x extent
            // is 1/√(1 − (hω/2)²) ≈ 7× the start at hω = 1.98 (damped: less), so
            // 100× bounds it; above, the spectral radius exceeds 1 by O(0.1) and
            // 20 000 steps grow far past 1000×
            assert!(run(0.99 * h0) < 0.1, "c = {c}: unstable below {h0:e}");
            assert!(run(1.01 * h0) > 1.0, "c = {c}: stable above {h0:e}");
        }
        // undamped: 2√(m/k); a dominant dashpot: about 2m/c
        assert!((ContactLaw::stiff(200.0).critical_dt(m) - 2.0 * (m / 200.0f64).sqrt()).abs() < 1e-18);
        let strong = ContactLaw {
            stiffness: 1e-3,
            damping: 0.05,
        };
        assert!((strong.critical_dt(m) / (2.0 * m / 0.05) - 1.0).abs() < 1e-3);
    }
}
