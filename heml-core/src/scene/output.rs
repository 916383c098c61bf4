//! Output of a run: VTU frames with a `.pvd` series, and `energy.csv`. Frames and the
//! series are written atomically (a temporary renamed over the target); the CSV is
//! opened once and appended: rows wait in a small buffer and go out as whole lines in
//! one write at each frame boundary, so a run stopped at any moment leaves complete
//! frames and a CSV whose content is a prefix of complete rows — and the cost of the
//! CSV stays linear in its length (it used to be rewritten whole at every frame).

use std::borrow::Cow;
use std::fmt::Write as _;
use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{HemlError, Result};
use crate::io::{write_vtu, FieldPrecision, PvdWriter, VtuEncoding, VtuFrame};
use crate::mesh::reorder::Permutation;
use crate::system::contact::ToolId;
use crate::system::{DtReason, Energies, System};
use crate::Vec3;

/// Columns of `energy.csv`: time and step, the energies (J) of
/// [`crate::system::Energies`] (gravity and nodal-load potentials relative to the
/// rest configuration), and the total support reaction (N) with its norm.
/// `dt` is the step that led to the row's state and `dt_reason` why it was chosen
/// (see [`crate::system::DtReason`]; `fixed` unless `dt_policy = "adapt"`), and
/// `cg_iterations` the conjugate-gradient iterations of that step (0 for explicit
/// integrators). A scene with `[[tool]]`s appends, per tool, the force the tissue
/// applies to it (N): `tool_<name>_fx, tool_<name>_fy, tool_<name>_fz`.
pub const CSV_HEADER: &str = "time,step,kinetic,elastic,gravity,loads,total,reaction_x,reaction_y,reaction_z,\
                              reaction_norm,dt,dt_reason,cg_iterations";

/// The open `energy.csv`: rows not yet written, and what was written so far.
struct Csv {
    file: File,
    path: PathBuf,
    pending: String,
    /// Write calls issued (the header and one per non-empty flush).
    writes: u64,
    /// Bytes written (header included): equals the file's length.
    bytes: u64,
}

/// The frames and the CSV of one run.
pub(crate) struct Output {
    dir: PathBuf,
    pvd: Option<PvdWriter>,
    /// How frames store their arrays, and the fields' precision.
    format: (VtuEncoding, FieldPrecision),
    frames: usize,
    /// Step count and path of the last frame written.
    last: Option<(u64, PathBuf)>,
    csv: Option<Csv>,
    /// The tools whose forces are appended to each CSV row.
    tools: Vec<ToolId>,
    /// When the system's nodes are renumbered: the permutation and the tets in the
    /// file's node numbering, so that frames read like the input mesh.
    file_order: Option<(Permutation, Vec<[u32; 4]>)>,
}

/// Removes the frames (`frame_NNNNN.vtu`, the names [`Output`] writes) an earlier
/// run left in `dir`, with a warning: the new `frames.pvd` lists only this run's
/// frames, and a folder holding both runs' files reads as one series in viewers
/// that open `frame_*.vtu` as a group. Other files are kept. Returns how many were
/// removed.
fn remove_earlier_frames(dir: &Path) -> Result<usize> {
    let entries = std::fs::read_dir(dir).map_err(|e| HemlError::io(dir, e))?;
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let is_frame = name
            .to_str()
            .and_then(|n| n.strip_prefix("frame_"))
            .and_then(|n| n.strip_suffix(".vtu"))
            .is_some_and(|digits| digits.len() >= 5 && digits.bytes().all(|b| b.is_ascii_digit()));
        if is_frame && entry.path().is_file() {
            std::fs::remove_file(entry.path()).map_err(|e| HemlError::io(entry.path(), e))?;
            removed += 1;
        }
    }
    if removed > 0 {
        log::warn!(
            "removed {removed} frame_*.vtu of an earlier run from {} (this run writes its own series)",
            dir.display()
        );
    }
    Ok(removed)
}

/// Where an output folder comes from, for messages.
const OUT_KEYS: &str = "the scene's [output] dir, or `heml run --out`";

/// Creates the output folder `dir` (and its parents), or says why it cannot: a file
/// or a dangling symbolic link in its place, or what the system refused (a missing
/// permission, a read-only file system), naming the folder and where it is set.
fn check_output_dir(dir: &Path) -> Result<()> {
    let meta = std::fs::symlink_metadata(dir);
    if let Ok(m) = &meta {
        if m.file_type().is_symlink() && !dir.exists() {
            let target = std::fs::read_link(dir).map_or_else(|_| "?".into(), |t| t.display().to_string());
            return Err(HemlError::Invalid(format!(
                "output folder {} is a symbolic link to {target}, which does not exist: create it, or choose \
                 another folder ({OUT_KEYS})",
                dir.display()
            )));
        }
    }
    if dir.exists() && !dir.is_dir() {
        return Err(HemlError::Invalid(format!(
            "output folder {} exists and is not a folder: choose another folder ({OUT_KEYS})",
            dir.display()
        )));
    }
    std::fs::create_dir_all(dir).map_err(|e| {
        HemlError::Invalid(format!(
            "cannot create the output folder {}: {e} ({OUT_KEYS})",
            dir.display()
        ))
    })
}

impl Output {
    /// Creates the directory and the empty series. `node_order` is the renumbering
    /// of `sys`'s nodes ([`super::Simulation::node_order`]), undone in every frame.
    pub(crate) fn create(
        dir: &Path,
        vtu: bool,
        format: (VtuEncoding, FieldPrecision),
        csv: bool,
        sys: &System,
        node_order: Option<&Permutation>,
        tools: Vec<(ToolId, String)>,
    ) -> Result<Output> {
        // (a run that writes nothing leaves no empty folder behind)
        if vtu || csv {
            check_output_dir(dir)?;
            crate::io::atomic::remove_stale_temporaries(dir);
        }
        if vtu {
            remove_earlier_frames(dir)?;
        }
        let pvd = if vtu {
            Some(PvdWriter::create(dir.join("frames.pvd"))?)
        } else {
            None
        };
        let csv = if csv {
            let path = dir.join("energy.csv");
            // a new file, never through what is there: an earlier run's CSV (or a
            // link planted in its place, whose target a plain create would have
            // overwritten) is removed first, and `create_new` refuses whatever
            // appears at the path in between
            match std::fs::symlink_metadata(&path) {
                Ok(m) if m.is_dir() => {
                    return Err(HemlError::Invalid(format!(
                        "{}: is a directory, where the run writes its CSV",
                        path.display()
                    )))
                }
                Ok(_) => std::fs::remove_file(&path).map_err(|e| HemlError::io(&path, e))?,
                Err(_) => {}
            }
            let mut file = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
                .map_err(|e| HemlError::io(&path, e))?;
            let mut header = CSV_HEADER.to_string();
            for (_, name) in &tools {
                let _ = write!(header, ",tool_{name}_fx,tool_{name}_fy,tool_{name}_fz");
            }
            header.push('\n');
            file.write_all(header.as_bytes()).map_err(|e| HemlError::io(&path, e))?;
            Some(Csv {
                file,
                path,
                pending: String::new(),
                writes: 1,
                bytes: header.len() as u64,
            })
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
            format,
            frames: 0,
            last: None,
            csv,
            tools: tools.into_iter().map(|(id, _)| id).collect(),
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
        // after a cut: only the remaining tets (and their cell fields)
        let (tets, tags, j, w) = cut_cells(sys, tets, j, w);
        let displacement = sys.displacements();
        let points = in_file_order(order, sys.positions());
        let displacement = in_file_order(order, &displacement);
        let velocity = in_file_order(order, sys.velocities());
        let (force, reaction) = (in_file_order(order, &force), in_file_order(order, &reaction));
        let path = self.dir.join(format!("frame_{:05}.vtu", self.frames));
        let frame = VtuFrame::new(&points, &tets)
            .tags(&tags)
            .point_vectors("displacement", &displacement)
            .point_vectors("velocity", &velocity)
            .point_vectors("force", &force)
            .point_vectors("reaction", &reaction)
            .cell_scalars("J", &j)
            .cell_scalars("energy_density", &w)
            .encoding(self.format.0)
            .precision(self.format.1);
        write_vtu(&path, &frame)?;
        pvd.add(sys.time(), &path)?;
        self.frames += 1;
        self.last = Some((sys.step_count(), path.clone()));
        Ok(Some(path))
    }

    /// Queues a CSV row (written by the next [`Output::flush_csv`]); `dt` is the step
    /// that led to this state, `reason` why it was chosen, and `cg_iterations` the
    /// conjugate-gradient iterations it took (0 for explicit integrators).
    pub(crate) fn row(&mut self, sys: &System, e: &Energies, dt: f64, reason: DtReason, cg_iterations: usize) {
        if let Some(csv) = &mut self.csv {
            let r = sys.total_reaction();
            let _ = writeln!(
                csv.pending,
                "{:e},{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{},{}",
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
                dt,
                reason.as_str(),
                cg_iterations
            );
            if !self.tools.is_empty() {
                csv.pending.pop(); // the newline: tool columns follow
                for &id in &self.tools {
                    let f = sys.tool_wrench(id).map(|w| w.force).unwrap_or(Vec3::repeat(f64::NAN));
                    let _ = write!(csv.pending, ",{:e},{:e},{:e}", f.x, f.y, f.z);
                }
                csv.pending.push('\n');
            }
        }
    }

    /// Appends the queued rows to `energy.csv` in one write (whole lines only).
    pub(crate) fn flush_csv(&mut self) -> Result<()> {
        let Some(csv) = &mut self.csv else {
            return Ok(());
        };
        if csv.pending.is_empty() {
            return Ok(());
        }
        csv.file
            .write_all(csv.pending.as_bytes())
            .map_err(|e| HemlError::io(&csv.path, e))?;
        csv.writes += 1;
        csv.bytes += csv.pending.len() as u64;
        csv.pending.clear();
        Ok(())
    }

    /// Write calls and bytes that went to `energy.csv` so far (header included).
    pub(crate) fn csv_io(&self) -> (u64, u64) {
        self.csv.as_ref().map_or((0, 0), |c| (c.writes, c.bytes))
    }

    pub(crate) fn wants_csv(&self) -> bool {
        self.csv.is_some()
    }
}

/// A point array of the system brought back to the mesh file's node order (as it is
/// when the nodes were not renumbered).
/// The cells a frame shows: every tet, or after a cut only the remaining ones, with
/// their tags and cell values `j`, `w` (per mesh tet).
#[allow(clippy::type_complexity)]
fn cut_cells<'a>(
    sys: &'a System,
    tets: &'a [[u32; 4]],
    j: Vec<f64>,
    w: Vec<f64>,
) -> (Cow<'a, [[u32; 4]]>, Cow<'a, [i32]>, Vec<f64>, Vec<f64>) {
    if sys.n_tets_alive() == tets.len() {
        return (Cow::Borrowed(tets), Cow::Borrowed(sys.mesh().tags()), j, w);
    }
    let kept = sys.alive_tets();
    let tags = sys.mesh().tags();
    (
        Cow::Owned(kept.iter().map(|&t| tets[t]).collect()),
        Cow::Owned(kept.iter().map(|&t| tags[t]).collect()),
        kept.iter().map(|&t| j[t]).collect(),
        kept.iter().map(|&t| w[t]).collect(),
    )
}

fn in_file_order<'a>(order: Option<&Permutation>, a: &'a [Vec3]) -> Cow<'a, [Vec3]> {
    match order {
        Some(p) => Cow::Owned(p.unapply(a)),
        None => Cow::Borrowed(a),
    }
}
