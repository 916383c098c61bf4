//! Runtime control of a [`System`](super::System) between steps: what tools, grasps
//! and moving node groups need.

mod pose;

pub use pose::Pose;
