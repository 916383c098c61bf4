//! Output of a run: VTU frames with a `.pvd` series, and `energy.csv`. Every file is
//! written atomically (the CSV is rewritten whole at each frame), so a run stopped at
//! any moment leaves complete files only.

use std::borrow::Cow;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{HemlError, Result};
use crate::io::atomic::write_atomic;
use crate::io::{write_vtu, PvdWriter, VtuEncoding, VtuFrame};
use crate::mesh::reorder::Permutation;
use crate::system::{Energies, System};
use crate::Vec3;

/// Columns of `energy.csv`: time and step, the energies (J) of
/// [`crate::system::Energies`] (gravity and nodal-load potentials relative to the
/// rest configuration), the total support reaction (N) with its norm, and the
/// conjugate-gradient iterations of the step (0 for explicit integrators).
pub const CSV_HEADER: &str =
    "time,step,kinetic,elastic,gravity,loads,total,reaction_x,reaction_y,reaction_z,reaction_norm,cg_iterations";

/// The frames and the CSV of one run.
pub(crate) struct Output {
    dir: PathBuf,
    pvd: Option<PvdWriter>,
    encoding: VtuEncoding,
    frames: usize,
    /// Step count and path of the last frame written.
    last: Option<(u64, PathBuf)>,
    csv: Option<String>,
    /// When the system's nodes are renumbered: the permutation and the tets in the
    /// file's node numbering, so that frames read like the input mesh.
    file_order: Option<(Permutation, Vec<[u32; 4]>)>,
}

impl Output {
    /// Creates the directory and the empty series. `node_order` is the renumbering
    /// of `sys`'s nodes ([`super::Simulation::node_order`]), undone in every frame.
    pub(crate) fn create(
        dir: &Path,
        vtu: bool,
        encoding: VtuEncoding,
        csv: bool,
        sys: &System,
        node_order: Option<&Permutation>,
    ) -> Result<Output> {
        std::fs::create_dir_all(dir).map_err(|e| HemlError::io(dir, e))?;
        let pvd = if vtu {
            Some(PvdWriter::create(dir.join("frames.pvd"))?)
        } else {
            None
        };
        let file_order = node_order.filter(|_| vtu).map(|p| {
            let tets = sys
                .mesh()
                .tets()
                .iter()
                .map(|t| t.map(|i| p.new_to_old[i as usize] as u32))
                .collect();
            (p.clone(), tets)
        });
        Ok(Output {
            dir: dir.to_path_buf(),
            pvd,
            encoding,
            frames: 0,
            last: None,
            csv: csv.then(|| format!("{CSV_HEADER}\n")),
            file_order,
        })
    }

    pub(crate) fn frames(&self) -> usize {
        self.frames
    }

    /// Writes the current state as the next frame (when VTU output is on) and
    /// returns its path (the existing one when this step was written already). Forces are brought up to date first; if that fails (a state
    /// whose forces are not finite) the frame is written with NaN forces and cell
    /// fields, so that the positions are still saved.
    pub(crate) fn frame(&mut self, sys: &mut System) -> Result<Option<PathBuf>> {
        let Some(pvd) = &mut self.pvd else {
            return Ok(None);
        };
        if let Some((step, path)) = &self.last {
            if *step == sys.step_count() {
                return Ok(Some(path.clone()));
            }
        }
        let forces_ok = sys.forces_current() || sys.compute_forces().is_ok();
        let n = sys.positions().len();
        let nan3 = Vec3::repeat(f64::NAN);
        let (force, reaction) = if forces_ok {
            (sys.forces().to_vec(), sys.reactions().to_vec())
        } else {
            (vec![nan3; n], vec![nan3; n])
        };
        let nt = sys.mesh().n_tets();
        let mut j = vec![f64::NAN; nt];
        let mut w = vec![f64::NAN; nt];
        for r in sys.regions() {
            if let Ok(states) = r.field().tet_states(sys.positions()) {
                for (&t, (jt, wt)) in r.field().tet_ids().iter().zip(states) {
                    j[t] = jt;
                    w[t] = wt;
                }
            }
        }
        let (order, tets) = match &self.file_order {
            Some((p, tets)) => (Some(p), tets.as_slice()),
            None => (None, sys.mesh().tets()),
        };
        let displacement = sys.displacements();
        let points = in_file_order(order, sys.positions());
        let displacement = in_file_order(order, &displacement);
        let velocity = in_file_order(order, sys.velocities());
        let (force, reaction) = (in_file_order(order, &force), in_file_order(order, &reaction));
        let path = self.dir.join(format!("frame_{:05}.vtu", self.frames));
        let frame = VtuFrame::new(&points, tets)
            .tags(sys.mesh().tags())
            .point_vectors("displacement", &displacement)
            .point_vectors("velocity", &velocity)
            .point_vectors("force", &force)
            .point_vectors("reaction", &reaction)
            .cell_scalars("J", &j)
            .cell_scalars("energy_density", &w)
            .encoding(self.encoding);
        write_vtu(&path, &frame)?;
        pvd.add(sys.time(), &path)?;
        self.frames += 1;
        self.last = Some((sys.step_count(), path.clone()));
        Ok(Some(path))
    }

    /// Appends a CSV row (kept in memory; see [`Output::flush_csv`]).
    pub(crate) fn row(&mut self, sys: &System, e: &Energies, cg_iterations: usize) {
        if let Some(csv) = &mut self.csv {
            let r = sys.total_reaction();
            let _ = writeln!(
                csv,
                "{:e},{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{}",
                sys.time(),
                sys.step_count(),
                e.kinetic,
                e.elastic,
                e.gravity,
                e.loads,
                e.total,
                r.x,
                r.y,
                r.z,
                r.norm(),
                cg_iterations
            );
        }
    }

    /// Rewrites `energy.csv` atomically with every row so far.
    pub(crate) fn flush_csv(&self) -> Result<()> {
        match &self.csv {
            Some(csv) => write_atomic(&self.dir.join("energy.csv"), |w| w.write_all(csv.as_bytes())),
            None => Ok(()),
        }
    }

    pub(crate) fn wants_csv(&self) -> bool {
        self.csv.is_some()
    }
}

/// A point array of the system brought back to the mesh file's node order (as it is
/// when the nodes were not renumbered).
fn in_file_order<'a>(order: Option<&Permutation>, a: &'a [Vec3]) -> Cow<'a, [Vec3]> {
    match order {
        Some(p) => Cow::Owned(p.unapply(a)),
        None => Cow::Borrowed(a),
    }
}
