//! What every runtime-control call shares: the checks of its input (all made before
//! anything changes, so that an error leaves the system as it was) and the
//! bookkeeping after a change (derived data and caches brought up to date).

use crate::error::{HemlError, Result};
use crate::system::stability::{critical_time_step, damped_safe};
use crate::system::System;
use crate::Vec3;

impl System {
    /// Errors inside a step (between `begin_step` and `finish_step`): the model may
    /// change only between steps.
    pub(crate) fn check_between_steps(&self, what: &str) -> Result<()> {
        match self.state.in_step {
            None => Ok(()),
            Some((t0, dt)) => Err(HemlError::Invalid(format!(
                "{what}: called inside a step (step {} from t = {t0}, dt = {dt}, between begin_step and \
                 finish_step); runtime control changes the system only between steps",
                self.state.step + 1
            ))),
        }
    }

    /// Checks a node set: not empty, every id in range, none twice.
    pub(super) fn check_node_set(&self, what: &str, nodes: &[usize]) -> Result<()> {
        let n = self.state.x.len();
        if nodes.is_empty() {
            return Err(HemlError::Invalid(format!("{what}: the node set is empty")));
        }
        let mut seen = vec![false; n];
        for &i in nodes {
            if i >= n {
                return Err(HemlError::Invalid(format!(
                    "{what}: node id {i} is out of range (the mesh has {n} nodes, ids 0..{})",
                    n.saturating_sub(1)
                )));
            }
            if std::mem::replace(&mut seen[i], true) {
                return Err(HemlError::Invalid(format!(
                    "{what}: node {} is listed twice",
                    self.input_id(i)
                )));
            }
        }
        Ok(())
    }

    /// Checks that every component of `v` is finite.
    pub(super) fn check_finite(what: &str, v: &Vec3) -> Result<()> {
        if v.iter().all(|c| c.is_finite()) {
            Ok(())
        } else {
            Err(HemlError::Invalid(format!("{what} {:?} is not finite", v.as_slice())))
        }
    }

    /// After a change of loads or grasps: the forces, the elastic energy and the
    /// caches that outlive a step (Newmark's acceleration) are stale, and the stable
    /// step may have moved (grasps enter it).
    pub(super) fn model_changed(&mut self) {
        self.model.revision += 1;
        self.invalidate();
        self.stepping.stable_dt = damped_safe(self, self.stepping.critical_dt);
    }

    /// After a change of the constraint lists: the mask, inverse masses, constrained
    /// ids and reactions follow them, the stable step is re-estimated when the set of
    /// free nodes changed (the power iteration of link laws runs over the free
    /// nodes), and the constraints are imposed at the current time (as the builder
    /// imposes them at t = 0), then [`Self::model_changed`].
    pub(super) fn constraints_changed(&mut self) {
        let n = self.state.x.len();
        let c = &mut self.model.constraints;
        c.mask = vec![false; n];
        for &i in &c.fixed {
            c.mask[i] = true;
        }
        for p in &c.prescribed {
            c.mask[p.node] = true;
        }
        let ids = c.constrained_nodes();
        for i in 0..n {
            self.model.inv_mass[i] = if c.mask[i] { 0.0 } else { 1.0 / self.model.mass[i] };
            if !c.mask[i] {
                self.eval.reaction[i] = Vec3::zeros();
            }
        }
        if ids != self.model.constrained_ids {
            self.model.constrained_ids = ids;
            self.eval.reaction_total = self.model.constrained_ids.iter().map(|&i| self.eval.reaction[i]).sum();
            self.stepping.critical_dt = critical_time_step(self);
        }
        let t = self.state.t;
        self.apply_constraints(t);
        self.model_changed();
    }
}
