//! A rigid tool (shape, contact law, pose), its id in a system, and the wrench the
//! tissue applies to it.

use super::law::ContactLaw;
use super::shape::ToolShape;
use crate::error::Result;
use crate::system::control::Pose;
use crate::Vec3;

/// A rigid tool: a [`ToolShape`] placed by a [`Pose`], touching the tissue through a
/// [`ContactLaw`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tool {
    /// What solid it is, in its own frame.
    pub shape: ToolShape,
    /// How it pushes on the surface nodes inside it.
    pub law: ContactLaw,
    /// Where it is.
    pub pose: Pose,
}

impl Tool {
    /// A sphere of `radius` at the origin.
    pub fn sphere(radius: f64, law: ContactLaw) -> Self {
        Tool {
            shape: ToolShape::Sphere { radius },
            law,
            pose: Pose::identity(),
        }
    }

    /// A capsule of `radius` around the local z axis from −`half_length` to
    /// +`half_length`, at the origin.
    pub fn capsule(radius: f64, half_length: f64, law: ContactLaw) -> Self {
        Tool {
            shape: ToolShape::Capsule { radius, half_length },
            law,
            pose: Pose::identity(),
        }
    }

    /// The half-space local z ≤ 0, at the origin.
    pub fn half_space(law: ContactLaw) -> Self {
        Tool {
            shape: ToolShape::HalfSpace,
            law,
            pose: Pose::identity(),
        }
    }

    /// The same tool at `pose`.
    pub fn at(self, pose: Pose) -> Self {
        Tool { pose, ..self }
    }

    /// Checks shape, law and pose.
    pub fn check(&self) -> Result<()> {
        self.shape.check()?;
        self.law.check()?;
        self.pose.check()
    }
}

/// Which tool of a [`crate::system::System`]: returned by
/// [`crate::system::System::add_tool`]. Ids are never reused, so the id of a removed
/// tool stays an error rather than silently naming another tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ToolId(pub(super) usize);

impl ToolId {
    /// The index (order of creation, from 0).
    pub fn index(self) -> usize {
        self.0
    }
}

impl std::fmt::Display for ToolId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "tool #{}", self.0)
    }
}

/// A force and a torque: what the tissue applies to a tool.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Wrench {
    /// Force on the tool (N).
    pub force: Vec3,
    /// Torque on the tool about its pose's origin (N·m).
    pub torque: Vec3,
}
