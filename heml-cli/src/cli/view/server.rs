//! The HTTP and WebSocket server of `heml view` (axum on tokio): the embedded page
//! at `/`, its scripts, and `/ws`, the live connection.
//!
//! Each connection sends the mesh, then forwards whatever is newest in the hub's
//! channels (frames, status, mesh changes, replies) and parses the page's commands.
//! A page that acks its frames ([`Request::Ack`]) has
//! at most one frame in flight: the next one waits for its ack, and by then it is the
//! newest, so a page that is busy gets fewer, fresher frames instead of a queue in
//! the sockets.
//! Messages over [`MAX_MESSAGE_BYTES`] end that connection (the WebSocket layer
//! refuses them); bad commands are logged and ignored. Nothing the page sends can
//! name a file: the routes serve the embedded assets only.

use std::sync::Arc;

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;

use super::assets;
use super::hub::{Envelope, Hub, PageCount, REPLY_CAPACITY};
use super::protocol::{parse_request, Reply, Request, MAX_MESSAGE_BYTES};

/// The application: routes and the shared hub.
pub fn app(hub: Arc<Hub>) -> Router {
    Router::new()
        .route("/", get(|| async { asset("index.html") }))
        .route("/{*path}", get(static_file))
        .route("/ws", get(ws))
        .with_state(hub)
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
            incoming = socket.recv() => match incoming {
                Some(Ok(Message::Text(text))) => {
                    match parse_request(text.as_str()) {
                        Ok(Request::Ack {}) => {
                            (acking, in_flight) = (true, false);
                            page.get_or_insert_with(|| PageCount::new(&hub));
                        }
                        Ok(request) => {
                            let name = super::protocol::request_name(&request);
                            let env = Envelope { request, reply: reply_tx.clone() };
                            if hub.commands.send(env).is_err() {
                                let _ = reply_tx.try_send(Reply::json(name, false, "the simulation has stopped").into());
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
            r = replies.recv() => match r {
                Some(text) => Message::Text(text),
                None => continue,
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
pub async fn serve(
    hub: Arc<Hub>,
    host: &str,
    port: u16,
    ready: impl FnOnce(std::net::SocketAddr),
) -> std::io::Result<()> {
    let listener = tokio::net::TcpListener::bind((host, port)).await?;
    ready(listener.local_addr()?);
    axum::serve(listener, app(hub)).await
}
