//! The live view: a run's channels served over the Foxglove WebSocket protocol
//! (`foxglove.websocket.v1`), the same topics, schemas and JSON messages as the log, so that the
//! Foxglove app or Lichtblick (*Open connection → Foxglove WebSocket*) shows a run as it happens with
//! the shipped layout.
//!
//! Why our own server on `tungstenite` and not the `foxglove` crate's: with only its `websocket`
//! feature the SDK adds about 50 crates to the build (tokio, prost, tracing, futures, flume,
//! parking_lot, serde_with, ...), `tungstenite` with its handshake about 13 (http, httparse, sha1,
//! bytes, ...), and the part of the protocol a simulator needs is small: `serverInfo`, `advertise`,
//! the client's `subscribe`/`unsubscribe`, binary `messageData` and `time`, and `status`.
//!
//! The server has the protocol's `time` capability: it publishes the simulated clock (the stamp of
//! each step's messages), so a client's clock, and the receive time of every message, is the time
//! the messages are stamped with rather than the wall clock.
//!
//! The simulation never waits for a client: [`LiveServer::publish`] hands each message to a bounded
//! queue per subscribed client and drops it for that client when the queue is full (a slow reader)
//! or the client is gone. Each client has its own thread that writes its queue to a non-blocking
//! socket. A client that subscribes late first gets the latest message of the channel, so that the
//! scene mesh, sent once at the start, still reaches it.

use super::record::Sink;
use super::topics::{Topic, TOPICS};
use crate::sim::RunResult;
use crate::{Error, Result};
use serde_json::{json, Value};
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Message, WebSocket};

/// Where `--live` listens when given no address: loopback only.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";
/// The WebSocket subprotocol of the Foxglove WebSocket protocol.
pub const SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// Messages queued per client; past that, new ones are dropped for it. A few seconds of a run at
/// default rates (about 20 messages per step), so a client that keeps up with real time loses none.
const QUEUE: usize = 1024;
/// How long closing waits for clients to receive what is queued for them.
const GRACE: Duration = Duration::from_secs(2);
/// How long a connecting client has to finish its WebSocket handshake.
const HANDSHAKE: Duration = Duration::from_secs(5);
/// Opcode of a binary `messageData` frame.
const MESSAGE_DATA: u8 = 0x01;
/// Opcode of a binary `time` frame (the server's clock, with the `time` capability).
const TIME: u8 = 0x02;

/// What the server delivered, for the report at the end of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LiveReport {
    /// Clients that completed the handshake.
    pub clients: usize,
    /// Messages written to clients.
    pub sent: u64,
    /// Messages dropped for a slow or disconnected client (queue full, or still queued at close).
    pub dropped: u64,
}

/// Per-client counters, kept after the client has gone.
#[derive(Default)]
struct Counters {
    queued: AtomicU64,
    sent: AtomicU64,
    dropped: AtomicU64,
}

enum Out {
    Data {
        subscription: u32,
        time_ns: u64,
        payload: Arc<[u8]>,
    },
    Text(String),
    /// The simulated clock, nanoseconds: not a message of a channel, so neither sent nor dropped
    /// messages count it.
    Time(u64),
}

struct Client {
    id: u64,
    /// (subscription id chosen by the client, channel index into [`TOPICS`]).
    subscriptions: Vec<(u32, usize)>,
    tx: SyncSender<Out>,
    counters: Arc<Counters>,
}

impl Client {
    /// Queues `out`, or counts it dropped; `false` when the client's thread has ended.
    fn offer(&self, out: Out) -> bool {
        let counted = !matches!(out, Out::Time(_));
        match self.tx.try_send(out) {
            Ok(()) => {
                if counted {
                    self.counters.queued.fetch_add(1, Ordering::Relaxed);
                }
                true
            }
            Err(TrySendError::Full(_)) => {
                // A dropped clock update is superseded by the next one.
                if counted {
                    self.counters.dropped.fetch_add(1, Ordering::Relaxed);
                }
                true
            }
            Err(TrySendError::Disconnected(_)) => false,
        }
    }
}

#[derive(Default)]
struct State {
    clients: Vec<Client>,
    /// The latest message of each channel, for clients that subscribe later.
    latest: Vec<Option<(u64, Arc<[u8]>)>>,
    /// The clock published last (the latest stamp), for clients that connect later.
    clock_ns: Option<u64>,
    /// Counters of every client served, gone or not.
    served: Vec<Arc<Counters>>,
    threads: Vec<JoinHandle<()>>,
    next_id: u64,
}

struct Shared {
    stop: AtomicBool,
    state: Mutex<State>,
    session: String,
}

impl Shared {
    fn state(&self) -> MutexGuard<'_, State> {
        // A client thread that panicked leaves consistent state behind (every update is one push
        // or assignment), so a poisoned lock is still usable.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// A Foxglove WebSocket server for one run (or one replayed log).
pub struct LiveServer {
    addr: SocketAddr,
    shared: Arc<Shared>,
    accept: Option<JoinHandle<()>>,
}

impl LiveServer {
    /// Listens on `addr` (`HOST:PORT`; port 0 picks a free one). A malformed address is a usage
    /// error; an address in use or not available here is a one-line runtime error.
    pub fn bind(addr: &str) -> Result<LiveServer> {
        let resolved = addr
            .to_socket_addrs()
            .ok()
            .and_then(|mut a| a.next())
            .ok_or_else(|| {
                Error::usage(format!(
                    "--live {addr}: not an address to listen on (HOST:PORT, e.g. {DEFAULT_ADDR})"
                ))
            })?;
        let listener = TcpListener::bind(resolved).map_err(|e| {
            Error::Runtime(match e.kind() {
                std::io::ErrorKind::AddrInUse => format!(
                    "--live {addr}: address already in use (another server listens there; choose another port with --live HOST:PORT)"
                ),
                _ => format!("--live {addr}: cannot listen there: {e}"),
            })
        })?;
        let local = listener
            .local_addr()
            .map_err(|e| Error::Runtime(format!("--live {addr}: {e}")))?;
        listener
            .set_nonblocking(true)
            .map_err(|e| Error::Runtime(format!("--live {addr}: {e}")))?;
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            state: Mutex::new(State {
                latest: vec![None; TOPICS.len()],
                ..State::default()
            }),
            session: format!(
                "tensorscout-{}-{}",
                std::process::id(),
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos())
            ),
        });
        let accept = {
            let shared = Arc::clone(&shared);
            std::thread::Builder::new()
                .name("live-accept".into())
                .spawn(move || accept_loop(listener, shared))
                .map_err(|e| Error::Runtime(format!("--live: cannot start the server: {e}")))?
        };
        Ok(LiveServer {
            addr: local,
            shared,
            accept: Some(accept),
        })
    }

    /// The address the server listens on (the port chosen when 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Whether some client has subscribed to at least one channel.
    pub fn has_subscriber(&self) -> bool {
        self.shared
            .state()
            .clients
            .iter()
            .any(|c| !c.subscriptions.is_empty())
    }

    /// Sends `payload` (a JSON message of `topic`) stamped `time_ns` to every client subscribed to
    /// its channel, never waiting: a client whose queue is full loses it.
    pub fn publish(&self, topic: &Topic, time_ns: u64, payload: &[u8]) {
        let Some(ch) = TOPICS.iter().position(|t| t.name == topic.name) else {
            return;
        };
        let payload: Arc<[u8]> = Arc::from(payload);
        let mut state = self.shared.state();
        if state.clock_ns.is_none_or(|c| time_ns > c) {
            state.clock_ns = Some(time_ns);
            state.clients.retain(|c| c.offer(Out::Time(time_ns)));
        }
        state.latest[ch] = Some((time_ns, Arc::clone(&payload)));
        state.clients.retain(|c| {
            c.subscriptions
                .iter()
                .filter(|s| s.1 == ch)
                .all(|&(subscription, _)| {
                    c.offer(Out::Data {
                        subscription,
                        time_ns,
                        payload: Arc::clone(&payload),
                    })
                })
        });
    }

    /// Sends a `status` message (0 info, 1 warning, 2 error) to every client.
    pub fn status(&self, level: u8, text: &str) {
        let msg = json!({"op": "status", "level": level, "message": text}).to_string();
        self.shared
            .state()
            .clients
            .retain(|c| c.offer(Out::Text(msg.clone())));
    }

    /// Stops accepting, lets each client receive what is queued for it (for at most a couple of
    /// seconds), closes the connections and reports what was sent and dropped.
    pub fn close(mut self) -> LiveReport {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(a) = self.accept.take() {
            let _ = a.join();
        }
        let threads = {
            let mut state = self.shared.state();
            // Dropping the senders tells each client thread to finish its queue and close.
            state.clients.clear();
            std::mem::take(&mut state.threads)
        };
        let deadline = Instant::now() + GRACE + Duration::from_millis(500);
        for t in threads {
            while !t.is_finished() && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(10));
            }
            if t.is_finished() {
                let _ = t.join();
            }
        }
        let state = self.shared.state();
        let mut report = LiveReport {
            clients: state.served.len(),
            ..LiveReport::default()
        };
        for c in &state.served {
            report.sent += c.sent.load(Ordering::Relaxed);
            report.dropped += c.dropped.load(Ordering::Relaxed) + c.queued.load(Ordering::Relaxed);
        }
        report
    }
}

impl Sink for LiveServer {
    fn put(&mut self, topic: &'static Topic, time_ns: u64, message: Vec<u8>) {
        self.publish(topic, time_ns, &message);
    }

    fn finish(&mut self, result: &RunResult) {
        self.status(
            0,
            &format!(
                "run ended: {} at t = {} s, completeness {:.3}",
                result.termination.as_str(),
                result.sim_time_s,
                result.completeness
            ),
        );
    }
}

fn accept_loop(listener: TcpListener, shared: Arc<Shared>) {
    while !shared.stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((stream, _)) => {
                let id = {
                    let mut s = shared.state();
                    s.next_id += 1;
                    s.next_id
                };
                let client_shared = Arc::clone(&shared);
                if let Ok(t) = std::thread::Builder::new()
                    .name(format!("live-client-{id}"))
                    .spawn(move || serve(stream, &client_shared, id))
                {
                    shared.state().threads.push(t);
                }
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
}

/// `serverInfo` and `advertise` (every channel: id = index in [`TOPICS`] + 1).
fn greeting(session: &str) -> [String; 2] {
    let info = json!({
        "op": "serverInfo", "name": format!("tensorscout {}", crate::VERSION),
        "capabilities": ["time"], "supportedEncodings": [], "metadata": {}, "sessionId": session
    });
    let channels: Vec<Value> = TOPICS
        .iter()
        .enumerate()
        .map(|(i, t)| {
            json!({
                "id": i + 1, "topic": t.name, "encoding": "json", "schemaName": t.schema_name,
                "schema": t.schema_json, "schemaEncoding": "jsonschema"
            })
        })
        .collect();
    let advertise = json!({"op": "advertise", "channels": channels});
    [info.to_string(), advertise.to_string()]
}

/// The handshake, answering with the Foxglove subprotocol when the client offers it.
// The callback's error type is tungstenite's (an HTTP response), not ours to shrink.
#[allow(clippy::result_large_err)]
fn handshake(stream: TcpStream) -> Option<WebSocket<TcpStream>> {
    use tungstenite::handshake::server::{Request, Response};
    use tungstenite::handshake::HandshakeError;
    stream.set_nonblocking(false).ok()?;
    stream.set_read_timeout(Some(HANDSHAKE)).ok()?;
    stream.set_write_timeout(Some(HANDSHAKE)).ok()?;
    let _ = stream.set_nodelay(true);
    let callback = |req: &Request, mut resp: Response| {
        let offered = req
            .headers()
            .get_all("Sec-WebSocket-Protocol")
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(','))
            .any(|p| p.trim() == SUBPROTOCOL);
        if offered {
            resp.headers_mut().insert(
                "Sec-WebSocket-Protocol",
                tungstenite::http::HeaderValue::from_static(SUBPROTOCOL),
            );
        }
        Ok(resp)
    };
    let config = WebSocketConfig::default().max_message_size(Some(1 << 20));
    match tungstenite::accept_hdr_with_config(stream, callback, Some(config)) {
        Ok(ws) => Some(ws),
        // The read timed out: a client that does not finish its handshake is not served.
        Err(HandshakeError::Interrupted(_)) | Err(HandshakeError::Failure(_)) => None,
    }
}

/// Whether `e` only means that the socket cannot take or give more now.
fn would_block(e: &tungstenite::Error) -> bool {
    matches!(e, tungstenite::Error::Io(io) if matches!(io.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut))
}

/// Applies a client's `subscribe` or `unsubscribe` (other operations are ignored).
fn on_client_text(text: &str, shared: &Shared, id: u64) {
    let Ok(v) = serde_json::from_str::<Value>(text) else {
        return;
    };
    let mut state = shared.state();
    let State {
        clients, latest, ..
    } = &mut *state;
    let Some(client) = clients.iter_mut().find(|c| c.id == id) else {
        return;
    };
    match v["op"].as_str() {
        Some("subscribe") => {
            for s in v["subscriptions"].as_array().into_iter().flatten() {
                let (Some(sub), Some(ch)) = (s["id"].as_u64(), s["channelId"].as_u64()) else {
                    continue;
                };
                let Some(ch) = (ch as usize).checked_sub(1).filter(|&c| c < TOPICS.len()) else {
                    continue;
                };
                let Ok(sub) = u32::try_from(sub) else {
                    continue;
                };
                client.subscriptions.retain(|&(s, _)| s != sub);
                client.subscriptions.push((sub, ch));
                if let Some((time_ns, payload)) = &latest[ch] {
                    client.offer(Out::Data {
                        subscription: sub,
                        time_ns: *time_ns,
                        payload: Arc::clone(payload),
                    });
                }
            }
        }
        Some("unsubscribe") => {
            let ids: Vec<u64> = v["subscriptionIds"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(Value::as_u64)
                .collect();
            client
                .subscriptions
                .retain(|&(s, _)| !ids.contains(&u64::from(s)));
        }
        _ => {}
    }
}

/// One client's connection: greeting, then its subscriptions in and its queue out, until it
/// leaves or the server closes.
fn serve(stream: TcpStream, shared: &Shared, id: u64) {
    let Some(mut ws) = handshake(stream) else {
        return;
    };
    for text in greeting(&shared.session) {
        if ws.send(Message::text(text)).is_err() {
            return;
        }
    }
    if ws.get_ref().set_nonblocking(true).is_err() {
        return;
    }
    let (tx, rx) = sync_channel(QUEUE);
    let counters = Arc::new(Counters::default());
    {
        let mut state = shared.state();
        if shared.stop.load(Ordering::SeqCst) {
            return;
        }
        state.served.push(Arc::clone(&counters));
        let client = Client {
            id,
            subscriptions: Vec::new(),
            tx,
            counters: Arc::clone(&counters),
        };
        if let Some(clock) = state.clock_ns {
            client.offer(Out::Time(clock));
        }
        state.clients.push(client);
    }
    pump(&mut ws, &rx, shared, id, &counters);
    shared.state().clients.retain(|c| c.id != id);
}

/// The client's loop; returns when the client left or the server closed (after the grace time).
fn pump(
    ws: &mut WebSocket<TcpStream>,
    rx: &Receiver<Out>,
    shared: &Shared,
    id: u64,
    counters: &Counters,
) {
    // Set while the socket takes no more: nothing more is taken off the queue until it drains.
    let mut blocked = false;
    let mut closing_since: Option<Instant> = None;
    loop {
        if shared.stop.load(Ordering::SeqCst) {
            closing_since.get_or_insert_with(Instant::now);
        }
        loop {
            match ws.read() {
                Ok(Message::Text(t)) => on_client_text(t.as_str(), shared, id),
                Ok(_) => {}
                Err(e) if would_block(&e) => break,
                Err(_) => return,
            }
        }
        if closing_since.is_some_and(|t| t.elapsed() > GRACE) {
            return;
        }
        if blocked {
            match ws.flush() {
                Ok(()) => blocked = false,
                Err(e) if would_block(&e) => {
                    std::thread::sleep(Duration::from_millis(5));
                    continue;
                }
                Err(_) => return,
            }
        }
        let first = match rx.recv_timeout(Duration::from_millis(10)) {
            Ok(out) => out,
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => {
                // The server closes: everything queued has been written; say goodbye.
                let _ = ws.close(None);
                let deadline = Instant::now() + GRACE;
                while Instant::now() < deadline {
                    match ws.flush() {
                        Err(e) if would_block(&e) => std::thread::sleep(Duration::from_millis(5)),
                        _ => return,
                    }
                }
                return;
            }
        };
        let mut next = Some(first);
        let mut batch = 0;
        while let Some(out) = next {
            // Only channel messages count as sent or dropped.
            let data = matches!(out, Out::Data { .. });
            let msg = match out {
                Out::Data {
                    subscription,
                    time_ns,
                    payload,
                } => {
                    let mut frame = Vec::with_capacity(13 + payload.len());
                    frame.push(MESSAGE_DATA);
                    frame.extend_from_slice(&subscription.to_le_bytes());
                    frame.extend_from_slice(&time_ns.to_le_bytes());
                    frame.extend_from_slice(&payload);
                    counters.queued.fetch_sub(1, Ordering::Relaxed);
                    Message::binary(frame)
                }
                Out::Text(t) => {
                    counters.queued.fetch_sub(1, Ordering::Relaxed);
                    Message::text(t)
                }
                Out::Time(ns) => {
                    let mut frame = Vec::with_capacity(9);
                    frame.push(TIME);
                    frame.extend_from_slice(&ns.to_le_bytes());
                    Message::binary(frame)
                }
            };
            match ws.write(msg) {
                Ok(()) => {}
                // Kept in the write buffer, to go out once the socket drains.
                Err(e) if would_block(&e) => blocked = true,
                Err(_) => {
                    if data {
                        counters.dropped.fetch_add(1, Ordering::Relaxed);
                    }
                    return;
                }
            }
            if data {
                counters.sent.fetch_add(1, Ordering::Relaxed);
            }
            batch += 1;
            next = if blocked || batch >= 64 {
                None
            } else {
                rx.try_recv().ok()
            };
        }
        match ws.flush() {
            Ok(()) => {}
            Err(e) if would_block(&e) => blocked = true,
            Err(_) => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn greeting_advertises_every_topic_with_its_schema() {
        let [info, advertise] = greeting("s");
        let info: Value = serde_json::from_str(&info).unwrap();
        assert_eq!(info["op"], "serverInfo");
        assert_eq!(info["sessionId"], "s");
        let adv: Value = serde_json::from_str(&advertise).unwrap();
        let channels = adv["channels"].as_array().unwrap();
        assert_eq!(channels.len(), TOPICS.len());
        for (c, t) in channels.iter().zip(TOPICS) {
            assert_eq!(c["topic"], t.name);
            assert_eq!(c["schemaName"], t.schema_name);
            assert_eq!(c["schema"], t.schema_json);
            assert_eq!(c["encoding"], "json");
        }
    }

    #[test]
    fn a_malformed_address_is_a_usage_error_and_a_taken_port_a_runtime_error() {
        let e = LiveServer::bind("no port").err().unwrap();
        assert_eq!(e.exit_code(), 2, "{e}");
        let first = LiveServer::bind("127.0.0.1:0").unwrap();
        let taken = first.local_addr().to_string();
        let e = LiveServer::bind(&taken).err().unwrap();
        assert_eq!(e.exit_code(), 1);
        assert!(e.to_string().contains("already in use"), "{e}");
        assert!(!e.to_string().contains('\n'));
        assert_eq!(first.close(), LiveReport::default());
    }
}
