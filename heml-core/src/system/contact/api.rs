//! The tool methods of [`System`]: add, move, read the wrench, remove.

use super::set::ToolSet;
use super::tool::{Tool, ToolId, Wrench};
use crate::error::{HemlError, Result};
use crate::system::control::Pose;
use crate::system::System;

impl System {
    /// Errors when called between [`System::begin_step`] and
    /// [`System::finish_step`]: runtime control acts between steps only.
    fn unknown_tool(&self, id: ToolId) -> HemlError {
        HemlError::Invalid(format!(
            "{id} does not exist (the system has {} tool(s); the ids of removed tools are not reused)",
            self.model.tools.len()
        ))
    }

    /// Adds a rigid tool in contact with the boundary surface; its forces enter
    /// from the next force evaluation. Errors (the system unchanged) on a bad shape,
    /// law or pose, or inside a step. Warns (see [`System::warnings`]) when the
    /// contact makes the surface nodes' explicit stable step
    /// ([`super::ContactLaw::critical_dt`], 2√(m/k) undamped) shorter than [`System::stable_dt`]: explicit integrators then need a smaller
    /// dt; implicit ones do not.
    pub fn add_tool(&mut self, tool: Tool) -> Result<ToolId> {
        self.check_between_steps("add_tool")?;
        tool.check()?;
        let m_min = self
            .model
            .surface
            .nodes()
            .iter()
            .map(|&i| self.model.mass[i as usize])
            .filter(|&m| m > 0.0)
            .fold(f64::INFINITY, f64::min);
        let id = self.model.tools.insert(tool, self.state.step);
        let critical = tool.law.critical_dt(m_min) * self.stepping.safety;
        if critical < self.stepping.stable_dt {
            self.warn(format!(
                "{id}: contact stiffness {:e} N/m limits the explicit time step to {critical:.3e} s (critical step \
                 of the spring and dashpot on the lightest surface node, {m_min:.3e} kg, × safety), below the stable estimate {:.3e} s; \
                 explicit integrators need a smaller dt or a softer contact (implicit ones do not)",
                tool.law.stiffness, self.stepping.stable_dt
            ));
        }
        self.invalidate();
        Ok(id)
    }

    /// Moves tool `id` to `pose`, where it is at the end of the next step
    /// (validated: a non-finite pose is an error and the system keeps the old one).
    /// During that step the tool moves at constant velocity from where it was, and
    /// the contact damping acts on the nodes' velocity relative to it; a tool not
    /// moved before a step, and every tool in a static solve, is at rest.
    pub fn set_tool_pose(&mut self, id: ToolId, pose: Pose) -> Result<()> {
        self.check_between_steps("set_tool_pose")?;
        pose.check().map_err(|e| HemlError::Invalid(format!("{id}: {e}")))?;
        if !self.model.tools.set_pose(id, pose, self.state.step) {
            return Err(self.unknown_tool(id));
        }
        self.invalidate();
        Ok(())
    }

    /// The force and torque (about the tool's pose origin) that the tissue applied
    /// to tool `id` at the last force evaluation — for a completed step, at its end
    /// state: minus the sum of the contact forces on the nodes. Support reactions
    /// ([`System::reactions`]) are separate.
    pub fn tool_wrench(&self, id: ToolId) -> Result<Wrench> {
        self.model.tools.wrench(id).ok_or_else(|| self.unknown_tool(id))
    }

    /// ∂F/∂t of tool `id`: how the force the tissue applies to it changes with its
    /// translation, the tissue held still, from the contacts of the last force
    /// evaluation ([`super::ToolSet::translation_stiffness`]; N/m, symmetric). What a
    /// haptic device renders between simulation states ([`super::LocalModel`]).
    pub fn tool_stiffness(&self, id: ToolId) -> Result<nalgebra::Matrix3<f64>> {
        self.model
            .tools
            .translation_stiffness(id, &self.state.x)
            .ok_or_else(|| self.unknown_tool(id))
    }

    /// Removes tool `id` and returns it.
    pub fn remove_tool(&mut self, id: ToolId) -> Result<Tool> {
        self.check_between_steps("remove_tool")?;
        let tool = self.model.tools.remove(id).ok_or_else(|| self.unknown_tool(id))?;
        self.invalidate();
        Ok(tool)
    }

    /// The tools, with the contacts of the last force evaluation.
    pub fn tools(&self) -> &ToolSet {
        &self.model.tools
    }
}
