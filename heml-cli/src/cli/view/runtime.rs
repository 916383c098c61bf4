//! The page's grasp, tool and cut commands on the library's runtime control:
//! `System::grasp`/`move_grasp`/`release_grasp`, a capsule tool
//! (`System::add_tool`/`set_tool_pose`/`tool_wrench`) and `System::cut`.

use heml::system::contact::{ContactLaw, Tool, ToolId};
use heml::system::control::{GraspId, Pose};
use heml::system::cut::Blade;
use heml::system::System;
use heml::Vec3;

use super::control::{diagonal, Controls};
use super::protocol::{GraspView, ToolView};

/// The tool's radius as a fraction of the body's bounding-box diagonal (a 5 mm
/// laparoscopic tip on a 20 cm organ).
pub const TOOL_RADIUS_FRACTION: f64 = 0.025;

/// The tool's shaft length as a fraction of the body's diagonal.
pub const TOOL_LENGTH_FRACTION: f64 = 0.5;

/// The live view's grasp and capsule tool, at most one of each at a time.
#[derive(Debug, Default)]
pub struct Runtime {
    grasp: Option<Grasped>,
    tool: Option<(ToolId, f64, f64)>,
}

/// A grasp and where its nodes were when it closed (for the status's `moved`).
#[derive(Debug)]
struct Grasped {
    id: GraspId,
    nodes: Vec<usize>,
    at: Vec<Vec3>,
}

fn text(e: heml::HemlError) -> String {
    e.to_string()
}

impl Runtime {
    /// The capsule tool, added on first use: radius and half-length from the body's
    /// size; contact stiffness k = m_min / dt_s² with m_min the lightest surface node
    /// and dt_s the system's stable step, so that the contact's own explicit limit
    /// 2√(m/k) is twice the tissue's (explicit integrators stay stable; implicit
    /// ones take any k).
    fn tool(&mut self, sys: &mut System) -> Result<(ToolId, f64, f64), String> {
        if let Some(t) = self.tool {
            return Ok(t);
        }
        let size = diagonal(sys.rest_positions());
        let (radius, half) = (TOOL_RADIUS_FRACTION * size, 0.5 * TOOL_LENGTH_FRACTION * size);
        let m_min = sys
            .surface()
            .nodes()
            .iter()
            .map(|&i| sys.masses()[i as usize])
            .filter(|&m| m > 0.0)
            .fold(f64::INFINITY, f64::min);
        let dt = sys.stable_dt();
        if !(m_min.is_finite() && dt.is_finite() && dt > 0.0) {
            return Err("no free surface node to touch".into());
        }
        let law = ContactLaw {
            stiffness: m_min / (dt * dt),
            damping: 0.0,
        };
        // parked far above the body until the first move places it
        let parked = Pose::translation(Vec3::new(0.0, 0.0, 1e3 * size.max(1.0)));
        let id = sys
            .add_tool(Tool::capsule(radius, half, law).at(parked))
            .map_err(text)?;
        Ok(*self.tool.insert((id, radius, half)))
    }
}

impl Controls for Runtime {
    fn grasp(&mut self, sys: &mut System, nodes: &[usize], target: Pose, k: f64, c: f64) -> Result<(), String> {
        if let Some(old) = self.grasp.take() {
            sys.release_grasp(old.id).map_err(text)?;
        }
        let id = sys.grasp(nodes, target, k, c).map_err(text)?;
        let at = nodes.iter().map(|&i| sys.positions()[i]).collect();
        self.grasp = Some(Grasped {
            id,
            nodes: nodes.to_vec(),
            at,
        });
        Ok(())
    }

    fn move_grasp(&mut self, sys: &mut System, target: Pose) -> Result<(), String> {
        sys.move_grasp(self.grasp.as_ref().ok_or("no grasp")?.id, target)
            .map_err(text)
    }

    fn release_grasp(&mut self, sys: &mut System) -> Result<(), String> {
        sys.release_grasp(self.grasp.take().ok_or("no grasp")?.id).map_err(text)
    }

    fn grasp_view(&self, sys: &System) -> Option<GraspView> {
        let g = self.grasp.as_ref()?;
        let x = sys.positions();
        let moved = g.nodes.iter().zip(&g.at).map(|(&i, a)| (x[i] - a).norm()).sum::<f64>() / g.nodes.len() as f64;
        Some(GraspView {
            nodes: g.nodes.len(),
            moved,
        })
    }

    /// `pose` places the tip (its origin) and the axis from the tip to the handle
    /// (its local z); the capsule's centre sits radius + half-length up that axis.
    fn move_tool(&mut self, sys: &mut System, pose: Pose) -> Result<(), String> {
        let (id, radius, half) = self.tool(sys)?;
        let centre = Pose {
            translation: pose.translation + pose.rotate(Vec3::z()) * (radius + half),
            rotation: pose.rotation,
        };
        sys.set_tool_pose(id, centre).map_err(text)
    }

    fn cut(&mut self, sys: &mut System, blade: [Vec3; 3]) -> Result<bool, String> {
        let report = sys.cut(&Blade::Triangle(blade)).map_err(text)?;
        Ok(!report.removed_tets.is_empty())
    }

    /// The grasp's force while one is held (what the hand feels), else the tool's.
    fn tool_force(&self, sys: &System) -> Option<Vec3> {
        if let Some(g) = &self.grasp {
            return sys.grasp_force(g.id).ok();
        }
        self.tool.and_then(|(id, ..)| sys.tool_wrench(id).ok()).map(|w| w.force)
    }

    fn tool_view(&self, sys: &System) -> Option<ToolView> {
        let (id, radius, half) = self.tool?;
        let pose = sys.tools().get(id)?.pose;
        let axis = pose.rotate(Vec3::z());
        let tip = pose.translation - axis * (radius + half);
        Some(ToolView {
            tip: [tip.x, tip.y, tip.z],
            axis: [axis.x, axis.y, axis.z],
            radius,
            length: 2.0 * half,
        })
    }

    fn forget(&mut self) {
        *self = Runtime::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::view::control::Adapter;
    use crate::cli::view::fields::tests::block;

    #[test]
    fn a_grasp_pulls_the_tissue_and_is_felt_then_a_tool_and_a_cut_act() {
        let mut sys = block(0.1, true);
        let mut a = Adapter::new(Box::new(Runtime::default()));
        // a node inside the block is not a surface node: refused, nothing held
        let inner = (0..sys.mesh().n_nodes())
            .find(|i| sys.surface().nodes().binary_search(&(*i as u32)).is_err())
            .unwrap();
        assert!(a
            .grasp_start(&mut sys, Some(inner as u32), None)
            .unwrap_err()
            .contains("not a node of the boundary surface"));
        assert!(a.grasp_view(&sys).is_none());
        // grasp the free far corner and pull it 1 cm along +x
        let corner = sys
            .surface()
            .nodes()
            .iter()
            .copied()
            .find(|&i| (sys.positions()[i as usize] - Vec3::new(0.1, 0.1, 0.1)).norm() < 1e-12)
            .unwrap();
        assert!(a
            .grasp_start(&mut sys, Some(corner), None)
            .unwrap()
            .starts_with("grasped"));
        let held = a.grasp_view(&sys).unwrap();
        assert!(held.nodes >= 1 && held.moved == 0.0);
        a.grasp_move(&mut sys, &[0.11, 0.1, 0.1]).unwrap();
        let mut be = heml::integrator("backward_euler").unwrap();
        for _ in 0..20 {
            be.step(&mut sys, 5e-3).unwrap();
        }
        // the patch followed (part of the way: the clamped block pulls back) and the
        // hand feels the tissue pull it back along −x
        let moved = a.grasp_view(&sys).unwrap().moved;
        assert!(moved > 1e-3 && moved < 1.1e-2, "moved {moved}");
        let felt = a.tool_force(&sys).unwrap();
        assert!(felt.x < 0.0, "{felt:?}");
        a.grasp_end(&mut sys).unwrap();
        assert!(a.grasp_view(&sys).is_none() && a.tool_force(&sys).is_none());
        // the tool: tip 2 mm into the top face (less than its radius, so the top face
        // meets its rounded tip), axis up; the tissue pushes it up
        a.tool_move(&mut sys, &[0.05, 0.05, 0.098], Some(&[0.0, 0.0, 1.0]))
            .unwrap();
        let view = a.tool_view(&sys).unwrap();
        assert!((view.tip[2] - 0.098).abs() < 1e-12 && view.axis == [0.0, 0.0, 1.0]);
        sys.compute_forces().unwrap();
        let f = a.tool_force(&sys).unwrap();
        assert!(f.z > 0.0, "{f:?}");
        // a cut through the middle removes tets; a NaN blade is refused unchanged
        let n = sys.n_tets_alive();
        let nan = [[f64::NAN; 3], [0.0; 3], [1.0, 0.0, 0.0]];
        assert!(a.cut(&mut sys, &nan).is_err());
        assert_eq!(sys.n_tets_alive(), n);
        assert!(a
            .cut(&mut sys, &[[0.051, -1.0, -1.0], [0.051, 3.0, -1.0], [0.051, -1.0, 3.0]])
            .unwrap());
        assert!(sys.n_tets_alive() < n && sys.surface().is_closed());
    }
}
