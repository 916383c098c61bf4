//! The `heml view` command: chooses what to show (a scene, the demo, a recorded
//! run), starts its producer thread and serves the page.

use std::path::PathBuf;
use std::sync::Arc;

use heml::scene::Scene;
use heml::{HemlError, Result};

use super::control::Controls;
use super::hub::Hub;
use super::playback::Recording;
use super::runtime::Runtime;
use super::{live, playback, server};
use crate::cli::demo::DEMO_SCENE;
use crate::threads::Placement;

/// Arguments of `heml view`.
#[derive(clap::Args, Debug, Clone)]
pub struct ViewArgs {
    /// A scene file (TOML), or a run's output directory or its `.pvd` to play back.
    #[arg(required_unless_present = "demo", conflicts_with = "demo")]
    pub input: Option<PathBuf>,
    /// Show the embedded demo scene (the one `heml demo` runs).
    #[arg(long)]
    pub demo: bool,
    /// TCP port (0: any free port).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Address to listen on. Anything but loopback exposes the simulation's controls
    /// to the network (there is no authentication).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Worker threads of the force assembly (pinned to CPUs when there are enough;
    /// at most 4 × the CPUs, up to 1024).
    #[arg(long, default_value_t = default_threads(), value_parser = crate::threads::thread_count)]
    pub threads: usize,
    /// Let the OS place the worker threads instead of pinning the k-th to the k-th CPU.
    #[arg(long)]
    pub no_pin: bool,
    /// Worker threads, placed by the OS (not pinned), while a page is connected
    /// when listening on loopback: its browser shares this machine's CPUs, and
    /// without a GPU it renders on them. 0: one fewer than `--threads` (at least 1),
    /// a core left to the browser.
    #[arg(long, default_value_t = 0, value_parser = crate::threads::thread_count_or_zero)]
    pub page_threads: usize,
    /// Most frames per second sent to a page (1-240).
    #[arg(long, default_value_t = live::FRAME_HZ, value_parser = frame_rate)]
    pub fps: f64,
    /// Do not open a browser; just print the URL.
    #[arg(long)]
    pub no_open: bool,
}

/// The pool size while a page is connected, `None` where it is the pool of
/// `--threads` (pages elsewhere, or that pool already unpinned and as large).
fn page_threads(args: &ViewArgs) -> Option<usize> {
    let n = if args.page_threads == 0 {
        args.threads.saturating_sub(1).max(1)
    } else {
        args.page_threads
    };
    (is_loopback(&args.host) && !(args.no_pin && n == args.threads)).then_some(n)
}

/// `--fps`: a frame rate in 1..=240 per second.
fn frame_rate(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (1.0..=240.0).contains(&v) => Ok(v),
        _ => Err(format!("{s:?} is not a frame rate in 1..=240 per second")),
    }
}

fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Is `host` a loopback address (or `localhost`)?
pub fn is_loopback(host: &str) -> bool {
    host == "localhost" || host.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

/// Runs `heml view` until interrupted.
pub fn run(args: ViewArgs) -> Result<()> {
    if !is_loopback(&args.host) {
        eprintln!(
            "heml warning: ********************************************************************\n\
             heml warning: listening on {} (not loopback): anyone who can reach this machine can\n\
             heml warning: watch and drive the simulation; there is no authentication.\n\
             heml warning: ********************************************************************",
            args.host
        );
    }
    let settings = live::Settings {
        threads: args.threads,
        placement: if args.no_pin { Placement::Os } else { Placement::Pinned },
        frame_hz: args.fps,
        page_threads: page_threads(&args),
    };
    let (hub, commands) = Hub::new();
    let hub = Arc::new(hub);
    // the producer first: a bad scene or recording is an error before anything listens
    let producer = match (&args.input, args.demo) {
        (_, true) => {
            let scene = Scene::from_toml_str_named(DEMO_SCENE, ".", "demo.toml (embedded)")?;
            live::spawn(scene, &settings, hub.clone(), commands, controls())?
        }
        (Some(p), false) if p.extension().is_some_and(|x| x == "toml") => {
            let scene = Scene::from_file(p)?;
            live::spawn(scene, &settings, hub.clone(), commands, controls())?
        }
        (Some(p), false) => {
            let rec = Recording::read(p)?;
            outln!("{}: {} frames", rec.source.display(), rec.frames.len());
            playback::spawn(rec, hub.clone(), commands)?
        }
        (None, false) => return Err(HemlError::Invalid("give a scene file, a run's output or --demo".into())),
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| HemlError::Invalid(format!("cannot start the server's runtime: {e}")))?;
    let no_open = args.no_open;
    let served = runtime.block_on(server::serve(hub, &args.host, args.port, |addr| {
        let url = format!("http://{addr}/");
        outln!("heml view: {url}  (Ctrl-C to stop)");
        if !no_open {
            open_browser(&url);
        }
    }));
    drop(producer);
    served.map_err(|e| HemlError::Invalid(format!("cannot serve on {}:{}: {e}", args.host, args.port)))
}

/// The grasp, tool and cut controls: the library's runtime control
/// ([`super::runtime::Runtime`]).
fn controls() -> Box<dyn Controls> {
    Box::new(Runtime::default())
}

/// Asks the desktop to open `url` (failure is not an error: the URL is printed).
fn open_browser(url: &str) {
    let opener = if cfg!(target_os = "macos") {
        "open"
    } else if cfg!(target_os = "windows") {
        "explorer"
    } else {
        "xdg-open"
    };
    if let Err(e) = std::process::Command::new(opener)
        .arg(url)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
    {
        log::info!("could not open a browser ({opener}: {e}); open {url} yourself");
    }
}

#[cfg(test)]
mod tests {
    use super::{page_threads, ViewArgs};

    fn args(threads: usize, page: usize, no_pin: bool, host: &str) -> ViewArgs {
        ViewArgs {
            input: None,
            demo: true,
            port: 0,
            host: host.into(),
            threads,
            no_pin,
            page_threads: page,
            fps: 40.0,
            no_open: true,
        }
    }

    #[test]
    fn a_connected_page_gets_its_own_pool_only_on_loopback() {
        // default: a core left to the browser, the workers unpinned
        assert_eq!(page_threads(&args(2, 0, false, "127.0.0.1")), Some(1));
        assert_eq!(page_threads(&args(8, 0, false, "localhost")), Some(7));
        assert_eq!(page_threads(&args(1, 0, false, "::1")), Some(1));
        assert_eq!(page_threads(&args(2, 2, false, "127.0.0.1")), Some(2));
        // the pages are on other machines: the pool of --threads
        assert_eq!(page_threads(&args(2, 0, false, "0.0.0.0")), None);
        // that pool is already unpinned and as large
        assert_eq!(page_threads(&args(1, 0, true, "127.0.0.1")), None);
        assert_eq!(page_threads(&args(2, 2, true, "127.0.0.1")), None);
        assert_eq!(page_threads(&args(2, 0, true, "127.0.0.1")), Some(1));
    }

    #[test]
    fn frame_rates_are_checked() {
        assert_eq!(super::frame_rate("40"), Ok(40.0));
        for bad in ["0", "241", "NaN", "x", "-5"] {
            assert!(super::frame_rate(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn loopback_hosts_are_recognised() {
        for h in ["127.0.0.1", "::1", "localhost", "127.0.0.2"] {
            assert!(super::is_loopback(h), "{h}");
        }
        for h in ["0.0.0.0", "192.168.1.2", "example.org", "::"] {
            assert!(!super::is_loopback(h), "{h}");
        }
    }
}
