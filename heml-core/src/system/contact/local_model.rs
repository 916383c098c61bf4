//! The local model of the tool–tissue interaction that the simulation publishes
//! for the haptic device (the "intermediate representation" of multirate haptics):
//! [`LocalModel`], whose docs give the design (which stiffness, bounded and passive
//! rendering), and [`StiffnessEstimator`], which builds it.

use crate::Vec3;
use nalgebra::{Matrix3, SymmetricEigen};
use std::time::Instant;

/// A first-order model of the force on a tool around a pose, published by the
/// simulation for a haptic device.
///
/// A 1 kHz device cannot wait for a simulation that advances 1 ms of simulated time
/// in several milliseconds of wall time. So the simulation publishes, with each
/// state, a first-order model of the force around the tool's pose — the force F₀ it
/// computed at the tool's translation x₀ and a stiffness K = ∂F/∂x — and the device
/// renders F(x) = F₀ + K·(x − x₀) at its own rate, at its current pose, without
/// waiting (Mark et al. 1996; Çavuşoğlu & Tendick 2000).
///
/// **Which K.** The contact stiffness with the tissue held still
/// ([`super::ToolSet::translation_stiffness`]) is exact over times too short for the
/// tissue to move, but over one simulation period the surface nodes yield, and the
/// force grows far less than the penalty springs alone predict (a soft organ is
/// some 10–100× more compliant than its contact springs). [`StiffnessEstimator`]
/// therefore corrects it with the tissue's observed compliance: a Broyden
/// (secant) update from the force change between successive states along the tool's
/// motion, bounded between 0 and the contact stiffness.
///
/// **Rendering: bounded and passive.** [`LocalModel::force_at`] renders a
/// symmetric negative semidefinite K (the estimator projects it so), never pulls (a
/// contact only pushes: the force is zero where the model would reverse F₀), and
/// bounds the extrapolation: the model is exact only near x₀, and a device that
/// runs ahead of a slow or stalled simulation would otherwise render K·(x − x₀)
/// over centimetres the simulation never computed (measured before this bound: a
/// 25 ms-old model rendered 1.23 N where the simulation computed 0.10 N). So each
/// model carries a **reach** r, the tool travel from x₀ the simulation vouches for
/// (in [`super::run_haptic_loop`], the simulated tool's largest travel in one
/// iteration: the next state's tool lies within r of x₀), and the rendered force is
/// clamped to the ball
///
/// |F(x)| ≤ min(F_max, |F₀| + ‖K‖_F · r),
///
/// which leaves F₀ + K·(x − x₀) untouched within r of x₀ (there |K·(x − x₀)| ≤
/// ‖K‖_F·r) and stops it growing beyond; unloading (the tool backing out to lift-off)
/// is never clamped. Passivity: the unclamped field F₀ + K·(x − x₀) is the gradient
/// of a concave potential (K symmetric negative semidefinite), and for an isotropic
/// K the radial clamp keeps it a gradient (the projection onto a ball of a gradient
/// map with a scalar Jacobian), so the device gains no energy around a closed path;
/// a new model can only change the force by what the simulation computed. A device
/// with virtual coupling adds its own damping on top.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalModel {
    /// The force the tissue applied to the tool at [`LocalModel::position`] (N).
    pub force: Vec3,
    /// The tool's translation the model was computed at (m).
    pub position: Vec3,
    /// ∂F/∂x that the device renders (N/m): symmetric, negative semidefinite.
    pub stiffness: Matrix3<f64>,
    /// The tool travel from [`LocalModel::position`] the simulation vouches for (m):
    /// [`LocalModel::force_at`] renders at most |F₀| + ‖K‖_F × reach
    /// (see [`LocalModel`]). 0 renders a zero-order hold beyond F₀'s size;
    /// infinity, the unbounded first-order model.
    pub reach: f64,
    /// Simulated time of the state (s).
    pub time: f64,
    /// Step count of the state.
    pub step: u64,
    /// When the simulation published it (the device's staleness clock).
    pub published: Instant,
}

impl LocalModel {
    /// No contact at `position`: zero force and stiffness.
    pub fn empty(position: Vec3) -> Self {
        LocalModel {
            force: Vec3::zeros(),
            position,
            stiffness: Matrix3::zeros(),
            reach: 0.0,
            time: 0.0,
            step: 0,
            published: Instant::now(),
        }
    }

    /// The largest force [`LocalModel::force_at`] renders with a device limit of
    /// `max_force` (N): min(`max_force`, |F₀| + ‖K‖_F × [`LocalModel::reach`]).
    pub fn bound(&self, max_force: f64) -> f64 {
        let k = self.stiffness.norm();
        // 0 × ∞ is no extrapolation (K = 0 with an unbounded reach), not NaN
        let extrapolation = if k > 0.0 && self.reach > 0.0 {
            k * self.reach
        } else {
            0.0
        };
        max_force.min(self.force.norm() + extrapolation)
    }

    /// The force to render at the device's tool translation `x`:
    /// F₀ + K·(x − x₀), zero where it would point against F₀ (contact never pulls),
    /// and no longer than [`LocalModel::bound`] (`max_force` in N, or less when the
    /// device has travelled beyond the model's reach).
    ///
    /// ```
    /// use heml_core::system::contact::LocalModel;
    /// use heml_core::Vec3;
    /// use nalgebra::Matrix3;
    /// let mut m = LocalModel::empty(Vec3::zeros());
    /// m.force = Vec3::new(0.0, 0.0, 1.0); // 1 N up, 100 N/m along z, vouched for 5 mm
    /// m.stiffness = Matrix3::from_diagonal(&Vec3::new(0.0, 0.0, -100.0));
    /// m.reach = 0.005;
    /// assert_eq!(m.force_at(Vec3::new(0.0, 0.0, -0.002), 10.0).z, 1.2); // pressed 2 mm further
    /// assert_eq!(m.force_at(Vec3::new(0.0, 0.0, 0.05), 10.0), Vec3::zeros()); // lifted off: no pull
    /// // a metre beyond the reach: 1 N + 100 N/m × 5 mm, not 101 N (to a rescaling's round-off)
    /// assert!((m.force_at(Vec3::new(0.0, 0.0, -1.0), 10.0).z - 1.5).abs() < 1e-15);
    /// assert_eq!(m.bound(1.2), 1.2); // or the device's limit, when lower
    /// ```
    pub fn force_at(&self, x: Vec3, max_force: f64) -> Vec3 {
        if self.force == Vec3::zeros() {
            return Vec3::zeros();
        }
        let f = self.force + self.stiffness * (x - self.position);
        if f.dot(&self.force) <= 0.0 || !f.iter().all(|c| c.is_finite()) {
            return Vec3::zeros();
        }
        let n = f.norm();
        let bound = self.bound(max_force);
        if n > bound {
            f * (bound / n)
        } else {
            f
        }
    }
}

/// The symmetric part of `k` with its eigenvalues clamped to [−`max`, 0]: the
/// nearest stiffness a device can render passively and stably.
fn renderable(k: &Matrix3<f64>, max: f64) -> Matrix3<f64> {
    let mut e = SymmetricEigen::new((k + k.transpose()) * 0.5);
    e.eigenvalues.iter_mut().for_each(|l| *l = l.clamp(-max, 0.0));
    e.recompose()
}

/// Builds [`LocalModel`]s from successive simulation states (on the simulation
/// thread): the contact stiffness corrected by the tissue's observed compliance
/// (see [`LocalModel`], "Which K").
///
/// Per new state (tool at x with force F, contact stiffness K_c): without contact
/// the model is empty and the history forgotten; on first contact K = K_c (the
/// short-time response); afterwards, when the tool moved by Δx (more than
/// `min_motion`), the secant condition K Δx = ΔF is imposed along Δx (Broyden:
/// K += (ΔF − K Δx) Δxᵀ / |Δx|²), and K is projected onto symmetric matrices with
/// eigenvalues in [−‖K_c‖, 0]: the tissue can only make the contact softer, never
/// stiffer nor unstable. Each model carries [`StiffnessEstimator::reach`].
#[derive(Debug, Clone, PartialEq)]
pub struct StiffnessEstimator {
    /// Smallest tool motion (m) between states that updates K (default 1 µm):
    /// below it, the force change is the tissue's own motion, not a response.
    pub min_motion: f64,
    /// The [`LocalModel::reach`] of the models (m). Default 0.25 mm: the travel of
    /// a tool following its device at 0.25 m/s for one 1 ms period, as
    /// [`super::run_haptic_loop`]'s simulated tool does by default (it sets this
    /// from its options).
    pub reach: f64,
    last: Option<(Vec3, Vec3)>,
    k: Matrix3<f64>,
}

impl Default for StiffnessEstimator {
    fn default() -> Self {
        StiffnessEstimator {
            min_motion: 1e-6,
            reach: 2.5e-4,
            last: None,
            k: Matrix3::zeros(),
        }
    }
}

impl StiffnessEstimator {
    /// The stiffness to publish for a state with the tool at `x`, force `force` and
    /// contact stiffness `contact` ([`super::ToolSet::translation_stiffness`]).
    pub fn update(&mut self, x: Vec3, force: Vec3, contact: &Matrix3<f64>) -> Matrix3<f64> {
        let bound = contact.norm(); // Frobenius ≥ spectral: a safe upper bound
        if force == Vec3::zeros() || bound == 0.0 {
            self.last = None;
            self.k = Matrix3::zeros();
            return self.k;
        }
        match self.last {
            None => self.k = *contact,
            Some((x0, f0)) => {
                let dx = x - x0;
                let d2 = dx.norm_squared();
                if d2 > self.min_motion * self.min_motion {
                    self.k += (force - f0 - self.k * dx) * dx.transpose() / d2;
                }
            }
        }
        self.k = renderable(&self.k, bound);
        self.last = Some((x, force));
        self.k
    }

    /// The model of tool `tool` of `sys` at its current state (call right after a
    /// step, before the tool moves), with the corrected stiffness.
    pub fn model(&mut self, sys: &crate::system::System, tool: super::ToolId) -> crate::Result<LocalModel> {
        let force = sys.tool_wrench(tool)?.force;
        let contact = sys.tool_stiffness(tool)?;
        let position = sys.tools().get(tool).map_or(Vec3::zeros(), |t| t.pose.translation);
        Ok(LocalModel {
            force,
            position,
            stiffness: self.update(position, force, &contact),
            reach: self.reach,
            time: sys.time(),
            step: sys.step_count(),
            published: Instant::now(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Along a 1-D press into a linear spring of stiffness s behind a stiffer contact
    /// (series: the force grows by s·dz), the estimator learns −s along z from the
    /// secants and keeps the other directions within bounds.
    #[test]
    fn estimator_learns_the_secant_and_stays_renderable() {
        let contact = Matrix3::from_diagonal(&Vec3::new(-500.0, -500.0, -2000.0));
        let s = 40.0;
        let mut est = StiffnessEstimator::default();
        let mut k = Matrix3::zeros();
        for i in 0..20 {
            let z = -1e-4 * f64::from(i);
            k = est.update(Vec3::new(0.0, 0.0, z), Vec3::new(0.0, 0.0, 0.1 - s * z), &contact);
        }
        // exact secants of an affine force along z: the zz entry is −s to round-off
        // (relative 1e-9: a few operations on values of size 1e3)
        assert!((k[(2, 2)] + s).abs() < 1e-9 * 2000.0, "{k}");
        let e = SymmetricEigen::new(k).eigenvalues;
        // renderable: symmetric with eigenvalues in [−‖K_c‖, 0]
        assert!(e.iter().all(|&l| l <= 0.0 && l >= -contact.norm()));
        assert_eq!(k, k.transpose());
        // losing contact forgets everything
        assert_eq!(
            est.update(Vec3::zeros(), Vec3::zeros(), &Matrix3::zeros()),
            Matrix3::zeros()
        );
    }
}
