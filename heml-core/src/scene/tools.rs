//! `[[tool]]`: rigid tools that follow a keyframed path through a scene (the
//! schema, its checks, and the path the runner samples before every step).

use serde::Deserialize;

use super::Scene;
use crate::error::{HemlError, Result};
use crate::system::contact::{ContactLaw, Tool, ToolId};
use crate::system::control::Pose;
use crate::system::System;
use crate::Vec3;

/// A tool's shape in a scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ToolShapeKind {
    /// A ball of `radius` centred on the pose.
    Sphere,
    /// A capsule of `radius` and `half_length` along the pose's local z.
    Capsule,
    /// The half-space below the pose's local xy plane (outward normal local z).
    HalfSpace,
}

/// One keyframe of a tool path.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeSpec {
    /// Time (s), strictly increasing along the path.
    pub time: f64,
    /// Position of the tool's origin (m).
    #[serde(deserialize_with = "super::exact::vec3")]
    pub position: [f64; 3],
    /// Rotation vector (axis × angle, radians) from the tool's own frame; default
    /// none.
    #[serde(default)]
    #[serde(deserialize_with = "super::exact::vec3")]
    pub rotation: [f64; 3],
}

/// `[[tool]]`: a rigid tool in penalty contact with the boundary surface, moving
/// along a keyframed path (translation interpolated linearly, rotation by slerp,
/// held before the first and after the last keyframe).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolSpec {
    /// Name of the CSV columns `tool_<name>_fx, _fy, _fz` (letters, digits, `_`,
    /// `-`); default `<index>` from 1.
    pub name: Option<String>,
    /// `sphere`, `capsule` or `half_space`.
    pub shape: ToolShapeKind,
    /// Radius (m) of a sphere or capsule.
    pub radius: Option<f64>,
    /// Half the axis length (m) of a capsule.
    pub half_length: Option<f64>,
    /// Penalty stiffness k (N/m per surface node).
    pub stiffness: f64,
    /// Normal damping c (N·s/m per node); default 0.
    #[serde(default)]
    pub damping: f64,
    /// Keyframes (at least one).
    pub path: Vec<KeyframeSpec>,
}

/// A checked tool path: poses at increasing times.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolPath {
    keys: Vec<(f64, Pose)>,
}

impl ToolPath {
    /// The pose at time `t`: Pose::lerp between the keyframes around `t`, the first
    /// before it and the last after it.
    pub fn at(&self, t: f64) -> Pose {
        let k = &self.keys;
        let i = k.partition_point(|(tk, _)| *tk <= t);
        if i == 0 {
            return k[0].1;
        }
        if i == k.len() {
            return k[i - 1].1;
        }
        let ((t0, p0), (t1, p1)) = (k[i - 1], k[i]);
        p0.lerp(&p1, (t - t0) / (t1 - t0))
    }
}

/// A tool of a built scene: its id in the system, its CSV name and its path.
#[derive(Debug, Clone, PartialEq)]
pub struct ScriptedTool {
    /// Id in [`crate::scene::Simulation::system`].
    pub id: ToolId,
    /// Name of its CSV columns.
    pub name: String,
    /// Where it goes.
    pub path: ToolPath,
}

impl ToolSpec {
    /// Checks the entry `i` (0-based; `what` names it with its line) and makes the
    /// tool at its first pose and its path. Errors name the key, e.g.
    /// `tool[1].path[2].time`.
    pub fn checked(&self, i: usize, what: &str) -> Result<(String, Tool, ToolPath)> {
        let key = |k: &str| format!("{what}: tool[{i}].{k}");
        let bad = |k: &str, msg: String| HemlError::Invalid(format!("{} {msg}", key(k)));
        let name = self.name.clone().unwrap_or_else(|| (i + 1).to_string());
        if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
            return Err(bad("name", format!("= {name:?} must be letters, digits, `_` or `-`")));
        }
        let size = |k: &str, v: Option<f64>| -> Result<f64> {
            v.ok_or_else(|| bad(k, format!("is missing (a {:?} needs it)", self.shape)))
        };
        let extra = |k: &str, v: Option<f64>| -> Result<()> {
            match v {
                Some(_) => Err(bad(k, format!("does not apply to a {:?}", self.shape))),
                None => Ok(()),
            }
        };
        let law = ContactLaw {
            stiffness: self.stiffness,
            damping: self.damping,
        };
        if !(law.stiffness.is_finite() && law.stiffness > 0.0) {
            return Err(bad(
                "stiffness",
                format!("= {} must be a finite number > 0 (N/m)", law.stiffness),
            ));
        }
        if !(law.damping.is_finite() && law.damping >= 0.0) {
            return Err(bad(
                "damping",
                format!("= {} must be a finite number >= 0 (N·s/m)", law.damping),
            ));
        }
        let positive = |k: &str, v: f64, zero_ok: bool| -> Result<f64> {
            if v.is_finite() && (v > 0.0 || zero_ok && v == 0.0) {
                Ok(v)
            } else {
                Err(bad(
                    k,
                    format!("= {v} must be a finite number {}", if zero_ok { ">= 0" } else { "> 0" }),
                ))
            }
        };
        let tool = match self.shape {
            ToolShapeKind::Sphere => {
                extra("half_length", self.half_length)?;
                Tool::sphere(positive("radius", size("radius", self.radius)?, false)?, law)
            }
            ToolShapeKind::Capsule => Tool::capsule(
                positive("radius", size("radius", self.radius)?, false)?,
                positive("half_length", size("half_length", self.half_length)?, true)?,
                law,
            ),
            ToolShapeKind::HalfSpace => {
                extra("radius", self.radius)?;
                extra("half_length", self.half_length)?;
                Tool::half_space(law)
            }
        };
        if self.path.is_empty() {
            return Err(bad(
                "path",
                "is empty: give at least one {time, position} keyframe".into(),
            ));
        }
        let mut keys = Vec::with_capacity(self.path.len());
        for (j, k) in self.path.iter().enumerate() {
            if !(k.time.is_finite() && k.time >= 0.0) {
                return Err(bad(
                    &format!("path[{j}].time"),
                    format!("= {} must be a finite number >= 0", k.time),
                ));
            }
            if let Some(&(prev, _)) = keys.last() {
                if k.time <= prev {
                    return Err(bad(
                        &format!("path[{j}].time"),
                        format!("= {} must increase (path[{}].time = {prev})", k.time, j - 1),
                    ));
                }
            }
            let pose = Pose::new(Vec3::from(k.position), Vec3::from(k.rotation))
                .map_err(|e| bad(&format!("path[{j}]"), format!("position/rotation: {e}")))?;
            keys.push((k.time, pose));
        }
        let path = ToolPath { keys };
        Ok((name, tool.at(path.at(0.0)), path))
    }
}

impl Scene {
    /// Adds the scene's `[[tool]]` entries to `system` (node numbering plays no
    /// part: tools touch the surface wherever it is).
    pub(crate) fn add_tools(&self, system: &mut System) -> Result<Vec<ScriptedTool>> {
        let mut out: Vec<ScriptedTool> = Vec::with_capacity(self.tools.len());
        for (i, spec) in self.tools.iter().enumerate() {
            let what = self.entry_name("tool", i);
            let (name, tool, path) = spec.checked(i, &what)?;
            if let Some(j) = out.iter().position(|t| t.name == name) {
                return Err(HemlError::Invalid(format!(
                    "{what}: tool[{i}].name = {name:?} is already the name of tool[{j}]"
                )));
            }
            let id = system
                .add_tool(tool)
                .map_err(|e| HemlError::Invalid(format!("{what}: {e}")))?;
            out.push(ScriptedTool { id, name, path });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(path: Vec<KeyframeSpec>) -> ToolSpec {
        ToolSpec {
            name: Some("probe".into()),
            shape: ToolShapeKind::Capsule,
            radius: Some(0.005),
            half_length: Some(0.02),
            stiffness: 100.0,
            damping: 0.0,
            path,
        }
    }

    fn key(time: f64, z: f64) -> KeyframeSpec {
        KeyframeSpec {
            time,
            position: [0.0, 0.0, z],
            rotation: [0.0, 0.0, 0.0],
        }
    }

    #[test]
    fn paths_interpolate_and_bad_keys_are_named() {
        let (_, tool, path) = spec(vec![key(0.1, 1.0), key(0.3, 0.0)]).checked(0, "s").unwrap();
        // held before the first keyframe, halfway at the middle, held after the last
        assert_eq!(tool.pose.translation.z, 1.0);
        assert_eq!(path.at(0.0).translation.z, 1.0);
        assert!((path.at(0.2).translation.z - 0.5).abs() < 1e-15);
        assert_eq!(path.at(5.0).translation.z, 0.0);
        let e = spec(vec![key(0.0, 0.0), key(0.2, 0.0), key(0.2, 0.0)])
            .checked(1, "s")
            .unwrap_err()
            .to_string();
        assert!(e.contains("tool[1].path[2].time = 0.2 must increase"), "{e}");
        let mut s = spec(vec![key(0.0, 0.0)]);
        s.stiffness = -1.0;
        assert!(s.checked(0, "s").unwrap_err().to_string().contains("tool[0].stiffness"));
        s.stiffness = 1.0;
        s.radius = None;
        assert!(s
            .checked(0, "s")
            .unwrap_err()
            .to_string()
            .contains("tool[0].radius is missing"));
        s.radius = Some(0.01);
        s.path[0].position[1] = f64::NAN;
        assert!(s.checked(0, "s").unwrap_err().to_string().contains("tool[0].path[0]"));
        s.path[0].position[1] = 0.0;
        s.name = Some("a,b".into());
        assert!(s.checked(0, "s").unwrap_err().to_string().contains("tool[0].name"));
    }
}
