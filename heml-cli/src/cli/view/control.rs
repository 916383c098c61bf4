//! The simulation side of the page's hands-on commands: grasp, tool, cut.
//!
//! The page's requests arrive here already parsed and checked
//! ([`super::protocol::parse_request`]); this module turns them into calls on a
//! [`Controls`] implementation, choosing the grasped node patch, the grasp's spring
//! constants and the target poses. [`super::runtime::Runtime`] implements them on the
//! library's runtime control.

use heml::mesh::surface::BoundarySurface;
use heml::system::control::Pose;
use heml::system::System;
use heml::Vec3;

use super::protocol::{GraspView, Ray, ToolView};

/// Natural frequency (Hz) of a grasped node on its spring: stiff enough to follow the
/// cursor within a few frames, soft enough to stay stable at explicit time steps
/// (ω·dt ≪ 2 for the usual dt of 1e-4..1e-3 s).
pub const GRASP_FREQUENCY_HZ: f64 = 10.0;

/// Radius of the grasped patch around the picked node, as a fraction of the body's
/// bounding-box diagonal.
pub const GRASP_RADIUS_FRACTION: f64 = 0.04;

/// What the live view needs of the library's runtime control.
pub trait Controls: Send {
    /// Ties `nodes` to `target` (their current placement is the identity pose) by
    /// springs of `stiffness` (N/m per node) and `damping` (N·s/m per node).
    fn grasp(
        &mut self,
        sys: &mut System,
        nodes: &[usize],
        target: Pose,
        stiffness: f64,
        damping: f64,
    ) -> Result<(), String>;
    /// Moves the current grasp's target.
    fn move_grasp(&mut self, sys: &mut System, target: Pose) -> Result<(), String>;
    /// Lets go of the current grasp.
    fn release_grasp(&mut self, sys: &mut System) -> Result<(), String>;
    /// Places the tool (tip position and axis).
    fn move_tool(&mut self, sys: &mut System, pose: Pose) -> Result<(), String>;
    /// Removes the tets the blade triangle crosses; `Ok(true)` when the surface changed.
    fn cut(&mut self, sys: &mut System, blade: [Vec3; 3]) -> Result<bool, String>;
    /// The force the tissue applies to the tool (N), when there is a tool.
    fn tool_force(&self, sys: &System) -> Option<Vec3>;
    /// The grasp in progress, when there is one.
    fn grasp_view(&self, _sys: &System) -> Option<GraspView> {
        None
    }
    /// The tool's placement and size for drawing, when there is a tool.
    fn tool_view(&self, _sys: &System) -> Option<ToolView> {
        None
    }
    /// Forgets grasp and tool ids after the system was rebuilt (reset, new parameter).
    fn forget(&mut self) {}
}

/// A grasp in progress: where it was taken, to turn cursor targets into poses.
#[derive(Debug, Clone, Copy)]
pub struct Held {
    /// Position of the picked node when grasped.
    pub anchor: Vec3,
}

/// Turns the page's hands-on commands into [`Controls`] calls.
pub struct Adapter {
    controls: Box<dyn Controls>,
    held: Option<Held>,
}

fn vec(p: &[f64; 3]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

impl Adapter {
    /// An adapter over `controls`.
    pub fn new(controls: Box<dyn Controls>) -> Self {
        Adapter { controls, held: None }
    }

    /// `grasp_start`: a node (a surface node id) or a ray picks the surface node; the
    /// nodes within [`GRASP_RADIUS_FRACTION`] of the body's size around it are tied to
    /// their current place by critically damped springs of [`GRASP_FREQUENCY_HZ`].
    pub fn grasp_start(&mut self, sys: &mut System, node: Option<u32>, ray: Option<Ray>) -> Result<String, String> {
        let surface = sys.surface();
        let picked = match (node, ray) {
            (Some(n), _) => {
                if surface.nodes().binary_search(&n).is_err() {
                    return Err(format!("node {n} is not a node of the boundary surface"));
                }
                n as usize
            }
            (None, Some(r)) => nearest_to_ray(surface, sys.positions(), &r).ok_or("the surface is empty")?,
            (None, None) => return Err("grasp_start needs a node or a ray".into()),
        };
        let x = sys.positions();
        let radius = GRASP_RADIUS_FRACTION * diagonal(sys.rest_positions());
        let nodes: Vec<usize> = surface
            .nodes()
            .iter()
            .map(|&i| i as usize)
            .filter(|&i| sys.is_free(i) && (x[i] - x[picked]).norm() <= radius)
            .collect();
        if nodes.is_empty() {
            return Err(format!("node {picked} and its neighbours are fixed: nothing to grasp"));
        }
        let mass = nodes.iter().map(|&i| sys.masses()[i]).sum::<f64>() / nodes.len() as f64;
        let omega = 2.0 * std::f64::consts::PI * GRASP_FREQUENCY_HZ;
        let anchor = x[picked];
        self.controls
            .grasp(sys, &nodes, Pose::identity(), mass * omega * omega, 2.0 * mass * omega)?;
        self.held = Some(Held { anchor });
        Ok(format!("grasped {} node(s) around node {picked}", nodes.len()))
    }

    /// `grasp_move`: the grasped patch follows `target` (the picked node's new place).
    pub fn grasp_move(&mut self, sys: &mut System, target: &[f64; 3]) -> Result<String, String> {
        let held = self.held.ok_or("no grasp in progress")?;
        self.controls
            .move_grasp(sys, Pose::translation(vec(target) - held.anchor))?;
        Ok(String::new())
    }

    /// `grasp_end`.
    pub fn grasp_end(&mut self, sys: &mut System) -> Result<String, String> {
        if self.held.take().is_none() {
            return Err("no grasp in progress".into());
        }
        self.controls.release_grasp(sys)?;
        Ok("released".into())
    }

    /// `tool_move`: the tool's tip at `position`, its axis along `axis` (else +z).
    pub fn tool_move(
        &mut self,
        sys: &mut System,
        position: &[f64; 3],
        axis: Option<&[f64; 3]>,
    ) -> Result<String, String> {
        let dir = axis.map_or(Vec3::z(), |a| vec(a).normalize());
        // rotation taking +z to `dir`: axis z × dir, angle between them
        let cross = Vec3::z().cross(&dir);
        let angle = dir.z.clamp(-1.0, 1.0).acos();
        let axis_angle = if cross.norm() > 1e-12 {
            cross.normalize() * angle
        } else if dir.z < 0.0 {
            Vec3::x() * std::f64::consts::PI
        } else {
            Vec3::zeros()
        };
        let pose = Pose::new(vec(position), axis_angle).map_err(|e| e.to_string())?;
        self.controls.move_tool(sys, pose)?;
        Ok(String::new())
    }

    /// `cut`: `Ok(true)` when the surface changed (the mesh message is re-sent).
    pub fn cut(&mut self, sys: &mut System, blade: &[[f64; 3]; 3]) -> Result<bool, String> {
        self.controls.cut(sys, blade.map(|p| vec(&p)))
    }

    /// The tool force for the status (N).
    pub fn tool_force(&self, sys: &System) -> Option<Vec3> {
        self.controls.tool_force(sys)
    }

    /// The tool for the status.
    pub fn tool_view(&self, sys: &System) -> Option<ToolView> {
        self.controls.tool_view(sys)
    }

    /// The grasp for the status.
    pub fn grasp_view(&self, sys: &System) -> Option<GraspView> {
        self.controls.grasp_view(sys)
    }

    /// After a rebuild of the system: no grasp or tool survives.
    pub fn forget(&mut self) {
        self.held = None;
        self.controls.forget();
    }
}

/// Bounding-box diagonal of `x`.
pub fn diagonal(x: &[Vec3]) -> f64 {
    let (lo, hi) = bounds(x);
    (hi - lo).norm()
}

/// Bounding box of `x` (zeros when empty).
pub fn bounds(x: &[Vec3]) -> (Vec3, Vec3) {
    if x.is_empty() {
        return (Vec3::zeros(), Vec3::zeros());
    }
    x.iter().fold((x[0], x[0]), |(lo, hi), p| (lo.inf(p), hi.sup(p)))
}

/// The surface node closest to the ray's line (in front of its origin; the nearest
/// to the origin among nodes equally close to the line).
pub fn nearest_to_ray(surface: &BoundarySurface, x: &[Vec3], ray: &Ray) -> Option<usize> {
    let o = vec(&ray.origin);
    let d = vec(&ray.direction).normalize();
    surface
        .nodes()
        .iter()
        .map(|&i| i as usize)
        .filter(|&i| (x[i] - o).dot(&d) >= 0.0)
        .map(|i| {
            let along = (x[i] - o).dot(&d);
            let off = (x[i] - o - d * along).norm();
            (i, off, along)
        })
        .min_by(|a, b| (a.1, a.2).partial_cmp(&(b.1, b.2)).unwrap_or(std::cmp::Ordering::Equal))
        .map(|(i, _, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::view::fields::tests::block;

    #[test]
    fn a_ray_picks_the_surface_node_on_its_line() {
        let sys = block(0.1, true);
        // straight down through the top corner (0.1, 0.1, 0.1)
        let ray = Ray {
            origin: [0.1, 0.1, 1.0],
            direction: [0.0, 0.0, -1.0],
        };
        let i = nearest_to_ray(sys.surface(), sys.positions(), &ray).unwrap();
        assert!((sys.positions()[i] - Vec3::new(0.1, 0.1, 0.1)).norm() < 1e-12);
    }
}
