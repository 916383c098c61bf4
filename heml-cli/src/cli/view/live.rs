//! The live simulation of `heml view`: the scene's system and integrator stepped on
//! their own thread (force assembly on a pinned pool), at real time when the machine
//! is faster than that, else as fast as it can; frames (≤ [`Settings::frame_hz`]) and status
//! (≈ [`STATUS_HZ`]) handed to the server through the [`Hub`], never waiting for a
//! page.
//!
//! Changing a material parameter rebuilds the system from the scene with the new
//! value (the built system has no way to swap its laws): positions, velocities, the
//! time and the step count are carried over (so prescribed motions continue), the
//! integrator starts afresh and a Prony series' internal state restarts from zero.
//!
//! An explicit integrator steps with the adaptive step ([`AdaptiveStep`], as
//! `dt_policy = "adapt"` in `heml run`) whatever the scene's policy: a person
//! grasping, pressing and cutting deforms the tissue in ways no scene foresees, and
//! the scene's step (at most the rest-state estimate) is only safe near rest.

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use heml::scene::{Scene, Simulation};
use heml::system::{AdaptiveStep, TimeStepPolicy};

use super::control::{Adapter, Controls};
use super::fields::SurfaceFields;
use super::hub::{Envelope, Hub};
use super::protocol::{encode_frame, request_name, FieldKind, MeshMessage, Reply, Request, Status};
use crate::threads::{thread_pool, Placement};

/// Most frames per second handed to the pages, by default: above the 30 a moving
/// organ needs, below the 60 of a display, whose extra frames a browser without a
/// GPU draws on the simulation's CPUs.
pub const FRAME_HZ: f64 = 40.0;
/// Status messages per second.
pub const STATUS_HZ: f64 = 10.0;
/// Falling behind real time by more than this (s of simulated time) restarts the
/// pacing clock: a slow simulation runs as fast as it can, without catching up in
/// bursts.
const MAX_LAG: f64 = 0.1;

/// The mesh message of `sys`'s surface.
pub fn mesh_message(
    sys: &heml::system::System,
    fields: &SurfaceFields,
    version: u64,
    mode: &'static str,
    source: &str,
) -> MeshMessage {
    MeshMessage::new(
        fields.nodes().to_vec(),
        sys.surface().triangles(),
        sys.rest_positions(),
        |n| !sys.is_free(n as usize),
        version,
        mode,
        source,
    )
}

/// Percentile `q` (0..1) of `sorted` (nearest rank), 0 when empty.
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let k = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1;
    sorted[k]
}

/// How the live simulation runs: its worker threads and the frame rate it hands out.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Worker threads of the force assembly.
    pub threads: usize,
    /// Where they run.
    pub placement: Placement,
    /// Most frames per second handed to the pages.
    pub frame_hz: f64,
    /// Worker threads, placed by the OS, while a page that draws (acks its frames,
    /// [`Hub::pages`]) is connected on the same machine (`None`: the pages are
    /// elsewhere, keep `threads`). A browser without a GPU renders on the CPU: a
    /// pinned worker it preempts stalls every step at the pool's barriers, workers
    /// the OS may move do not.
    pub page_threads: Option<usize>,
}

/// The running simulation and what the view knows about it.
struct Live {
    scene: Scene,
    sim: Simulation,
    /// The adaptive step of an explicit integrator (`None` for implicit ones, which
    /// take the scene's step).
    adapt: Option<AdaptiveStep>,
    pool: rayon::ThreadPool,
    /// The pool while a page is connected ([`Settings::page_threads`]).
    page_pool: Option<rayon::ThreadPool>,
    fields: SurfaceFields,
    adapter: Adapter,
    hub: Arc<Hub>,
    field: FieldKind,
    paused: bool,
    frame: u64,
    mesh_version: u64,
    /// Wall times of the steps since the last status (ms).
    step_ms: Vec<f64>,
    last_frame: Instant,
    /// Least wall time between two frames.
    frame_period: Duration,
    /// Start of the status period and the simulated time then.
    period: (Instant, f64),
    /// Pacing: wall instant and simulated time that correspond.
    anchor: (Instant, f64),
    error: Option<String>,
    status: Status,
}

/// Builds the scene's simulation (errors before any thread starts) and runs it on
/// a new thread until the command channel closes.
pub fn spawn(
    scene: Scene,
    settings: &Settings,
    hub: Arc<Hub>,
    commands: Receiver<Envelope>,
    controls: Box<dyn Controls>,
) -> heml::Result<std::thread::JoinHandle<()>> {
    let scene = for_viewing(scene);
    let mut sim = build(&scene)?;
    let (pool, _) = thread_pool(settings.threads, settings.placement)?;
    let page_pool = match settings.page_threads {
        Some(n) => Some(thread_pool(n, Placement::Os)?.0),
        None => None,
    };
    let fields = SurfaceFields::new(&sim.system);
    let now = Instant::now();
    let adapt = adaptive_step(&mut sim);
    let mut live = Live {
        scene,
        sim,
        adapt,
        pool,
        page_pool,
        fields,
        adapter: Adapter::new(controls),
        hub,
        field: FieldKind::Displacement,
        paused: false,
        frame: 0,
        mesh_version: 0,
        step_ms: Vec::new(),
        last_frame: now,
        frame_period: Duration::from_secs_f64(1.0 / settings.frame_hz),
        period: (now, 0.0),
        anchor: (now, 0.0),
        error: None,
        status: Status::default(),
    };
    live.publish_mesh();
    live.publish_frame();
    live.publish_status();
    std::thread::Builder::new()
        .name("heml-view-sim".into())
        // (the loop itself on a pinned worker of the pool, each step without the
        // hand-over to the pool, measured 2.4x slower in real time at load 18: the
        // pinned loop cannot leave a CPU another process holds)
        .spawn(move || live.run(commands))
        .map_err(|e| heml::HemlError::Invalid(format!("cannot start the simulation thread: {e}")))
}

/// `scene` as the viewer runs it: until the page's user closes it, writing no
/// files. The run-length and output limits of `heml run` (`warn_steps`,
/// `max_steps`, the output-size estimates of `[output]`) judge a run to its
/// `duration`; a viewer has none, so they are lifted rather than warning that an
/// hour of simulated time is millions of steps.
pub fn for_viewing(mut scene: Scene) -> Scene {
    scene.solver.warn_steps = Some(u64::MAX);
    scene.solver.max_steps = Some(u64::MAX);
    scene.output.vtu = false;
    scene.output.csv = false;
    scene
}

/// The adaptive step for `sim`'s explicit integrator, from the scene's step.
fn adaptive_step(sim: &mut Simulation) -> Option<AdaptiveStep> {
    let explicit = sim.integrator.implicit_settings_mut().is_none();
    explicit.then(|| AdaptiveStep::new(&sim.system, sim.dt, sim.adapt_every))
}

/// The scene built, its step policy relaxed as `heml run` does for a warned dt.
fn build(scene: &Scene) -> heml::Result<Simulation> {
    let mut sim = scene.build()?;
    for w in &sim.warnings {
        log::warn!("{w}");
    }
    if sim.dt > sim.system.stable_dt() && sim.dt_policy == TimeStepPolicy::Warn {
        sim.system.set_time_step_policy(TimeStepPolicy::Ignore);
    }
    sim.system.compute_forces()?;
    // an implicit integrator's pattern and symbolic analysis now, not in the first
    // live step
    sim.integrator.prepare(&sim.system)?;
    Ok(sim)
}

impl Live {
    fn run(mut self, commands: Receiver<Envelope>) {
        loop {
            // commands first: never more than a step's delay
            loop {
                let next = if self.paused || self.error.is_some() {
                    match commands.recv_timeout(Duration::from_secs_f64(1.0 / STATUS_HZ)) {
                        Ok(env) => Some(env),
                        Err(RecvTimeoutError::Timeout) => None,
                        Err(RecvTimeoutError::Disconnected) => return,
                    }
                } else {
                    match commands.try_recv() {
                        Ok(env) => Some(env),
                        Err(std::sync::mpsc::TryRecvError::Empty) => None,
                        Err(std::sync::mpsc::TryRecvError::Disconnected) => return,
                    }
                };
                match next {
                    Some(env) => self.handle(env),
                    None => break,
                }
            }
            if !self.paused && self.error.is_none() && self.due() {
                self.step();
            }
            if self.last_frame.elapsed() >= self.frame_period {
                self.publish_frame();
            }
            if self.period.0.elapsed().as_secs_f64() >= 1.0 / STATUS_HZ {
                self.publish_status();
            }
        }
    }

    /// Whether the next step is due: false (after a nap of at most 2 ms, so that
    /// commands, frames and status keep flowing) while the simulation is ahead of
    /// real time. The loop asks again rather than stepping after the nap: with a
    /// step of 20 ms (an implicit scene) and a nap capped at 2 ms, stepping anyway
    /// ran the kidney at 7x real time.
    fn due(&mut self) -> bool {
        let t = self.sim.system.time();
        let target = self.anchor.1 + self.anchor.0.elapsed().as_secs_f64();
        if t > target {
            std::thread::sleep(Duration::from_secs_f64((t - target).min(0.002)));
            return false;
        }
        if target - t > MAX_LAG {
            self.anchor = (Instant::now(), t);
        }
        true
    }

    fn step(&mut self) {
        let start = Instant::now();
        let dt = match &mut self.adapt {
            Some(adapt) => adapt.next(&self.sim.system).0,
            None => self.sim.dt,
        };
        // the scene's script, as `heml run` plays it: cuts, ramped surface loads,
        // scripted tools
        let result = match self.sim.before_step(dt) {
            Ok(cut) => {
                if cut {
                    self.fields = SurfaceFields::new(&self.sim.system);
                    self.mesh_version += 1;
                    self.publish_mesh();
                }
                let pool = match &self.page_pool {
                    Some(p) if self.hub.pages.load(std::sync::atomic::Ordering::Relaxed) > 0 => p,
                    _ => &self.pool,
                };
                let Simulation { integrator, system, .. } = &mut self.sim;
                pool.install(|| integrator.step(system, dt))
            }
            Err(e) => Err(e),
        };
        self.step_ms.push(start.elapsed().as_secs_f64() * 1e3);
        if let Err(e) = result {
            log::error!("view: the simulation stopped: {e}");
            self.error = Some(e.to_string());
            self.publish_status();
        }
    }

    fn restart_clocks(&mut self) {
        let now = Instant::now();
        let t = self.sim.system.time();
        self.anchor = (now, t);
        self.period = (now, t);
        self.step_ms.clear();
    }

    fn handle(&mut self, env: Envelope) {
        let name = request_name(&env.request);
        let result: Result<String, String> = match &env.request {
            Request::Pause {} => {
                self.paused = true;
                Ok("paused".into())
            }
            Request::Resume {} => {
                self.paused = false;
                self.error = None;
                self.restart_clocks();
                Ok("running".into())
            }
            Request::Step {} => {
                self.paused = true;
                if self.error.is_none() {
                    self.step();
                }
                self.publish_frame();
                Ok(format!("t = {} s", self.sim.system.time()))
            }
            Request::Reset {} => self.rebuild().map(|_| "reset".into()),
            Request::SetParam { name, value } => self.set_param(name, *value),
            Request::Field { field } => {
                self.field = *field;
                self.publish_frame();
                Ok(String::new())
            }
            Request::GraspStart { node, ray } => self.adapter.grasp_start(&mut self.sim.system, *node, *ray),
            Request::GraspMove { target } => self.adapter.grasp_move(&mut self.sim.system, target),
            Request::GraspEnd {} => self.adapter.grasp_end(&mut self.sim.system),
            Request::ToolMove { position, axis } => {
                self.adapter.tool_move(&mut self.sim.system, position, axis.as_ref())
            }
            // flow control is the connection's (the server never forwards it)
            Request::Ack {} => return,
            Request::Cut { blade } => match self.adapter.cut(&mut self.sim.system, blade) {
                Ok(changed) => {
                    if changed {
                        self.fields = SurfaceFields::new(&self.sim.system);
                        self.mesh_version += 1;
                        self.publish_mesh();
                    }
                    Ok("cut".into())
                }
                Err(e) => Err(e),
            },
        };
        match result {
            Ok(msg) => env.answer(Reply::json(name, true, msg)),
            Err(msg) => {
                // answered to the page; a drag repeats it 60 times a second, so not a warning
                log::info!("view: {name}: {msg}");
                env.answer(Reply::json(name, false, msg));
            }
        }
        self.publish_status();
    }

    /// `set_param`: the value set in every material of the scene that has the
    /// parameter, and those materials' laws replaced in the running system
    /// ([`Scene::update_laws`]): the state, cuts, grasps, tools and viscous history
    /// stay. The explicit step's adaptive controller follows the new stiffness.
    fn set_param(&mut self, name: &str, value: f64) -> Result<String, String> {
        let old: Vec<Option<f64>> = self.scene.materials.iter().map(|m| m.params.get(name)).collect();
        let entries: Vec<usize> = (0..old.len()).filter(|&k| old[k].is_some()).collect();
        if entries.is_empty() {
            let mut known: Vec<String> = self
                .scene
                .materials
                .iter()
                .flat_map(|m| m.params.0.keys().cloned())
                .collect();
            known.sort();
            known.dedup();
            return Err(format!(
                "no material of the scene has a parameter {name:?} (it has {known:?})"
            ));
        }
        let set_all = |scene: &mut Scene, values: &[Option<f64>]| {
            for (m, v) in scene.materials.iter_mut().zip(values) {
                if let Some(v) = v {
                    m.params.set(name, *v);
                }
            }
        };
        let new: Vec<Option<f64>> = old.iter().map(|o| o.map(|_| value)).collect();
        set_all(&mut self.scene, &new);
        // the laws are set together or not at all: an error leaves the system as it was
        if let Err(e) = self.scene.update_laws(&mut self.sim.system, &entries) {
            set_all(&mut self.scene, &old);
            return Err(e.to_string());
        }
        if let Err(e) = self.sim.system.compute_forces() {
            // the new laws cannot take the current state (a non-finite force): back
            // to the old ones, which could
            set_all(&mut self.scene, &old);
            if let Err(e2) = self
                .scene
                .update_laws(&mut self.sim.system, &entries)
                .and_then(|()| self.sim.system.compute_forces())
            {
                log::warn!("view: set_param {name}: restoring the old laws failed: {e2}");
            }
            return Err(e.to_string());
        }
        self.adapt = adaptive_step(&mut self.sim);
        self.error = None;
        self.restart_clocks();
        self.publish_frame();
        Ok(format!("{name} = {value}"))
    }

    /// Rebuilds the simulation from the scene (a reset): the scene's cuts happen
    /// again. On failure the old simulation stays.
    fn rebuild(&mut self) -> Result<(), String> {
        let mut sim = build(&self.scene).map_err(|e| e.to_string())?;
        self.fields = SurfaceFields::new(&sim.system);
        self.mesh_version += 1;
        self.adapt = adaptive_step(&mut sim);
        self.sim = sim;
        self.adapter.forget();
        self.error = None;
        self.publish_mesh();
        self.restart_clocks();
        self.publish_frame();
        Ok(())
    }

    fn publish_mesh(&mut self) {
        let msg = mesh_message(
            &self.sim.system,
            &self.fields,
            self.mesh_version,
            "live",
            &self.scene.origin.display().to_string(),
        );
        match serde_json::to_string(&msg) {
            Ok(text) => {
                self.hub.mesh.send_replace(text.into());
            }
            Err(e) => log::error!("view: cannot encode the mesh: {e}"),
        }
    }

    fn publish_frame(&mut self) {
        let sys = &self.sim.system;
        let xyz = self.fields.positions(sys);
        let values = self.fields.values(sys, self.field);
        self.frame += 1;
        let bytes = encode_frame(self.frame, sys.time(), self.field, self.mesh_version, &xyz, &values);
        self.hub.frames.send_replace(bytes.into());
        self.last_frame = Instant::now();
    }

    fn publish_status(&mut self) {
        let now = Instant::now();
        let sys = &self.sim.system;
        let wall = now.duration_since(self.period.0).as_secs_f64();
        let mut ms = std::mem::take(&mut self.step_ms);
        ms.sort_by(f64::total_cmp);
        let s = &mut self.status;
        if wall > 0.0 && !ms.is_empty() {
            s.real_time_factor = (sys.time() - self.period.1) / wall;
            s.step_ms_p50 = percentile(&ms, 0.5);
            s.step_ms_p99 = percentile(&ms, 0.99);
        } else if self.paused {
            s.real_time_factor = 0.0;
        }
        self.period = (now, sys.time());
        s.kind = "status";
        s.time = sys.time();
        s.steps = sys.step_count();
        s.frame = self.frame;
        s.paused = self.paused;
        s.integrator = self.sim.integrator.name().into();
        s.dt = self.adapt.as_ref().map_or(self.sim.dt, AdaptiveStep::dt);
        s.min_j = self.fields.min_j(sys);
        s.tool_force = self.adapter.tool_force(sys).map(|f| [f.x, f.y, f.z]);
        s.tool = self.adapter.tool_view(sys);
        s.grasp = self.adapter.grasp_view(sys);
        if let Some(r) = sys.regions().first() {
            let law = r.material();
            s.law = law.name().into();
            s.law_params = law
                .param_info()
                .iter()
                .zip(law.param_values())
                .map(|(p, v)| (p.name.to_string(), v))
                .collect();
        }
        s.scene_params = self
            .scene
            .materials
            .first()
            .map(|m| m.params.0.iter().map(|(k, v)| (k.clone(), *v)).collect())
            .unwrap_or_default();
        s.field = Some(self.field);
        s.error = self.error.clone();
        match serde_json::to_string(&*s) {
            Ok(text) => {
                self.hub.status.send_replace(text.into());
            }
            Err(e) => log::error!("view: cannot encode the status: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{for_viewing, percentile};
    use crate::cli::demo::DEMO_SCENE;
    use heml::scene::Scene;

    #[test]
    fn a_viewed_scene_has_no_run_length_or_output_limits() {
        let mut scene = Scene::from_toml_str_named(DEMO_SCENE, ".", "demo.toml (embedded)").unwrap();
        // a week of simulated time: far above max_steps at the demo's step
        scene.solver.duration = 6.048e5;
        let err = scene.build().unwrap_err().to_string();
        assert!(err.contains("max_steps"), "{err}");
        let sim = for_viewing(scene).build().unwrap();
        // nothing to warn about (the plan's warnings are what `heml view` printed)
        // and nothing to write
        assert!(sim.plan.warnings.is_empty(), "{:?}", sim.plan.warnings);
        assert!(sim.plan.steps > 1_000_000_000 && sim.plan.est_bytes == 0);
        assert!(!sim.vtu && !sim.csv);
    }

    #[test]
    fn percentiles_are_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 0.5), 50.0);
        assert_eq!(percentile(&v, 0.99), 99.0);
        assert_eq!(percentile(&[3.0], 0.99), 3.0);
        assert_eq!(percentile(&[], 0.5), 0.0);
    }
}
