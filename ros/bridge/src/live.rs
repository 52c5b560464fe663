//! The live link to ROS 2: one Zenoh session on its own thread, speaking rmw_zenoh's format.
//! It declares the node's and each publisher's liveliness tokens, publishes each sample on
//! `<domain>/<topic>/<DDS type>/RIHS01_<hash>` with the attachment (sequence number, source
//! timestamp, GID), and watches the router: when none is reachable it says so once, and
//! Zenoh reconnects in the background (tokens and publishers are re-announced by Zenoh when
//! the link comes back).
//!
//! The run's loop only ever calls [`LiveLink::offer`], which never waits: a bounded queue
//! feeds the thread; a best-effort sample is dropped when more than a few of them wait, and
//! a reliable one only when the whole queue is full (both counted).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use gelgrip_ros_wire::names::{NodeIdentity, Qos, Reliability, attachment, data_key, gid};
use thiserror::Error;
use zenoh::Wait;
use zenoh::qos::CongestionControl;

use super::config::RosConfig;
use super::feed::{Sample, Topic};

/// The queue between the loop and the publisher thread, samples.
const QUEUE_SAMPLES: usize = 256;
/// Best-effort samples (images, depth) that may wait at once; more are dropped.
const BEST_EFFORT_IN_FLIGHT: usize = 16;
/// Keep-last depth announced for reliable topics (rmw's default) and best-effort ones
/// (sensor data's).
const RELIABLE_DEPTH: u32 = 10;
const BEST_EFFORT_DEPTH: u32 = 5;
/// How long without a router before it is reported missing.
const ROUTER_GRACE: Duration = Duration::from_secs(2);

/// Why the link could not start.
#[derive(Debug, Error)]
pub enum LiveError {
    /// Zenoh refused the configuration or the session.
    #[error("ROS 2 over Zenoh: {0}")]
    Zenoh(String),
    /// The thread could not be spawned.
    #[error("ROS 2 over Zenoh: starting the publisher thread: {0}")]
    Thread(#[from] std::io::Error),
}

/// Counters of the link.
#[derive(Debug, Default)]
pub struct LinkCounters {
    /// Samples put on the network.
    pub published: AtomicU64,
    /// Best-effort samples dropped because the publisher was behind.
    pub dropped_best_effort: AtomicU64,
    /// Reliable samples dropped because the queue was full.
    pub dropped_reliable: AtomicU64,
}

/// The loop's end of the link.
pub struct LiveLink {
    tx: Option<SyncSender<Sample>>,
    best_effort: Vec<bool>,
    in_flight: Arc<AtomicUsize>,
    counters: Arc<LinkCounters>,
    warned_full: AtomicBool,
    thread: Option<JoinHandle<()>>,
    /// The session's id (the `<session id>` of the liveliness tokens).
    pub session_id: String,
    /// The session, and the node it is (for the command side to declare on).
    session: zenoh::Session,
    node: NodeIdentity,
}

impl std::fmt::Debug for LiveLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveLink")
            .field("session_id", &self.session_id)
            .finish_non_exhaustive()
    }
}

/// The Zenoh configuration of `config`: its mode and endpoints, multicast scouting off (as
/// rmw_zenoh), connecting in the background forever, listening on loopback only as a peer.
fn zenoh_config(config: &RosConfig) -> Result<zenoh::Config, LiveError> {
    let z = |e: Box<dyn std::error::Error + Send + Sync>| LiveError::Zenoh(e.to_string());
    let mut c = zenoh::Config::default();
    let endpoints = serde_json_list(&config.connect);
    c.insert_json5("mode", &format!("\"{}\"", config.mode.as_str()))
        .map_err(z)?;
    c.insert_json5("connect/endpoints", &endpoints).map_err(z)?;
    c.insert_json5("connect/timeout_ms", "-1").map_err(z)?;
    c.insert_json5("connect/exit_on_failure", "false")
        .map_err(z)?;
    c.insert_json5("scouting/multicast/enabled", "false")
        .map_err(z)?;
    if config.mode == super::config::ZenohMode::Peer {
        c.insert_json5("listen/endpoints", "[\"tcp/127.0.0.1:0\"]")
            .map_err(z)?;
    }
    Ok(c)
}

fn serde_json_list(items: &[String]) -> String {
    let quoted: Vec<String> = items
        .iter()
        .map(|s| format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\"")))
        .collect();
    format!("[{}]", quoted.join(","))
}

impl LiveLink {
    /// Open the session and start publishing `topics` as node `gelgrip` in the configured
    /// namespace. Returns once the session is open (the router may still be down).
    pub fn start(config: &RosConfig, topics: Vec<Topic>) -> Result<Self, LiveError> {
        let zc = zenoh_config(config)?;
        let session = zenoh::open(zc)
            .wait()
            .map_err(|e| LiveError::Zenoh(e.to_string()))?;
        let session_id = session.zid().to_string();
        let node = NodeIdentity {
            domain: config.domain_id,
            session_id: session_id.clone(),
            namespace: config.namespace.clone(),
            name: "gelgrip".into(),
        };
        let best_effort: Vec<bool> = topics
            .iter()
            .map(|t| t.reliability == Reliability::BestEffort)
            .collect();
        let (tx, rx) = sync_channel(QUEUE_SAMPLES);
        let in_flight = Arc::new(AtomicUsize::new(0));
        let counters = Arc::new(LinkCounters::default());
        let worker = Worker {
            session: session.clone(),
            node: node.clone(),
            topics,
            rx,
            in_flight: in_flight.clone(),
            counters: counters.clone(),
            router: config.connect.join(", "),
        };
        let thread = std::thread::Builder::new()
            .name("ros-publisher".into())
            .spawn(move || worker.run())?;
        Ok(Self {
            tx: Some(tx),
            best_effort,
            in_flight,
            counters,
            warned_full: AtomicBool::new(false),
            thread: Some(thread),
            session_id,
            session,
            node,
        })
    }

    /// The Zenoh session and the node (the command side declares on them).
    pub fn session(&self) -> (&zenoh::Session, &NodeIdentity) {
        (&self.session, &self.node)
    }

    /// Hand `sample` to the publisher thread without waiting; dropped (and counted) when the
    /// thread is behind.
    pub fn offer(&self, sample: Sample) {
        let Some(tx) = &self.tx else { return };
        let best_effort = self.best_effort.get(sample.topic).copied().unwrap_or(true);
        if best_effort {
            if self.in_flight.load(Ordering::Relaxed) >= BEST_EFFORT_IN_FLIGHT {
                self.counters
                    .dropped_best_effort
                    .fetch_add(1, Ordering::Relaxed);
                return;
            }
            self.in_flight.fetch_add(1, Ordering::Relaxed);
        }
        match tx.try_send(sample) {
            Ok(()) => {}
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                if best_effort {
                    self.in_flight.fetch_sub(1, Ordering::Relaxed);
                    self.counters
                        .dropped_best_effort
                        .fetch_add(1, Ordering::Relaxed);
                } else {
                    self.counters
                        .dropped_reliable
                        .fetch_add(1, Ordering::Relaxed);
                    if !self.warned_full.swap(true, Ordering::Relaxed) {
                        tracing::warn!(
                            "ROS 2: the publisher is behind; reliable samples are being \
                             dropped (counted in the run's report)"
                        );
                    }
                }
            }
        }
    }

    /// The counters.
    pub fn counters(&self) -> &LinkCounters {
        &self.counters
    }

    /// Stop: publish what is queued, withdraw the tokens, close the session.
    pub fn finish(&mut self) {
        self.tx = None;
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("ROS 2: the publisher thread panicked");
        }
    }
}

impl Drop for LiveLink {
    fn drop(&mut self) {
        self.finish();
    }
}

/// The liveliness tokens (kept alive while publishing) and each topic's publisher and GID.
type Declared = (
    Vec<zenoh::liveliness::LivelinessToken>,
    Vec<(zenoh::pubsub::Publisher<'static>, [u8; 16])>,
);

struct Worker {
    session: zenoh::Session,
    node: NodeIdentity,
    topics: Vec<Topic>,
    rx: Receiver<Sample>,
    in_flight: Arc<AtomicUsize>,
    counters: Arc<LinkCounters>,
    router: String,
}

impl Worker {
    fn run(self) {
        let declared = match self.declare() {
            Ok(d) => d,
            Err(e) => {
                tracing::error!("ROS 2: {e}; not publishing");
                // Keep draining, so the loop's queue never fills.
                while self.rx.recv().is_ok() {}
                return;
            }
        };
        let (_tokens, publishers) = declared;
        let mut sequence = vec![0i64; self.topics.len()];
        let started = Instant::now();
        let mut last_check = Instant::now();
        let mut router_up: Option<bool> = None;
        loop {
            match self.rx.recv_timeout(Duration::from_millis(250)) {
                Ok(sample) => {
                    if self
                        .topics
                        .get(sample.topic)
                        .is_some_and(|t| t.reliability == Reliability::BestEffort)
                    {
                        self.in_flight.fetch_sub(1, Ordering::Relaxed);
                    }
                    let Some((publisher, gid)) = publishers.get(sample.topic) else {
                        continue;
                    };
                    let seq = &mut sequence[sample.topic];
                    *seq += 1;
                    let ts = i64::try_from(sample.stamp.unix_ns()).unwrap_or(i64::MAX);
                    let att = attachment(*seq, ts, gid);
                    match publisher.put(sample.cdr).attachment(att.to_vec()).wait() {
                        Ok(()) => {
                            self.counters.published.fetch_add(1, Ordering::Relaxed);
                        }
                        Err(e) => tracing::debug!("ROS 2: put: {e}"),
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if last_check.elapsed() >= Duration::from_millis(500) {
                last_check = Instant::now();
                let up = self.session.info().routers_zid().wait().next().is_some();
                match (router_up, up) {
                    (Some(false) | None, true) => {
                        if router_up == Some(false) {
                            tracing::warn!(
                                "ROS 2: connected to the router again ({})",
                                self.router
                            );
                        } else {
                            tracing::info!("ROS 2: connected to the router ({})", self.router);
                        }
                        router_up = Some(true);
                    }
                    (Some(true), false) => {
                        tracing::warn!(
                            "ROS 2: lost the router ({}); the run goes on and Zenoh reconnects",
                            self.router
                        );
                        router_up = Some(false);
                    }
                    (None, false) if started.elapsed() >= ROUTER_GRACE => {
                        tracing::warn!(
                            "ROS 2: no router at {}; the run goes on and Zenoh keeps trying",
                            self.router
                        );
                        router_up = Some(false);
                    }
                    _ => {}
                }
            }
        }
        drop(publishers);
        drop(_tokens);
        if let Err(e) = self.session.close().wait() {
            tracing::debug!("ROS 2: closing the session: {e}");
        }
    }

    /// Declare the node's token, then each topic's token and publisher.
    fn declare(&self) -> Result<Declared, String> {
        let mut tokens = Vec::with_capacity(self.topics.len() + 1);
        let token = |key: String| {
            self.session
                .liveliness()
                .declare_token(key.clone())
                .wait()
                .map_err(|e| format!("liveliness token {key}: {e}"))
        };
        tokens.push(token(self.node.node_token())?);
        let mut publishers = Vec::with_capacity(self.topics.len());
        for (i, t) in self.topics.iter().enumerate() {
            let (depth, congestion) = match t.reliability {
                Reliability::Reliable => (RELIABLE_DEPTH, CongestionControl::Block),
                Reliability::BestEffort => (BEST_EFFORT_DEPTH, CongestionControl::Drop),
            };
            let qos = Qos {
                reliability: t.reliability,
                depth,
            };
            let entity = u32::try_from(i + 1).unwrap_or(u32::MAX);
            let key = self.node.publisher_token(entity, &t.name, t.ty, qos);
            let g = gid(&key);
            tokens.push(token(key)?);
            let data = data_key(self.node.domain, &t.name, t.ty);
            let publisher = self
                .session
                .declare_publisher(data.clone())
                .congestion_control(congestion)
                .wait()
                .map_err(|e| format!("publisher {data}: {e}"))?;
            publishers.push((publisher, g));
        }
        Ok((tokens, publishers))
    }
}
