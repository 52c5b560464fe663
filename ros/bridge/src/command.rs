//! Commanding gelgrip from ROS 2 (`[ros] commands = true`): the
//! `control_msgs/action/GripperCommand` action at `<ns>/gripper_cmd` and the
//! `std_srvs/srv/Trigger` services `<ns>/release`, `<ns>/stop` and `<ns>/estop`, on the
//! publisher's Zenoh session in rmw_zenoh's format: a queryable per service on
//! `<domain>/<service>/<DDS type>/RIHS01_<hash>` with a service-server (`SS`) liveliness
//! token, replies carrying the request's sequence number and the client's GID; the action's
//! `feedback` and `status` topics as publishers with `MP` tokens.
//!
//! Everything goes through the grasp API the dashboard uses ([`GripperHandle`] and a
//! [`GraspGoals`] store): a goal is a grasp, a new goal preempts the running one (which
//! ends aborted, reason `preempted`), a cancel is a stop (the fingers hold), and what the
//! API refuses (a task driving, the run ending, a force beyond the hand) rejects the goal
//! or answers `success: false`, with the reason in the log and the service's message.
//!
//! One thread owns the state: the queryables' callbacks and the run's observer only hand it
//! events through a bounded queue, so neither the network nor the loop waits on the other.
//! Bad input (bytes that do not decode, NaN or out-of-range numbers, unknown goal ids, a
//! service that does not exist) gets a rejection or an error reply and one log line.

use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use gelgrip_controller::grasp::{GraspRequest, Phase, TargetForce};
use gelgrip_controller::grasp_goals::{GoalState, GraspGoals};
use gelgrip_controller::gripper::GripperHandle;
use gelgrip_controller::runtime::ports::{Observer, ObserverError};
use gelgrip_controller::runtime::report::SetReport;
use gelgrip_ros_wire::Message;
use gelgrip_ros_wire::actions::{
    self, CancelGoalResponse, FeedbackMessage, GetResultResponse, GoalInfo, GoalStatusArray,
    GoalStatusCode, GripperState, SendGoalResponse,
};
use gelgrip_ros_wire::msgs::Time;
use gelgrip_ros_wire::names::{NodeIdentity, qualify};
use gelgrip_ros_wire::services::{self, TriggerResponse};
use zenoh::Wait;
use zenoh::query::Query;

use super::command_goals::{
    CLOSE_POSITION_RAD, Ending, FingerNow, GoalRequest, cancel_targets, check_goal, finish,
    in_contact, state_now,
};
use super::command_wire::{Declared, Event, Service, Snapshot, reply, request_parts, unix_now_ns};
use super::live::LiveError;

/// Events waiting for the command thread at most.
const QUEUE_EVENTS: usize = 256;
/// Goals kept for `get_result` and the status topic.
const GOALS_KEPT: usize = 32;
/// An ended goal's result is kept this long (rcl_action's default `result_timeout`), then
/// forgotten: a long run's status topic does not carry its old goals forever.
const RESULT_TIMEOUT: Duration = Duration::from_secs(15 * 60);
/// `get_result` requests waiting on one goal at most; more get an error reply.
const WAITING_PER_GOAL: usize = 8;
/// Feedback at most this often.
const FEEDBACK_PERIOD: Duration = Duration::from_millis(100);
/// The status topic is published again this often while goals are kept (for late joiners).
const STATUS_PERIOD: Duration = Duration::from_secs(1);
/// A goal's approach speed and timeout (the dashboard's defaults).
const SPEED_DEG_S: f64 = 15.0;
const TIMEOUT_S: f64 = 20.0;

/// The run's command side: an observer feeding the command thread.
pub struct RosCommands {
    tx: Option<SyncSender<Event>>,
    thread: Option<JoinHandle<()>>,
    range_deg: Vec<f64>,
}

impl std::fmt::Debug for RosCommands {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RosCommands").finish_non_exhaustive()
    }
}

/// What the command side needs of the run.
#[derive(Debug, Clone)]
pub struct CommandSetup {
    /// The grasp API (`None`: this run has none, and every command is refused saying so).
    pub gripper: Option<GripperHandle>,
    /// The configured current limit, mA (each goal's cap).
    pub current_limit_ma: f64,
    /// Each finger's servo travel from open to closed, degrees.
    pub range_deg: Vec<f64>,
}

fn now_stamp() -> Time {
    let ns = u64::try_from(unix_now_ns()).unwrap_or(0);
    Time::from_unix_us(ns / 1000)
}

/// A goal id as the log shows it (its first 4 bytes, hex).
fn short(id: &[u8; 16]) -> String {
    id[..4].iter().map(|b| format!("{b:02x}")).collect()
}

impl RosCommands {
    /// The command side of a `gelgrip run` publishing through `publisher`: when
    /// `[ros] commands = true` (`None` otherwise: nothing is declared).
    pub fn for_run(
        config: &gelgrip_controller::config::AppConfig,
        publisher: &crate::publisher::RosPublisher,
        gripper: Option<GripperHandle>,
    ) -> Result<Option<Self>, crate::BridgeError> {
        let ros = super::config::RosConfig::from_section(&config.ros)
            .map_err(crate::BridgeError::Config)?;
        if !ros.commands {
            return Ok(None);
        }
        if gripper.is_none() {
            tracing::warn!(
                "ROS 2: [ros] commands = true, but this run has no grasp API (no finger \
                 servos, a task of its own, or sensors without models): every goal and \
                 service call is refused"
            );
        }
        let setup = CommandSetup {
            gripper,
            current_limit_ma: config.servos.current_limit_ma,
            range_deg: config
                .layout
                .fingers
                .iter()
                .map(|f| f.servo_range_deg)
                .collect(),
        };
        let (session, node) = publisher.link().session();
        Ok(Some(Self::start(session, node, setup)?))
    }

    /// Declare the action and the services on `session` as `node`, and start the thread.
    pub fn start(
        session: &zenoh::Session,
        node: &NodeIdentity,
        setup: CommandSetup,
    ) -> Result<Self, LiveError> {
        let (tx, rx) = sync_channel(QUEUE_EVENTS);
        let declared = Declared::new(session, node, &tx)?;
        let range_deg = setup.range_deg.clone();
        let worker = Worker {
            rx,
            declared,
            goals: Vec::new(),
            store: GraspGoals::new(),
            setup,
            fingers: Vec::new(),
            last_feedback: None,
            last_status: Instant::now(),
        };
        let thread = std::thread::Builder::new()
            .name("ros-commands".into())
            .spawn(move || worker.run())?;
        tracing::info!(
            action = qualify(&node.namespace, "gripper_cmd"),
            "ROS 2: serving the GripperCommand action and the release, stop and estop services"
        );
        Ok(Self {
            tx: Some(tx),
            thread: Some(thread),
            range_deg,
        })
    }
}

impl Observer for RosCommands {
    /// Never waits: a report is dropped when the command thread is behind.
    fn observe(&mut self, report: &SetReport<'_>) -> Result<(), ObserverError> {
        let (Some(tx), Some(g)) = (&self.tx, &report.gripper) else {
            return Ok(());
        };
        let fingers = g
            .fingers
            .iter()
            .zip(report.servos.map_or(&[][..], |s| s.states))
            .zip(&self.range_deg)
            .map(|((f, s), range)| FingerNow {
                phase: f.phase,
                force_n: f.force_n,
                target_force_n: f.target_force_n,
                opening_rad: (range - s.position_deg).max(0.0).to_radians(),
            })
            .collect();
        let snapshot = Snapshot {
            at: Instant::now(),
            fingers,
        };
        let _ = tx.try_send(Event::Report(snapshot));
        Ok(())
    }

    fn finish(&mut self) -> Result<(), ObserverError> {
        if let Some(tx) = self.tx.take() {
            let _ = tx.send(Event::Stop);
        }
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("ROS 2: the command thread panicked");
        }
        Ok(())
    }
}

impl Drop for RosCommands {
    fn drop(&mut self) {
        let _ = Observer::finish(self);
    }
}

/// One goal of the action.
struct ActionGoal {
    info: GoalInfo,
    grasp_id: u64,
    request: GoalRequest,
    status: GoalStatusCode,
    result: GripperState,
    ending: Ending,
    /// `get_result` requests waiting for the end: the query, its sequence number and the
    /// client's GID.
    waiting: Vec<(Query, i64, [u8; 16])>,
    arrived: Instant,
    write_seen: bool,
    /// When it ended (its result is forgotten [`RESULT_TIMEOUT`] later).
    ended: Option<Instant>,
}

struct Worker {
    rx: Receiver<Event>,
    declared: Declared,
    goals: Vec<ActionGoal>,
    store: GraspGoals,
    setup: CommandSetup,
    fingers: Vec<FingerNow>,
    last_feedback: Option<Instant>,
    last_status: Instant,
}

impl Worker {
    fn run(mut self) {
        loop {
            match self.rx.recv_timeout(STATUS_PERIOD) {
                Ok(Event::Query(service, q, arrived)) => self.query(service, q, arrived),
                Ok(Event::Report(s)) => self.report(s),
                Ok(Event::Stop) | Err(RecvTimeoutError::Disconnected) => break,
                Err(RecvTimeoutError::Timeout) => {}
            }
            let kept = self.goals.len();
            self.goals
                .retain(|g| g.ended.is_none_or(|t| t.elapsed() < RESULT_TIMEOUT));
            if self.goals.len() < kept
                || (!self.goals.is_empty() && self.last_status.elapsed() >= STATUS_PERIOD)
            {
                self.publish_status();
            }
        }
        // The run has ended: goals still open end aborted.
        for i in 0..self.goals.len() {
            if !self.goals[i].status.is_terminal() {
                self.end(i, GoalStatusCode::Aborted, "the run ended".into());
            }
        }
    }

    fn query(&mut self, service: Service, q: Query, arrived: Instant) {
        if service == Service::Unknown
            && self
                .declared
                .keys
                .iter()
                .any(|k| k.intersects(q.key_expr()))
        {
            // A service's own query, seen by the namespace's queryable too.
            return;
        }
        let (payload, att) = request_parts(&q);
        // (Queries under the namespace without an attachment, not ROS requests, never get
        // here: `command_wire::hand_over` drops them.)
        let Some((seq, client)) = att else {
            tracing::warn!(
                "ROS 2: {}: a request without rmw_zenoh's attachment; refused",
                q.key_expr()
            );
            let _ = q
                .reply_err("gelgrip: requests carry rmw_zenoh's 33-byte attachment")
                .wait();
            return;
        };
        match service {
            Service::Unknown => {
                tracing::warn!("ROS 2: a request for {}: no such service", q.key_expr());
                let _ = q
                    .reply_err(format!("gelgrip: no service at {}", q.key_expr()))
                    .wait();
            }
            Service::SendGoal => {
                let response = self.send_goal(&payload, arrived);
                reply(&q, seq, &client, response.to_cdr());
            }
            Service::CancelGoal => {
                let response = self.cancel_goal(&payload);
                reply(&q, seq, &client, response.to_cdr());
            }
            Service::GetResult => self.get_result(&payload, q, seq, client),
            Service::Release | Service::Stop | Service::Estop => {
                let response = self.trigger(service, &payload);
                reply(&q, seq, &client, response.to_cdr());
            }
        }
    }

    fn max_opening_rad(&self) -> f64 {
        self.setup
            .range_deg
            .iter()
            .fold(0.0f64, |m, r| m.max(*r))
            .to_radians()
    }

    fn send_goal(&mut self, payload: &[u8], arrived: Instant) -> SendGoalResponse {
        let stamp = now_stamp();
        let refuse = |id: &str, why: String| {
            tracing::warn!("ROS 2: goal {id} rejected: {why}");
            SendGoalResponse {
                accepted: false,
                stamp,
            }
        };
        let request = match actions::decode_send_goal(payload) {
            Ok(r) => r,
            Err(e) => return refuse("?", format!("malformed request: {e}")),
        };
        let id = short(&request.goal_id);
        if self.goals.iter().any(|g| g.info.goal_id == request.goal_id) {
            return refuse(&id, "its goal id is already in use".into());
        }
        let mut goal = match check_goal(&request, self.max_opening_rad()) {
            Ok(g) => g,
            Err(why) => return refuse(&id, why),
        };
        let Some(handle) = &self.setup.gripper else {
            return refuse(&id, "this run has no grasp API".into());
        };
        let force = if goal.auto {
            TargetForce::Auto
        } else {
            TargetForce::Newtons(goal.max_effort_n)
        };
        let (target_force_n, auto_target) = handle.target(force);
        goal.max_effort_n = target_force_n;
        let grasp = GraspRequest {
            target_force_n,
            speed_deg_s: SPEED_DEG_S,
            current_limit_ma: self.setup.current_limit_ma,
            fingers: (0..self.setup.range_deg.len()).collect(),
            timeout_s: TIMEOUT_S,
            auto_target,
        };
        let grasp_id = match self.store.start(handle, grasp) {
            Ok(n) => n,
            Err(e) => return refuse(&id, e.to_string()),
        };
        tracing::info!(
            "ROS 2: goal {id} accepted as grasp {grasp_id}: {}{}",
            if goal.auto {
                format!("auto, from {} N per finger", goal.max_effort_n)
            } else {
                format!("{} N per finger", goal.max_effort_n)
            },
            if goal.position_rad > CLOSE_POSITION_RAD {
                format!(", stopping at an opening of {:.3} rad", goal.position_rad)
            } else {
                String::new()
            }
        );
        self.goals.push(ActionGoal {
            info: GoalInfo {
                goal_id: request.goal_id,
                stamp,
            },
            grasp_id,
            request: goal,
            status: GoalStatusCode::Executing,
            result: GripperState::default(),
            ending: Ending::Grasp,
            waiting: Vec::new(),
            arrived,
            write_seen: false,
            ended: None,
        });
        // The new goal's first feedback comes with the next report, not 100 ms after the
        // preempted goal's last one.
        self.last_feedback = None;
        if self.goals.len() > GOALS_KEPT
            && let Some(i) = self.goals.iter().position(|g| g.status.is_terminal())
        {
            self.goals.remove(i);
        }
        self.publish_status();
        SendGoalResponse {
            accepted: true,
            stamp,
        }
    }

    fn cancel_goal(&mut self, payload: &[u8]) -> CancelGoalResponse {
        let refused = |code, why: String| {
            tracing::warn!("ROS 2: cancel refused: {why}");
            CancelGoalResponse {
                return_code: code,
                goals_canceling: Vec::new(),
            }
        };
        let request = match actions::decode_cancel_goal(payload) {
            Ok(r) => r,
            Err(e) => {
                return refused(
                    actions::CancelCode::Rejected,
                    format!("malformed request: {e}"),
                );
            }
        };
        let known: Vec<(GoalInfo, bool)> = self
            .goals
            .iter()
            .map(|g| (g.info, g.status.is_terminal()))
            .collect();
        let targets = match cancel_targets(&request, &known) {
            Ok(t) => t,
            Err(code) => {
                return refused(code, format!("goal {}: {code:?}", short(&request.goal_id)));
            }
        };
        let Some(handle) = &self.setup.gripper else {
            return refused(
                actions::CancelCode::Rejected,
                "this run has no grasp API".into(),
            );
        };
        // Only the newest goal's grasp can still be running: an older goal not yet ended was
        // preempted, and stopping for it would stop whatever grasp replaced it.
        let running = self.goals.iter().rev().find(|g| !g.status.is_terminal());
        let stops = running.is_some_and(|g| {
            targets.contains(&g.info)
                && self
                    .store
                    .status(g.grasp_id)
                    .is_some_and(|st| st.state == GoalState::Running)
        });
        if stops && let Err(e) = handle.stop() {
            return refused(actions::CancelCode::Rejected, e.to_string());
        }
        for g in self.goals.iter_mut().filter(|g| targets.contains(&g.info)) {
            g.status = GoalStatusCode::Canceling;
            g.ending = Ending::Canceled;
            tracing::info!(
                "ROS 2: goal {} canceling: the fingers hold",
                short(&g.info.goal_id)
            );
        }
        self.publish_status();
        CancelGoalResponse {
            return_code: actions::CancelCode::None,
            goals_canceling: targets,
        }
    }

    fn get_result(&mut self, payload: &[u8], q: Query, seq: i64, client: [u8; 16]) {
        let unknown = GetResultResponse {
            status: GoalStatusCode::Unknown,
            result: GripperState::default(),
        };
        let id = match actions::decode_get_result(payload) {
            Ok(id) => id,
            Err(e) => {
                tracing::warn!("ROS 2: get_result: malformed request: {e}");
                reply(&q, seq, &client, unknown.to_cdr());
                return;
            }
        };
        match self.goals.iter_mut().find(|g| g.info.goal_id == id) {
            None => {
                tracing::warn!("ROS 2: get_result: unknown goal {}", short(&id));
                reply(&q, seq, &client, unknown.to_cdr());
            }
            Some(g) if g.status.is_terminal() => {
                let r = GetResultResponse {
                    status: g.status,
                    result: g.result,
                };
                reply(&q, seq, &client, r.to_cdr());
            }
            Some(g) if g.waiting.len() >= WAITING_PER_GOAL => {
                tracing::warn!(
                    "ROS 2: get_result: goal {}: {WAITING_PER_GOAL} requests wait already; refused",
                    short(&id)
                );
                let _ = q
                    .reply_err("gelgrip: too many get_result requests wait on this goal")
                    .wait();
            }
            Some(g) => g.waiting.push((q, seq, client)),
        }
    }

    fn trigger(&mut self, service: Service, payload: &[u8]) -> TriggerResponse {
        let name = service.relative();
        let answer = |success: bool, message: String| {
            if success {
                tracing::info!("ROS 2: {name}: {message}");
            } else {
                tracing::warn!("ROS 2: {name} refused: {message}");
            }
            TriggerResponse { success, message }
        };
        if let Err(e) = services::decode_trigger_request(payload) {
            return answer(false, format!("malformed request: {e}"));
        }
        let Some(handle) = &self.setup.gripper else {
            return answer(false, "this run has no grasp API".into());
        };
        let task = handle.busy();
        let (done, what) = match service {
            Service::Release => (handle.release(), "released: every finger opens"),
            Service::Stop => (handle.stop(), "stopped: every finger holds where it is"),
            _ => (
                handle.estop(),
                "e-stopped: every finger holds where it is at the minimum current",
            ),
        };
        match done {
            Ok(()) => {
                let interrupted =
                    task.map_or_else(String::new, |t| format!(" (task `{t}` interrupted)"));
                answer(true, format!("{what}{interrupted}"))
            }
            Err(e) => answer(false, e.to_string()),
        }
    }

    fn report(&mut self, s: Snapshot) {
        self.fingers = s.fingers;
        for i in 0..self.goals.len() {
            if self.goals[i].status.is_terminal() {
                continue;
            }
            let Some(st) = self.store.status(self.goals[i].grasp_id) else {
                self.end(
                    i,
                    GoalStatusCode::Aborted,
                    "forgotten by the grasp API".into(),
                );
                continue;
            };
            if st.state == GoalState::Done {
                let (status, result, why) =
                    finish(st.result.as_ref(), self.goals[i].ending, &self.fingers);
                self.goals[i].result = result;
                self.end(i, status, why);
            }
        }
        let Some(i) = self.goals.iter().rposition(|g| !g.status.is_terminal()) else {
            return;
        };
        let g = &mut self.goals[i];
        if !g.write_seen
            && self.fingers.iter().any(|f| {
                f.phase != Phase::Open && (f.target_force_n - g.request.max_effort_n).abs() < 1e-9
            })
        {
            g.write_seen = true;
            tracing::info!(
                "ROS 2: goal {}: first servo write within {:.1} ms of its arrival",
                short(&g.info.goal_id),
                s.at.duration_since(g.arrived).as_secs_f64() * 1e3
            );
        }
        if g.ending == Ending::Grasp
            && g.request.position_rad > CLOSE_POSITION_RAD
            && !in_contact(&self.fingers)
            && state_now(&self.fingers).position_rad <= g.request.position_rad
            && let Some(h) = &self.setup.gripper
            && h.stop().is_ok()
        {
            g.ending = Ending::AtPosition;
        }
        if g.status == GoalStatusCode::Executing
            && self
                .last_feedback
                .is_none_or(|t| s.at.duration_since(t) >= FEEDBACK_PERIOD)
        {
            self.last_feedback = Some(s.at);
            let m = FeedbackMessage {
                goal_id: g.info.goal_id,
                feedback: state_now(&self.fingers),
            };
            self.declared.publish(true, m.to_cdr());
        }
    }

    /// Goal `i` has ended: answer its waiting `get_result` requests, log, publish the status.
    fn end(&mut self, i: usize, status: GoalStatusCode, why: String) {
        let g = &mut self.goals[i];
        g.status = status;
        g.ended = Some(Instant::now());
        let r = GetResultResponse {
            status,
            result: g.result,
        };
        for (q, seq, client) in g.waiting.drain(..) {
            reply(&q, seq, &client, r.to_cdr());
        }
        tracing::info!(
            "ROS 2: goal {} {status:?} ({why}): position {:.3} rad, effort {:.2} N, stalled {}, \
             reached_goal {}",
            short(&g.info.goal_id),
            g.result.position_rad,
            g.result.effort_n,
            g.result.stalled,
            g.result.reached_goal
        );
        self.publish_status();
    }

    fn publish_status(&mut self) {
        self.last_status = Instant::now();
        let m = GoalStatusArray {
            status_list: self.goals.iter().map(|g| (g.info, g.status)).collect(),
        };
        self.declared.publish(false, m.to_cdr());
    }
}
