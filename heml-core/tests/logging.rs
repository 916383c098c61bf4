//! The library reports through the `log` facade, never by printing: a warning is both
//! kept in `System::warnings()` and logged at the `Warn` level, and the quasi-static
//! progress lines are `Info` records that only appear when asked for.
//!
//! A logger is process-wide and the tests of this file run on parallel threads, so the
//! recording logger below tags every record with the thread that emitted it and each
//! test looks only at its own thread's records (the library logs on the caller's
//! thread).

use std::sync::Mutex;
use std::thread::{self, ThreadId};

use heml_core::law::{LinkLaw, MaterialInfo, OpCount, ParamInfo};
use heml_core::material::Link;
use heml_core::mesh::generate::{box_mesh, HexSplit};
use heml_core::system::{StaticOptions, System, TimeStepPolicy};
use heml_core::{TetMesh, Vec3};
use log::{Level, LevelFilter, Log, Metadata, Record};

/// One log record as the test sees it.
#[derive(Debug, Clone)]
struct Entry {
    thread: ThreadId,
    level: Level,
    target: String,
    message: String,
}

/// Keeps every record in memory.
struct Recorder(Mutex<Vec<Entry>>);

impl Log for Recorder {
    fn enabled(&self, _: &Metadata) -> bool {
        true
    }
    fn log(&self, record: &Record) {
        self.0.lock().unwrap().push(Entry {
            thread: thread::current().id(),
            level: record.level(),
            target: record.target().to_string(),
            message: record.args().to_string(),
        });
    }
    fn flush(&self) {}
}

static RECORDER: Recorder = Recorder(Mutex::new(Vec::new()));

/// Installs the recorder (once per process) and returns the records this thread has
/// emitted so far, in order.
fn records() -> Vec<Entry> {
    // a second install fails harmlessly: the recorder is already in place
    let _ = log::set_logger(&RECORDER);
    log::set_max_level(LevelFilter::Trace);
    let me = thread::current().id();
    RECORDER
        .0
        .lock()
        .unwrap()
        .iter()
        .filter(|e| e.thread == me)
        .cloned()
        .collect()
}

/// Mass–spring w = k/2 (√l − √L)² (heml-core alone has no registered laws).
#[derive(Debug, Clone, Copy)]
struct Spring {
    k: f64,
}

impl MaterialInfo for Spring {
    const NAME: &'static str = "logging_test_spring";
    const PARAMS: &'static [ParamInfo] = &[];
    const ENERGY: &'static str = "";
    const DOC: &'static str = "";
    fn to_params(&self) -> Vec<f64> {
        vec![self.k]
    }
    fn from_params(v: &[f64]) -> Self {
        Spring { k: v[0] }
    }
}

impl LinkLaw for Spring {
    const OPS: OpCount = OpCount {
        add: 0,
        mul: 0,
        div: 0,
        func: 0,
    };
    fn w(&self, l: f64, r: f64) -> f64 {
        0.5 * self.k * (l.sqrt() - r.sqrt()).powi(2)
    }
    fn dw(&self, l: f64, r: f64) -> (f64, f64) {
        (self.w(l, r), 0.5 * self.k * (1.0 - (r / l).sqrt()))
    }
    fn d2w(&self, l: f64, r: f64) -> f64 {
        0.25 * self.k * r.sqrt() / (l * l.sqrt())
    }
}

fn warnings_of(entries: &[Entry]) -> Vec<&Entry> {
    entries.iter().filter(|e| e.level == Level::Warn).collect()
}

#[test]
fn warnings_are_collected_and_logged() {
    let before = records().len();
    // a mesh with one node that no tet uses: pinned, with a builder warning
    let tet = box_mesh([1.0, 1.0, 1.0], [1, 1, 1], HexSplit::Six).unwrap();
    let mut nodes = tet.nodes().to_vec();
    nodes.push(Vec3::new(5.0, 5.0, 5.0));
    let tets = tet.tets().iter().map(|t| t.map(|i| i as usize)).collect();
    let mesh = TetMesh::new(nodes, tets).unwrap();
    let mut sys = System::builder(mesh)
        .material_law(Box::new(Link(Spring { k: 10.0 })))
        .fix_where(|p| p.z < 1e-9)
        .pin_unreferenced()
        .build()
        .unwrap();
    assert_eq!(sys.warnings().len(), 1, "{:?}", sys.warnings());
    // the time-step warning, issued by the system itself (once per system)
    let big = 1.5 * sys.stable_dt();
    for _ in 0..2 {
        sys.begin_step(big).unwrap();
        sys.compute_forces().unwrap();
        sys.kick(big);
        sys.drift(big);
        sys.finish_step().unwrap();
    }
    assert_eq!(sys.warnings().len(), 2, "{:?}", sys.warnings());
    assert!(sys.warnings()[0].contains("pinned"), "{:?}", sys.warnings());
    assert!(
        sys.warnings()[1].contains("exceeds the stable estimate"),
        "{:?}",
        sys.warnings()
    );

    let logged = records()[before..].to_vec();
    let logged = warnings_of(&logged);
    let messages: Vec<&str> = logged.iter().map(|e| e.message.as_str()).collect();
    // exactly the collected warnings, in the same order, with the same text
    assert_eq!(messages, sys.warnings(), "{logged:?}");
    assert!(
        logged.iter().all(|e| e.target.starts_with("heml_core::system")),
        "{logged:?}"
    );
}

#[test]
fn an_ignored_time_step_logs_nothing() {
    let before = records().len();
    let mesh = box_mesh([1.0, 1.0, 1.0], [1, 1, 1], HexSplit::Six).unwrap();
    let mut sys = System::builder(mesh)
        .material_law(Box::new(Link(Spring { k: 10.0 })))
        .fix_where(|p| p.z < 1e-9)
        .time_step_policy(TimeStepPolicy::Ignore)
        .build()
        .unwrap();
    let big = 1.5 * sys.stable_dt();
    sys.begin_step(big).unwrap();
    sys.compute_forces().unwrap();
    sys.kick(big);
    sys.drift(big);
    sys.finish_step().unwrap();
    assert!(sys.warnings().is_empty());
    let logged = records()[before..].to_vec();
    assert!(warnings_of(&logged).is_empty(), "{logged:?}");
}

#[test]
fn static_progress_is_logged_only_when_asked() {
    let build = || {
        let mesh = box_mesh([0.1, 0.1, 0.1], [2, 2, 2], HexSplit::Six).unwrap();
        System::builder(mesh)
            .material_law(Box::new(Link(Spring { k: 2000.0 })))
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .fix_where(|p| p.z > 0.1 - 1e-9)
            .build()
            .unwrap()
    };
    let before = records().len();
    let quiet = build().solve_static(&StaticOptions::default()).unwrap();
    assert!(records()[before..].is_empty(), "{:?}", &records()[before..]);

    let before = records().len();
    let every = 50;
    let report = build()
        .solve_static(&StaticOptions {
            progress_every: every,
            ..StaticOptions::default()
        })
        .unwrap();
    // logging does not change the solve
    assert_eq!(report, quiet);
    let logged = records()[before..].to_vec();
    assert!(logged
        .iter()
        .all(|e| e.level == Level::Info && e.target.starts_with("heml_core::system::statics")));
    // a link law has no tangent: dynamic relaxation, one line every `every`
    // iterations from 0, plus the converged one
    let lines = report.iterations / every + 1 + usize::from(report.iterations % every != 0);
    assert_eq!(logged.len(), lines, "{} iterations: {logged:?}", report.iterations);
    assert!(
        logged.iter().all(|e| e.message.starts_with("quasi-static: iteration")),
        "{logged:?}"
    );
}
