//! Grasps as goals: a grasp started through [`GraspGoals::start`] gets an id at once, and
//! its state (`running`, then `done` with the outcome) can be asked for by id later, as a
//! robot API (a ROS action, the dashboard's `POST /api/grasps`) accepts a goal and reports
//! on it.
//!
//! It wraps the grasp API ([`GripperHandle`]), so everything the handle does still holds: a
//! new goal preempts the running one (which ends `preempted`), a task that owns the gripper
//! refuses it, and an invalid request is refused before it gets an id. Ids count up from 1
//! per store (one store per run); the last [`GraspGoals::KEPT`] goals are kept. Nothing is
//! spawned: a goal's outcome is collected when someone asks.

use std::collections::VecDeque;
use std::sync::Mutex;

use serde::Serialize;

use crate::grasp::{GraspOutcome, GraspRequest};
use crate::gripper::{GripperError, GripperHandle, PendingGrasp};

/// Where a goal is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GoalState {
    /// The grasp has not ended.
    Running,
    /// It ended; the result (or the error) is known.
    Done,
}

/// A goal as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GoalStatus {
    /// Its id.
    pub id: u64,
    /// Running or done.
    pub state: GoalState,
    /// The grasp's outcome once done (`None` while running, or when it ended without one).
    pub result: Option<GraspOutcome>,
    /// Why a finished goal has no result (the run loop stopped), if so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

#[derive(Debug)]
struct Goal {
    id: u64,
    pending: Option<PendingGrasp>,
    ended: Option<Result<GraspOutcome, GripperError>>,
}

impl Goal {
    /// Collect the outcome if it has arrived; the status now.
    fn poll(&mut self) -> GoalStatus {
        if let Some(p) = &mut self.pending
            && let Some(ended) = p.try_outcome()
        {
            self.ended = Some(ended);
            self.pending = None;
        }
        let (state, result, error) = match &self.ended {
            None => (GoalState::Running, None, None),
            Some(Ok(o)) => (GoalState::Done, Some(o.clone()), None),
            Some(Err(e)) => (GoalState::Done, None, Some(e.to_string())),
        };
        GoalStatus {
            id: self.id,
            state,
            result,
            error,
        }
    }
}

#[derive(Debug, Default)]
struct Goals {
    last_id: u64,
    kept: VecDeque<Goal>,
}

/// The goals of one run.
#[derive(Debug, Default)]
pub struct GraspGoals {
    goals: Mutex<Goals>,
}

impl GraspGoals {
    /// Goals kept for asking; older ones are forgotten.
    pub const KEPT: usize = 100;

    /// An empty store.
    pub fn new() -> Self {
        Self::default()
    }

    /// Start a grasp through `handle`; its id. Refused (with no id used) as
    /// [`GripperHandle::start_grasp`] refuses.
    pub fn start(
        &self,
        handle: &GripperHandle,
        request: GraspRequest,
    ) -> Result<u64, GripperError> {
        let mut goals = self.goals.lock().map_err(|_| GripperError::Stopped)?;
        let pending = handle.start_grasp(request)?;
        goals.last_id += 1;
        let id = goals.last_id;
        goals.kept.push_back(Goal {
            id,
            pending: Some(pending),
            ended: None,
        });
        while goals.kept.len() > Self::KEPT {
            goals.kept.pop_front();
        }
        Ok(id)
    }

    /// Goal `id`'s status (`None`: never started, or forgotten).
    pub fn status(&self, id: u64) -> Option<GoalStatus> {
        let mut goals = self.goals.lock().ok()?;
        goals.kept.iter_mut().find(|g| g.id == id).map(Goal::poll)
    }

    /// The newest goal's status.
    pub fn latest(&self) -> Option<GoalStatus> {
        let mut goals = self.goals.lock().ok()?;
        goals.kept.back_mut().map(Goal::poll)
    }
}

#[cfg(test)]
mod tests;
