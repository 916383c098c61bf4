//! The hand-off between the thread that produces frames (the simulation or the
//! playback) and the server's connections: latest-wins `watch` channels for frames,
//! status and mesh, a channel of commands the other way.
//!
//! The producer never waits: it replaces the value in a `watch` (a slow page skips
//! the frames it had no time for, nothing queues) and drains its command channel
//! without blocking. The command channel is bounded ([`COMMAND_CAPACITY`]): a
//! connection that finds it full answers that command `busy` instead of queueing it
//! (a client flooding commands cannot grow the server's memory or delay the others'
//! commands without bound). Replies to a command go back to the connection that sent
//! it through a small bounded channel, dropped when full.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;

use axum::body::Bytes;
use axum::extract::ws::Utf8Bytes;
use tokio::sync::watch;

use super::protocol::Request;

/// Capacity of a connection's reply channel (replies beyond it are dropped).
pub const REPLY_CAPACITY: usize = 32;

/// Most commands waiting for the producer, all connections together; a command
/// beyond them is refused with a `busy` reply.
pub const COMMAND_CAPACITY: usize = 256;

/// A command with where to answer it.
pub struct Envelope {
    /// The parsed command.
    pub request: Request,
    /// The sending connection's reply channel.
    pub reply: tokio::sync::mpsc::Sender<Utf8Bytes>,
}

impl Envelope {
    /// Sends `text` back to the connection, unless it is gone or its channel full.
    pub fn answer(&self, text: String) {
        let _ = self.reply.try_send(text.into());
    }
}

/// The producer's side and the connections' side of the hand-off.
pub struct Hub {
    /// Latest binary frame.
    pub frames: watch::Sender<Bytes>,
    /// Latest status JSON.
    pub status: watch::Sender<Utf8Bytes>,
    /// Current mesh JSON.
    pub mesh: watch::Sender<Utf8Bytes>,
    /// Commands to the producer (at most [`COMMAND_CAPACITY`] waiting: send with
    /// `try_send`, never blocking the server's runtime).
    pub commands: mpsc::SyncSender<Envelope>,
    /// Connections that ack their frames: pages that draw them (a client that only
    /// reads the status, as the tests' and measurements' do, is not counted).
    pub pages: AtomicUsize,
}

/// One acking page counted in [`Hub::pages`] while it lives.
pub struct PageCount<'a>(&'a AtomicUsize);

impl<'a> PageCount<'a> {
    /// Counts a page in `hub` until dropped.
    pub fn new(hub: &'a Hub) -> Self {
        hub.pages.fetch_add(1, Ordering::Relaxed);
        PageCount(&hub.pages)
    }
}

impl Drop for PageCount<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::Relaxed);
    }
}

impl Hub {
    /// A hub and the producer's end of the command channel.
    pub fn new() -> (Hub, mpsc::Receiver<Envelope>) {
        let (commands, rx) = mpsc::sync_channel(COMMAND_CAPACITY);
        let hub = Hub {
            frames: watch::Sender::new(Bytes::new()),
            status: watch::Sender::new(Utf8Bytes::from_static("")),
            mesh: watch::Sender::new(Utf8Bytes::from_static("")),
            commands,
            pages: AtomicUsize::new(0),
        };
        (hub, rx)
    }
}
