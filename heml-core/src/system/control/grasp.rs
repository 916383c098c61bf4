//! Soft grasps: a node set tied to a target pose by per-node springs with damping,
//! the "spring to target" actuator of soft-tissue simulators.
//!
//! Each grasped node i gets the force f_i = −k (x_i − T(a_i)) − c v_i, with T the
//! grasp's current target pose and a_i the node's **anchor**: its position at grasp
//! time expressed in the frame of the pose given to
//! [`System::grasp`](crate::system::System::grasp), a_i = T₀⁻¹ x_i(t_grasp). So a
//! grasp holds its nodes where they are when it closes, whatever T₀ is (a tool's
//! world pose works as is), and moving the target to T moves the anchors rigidly with
//! it: T T₀⁻¹ is the motion applied to the grasped patch. With T₀ = identity the
//! anchors are the grasp-time positions themselves.

use super::Pose;
use crate::error::{HemlError, Result};
use crate::system::System;
use crate::Vec3;

/// Names a grasp of a [`System`] (never reused in a system).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct GraspId(pub(crate) u64);

impl GraspId {
    /// Its number (bindings and logs name grasps by it; never reused in a system).
    pub fn index(self) -> u64 {
        self.0
    }
}

impl std::fmt::Display for GraspId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "grasp #{}", self.0)
    }
}

/// One grasp: its nodes, their anchors, the target pose and the spring constants.
#[derive(Debug, Clone)]
pub(crate) struct Grasp {
    pub(crate) nodes: Vec<usize>,
    /// a_i = T₀⁻¹ x_i at grasp time.
    pub(crate) anchors: Vec<Vec3>,
    pub(crate) pose: Pose,
    /// Spring stiffness k (N/m) per node.
    pub(crate) stiffness: f64,
    /// Damping c (N·s/m) per node.
    pub(crate) damping: f64,
}

impl Grasp {
    /// Where the springs pull node `nodes[k]`.
    fn target(&self, k: usize) -> Vec3 {
        self.pose.apply(self.anchors[k])
    }

    /// Σ over the nodes of k (x_i − T(a_i)) + c v_i: the force the tissue applies to
    /// the grasp (minus what the grasp applies to the tissue).
    pub(crate) fn force_on_grasp(&self, x: &[Vec3], v: &[Vec3]) -> Vec3 {
        (0..self.nodes.len())
            .map(|k| {
                let i = self.nodes[k];
                (x[i] - self.target(k)) * self.stiffness + v[i] * self.damping
            })
            .sum()
    }

    /// ½ k Σ |x_i − T(a_i)|².
    fn energy(&self, x: &[Vec3]) -> f64 {
        0.5 * self.stiffness
            * self
                .nodes
                .iter()
                .enumerate()
                .map(|(k, &i)| (x[i] - self.target(k)).norm_squared())
                .sum::<f64>()
    }
}

/// The grasps of a system, in creation order (forces are summed in that order, so
/// runs are reproducible bit for bit).
#[derive(Debug, Clone, Default)]
pub(crate) struct Grasps {
    next: u64,
    list: Vec<(GraspId, Grasp)>,
}

impl Grasps {
    /// Adds a grasp; returns its id.
    pub(crate) fn insert(&mut self, grasp: Grasp) -> GraspId {
        let id = GraspId(self.next);
        self.next += 1;
        self.list.push((id, grasp));
        id
    }

    pub(crate) fn get(&self, id: GraspId) -> Option<&Grasp> {
        self.list.iter().find(|(g, _)| *g == id).map(|(_, g)| g)
    }

    pub(crate) fn get_mut(&mut self, id: GraspId) -> Option<&mut Grasp> {
        self.list.iter_mut().find(|(g, _)| *g == id).map(|(_, g)| g)
    }

    pub(crate) fn remove(&mut self, id: GraspId) -> Option<Grasp> {
        let k = self.list.iter().position(|(g, _)| *g == id)?;
        Some(self.list.remove(k).1)
    }

    pub(crate) fn ids(&self) -> impl Iterator<Item = GraspId> + '_ {
        self.list.iter().map(|(id, _)| *id)
    }

    /// Adds every grasp's spring and damper forces to `f`.
    pub(crate) fn add_forces(&self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        for (_, g) in &self.list {
            for (k, &i) in g.nodes.iter().enumerate() {
                f[i] -= (x[i] - g.target(k)) * g.stiffness + v[i] * g.damping;
            }
        }
    }

    /// Potential energy of all the springs.
    pub(crate) fn energy(&self, x: &[Vec3]) -> f64 {
        self.list.iter().map(|(_, g)| g.energy(x)).sum()
    }

    /// Σ over the grasped nodes of c/(2·`cv`)·|v⁺_i|², with v⁺_i = `velocity(i)`
    /// the end-of-step velocity of an implicit step (v⁺ = v + c_v d): the
    /// dissipation potential of the dampers, whose gradient with respect to the
    /// end-of-step positions is c·v⁺, minus their force. The implicit step's
    /// line-search merit needs it: without it the Newton step (which solves for
    /// the dampers' force too) is no descent direction of the merit where the
    /// dampers dominate, as on a grasped patch of small nodes (c·c_v = 50 N/m
    /// against m/h² ≈ 0.003 N/m on gen_kidney_100k's end: the line search stalled
    /// at every step and the motion diverged).
    pub(crate) fn damper_potential(&self, velocity: impl Fn(usize) -> Vec3, cv: f64) -> f64 {
        self.list
            .iter()
            .map(|(_, g)| 0.5 * g.damping / cv * g.nodes.iter().map(|&i| velocity(i).norm_squared()).sum::<f64>())
            .sum()
    }

    /// Per node, Σ over the grasps holding it of k + c·`cv`: what the springs and
    /// dampers add to the diagonal of an implicit step's operator when the
    /// end-of-step velocity is v⁺ = v + c_v d. `None` without grasps.
    pub(crate) fn diagonal(&self, n: usize, cv: f64) -> Option<Vec<f64>> {
        if self.list.is_empty() {
            return None;
        }
        let mut d = vec![0.0; n];
        for (_, g) in &self.list {
            for &i in &g.nodes {
                d[i] += g.stiffness + g.damping * cv;
            }
        }
        Some(d)
    }

    /// (max_i Σk/m_i, max_i Σc/m_i) over the free grasped nodes (`inv_mass` is 0 on
    /// constrained ones): the squared frequency and the mass-damping rate the springs
    /// add to the explicit stability estimate.
    pub(crate) fn rates(&self, inv_mass: &[f64]) -> (f64, f64) {
        if self.list.is_empty() {
            return (0.0, 0.0);
        }
        let mut k = vec![0.0; inv_mass.len()];
        let mut c = vec![0.0; inv_mass.len()];
        for (_, g) in &self.list {
            for &i in &g.nodes {
                k[i] += g.stiffness;
                c[i] += g.damping;
            }
        }
        let max = |s: &[f64]| s.iter().zip(inv_mass).map(|(a, im)| a * im).fold(0.0, f64::max);
        (max(&k), max(&c))
    }
}

impl System {
    /// Grasps `nodes` with springs of stiffness `stiffness` (N/m per node) and
    /// dampers `damping` (N·s/m per node) tied to the target pose `target` (see the
    /// [module docs](self) for the anchors: the grasp holds the nodes where they are
    /// now, and [`System::move_grasp`] moves them rigidly with the target). Constrained
    /// nodes may be grasped: their constraint wins and the spring force goes into
    /// their reaction. The springs enter the explicit stable step (see
    /// [`super::super::stable_time_step`]) and the implicit integrators' tangent.
    ///
    /// Errors inside a step, on an empty set, an unknown node, a node listed twice, a
    /// non-finite pose, a stiffness that is not finite and > 0 or a damping that is
    /// not finite and ≥ 0, leaving the system unchanged.
    pub fn grasp(&mut self, nodes: &[usize], target: Pose, stiffness: f64, damping: f64) -> Result<GraspId> {
        self.check_between_steps("grasp")?;
        self.check_node_set("grasp", nodes)?;
        target
            .check()
            .map_err(|e| HemlError::Invalid(format!("grasp: target {e}")))?;
        if !(stiffness.is_finite() && stiffness > 0.0) {
            return Err(HemlError::Invalid(format!(
                "grasp: stiffness {stiffness} must be a finite number > 0 (N/m)"
            )));
        }
        if !(damping.is_finite() && damping >= 0.0) {
            return Err(HemlError::Invalid(format!(
                "grasp: damping {damping} must be a finite number >= 0 (N·s/m)"
            )));
        }
        let frame = target.inverse();
        let anchors = nodes.iter().map(|&i| frame.apply(self.state.x[i])).collect();
        let id = self.model.grasps.insert(Grasp {
            nodes: nodes.to_vec(),
            anchors,
            pose: target,
            stiffness,
            damping,
        });
        self.model_changed();
        Ok(id)
    }

    /// Moves the target of grasp `id` to `pose`. Errors inside a step, on an unknown
    /// grasp or a non-finite pose, leaving the system unchanged.
    pub fn move_grasp(&mut self, id: GraspId, pose: Pose) -> Result<()> {
        self.check_between_steps("move_grasp")?;
        pose.check()
            .map_err(|e| HemlError::Invalid(format!("move_grasp {id}: {e}")))?;
        let g = self.model.grasps.get_mut(id).ok_or_else(|| unknown("move_grasp", id))?;
        g.pose = pose;
        self.model_changed();
        Ok(())
    }

    /// Opens grasp `id`: its springs stop acting from the next force evaluation.
    /// Errors inside a step or on an unknown (or already released) grasp, leaving the
    /// system unchanged.
    pub fn release_grasp(&mut self, id: GraspId) -> Result<()> {
        self.check_between_steps("release_grasp")?;
        self.model
            .grasps
            .remove(id)
            .ok_or_else(|| unknown("release_grasp", id))?;
        self.model_changed();
        Ok(())
    }

    /// The force the tissue applies to grasp `id` at the current state:
    /// Σ_i k (x_i − T(a_i)) + c v_i, the opposite of what the springs apply to the
    /// tissue (what a haptic device should render). Errors on an unknown grasp.
    pub fn grasp_force(&self, id: GraspId) -> Result<Vec3> {
        let g = self.model.grasps.get(id).ok_or_else(|| unknown("grasp_force", id))?;
        Ok(g.force_on_grasp(&self.state.x, &self.state.v))
    }

    /// The target pose of grasp `id`.
    pub fn grasp_pose(&self, id: GraspId) -> Result<Pose> {
        Ok(self.model.grasps.get(id).ok_or_else(|| unknown("grasp_pose", id))?.pose)
    }

    /// The ids of the grasps in place, oldest first.
    pub fn grasp_ids(&self) -> Vec<GraspId> {
        self.model.grasps.ids().collect()
    }

    /// Adds the forces of the runtime controls (grasp springs and dampers) to the
    /// total force: called once per force evaluation, after the loads.
    pub(crate) fn add_control_forces(&mut self) {
        self.model
            .grasps
            .add_forces(&self.state.x, &self.state.v, &mut self.eval.force);
    }
}

fn unknown(what: &str, id: GraspId) -> HemlError {
    HemlError::Invalid(format!("{what}: no {id} (never made, or already released)"))
}
