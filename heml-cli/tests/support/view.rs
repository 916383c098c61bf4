//! Starting `heml view` for the tests and talking to it over its WebSocket.
#![allow(dead_code)] // each test file uses part of it

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use tokio_tungstenite::tungstenite::Message;

/// A running `heml view`, stopped when dropped.
pub struct ViewServer {
    child: Child,
    /// `http://127.0.0.1:PORT/`
    pub url: String,
}

impl ViewServer {
    /// `heml view ARGS --port 0 --no-open`, once it prints its URL.
    pub fn start(args: &[&str]) -> ViewServer {
        ViewServer::start_binary(env!("CARGO_BIN_EXE_heml").as_ref(), args)
    }

    /// [`ViewServer::start`] with another build of `heml` (to compare two builds).
    pub fn start_binary(heml: &std::path::Path, args: &[&str]) -> ViewServer {
        let mut child = Command::new(heml)
            .args(args)
            .args(["--port", "0", "--no-open"])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start heml view");
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if let Some(rest) = line.strip_prefix("heml view: ") {
                    let _ = tx.send(rest.split_whitespace().next().unwrap_or("").to_string());
                }
            }
        });
        let url = match rx.recv_timeout(Duration::from_secs(60)) {
            Ok(url) => url,
            Err(_) => {
                let _ = child.kill();
                panic!("heml view printed no URL within 60 s");
            }
        };
        ViewServer { child, url }
    }

    /// The server's process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// `ws://…/ws`
    pub fn ws_url(&self) -> String {
        format!("{}ws", self.url.replacen("http://", "ws://", 1))
    }

    /// The server process is still running.
    pub fn alive(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }
}

impl Drop for ViewServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// A WebSocket client of the view, remembering the last status and mesh.
pub struct Client {
    socket: Socket,
    /// Last `status` message.
    pub status: serde_json::Value,
    /// Last `mesh` message.
    pub mesh: serde_json::Value,
    /// Replies received, in order.
    pub replies: Vec<serde_json::Value>,
    /// Binary frames received and the size of the last one.
    pub frames: u64,
    pub frame_bytes: usize,
    /// The last binary frame.
    pub last_frame: Vec<u8>,
    /// The connection was closed by the server.
    pub closed: bool,
}

impl Client {
    pub async fn connect(server: &ViewServer) -> Client {
        let (socket, _) = tokio_tungstenite::connect_async(server.ws_url())
            .await
            .expect("connect");
        Client {
            socket,
            status: serde_json::Value::Null,
            mesh: serde_json::Value::Null,
            replies: Vec::new(),
            frames: 0,
            frame_bytes: 0,
            last_frame: Vec::new(),
            closed: false,
        }
    }

    pub async fn send_text(&mut self, text: &str) {
        if self.socket.send(Message::text(text)).await.is_err() {
            self.closed = true;
        }
    }

    pub async fn send(&mut self, json: serde_json::Value) {
        self.send_text(&json.to_string()).await;
    }

    pub async fn send_binary(&mut self, bytes: Vec<u8>) {
        if self.socket.send(Message::binary(bytes)).await.is_err() {
            self.closed = true;
        }
    }

    /// Reads messages for up to `timeout` or until `done` holds; false on timeout.
    pub async fn until(&mut self, timeout: Duration, mut done: impl FnMut(&Client) -> bool) -> bool {
        let end = Instant::now() + timeout;
        while !done(self) {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() || self.closed {
                return false;
            }
            match tokio::time::timeout(left, self.socket.next()).await {
                Err(_) => return done(self),
                Ok(None) | Ok(Some(Err(_))) | Ok(Some(Ok(Message::Close(_)))) => self.closed = true,
                Ok(Some(Ok(Message::Text(t)))) => {
                    let v: serde_json::Value = serde_json::from_str(t.as_str()).expect("the server sends JSON");
                    match v["type"].as_str() {
                        Some("status") => self.status = v,
                        Some("mesh") => self.mesh = v,
                        Some("reply") => self.replies.push(v),
                        other => panic!("unknown message type {other:?}"),
                    }
                }
                Ok(Some(Ok(Message::Binary(b)))) => {
                    self.frames += 1;
                    self.frame_bytes = b.len();
                    self.last_frame = b.to_vec();
                }
                Ok(Some(Ok(_))) => {}
            }
        }
        true
    }

    /// Reads for `d`, keeping the newest status.
    pub async fn drain(&mut self, d: Duration) {
        self.until(d, |_| false).await;
    }

    /// The colour field id and values of the last frame.
    pub fn frame_field(&self) -> (u32, Vec<f32>) {
        let b = &self.last_frame;
        if b.len() < 32 {
            return (u32::MAX, Vec::new());
        }
        let word = |o: usize| [b[o], b[o + 1], b[o + 2], b[o + 3]];
        let n = u32::from_le_bytes(word(4)) as usize;
        let values = (0..n).map(|k| f32::from_le_bytes(word(32 + 12 * n + 4 * k))).collect();
        (u32::from_le_bytes(word(24)), values)
    }

    pub fn time(&self) -> f64 {
        self.status["time"].as_f64().unwrap_or(f64::NAN)
    }
    pub fn steps(&self) -> u64 {
        self.status["steps"].as_u64().unwrap_or(u64::MAX)
    }
    pub fn paused(&self) -> bool {
        self.status["paused"].as_bool().unwrap_or(false)
    }
    /// A law parameter of the first material (e.g. `mu`).
    pub fn law_param(&self, name: &str) -> f64 {
        self.named("law_params", name)
    }
    /// A scene parameter of the first material (e.g. `E`).
    pub fn scene_param(&self, name: &str) -> f64 {
        self.named("scene_params", name)
    }
    /// The value of `name` in the status's list of (name, value) pairs `list`.
    fn named(&self, list: &str, name: &str) -> f64 {
        self.status[list]
            .as_array()
            .and_then(|a| a.iter().find(|p| p[0] == name))
            .and_then(|p| p[1].as_f64())
            .unwrap_or(f64::NAN)
    }
}
