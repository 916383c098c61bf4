//! The HTTP and WebSocket server of `heml view` (axum on tokio): the embedded page
//! at `/`, its scripts, and `/ws`, the live connection.
//!
//! Each connection sends the mesh, then forwards whatever is newest in the hub's
//! channels (frames, status, mesh changes, replies) and parses the page's commands.
//! A page that acks its frames ([`super::protocol::Request::Ack`]) has
//! at most one frame in flight: the next one waits for its ack, and by then it is the
//! newest, so a page that is busy gets fewer, fresher frames instead of a queue in
//! the sockets.
//! Messages over [`MAX_MESSAGE_BYTES`] end that connection (the WebSocket layer
//! refuses them); bad commands are logged and ignored; a command that finds the
//! producer's queue full is answered `busy` ([`super::hub::COMMAND_CAPACITY`]).
//! Nothing the page sends can name a file: the routes serve the embedded assets only.
//!
//! Other sites: every request must name this server in its `Host` header (its bound
//! address or a loopback name, with its port: no DNS rebinding), and a WebSocket
//! handshake that carries an `Origin` must come from a page of such a host (no
//! cross-site WebSocket hijacking); others get 403 ([`Hosts`]). Connections have
//! [`HEADER_TIMEOUT`] to send their request's headers, and at most
//! [`MAX_CONNECTIONS`] are served at once (more wait to be accepted).

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;

use super::assets;
use super::hub::{Envelope, Hub, PageCount, REPLY_CAPACITY};
use super::protocol::{parse_request, Reply, Request as PageRequest, MAX_MESSAGE_BYTES};

/// Time a connection has to send a request's headers before it is closed.
pub const HEADER_TIMEOUT: Duration = Duration::from_secs(5);

/// Most connections served at once (pages, their scripts, tools).
pub const MAX_CONNECTIONS: usize = 128;

/// The `Host` values (`name:port`, lower case) this server answers to: the address
/// it is bound to, `--host` as given, and the loopback names. Bound to an
/// unspecified address (`0.0.0.0`, `::`), any IP address with the port is accepted
/// too (a rebinding attack needs a name), but no other name.
#[derive(Debug, Clone)]
pub struct Hosts {
    names: Vec<String>,
    port: u16,
    any_ip: bool,
}

impl Hosts {
    /// The hosts of a server bound to `addr`, asked for with `--host host`.
    pub fn new(host: &str, addr: SocketAddr) -> Hosts {
        let port = addr.port();
        let bracket = |h: &str| {
            if h.contains(':') && !h.starts_with('[') {
                format!("[{h}]")
            } else {
                h.to_string()
            }
        };
        let mut bare = vec![
            "127.0.0.1".to_string(),
            "localhost".to_string(),
            "[::1]".to_string(),
            bracket(&addr.ip().to_string()),
            bracket(host).to_ascii_lowercase(),
        ];
        bare.dedup();
        let mut names: Vec<String> = bare.iter().map(|h| format!("{h}:{port}")).collect();
        if port == 80 {
            names.extend(bare);
        }
        Hosts {
            names,
            port,
            any_ip: addr.ip().is_unspecified(),
        }
    }

    /// Whether `host` (a `Host` header, or an origin without its scheme) names this
    /// server.
    pub fn allows(&self, host: &str) -> bool {
        let host = host.to_ascii_lowercase();
        self.names.contains(&host) || (self.any_ip && host.parse::<SocketAddr>().is_ok_and(|a| a.port() == self.port))
    }

    /// Why a request with these `Host` and `Origin` headers is refused, if it is.
    pub fn refusal(&self, path: &str, host: Option<&[u8]>, origin: Option<&[u8]>) -> Option<String> {
        let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
        match host {
            None => return Some("no Host header".into()),
            Some(h) if !std::str::from_utf8(h).is_ok_and(|h| self.allows(h)) => {
                return Some(format!("Host {:?} is not this server", text(h)));
            }
            Some(_) => {}
        }
        match origin {
            Some(o) if path == "/ws" => {
                let ok = std::str::from_utf8(o)
                    .ok()
                    .and_then(|o| o.strip_prefix("http://"))
                    .is_some_and(|h| self.allows(h));
                (!ok).then(|| format!("Origin {:?} is not a page of this server", text(o)))
            }
            _ => None,
        }
    }
}

/// The application: routes, the shared hub, and the `Host`/`Origin` check.
pub fn app(hub: Arc<Hub>, hosts: Arc<Hosts>) -> Router {
    Router::new()
        .route("/", get(|| async { asset("index.html") }))
        .route("/{*path}", get(static_file))
        .route("/ws", get(ws))
        .with_state(hub)
        .layer(axum::middleware::from_fn_with_state(hosts, check_hosts))
}

/// Refuses (403) a request for another host or a WebSocket from another site's page.
async fn check_hosts(State(hosts): State<Arc<Hosts>>, req: Request, next: Next) -> Response {
    let headers = req.headers();
    let refusal = hosts.refusal(
        req.uri().path(),
        headers.get(header::HOST).map(|h| h.as_bytes()),
        headers.get(header::ORIGIN).map(|h| h.as_bytes()),
    );
    match refusal {
        None => next.run(req).await,
        Some(why) => {
            // once: a hostile page may retry without end
            static LOGGED: AtomicBool = AtomicBool::new(false);
            if !LOGGED.swap(true, Ordering::Relaxed) {
                log::warn!(
                    "view: refused a request for {} ({why}); further refusals are logged at debug level",
                    req.uri().path()
                );
            } else {
                log::debug!("view: refused a request for {} ({why})", req.uri().path());
            }
            (
                StatusCode::FORBIDDEN,
                [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
                format!("forbidden: {why}\n"),
            )
                .into_response()
        }
    }
}

async fn static_file(axum::extract::Path(path): axum::extract::Path<String>) -> Response {
    asset(&path)
}

fn asset(path: &str) -> Response {
    match assets::find(path) {
        Some((body, mime)) => (
            [(header::CONTENT_TYPE, mime), (header::CACHE_CONTROL, "no-cache")],
            body,
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, "not found").into_response(),
    }
}

async fn ws(upgrade: WebSocketUpgrade, State(hub): State<Arc<Hub>>) -> Response {
    upgrade
        .max_message_size(MAX_MESSAGE_BYTES)
        .max_frame_size(MAX_MESSAGE_BYTES)
        .on_upgrade(move |socket| connection(socket, hub))
}

/// One page's connection, until it closes or misbehaves at the protocol level.
async fn connection(mut socket: WebSocket, hub: Arc<Hub>) {
    let mut frames = hub.frames.subscribe();
    let mut status = hub.status.subscribe();
    let mut mesh = hub.mesh.subscribe();
    let (reply_tx, mut replies) = tokio::sync::mpsc::channel(REPLY_CAPACITY);
    // the current mesh first, then the newest frame (the page draws at once)
    mesh.mark_changed();
    frames.mark_changed();
    // flow control: set once the page acks a frame, then one frame in flight at a time
    let (mut acking, mut in_flight) = (false, false);
    let mut page = None;
    loop {
        let out = tokio::select! {
            biased;
            m = mesh.changed() => match m {
                Ok(()) => Message::Text(mesh.borrow_and_update().clone()),
                Err(_) => break,
            },
            // replies before reading more: a client that floods commands gets its
            // answers (and waits for them) instead of filling the reply channel
            r = replies.recv() => match r {
                Some(text) => Message::Text(text),
                None => continue,
            },
            incoming = socket.recv() => match incoming {
                Some(Ok(Message::Text(text))) => {
                    match parse_request(text.as_str()) {
                        Ok(PageRequest::Ack {}) => {
                            (acking, in_flight) = (true, false);
                            page.get_or_insert_with(|| PageCount::new(&hub));
                        }
                        Ok(request) => {
                            let name = super::protocol::request_name(&request);
                            let env = Envelope { request, reply: reply_tx.clone() };
                            // never waits: a full queue refuses the command
                            let refused = match hub.commands.try_send(env) {
                                Ok(()) => None,
                                Err(std::sync::mpsc::TrySendError::Full(_)) => Some("busy: too many commands queued"),
                                Err(std::sync::mpsc::TrySendError::Disconnected(_)) => Some("the simulation has stopped"),
                            };
                            if let Some(why) = refused {
                                let _ = reply_tx.try_send(Reply::json(name, false, why).into());
                            }
                        }
                        Err(e) => {
                            log::warn!("view: ignored a message from the page: {e}");
                            let _ = reply_tx.try_send(Reply::json("?", false, e).into());
                        }
                    }
                    continue;
                }
                Some(Ok(Message::Binary(b))) => {
                    log::warn!("view: ignored a binary message of {} bytes from the page", b.len());
                    continue;
                }
                Some(Ok(Message::Close(_))) | None => break,
                Some(Ok(_)) => continue, // ping/pong: answered by the WebSocket layer
                Some(Err(e)) => {
                    log::warn!("view: closed a connection: {e}");
                    break;
                }
            },
            s = status.changed() => match s {
                Ok(()) => Message::Text(status.borrow_and_update().clone()),
                Err(_) => break,
            },
            f = frames.changed(), if !(acking && in_flight) => match f {
                Ok(()) => {
                    let bytes = frames.borrow_and_update().clone();
                    if bytes.is_empty() {
                        continue;
                    }
                    in_flight = true;
                    Message::Binary(bytes)
                }
                Err(_) => break,
            },
        };
        if socket.send(out).await.is_err() {
            break;
        }
    }
}

/// Binds `host:port` (port 0: a free one) and serves until the process ends.
/// Returns the bound address once listening, through `ready`.
pub async fn serve(hub: Arc<Hub>, host: &str, port: u16, ready: impl FnOnce(SocketAddr)) -> std::io::Result<()> {
    let listener = tokio::net::TcpListener::bind((host, port)).await?;
    let addr = listener.local_addr()?;
    let app = app(hub, Arc::new(Hosts::new(host, addr)));
    ready(addr);
    // served by hand rather than by axum::serve, which sets no header-read timeout
    let slots = Arc::new(tokio::sync::Semaphore::new(MAX_CONNECTIONS));
    loop {
        let Ok(slot) = slots.clone().acquire_owned().await else {
            return Ok(()); // never closed
        };
        let stream = match listener.accept().await {
            Ok((stream, _)) => stream,
            Err(e) => {
                // out of file descriptors and the like: wait for connections to end
                log::debug!("view: accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        let _ = stream.set_nodelay(true);
        let service = hyper_util::service::TowerToHyperService::new(app.clone());
        tokio::spawn(async move {
            let served = hyper::server::conn::http1::Builder::new()
                .timer(hyper_util::rt::TokioTimer::new())
                .header_read_timeout(HEADER_TIMEOUT)
                .serve_connection(hyper_util::rt::TokioIo::new(stream), service)
                .with_upgrades()
                .await;
            if let Err(e) = served {
                log::debug!("view: connection ended: {e}");
            }
            drop(slot);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::Hosts;

    #[test]
    fn only_this_servers_hosts_and_pages_are_served() {
        let h = Hosts::new("127.0.0.1", "127.0.0.1:8123".parse().unwrap());
        for ok in ["127.0.0.1:8123", "localhost:8123", "LocalHost:8123", "[::1]:8123"] {
            assert!(h.allows(ok), "{ok}");
        }
        for bad in [
            "127.0.0.1:8124",
            "localhost",
            "rebind.attacker.example:8123",
            "10.0.0.1:8123",
            "",
        ] {
            assert!(!h.allows(bad), "{bad}");
        }
        let host = Some(&b"127.0.0.1:8123"[..]);
        assert_eq!(h.refusal("/ws", host, None), None);
        assert_eq!(h.refusal("/ws", host, Some(b"http://localhost:8123")), None);
        assert!(h.refusal("/ws", host, Some(b"http://evil.example.com")).is_some());
        assert!(h.refusal("/ws", host, Some(b"null")).is_some());
        assert!(h.refusal("/ws", host, Some(b"https://localhost:8123")).is_some());
        assert!(h.refusal("/", Some(b"evil.example.com"), None).is_some());
        assert!(h.refusal("/", None, None).is_some());
        // bound to every address: any IP literal with the port, no other name
        let h = Hosts::new("0.0.0.0", "0.0.0.0:8123".parse().unwrap());
        assert!(h.allows("192.168.1.5:8123") && h.allows("localhost:8123"));
        assert!(!h.allows("rebind.attacker.example:8123") && !h.allows("192.168.1.5:80"));
        // a name given to --host
        let h = Hosts::new("myhost.local", "192.168.1.5:8123".parse().unwrap());
        assert!(h.allows("myhost.local:8123") && h.allows("192.168.1.5:8123"));
    }
}
