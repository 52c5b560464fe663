//! The command side's wire (see [`super::command`]): the services it serves and their
//! names and types, its Zenoh declarations (a queryable and an `SS` token per service, a
//! namespace-wide queryable answering unknown services, the feedback and status publishers
//! with `MP` tokens), the hand-over from Zenoh's callbacks to the command thread, and replies
//! with rmw_zenoh's attachment.

use std::sync::mpsc::{SyncSender, TrySendError};
use std::time::Instant;

use gelgrip_ros_wire::actions;
use gelgrip_ros_wire::names::{
    NodeIdentity, Qos, Reliability, attachment, data_key, gid, parse_attachment, qualify,
};
use gelgrip_ros_wire::services;
use zenoh::Wait;
use zenoh::query::Query;

use super::command_goals::FingerNow;
use super::live::LiveError;

/// Entity ids of the command side's tokens start here (the topics' publishers count from 1).
const FIRST_ENTITY_ID: u32 = 100;

/// A service the command side serves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Service {
    SendGoal,
    CancelGoal,
    GetResult,
    Release,
    Stop,
    Estop,
    /// A query under the namespace that names no service here.
    Unknown,
}

impl Service {
    pub(super) const ALL: [Self; 6] = [
        Self::SendGoal,
        Self::CancelGoal,
        Self::GetResult,
        Self::Release,
        Self::Stop,
        Self::Estop,
    ];

    pub(super) fn relative(self) -> &'static str {
        match self {
            Self::SendGoal => "gripper_cmd/_action/send_goal",
            Self::CancelGoal => "gripper_cmd/_action/cancel_goal",
            Self::GetResult => "gripper_cmd/_action/get_result",
            Self::Release => "release",
            Self::Stop => "stop",
            Self::Estop => "estop",
            Self::Unknown => "?",
        }
    }

    pub(super) fn ty(self) -> &'static gelgrip_ros_wire::MsgType {
        match self {
            Self::SendGoal => &actions::SEND_GOAL,
            Self::CancelGoal => &actions::CANCEL_GOAL,
            Self::GetResult => &actions::GET_RESULT,
            _ => &services::TRIGGER,
        }
    }
}

/// The fingers as one pass of the loop left them.
#[derive(Debug)]
pub(super) struct Snapshot {
    pub(super) at: Instant,
    pub(super) fingers: Vec<FingerNow>,
}

pub(super) enum Event {
    /// A request, and when its callback ran.
    Query(Service, Query, Instant),
    Report(Snapshot),
    /// The run has ended (the queryables' callbacks hold senders too, so the channel
    /// never closes by itself).
    Stop,
}

pub(super) fn unix_now_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// The command side's Zenoh entities, alive while it serves.
pub(super) struct Declared {
    _tokens: Vec<zenoh::liveliness::LivelinessToken>,
    _queryables: Vec<zenoh::query::Queryable<()>>,
    /// The services' keys (a query on one of them is that service's, not an unknown one).
    pub(super) keys: Vec<zenoh::key_expr::KeyExpr<'static>>,
    feedback: (zenoh::pubsub::Publisher<'static>, [u8; 16]),
    status: (zenoh::pubsub::Publisher<'static>, [u8; 16]),
    sequence: i64,
}

impl Declared {
    pub(super) fn new(
        session: &zenoh::Session,
        node: &NodeIdentity,
        tx: &SyncSender<Event>,
    ) -> Result<Self, LiveError> {
        let z = |what: &str, e: zenoh::Error| LiveError::Zenoh(format!("{what}: {e}"));
        let mut tokens = Vec::new();
        let mut queryables = Vec::new();
        let mut keys = Vec::new();
        let mut entity = FIRST_ENTITY_ID;
        for service in Service::ALL {
            let name = qualify(&node.namespace, service.relative());
            let token = node.service_token(entity, &name, service.ty());
            entity += 1;
            tokens.push(
                session
                    .liveliness()
                    .declare_token(token.clone())
                    .wait()
                    .map_err(|e| z(&token, e))?,
            );
            let key = data_key(node.domain, &name, service.ty());
            keys.push(zenoh::key_expr::KeyExpr::try_from(key.clone()).map_err(|e| z(&key, e))?);
            let tx = tx.clone();
            queryables.push(
                session
                    .declare_queryable(key.clone())
                    .complete(true)
                    .callback(move |q| hand_over(&tx, service, q))
                    .wait()
                    .map_err(|e| z(&key, e))?,
            );
        }
        // Queries for any other key under the namespace: answered with an error (not
        // complete, so a query for a real service goes to that service).
        let ns_key =
            format!("{}/{}/**", node.domain, node.namespace.trim_matches('/')).replace("//", "/");
        let tx = tx.clone();
        queryables.push(
            session
                .declare_queryable(ns_key.clone())
                .complete(false)
                .callback(move |q| hand_over(&tx, Service::Unknown, q))
                .wait()
                .map_err(|e| z(&ns_key, e))?,
        );
        let mut publisher = |relative: &str, ty: &'static gelgrip_ros_wire::MsgType, depth: u32| {
            let name = qualify(&node.namespace, relative);
            let qos = Qos {
                reliability: Reliability::Reliable,
                depth,
            };
            let token = node.publisher_token(entity, &name, ty, qos);
            entity += 1;
            let g = gid(&token);
            let t = session
                .liveliness()
                .declare_token(token.clone())
                .wait()
                .map_err(|e| z(&token, e))?;
            let key = data_key(node.domain, &name, ty);
            let p = session
                .declare_publisher(key.clone())
                .wait()
                .map_err(|e| z(&key, e))?;
            Ok::<_, LiveError>((t, (p, g)))
        };
        let (t1, feedback) = publisher(
            "gripper_cmd/_action/feedback",
            &actions::FEEDBACK_MESSAGE,
            10,
        )?;
        let (t2, status) = publisher("gripper_cmd/_action/status", &actions::GOAL_STATUS_ARRAY, 1)?;
        tokens.push(t1);
        tokens.push(t2);
        Ok(Self {
            _tokens: tokens,
            _queryables: queryables,
            keys,
            feedback,
            status,
            sequence: 0,
        })
    }

    pub(super) fn publish(&mut self, feedback: bool, cdr: Vec<u8>) {
        self.sequence += 1;
        let (p, g) = if feedback {
            &self.feedback
        } else {
            &self.status
        };
        let att = attachment(self.sequence, unix_now_ns(), g);
        if let Err(e) = p.put(cdr).attachment(att.to_vec()).wait() {
            tracing::debug!("ROS 2: put: {e}");
        }
    }
}

/// A queryable's callback: hand the query to the command thread, never waiting.
fn hand_over(tx: &SyncSender<Event>, service: Service, q: Query) {
    if service == Service::Unknown && q.attachment().is_none() {
        // Not a ROS request (a Zenoh tool's query, a history query under the namespace):
        // dropped here, so such queries never take the queue's room from real requests.
        return;
    }
    match tx.try_send(Event::Query(service, q, Instant::now())) {
        Ok(()) => {}
        Err(TrySendError::Full(Event::Query(_, q, _))) => {
            tracing::warn!(
                "ROS 2: {}: too many requests at once; refused",
                q.key_expr()
            );
            let _ = q.reply_err("gelgrip: too many requests at once").wait();
        }
        Err(_) => {}
    }
}

/// A request's payload and attachment (sequence number, client GID).
pub(super) fn request_parts(q: &Query) -> (Vec<u8>, Option<(i64, [u8; 16])>) {
    let payload = q.payload().map(|p| p.to_bytes().into_owned());
    let att = q.attachment().and_then(|a| parse_attachment(&a.to_bytes()));
    (payload.unwrap_or_default(), att)
}

pub(super) fn reply(q: &Query, seq: i64, client: &[u8; 16], cdr: Vec<u8>) {
    let att = attachment(seq, unix_now_ns(), client);
    if let Err(e) = q
        .reply(q.key_expr().clone(), cdr)
        .attachment(att.to_vec())
        .wait()
    {
        tracing::debug!("ROS 2: reply on {}: {e}", q.key_expr());
    }
}
