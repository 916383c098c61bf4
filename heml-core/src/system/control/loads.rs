//! Runtime control of the loads: gravity and constant nodal forces.

use crate::error::Result;
use crate::system::System;
use crate::Vec3;

impl System {
    /// Sets the gravity acceleration (applied as m_i g from the next force
    /// evaluation). Errors inside a step or on a non-finite vector, leaving the
    /// system unchanged.
    pub fn set_gravity(&mut self, g: Vec3) -> Result<()> {
        self.check_between_steps("set_gravity")?;
        Self::check_finite("set_gravity: gravity", &g)?;
        self.model.gravity = g;
        self.model_changed();
        Ok(())
    }

    /// Replaces the constant nodal forces by `forces` (node, force); several entries
    /// on one node add up, as in [`SystemBuilder::nodal_force`](crate::system::SystemBuilder::nodal_force).
    /// Errors inside a step, on an unknown node or a non-finite force, leaving the
    /// system unchanged.
    pub fn set_nodal_forces(&mut self, forces: &[(usize, Vec3)]) -> Result<()> {
        self.check_between_steps("set_nodal_forces")?;
        for &(i, f) in forces {
            self.check_node_set("set_nodal_forces", &[i])?;
            Self::check_finite(&format!("set_nodal_forces: force on node {}", self.input_id(i)), &f)?;
        }
        self.model.nodal = forces.to_vec();
        self.model_changed();
        Ok(())
    }

    /// Removes every constant nodal force. Errors inside a step.
    pub fn clear_nodal_forces(&mut self) -> Result<()> {
        self.set_nodal_forces(&[])
    }
}
