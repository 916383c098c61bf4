//! The library reports through the `log` facade, never by printing: a warning is both
//! kept in `System::warnings()` and logged at the `Warn` level, and the quasi-static
//! progress lines are `Info` records that appear only when asked for.
//!
//! A logger is process-wide and the unit tests run on parallel threads, so the
//! recording logger below tags every record with the thread that emitted it and each
//! test looks only at its own thread's records (the library logs on the caller's
//! thread).

use super::*;
use log::{Level, LevelFilter, Log, Metadata, Record};
use std::sync::Mutex;
use std::thread::{self, ThreadId};

/// One log record as the tests see it.
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

/// The records of this thread since `before` (a length of [`records`]).
fn since(before: usize) -> Vec<Entry> {
    records()[before..].to_vec()
}

fn warnings_of(entries: &[Entry]) -> Vec<&Entry> {
    entries.iter().filter(|e| e.level == Level::Warn).collect()
}

#[test]
fn warnings_are_collected_and_logged() {
    let before = records().len();
    // a node that no tet uses: pinned, with a builder warning
    let m = regular_tet();
    let mut nodes = m.nodes().to_vec();
    nodes.push(Vec3::new(5.0, 5.0, 5.0));
    let m = TetMesh::new(nodes, vec![[0, 1, 2, 3]]).unwrap();
    let mut sys = System::builder(m)
        .material_law(spring(10.0))
        .fix_nodes([0, 1, 2])
        .pin_unreferenced()
        .build()
        .unwrap();
    assert_eq!(sys.warnings().len(), 1, "{:?}", sys.warnings());
    // the time-step warning, issued by the system itself (once per system)
    let big = 1.5 * sys.stable_dt();
    step(&mut sys, big).unwrap();
    step(&mut sys, big).unwrap();
    assert_eq!(sys.warnings().len(), 2, "{:?}", sys.warnings());
    assert!(sys.warnings()[0].contains("pinned"), "{:?}", sys.warnings());
    assert!(
        sys.warnings()[1].contains("exceeds the stable estimate"),
        "{:?}",
        sys.warnings()
    );

    let logged = since(before);
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
    let mut sys = System::builder(regular_tet())
        .material_law(spring(10.0))
        .fix_nodes([0, 1, 2])
        .time_step_policy(TimeStepPolicy::Ignore)
        .build()
        .unwrap();
    let big = 1.5 * sys.stable_dt();
    step(&mut sys, big).unwrap();
    assert!(sys.warnings().is_empty());
    let logged = since(before);
    assert!(warnings_of(&logged).is_empty(), "{logged:?}");
}

#[test]
fn static_progress_is_logged_only_when_asked() {
    // a hanging cube: link law (no tangent: dynamic relaxation), then an invariant
    // law (Newton)
    for (law, newton) in [(spring(2000.0), false), (neo(1e4, 4e4), true)] {
        let mut sys = System::builder(box_mesh([0.1, 0.1, 0.1], [2, 2, 2], HexSplit::Six).unwrap())
            .material_law(law)
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .fix_where(|p| p.z > 0.1 - 1e-9)
            .build()
            .unwrap();
        let start = sys.positions().to_vec();
        let before = records().len();
        let quiet = sys.solve_static(&StaticOptions::default()).unwrap();
        assert!(since(before).is_empty(), "{:?}", since(before));

        sys.positions_mut().copy_from_slice(&start);
        let before = records().len();
        let every = 50;
        let report = sys
            .solve_static(&StaticOptions {
                progress_every: every,
                ..StaticOptions::default()
            })
            .unwrap();
        // logging does not change the solve
        assert_eq!(report, quiet);
        let logged = since(before);
        assert!(
            logged
                .iter()
                .all(|e| e.level == Level::Info && e.target.starts_with("heml_core::system::statics")),
            "{logged:?}"
        );
        let it = report.iterations;
        if newton {
            // every Newton iteration, from 0 to the converged one
            assert_eq!(logged.len(), it + 1, "{it} iterations: {logged:?}");
            assert!(
                logged.iter().all(|e| e.message.starts_with("quasi-static Newton")),
                "{logged:?}"
            );
        } else {
            // one line every `every` iterations from 0, plus the converged one
            assert_eq!(
                logged.len(),
                it / every + 1 + usize::from(!it.is_multiple_of(every)),
                "{it}: {logged:?}"
            );
            assert!(
                logged.iter().all(|e| e.message.starts_with("quasi-static: iteration")),
                "{logged:?}"
            );
        }
    }
}
