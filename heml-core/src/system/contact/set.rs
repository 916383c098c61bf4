//! [`ToolSet`]: the tools of a system, the contacts of the last force evaluation,
//! and the contact stiffness the implicit solvers add to their operators.

use super::tool::{Tool, ToolId, Wrench};
use crate::system::control::Pose;
use crate::Vec3;
use nalgebra::Matrix3;

/// A tool and what the last force evaluation found for it.
#[derive(Debug, Clone)]
struct Slot {
    tool: Tool,
    /// The system's step count when the pose was last set: the pose is where the
    /// tool is at the end of step `pose_step + 1`.
    pose_step: u64,
    /// Where the tool was at the start of that step (gives its velocity).
    prev: Pose,
    wrench: Wrench,
}

/// One surface node inside a tool at the last force evaluation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// The tool.
    pub tool: ToolId,
    /// The node (system numbering).
    pub node: usize,
    /// Penetration depth (m), > 0.
    pub depth: f64,
    /// The tool's outward unit normal (world frame): the direction of the force.
    pub normal: Vec3,
    /// The force on the node (N).
    pub force: Vec3,
    /// ∂|f|/∂d: the law's stiffness, 0 when the force is clamped at zero.
    pub(crate) stiffness: f64,
    /// ∂|f|/∂(−v_n): the law's damping, 0 when clamped.
    pub(crate) damping: f64,
}

/// The rigid tools of a system ([`crate::system::System::tools`]).
#[derive(Debug, Clone, Default)]
pub struct ToolSet {
    slots: Vec<Option<Slot>>,
    contacts: Vec<Contact>,
    energy: f64,
}

impl ToolSet {
    pub(super) fn insert(&mut self, tool: Tool, step: u64) -> ToolId {
        self.slots.push(Some(Slot {
            tool,
            pose_step: step,
            prev: tool.pose,
            wrench: Wrench::default(),
        }));
        ToolId(self.slots.len() - 1)
    }

    fn slot(&self, id: ToolId) -> Option<&Slot> {
        self.slots.get(id.0).and_then(Option::as_ref)
    }

    /// Moves tool `id` to `pose` before the step after `step` completed steps (the
    /// first move since then starts the tool's motion from where it is).
    pub(super) fn set_pose(&mut self, id: ToolId, pose: Pose, step: u64) -> bool {
        let Some(s) = self.slots.get_mut(id.0).and_then(Option::as_mut) else {
            return false;
        };
        if step != s.pose_step {
            s.prev = s.tool.pose;
            s.pose_step = step;
        }
        s.tool.pose = pose;
        true
    }

    pub(super) fn remove(&mut self, id: ToolId) -> Option<Tool> {
        let slot = self.slots.get_mut(id.0)?.take()?;
        self.contacts.retain(|c| c.tool != id);
        Some(slot.tool)
    }

    /// The tool `id`, if it exists.
    pub fn get(&self, id: ToolId) -> Option<&Tool> {
        self.slot(id).map(|s| &s.tool)
    }

    /// The wrench the tissue applied to tool `id` at the last force evaluation.
    pub fn wrench(&self, id: ToolId) -> Option<Wrench> {
        self.slot(id).map(|s| s.wrench)
    }

    /// The ids of the tools, in order of creation.
    pub fn ids(&self) -> impl Iterator<Item = ToolId> + '_ {
        self.slots
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_some())
            .map(|(i, _)| ToolId(i))
    }

    /// Number of tools.
    pub fn len(&self) -> usize {
        self.slots.iter().filter(|s| s.is_some()).count()
    }

    /// Whether there is no tool.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The penetrating surface nodes of the last force evaluation.
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// The deepest penetration of the last force evaluation (0 without contact).
    pub fn max_penetration(&self) -> f64 {
        self.contacts.iter().map(|c| c.depth).fold(0.0, f64::max)
    }

    /// The penalty potential Σ ½ k d² of the last force evaluation (J).
    pub fn energy(&self) -> f64 {
        self.energy
    }

    /// Adds the contact forces of every tool on the nodes `surface` (positions `x`,
    /// velocities `v`) to `force`, and records contacts, wrenches and energy.
    ///
    /// `step`: inside a step, the number of completed steps and the step size. A
    /// tool moved before this step moves, during it, from its previous pose to the
    /// new one at constant velocity (what the damping sees); outside a step (a
    /// static solve) and when not moved, tools are at rest.
    pub(crate) fn add_forces(
        &mut self,
        surface: &[u32],
        x: &[Vec3],
        v: &[Vec3],
        step: Option<(u64, f64)>,
        force: &mut [Vec3],
    ) {
        self.contacts.clear();
        self.energy = 0.0;
        for (k, slot) in self.slots.iter_mut().enumerate() {
            let Some(s) = slot else { continue };
            let pose = s.tool.pose;
            let law = s.tool.law;
            let inv = pose.inverse();
            // velocity of the tool's material point now at y: (y − where it was)/dt
            let prev = step
                .filter(|&(n, _)| n == s.pose_step && s.prev != pose)
                .map(|(_, dt)| (s.prev, 1.0 / dt));
            let mut w = Wrench::default();
            for &i in surface {
                let i = i as usize;
                let local = inv.apply(x[i]);
                let Some((depth, n_local)) = s.tool.shape.penetration(local) else {
                    continue;
                };
                let n = pose.rotate(n_local);
                let v_tool = prev.map_or(Vec3::zeros(), |(p, inv_dt)| (x[i] - p.apply(local)) * inv_dt);
                let (magnitude, active) = law.normal_force(depth, (v[i] - v_tool).dot(&n));
                let f = n * magnitude;
                force[i] += f;
                w.force -= f;
                w.torque -= (x[i] - pose.translation).cross(&f);
                self.energy += 0.5 * law.stiffness * depth * depth;
                let (stiffness, damping) = if active {
                    (law.stiffness, law.damping)
                } else {
                    (0.0, 0.0)
                };
                self.contacts.push(Contact {
                    tool: ToolId(k),
                    node: i,
                    depth,
                    normal: n,
                    force: f,
                    stiffness,
                    damping,
                });
            }
            s.wrench = w;
        }
    }

    /// ∂F/∂t: the derivative of the contact force F on tool `id` (the tissue's push,
    /// minus the sum of the nodal contact forces) with respect to the tool's
    /// translation t, the tissue nodes at `x` held where they are and at rest — the
    /// stiffness the tool feels over times too short for the tissue to move. Of the
    /// contacts of the last force evaluation (call it right after one, before the
    /// tool moves). Each active contact (force φ·n, φ = k·d − c·v_n > 0) adds
    /// −(k n nᵀ − φ R (∂n/∂p) Rᵀ): the depth grows by n·δ when the tool moves by δ
    /// and the normal turns with the tool ([`ToolShape::normal_derivative`], R the
    /// tool's rotation); the dashpot adds nothing at rest. A clamped contact (φ = 0)
    /// adds nothing: the one-sided derivative of a force that only pushes.
    /// Symmetric. Not always negative semidefinite: the turning term φ/r·(I − n nᵀ)
    /// is positive sideways (a ball on a point slides off), which is why a haptic
    /// renderer projects it ([`super::LocalModel`]).
    ///
    /// [`ToolShape::normal_derivative`]: super::ToolShape::normal_derivative
    pub fn translation_stiffness(&self, id: ToolId, x: &[Vec3]) -> Option<Matrix3<f64>> {
        let s = self.slot(id)?;
        let pose = s.tool.pose;
        let inv = pose.inverse();
        let r = Matrix3::from_columns(&[pose.rotate(Vec3::x()), pose.rotate(Vec3::y()), pose.rotate(Vec3::z())]);
        let mut k = Matrix3::zeros();
        for c in self.contacts.iter().filter(|c| c.tool == id && c.stiffness > 0.0) {
            let turn = r * s.tool.shape.normal_derivative(inv.apply(x[c.node])) * r.transpose();
            k -= c.normal * c.normal.transpose() * c.stiffness - turn * c.force.norm();
        }
        Some(k)
    }

    /// Adds the contact tangent (k + c·c_v)·n nᵀ of every active contact to the
    /// nodal 3×3 diagonal blocks; `cv` = ∂v/∂x of the scheme (0 for a static solve).
    /// The curvature term k·d·∂n/∂x is left out: it is negative (it would make the
    /// operator indefinite) and vanishes with the depth.
    pub(crate) fn add_diagonal_blocks(&self, cv: f64, blocks: &mut [Matrix3<f64>]) {
        for c in &self.contacts {
            blocks[c.node] += c.normal * c.normal.transpose() * (c.stiffness + c.damping * cv);
        }
    }
}
