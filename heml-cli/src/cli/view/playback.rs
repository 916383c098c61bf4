//! `heml view OUTPUT_DIR` or `heml view frames.pvd`: a finished run's VTU frames
//! played back in the same page, at their simulated times, looping.
//!
//! The frames are read with the library's VTU reader before the server starts (the
//! first frame gives the mesh and its boundary surface; every frame must have the
//! same number of points). Only the surface positions are kept, so memory grows with
//! the surface times the number of frames. Colour: displacement from the first
//! frame (the reader keeps points and cells, not the frames' point data, so J and
//! energy density are not offered in playback).

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use heml::mesh::surface::BoundarySurface;
use heml::{HemlError, Result, Vec3};

use super::hub::{Envelope, Hub};
use super::protocol::{encode_frame, request_name, FieldKind, MeshMessage, Reply, Request, Status};

/// Most frames a playback loads.
pub const MAX_FRAMES: usize = 100_000;

/// Most bytes of frames a playback keeps (f32 positions and colour values, 16 bytes
/// per surface vertex and frame), checked from the first frame before loading.
pub const MAX_FRAME_BYTES: usize = 2 << 30;

/// Longest span of simulated time a playback plays (its player waits in real time).
pub const MAX_SPAN_SECONDS: f64 = 1e9;

/// Checks that the `.pvd` entries' times are finite and increasing, over a span a
/// player can wait for.
fn check_times(pvd: &Path, entries: &[(f64, String)]) -> Result<()> {
    let bad = |k: usize, what: String| {
        Err(HemlError::Invalid(format!(
            "{}: entry {} ({}): {what}",
            pvd.display(),
            k + 1,
            entries[k].1
        )))
    };
    for (k, (t, _)) in entries.iter().enumerate() {
        if !t.is_finite() {
            return bad(k, format!("timestep {t} is not a finite number"));
        }
        if k > 0 && *t <= entries[k - 1].0 {
            return bad(
                k,
                format!(
                    "timestep {t} is not after the previous entry's {} (the times must increase)",
                    entries[k - 1].0
                ),
            );
        }
        if t - entries[0].0 > MAX_SPAN_SECONDS {
            return bad(
                k,
                format!("timestep {t}: more than {MAX_SPAN_SECONDS} s after the first"),
            );
        }
    }
    Ok(())
}

/// A loaded run: surface vertex positions per frame.
pub struct Recording {
    /// Where it was read from.
    pub source: PathBuf,
    /// (time, f32 xyz of the surface vertices) per frame.
    pub frames: Vec<(f64, Vec<f32>)>,
    /// Displacement magnitude from the first frame, per frame and vertex.
    pub values: Vec<Vec<f32>>,
    /// The mesh message.
    pub mesh: MeshMessage,
}

/// The `.pvd` of `path`: itself, or the only `.pvd` inside a directory.
pub fn find_pvd(path: &Path) -> Result<PathBuf> {
    if !path.is_dir() {
        return Ok(path.to_path_buf());
    }
    let entries = std::fs::read_dir(path).map_err(|e| HemlError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    let mut pvds: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "pvd"))
        .collect();
    pvds.sort();
    match pvds.len() {
        1 => Ok(pvds.remove(0)),
        0 => Err(HemlError::Invalid(format!(
            "{}: no .pvd file in this directory (give a scene file, --demo, or a run's output directory)",
            path.display()
        ))),
        _ => Err(HemlError::Invalid(format!(
            "{}: several .pvd files ({}); name one",
            path.display(),
            pvds.iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

impl Recording {
    /// Reads the frames listed by the `.pvd` at `path` (or in the directory `path`).
    pub fn read(path: &Path) -> Result<Recording> {
        let pvd = find_pvd(path)?;
        let entries = heml::io::read_pvd(&pvd)?;
        if entries.is_empty() {
            return Err(HemlError::Invalid(format!(
                "{}: the .pvd lists no frames",
                pvd.display()
            )));
        }
        if entries.len() > MAX_FRAMES {
            return Err(HemlError::Invalid(format!(
                "{}: {} frames, more than the {MAX_FRAMES} a playback loads",
                pvd.display(),
                entries.len()
            )));
        }
        check_times(&pvd, &entries)?;
        let dir = pvd.parent().unwrap_or(Path::new("."));
        let first_path = dir.join(&entries[0].1);
        let mesh = heml::io::vtu::read(&first_path)?.into_mesh()?;
        let surface = BoundarySurface::of_tet_mesh(&mesh);
        let rest = mesh.nodes().to_vec();
        let nodes = surface.nodes().to_vec();
        // every frame has the first's points: its size times the count, before loading
        let bytes = entries.len().saturating_mul(nodes.len()).saturating_mul(16);
        if bytes > MAX_FRAME_BYTES {
            return Err(HemlError::Invalid(format!(
                "{}: {} frames of {} surface vertices would take {:.1} GiB, more than the {} GiB a playback loads",
                pvd.display(),
                entries.len(),
                nodes.len(),
                bytes as f64 / (1u64 << 30) as f64,
                MAX_FRAME_BYTES >> 30
            )));
        }
        let mut frames = Vec::with_capacity(entries.len());
        let mut values = Vec::with_capacity(entries.len());
        for (time, file) in &entries {
            let p = dir.join(file);
            let data = heml::io::vtu::read(&p)?;
            if data.nodes.len() != rest.len() {
                return Err(HemlError::Invalid(format!(
                    "{}: {} points, but the first frame ({}) has {}",
                    p.display(),
                    data.nodes.len(),
                    first_path.display(),
                    rest.len()
                )));
            }
            let at = |n: u32| -> Vec3 { data.nodes[n as usize] };
            frames.push((
                *time,
                nodes
                    .iter()
                    .flat_map(|&n| {
                        let q = at(n);
                        [q.x as f32, q.y as f32, q.z as f32]
                    })
                    .collect(),
            ));
            values.push(
                nodes
                    .iter()
                    .map(|&n| (at(n) - rest[n as usize]).norm() as f32)
                    .collect(),
            );
        }
        let source = pvd.display().to_string();
        let mesh = MeshMessage::new(nodes, surface.triangles(), &rest, |_| false, 0, "playback", &source);
        Ok(Recording {
            source: pvd,
            frames,
            values,
            mesh,
        })
    }
}

/// Plays `rec` on a new thread until the command channel closes.
pub fn spawn(rec: Recording, hub: Arc<Hub>, commands: Receiver<Envelope>) -> Result<std::thread::JoinHandle<()>> {
    match serde_json::to_string(&rec.mesh) {
        Ok(text) => {
            hub.mesh.send_replace(text.into());
        }
        Err(e) => return Err(HemlError::Invalid(format!("cannot encode the mesh: {e}"))),
    }
    std::thread::Builder::new()
        .name("heml-view-playback".into())
        .spawn(move || play(rec, hub, commands))
        .map_err(|e| HemlError::Invalid(format!("cannot start the playback thread: {e}")))
}

fn play(rec: Recording, hub: Arc<Hub>, commands: Receiver<Envelope>) {
    let n = rec.frames.len();
    let mut k = 0;
    let mut paused = false;
    let mut published = 0u64;
    let t0 = rec.frames[0].0;
    // wall instant at which frame `k` is due
    let mut start = Instant::now();
    let show = |k: usize, paused: bool, published: &mut u64| {
        *published += 1;
        let (t, xyz) = &rec.frames[k];
        let bytes = encode_frame(*published, *t, FieldKind::Displacement, 0, xyz, &rec.values[k]);
        hub.frames.send_replace(bytes.into());
        let dt = if n > 1 {
            (rec.frames[n - 1].0 - t0) / (n - 1) as f64
        } else {
            0.0
        };
        let status = Status {
            kind: "status",
            time: *t,
            steps: k as u64,
            frame: *published,
            paused,
            real_time_factor: if paused { 0.0 } else { 1.0 },
            integrator: "playback".into(),
            dt,
            min_j: f64::NAN,
            field: Some(FieldKind::Displacement),
            ..Status::default()
        };
        if let Ok(text) = serde_json::to_string(&status) {
            hub.status.send_replace(text.into());
        }
    };
    show(0, paused, &mut published);
    loop {
        let due = start + Duration::from_secs_f64((rec.frames[k].0 - t0).max(0.0));
        let wait = if paused {
            Duration::from_millis(100)
        } else {
            due.saturating_duration_since(Instant::now())
        };
        match commands.recv_timeout(wait) {
            Ok(env) => {
                let name = request_name(&env.request);
                let reply = match env.request {
                    Request::Pause {} => {
                        paused = true;
                        Ok(())
                    }
                    Request::Resume {} => {
                        paused = false;
                        start = Instant::now() - Duration::from_secs_f64((rec.frames[k].0 - t0).max(0.0));
                        Ok(())
                    }
                    Request::Step {} => {
                        paused = true;
                        k = (k + 1) % n;
                        Ok(())
                    }
                    Request::Reset {} => {
                        k = 0;
                        start = Instant::now();
                        Ok(())
                    }
                    Request::Field {
                        field: FieldKind::Displacement,
                    } => Ok(()),
                    _ => Err("not available in playback (a recorded run shows its frames' displacement only)"),
                };
                match reply {
                    Ok(()) => env.answer(Reply::json(name, true, "")),
                    Err(m) => env.answer(Reply::json(name, false, m)),
                }
                show(k, paused, &mut published);
            }
            Err(RecvTimeoutError::Timeout) => {
                if !paused {
                    show(k, paused, &mut published);
                    k += 1;
                    if k == n {
                        k = 0;
                        start = Instant::now();
                    }
                }
            }
            Err(RecvTimeoutError::Disconnected) => return,
        }
    }
}
