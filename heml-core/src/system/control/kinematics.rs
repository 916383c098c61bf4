//! Runtime control of the kinematic constraints: fixing and releasing nodes, and
//! moving a prescribed node group to a rigid pose or to per-node targets.
//!
//! The constraints are imposed at once at the current time (a fixed node goes back to
//! its rest position, a prescribed one to its target, both with zero velocity): the
//! system is then the one the builder would make with the same constraint lists and
//! the current state. A moved group jumps to its new place; move it in small
//! increments (e.g. once per step, along a [`Pose::lerp`] path) for a smooth motion.

use super::Pose;
use crate::error::{HemlError, Result};
use crate::system::constraints::{Prescribed, Ramp};
use crate::system::System;
use crate::Vec3;

impl System {
    /// Holds `nodes` at their rest positions (as
    /// [`SystemBuilder::fix_nodes`](crate::system::SystemBuilder::fix_nodes) does);
    /// prescribed nodes among them become fixed. Masses do not change; the inverse
    /// masses, constrained ids, reactions and the stable step follow. Errors inside a
    /// step, on an empty set, an unknown node or a node listed twice, leaving the
    /// system unchanged.
    pub fn fix_nodes(&mut self, nodes: &[usize]) -> Result<()> {
        self.check_between_steps("fix_nodes")?;
        self.check_node_set("fix_nodes", nodes)?;
        let chosen = mask(self.state.x.len(), nodes);
        let c = &mut self.model.constraints;
        c.prescribed.retain(|p| !chosen[p.node]);
        c.fixed.extend(nodes);
        c.fixed.sort_unstable();
        c.fixed.dedup();
        self.constraints_changed();
        Ok(())
    }

    /// Releases `nodes` (fixed or prescribed): they move freely from their current
    /// position and velocity on, and their reactions drop to zero. Errors inside a
    /// step, on an empty set, an unknown node, a node listed twice, a node that is
    /// not constrained or one that belongs to no tet (it has no mass to move with),
    /// leaving the system unchanged.
    pub fn release_nodes(&mut self, nodes: &[usize]) -> Result<()> {
        self.check_between_steps("release_nodes")?;
        self.check_node_set("release_nodes", nodes)?;
        for &i in nodes {
            if !self.model.constraints.is_constrained(i) {
                return Err(HemlError::Invalid(format!(
                    "release_nodes: node {} is not constrained (neither fixed nor prescribed)",
                    self.input_id(i)
                )));
            }
            if self.model.mass[i] <= 0.0 {
                return Err(HemlError::Invalid(format!(
                    "release_nodes: node {} belongs to no tet and has no mass; it cannot move freely",
                    self.input_id(i)
                )));
            }
        }
        let chosen = mask(self.state.x.len(), nodes);
        let c = &mut self.model.constraints;
        c.fixed.retain(|&i| !chosen[i]);
        c.prescribed.retain(|p| !chosen[p.node]);
        self.constraints_changed();
        Ok(())
    }

    /// Prescribes `nodes` at `pose` applied to their rest positions, x_i = R X_i + t,
    /// with zero velocity (free and fixed nodes among them become prescribed, the
    /// prescribed ones get the new target). The same as the builder's
    /// `prescribe_with(nodes, |X| pose.apply(X) − X, Ramp::Step)`. Errors inside a
    /// step, on a non-finite pose, an empty set, an unknown node or a node listed
    /// twice, leaving the system unchanged.
    pub fn prescribe_pose(&mut self, nodes: &[usize], pose: &Pose) -> Result<()> {
        self.check_between_steps("prescribe_pose")?;
        pose.check()
            .map_err(|e| HemlError::Invalid(format!("prescribe_pose: {e}")))?;
        self.check_node_set("prescribe_pose", nodes)?;
        let rest = self.model.mesh.nodes();
        let targets: Vec<Vec3> = nodes.iter().map(|&i| pose.apply(rest[i])).collect();
        self.set_prescribed(nodes, &targets);
        Ok(())
    }

    /// Prescribes each of `nodes` at its own target position `targets[k]`, with zero
    /// velocity. Errors inside a step, on a length mismatch, a non-finite target, an
    /// empty set, an unknown node or a node listed twice, leaving the system
    /// unchanged.
    pub fn prescribe_targets(&mut self, nodes: &[usize], targets: &[Vec3]) -> Result<()> {
        self.check_between_steps("prescribe_targets")?;
        self.check_node_set("prescribe_targets", nodes)?;
        if targets.len() != nodes.len() {
            return Err(HemlError::Invalid(format!(
                "prescribe_targets: {} targets for {} nodes (one per node)",
                targets.len(),
                nodes.len()
            )));
        }
        for (&i, t) in nodes.iter().zip(targets) {
            Self::check_finite(&format!("prescribe_targets: target of node {}", self.input_id(i)), t)?;
        }
        self.set_prescribed(nodes, targets);
        Ok(())
    }

    /// Prescribes checked `nodes` at `targets` (held, Step ramp).
    fn set_prescribed(&mut self, nodes: &[usize], targets: &[Vec3]) {
        let rest = self.model.mesh.nodes();
        let new: Vec<Prescribed> = nodes
            .iter()
            .zip(targets)
            .map(|(&node, t)| Prescribed {
                node,
                displacement: t - rest[node],
                ramp: Ramp::Step,
            })
            .collect();
        let n = self.state.x.len();
        let chosen = mask(n, nodes);
        let c = &mut self.model.constraints;
        c.fixed.retain(|&i| !chosen[i]);
        let mut slot = vec![None; n];
        for (k, p) in c.prescribed.iter().enumerate() {
            slot[p.node] = Some(k);
        }
        for p in new {
            match slot[p.node] {
                Some(k) => c.prescribed[k] = p,
                None => c.prescribed.push(p),
            }
        }
        self.constraints_changed();
    }
}

/// `nodes` (checked ids) as a per-node flag.
fn mask(n: usize, nodes: &[usize]) -> Vec<bool> {
    let mut m = vec![false; n];
    for &i in nodes {
        m[i] = true;
    }
    m
}
