//! Streaming sensing: each sensor's frame is processed the moment it arrives, before the
//! gate has decided on its set, so that when a set completes only its last frame's work
//! remains.
//!
//! A [`StreamingSensors`] owns every sensor's [`SensorPipeline`]. [`StreamingSensors::arrive`]
//! queues a frame and hands its work to the rayon pool; the result waits in the sensor's
//! slot, keyed by the frame (its trigger sequence and its bytes). [`StreamingSensors::process`]
//! is given the set the gate emitted: a sensor whose slot holds the result of that very
//! frame takes it; one whose frame is queued or not yet seen is processed then: on the
//! caller's thread when it is the only one (as a rule the set's last frame: no hand-off to
//! the pool and back on the critical path; its stages split in two with a worker kept
//! polling meanwhile, [`crate::halves`]), else the sensors in parallel, as
//! [`super::process_set`]. A result is only ever handed out for the frame it was computed
//! from, so the work done for a set the gate refused never reaches the
//! caller: it is overwritten by the sensor's next frame, and dropped as soon as a newer set
//! is processed.
//!
//! The work itself is [`SensorPipeline::process`], the same call on the same state as the
//! non-streaming path, so the results are bit-for-bit the same.
//!
//! Locks and rayon: a pipeline may run rayon work of its own (an MLP's kernels), and a rayon
//! worker waiting on it runs other tasks meanwhile. So no rayon task ever waits for a slot's
//! lock: a frame's task takes the lock only if it is free (else whoever holds it, or the
//! next set, sees to the frame), and a set's frames are processed in parallel only after the
//! caller's thread has taken every slot's lock. A pipeline whose reference
//! drifts (`reference = "drift"`) refreshes that reference as it processes a quiet frame:
//! such a sensor is not processed ahead, since a refused set must not move its reference;
//! it is processed when its set is emitted, as before.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError, TryLockError};

use bytes::Bytes;

use crate::contact::ContactSummary;
use crate::halves::keep_a_worker_awake;
use crate::pipeline::{Needs, PipelineError, SensorPipeline};

/// One sensor's frame: its trigger sequence and its JPEG bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameKey {
    /// The trigger sequence of its set.
    pub trigger_seq: u32,
    /// The JPEG bytes (compared by content: the same frame, not merely the same set).
    pub jpeg: Bytes,
}

/// A result computed ahead of its set.
type Precomputed = (FrameKey, Result<ContactSummary, PipelineError>);

/// One sensor's pipeline and its frame in flight.
#[derive(Debug)]
struct Slot {
    pipe: SensorPipeline,
    /// A frame waiting for its work.
    queued: Option<FrameKey>,
    /// The last frame worked on ahead, and its result.
    done: Option<Precomputed>,
    /// The frame whose work the pipeline's buffers hold (its depth window).
    last: Option<FrameKey>,
    /// The last frame handed out in a processed set.
    committed: Option<FrameKey>,
}

impl Slot {
    /// Work on the queued frame, if any (a rayon task).
    fn run_queued(&mut self, needs: Needs) {
        let Some(key) = self.queued.take() else {
            return;
        };
        let result = self.pipe.process(&key.jpeg, needs);
        self.last = Some(key.clone());
        self.done = Some((key, result));
    }

    /// Whether the result for `key` was worked on ahead and waits here.
    fn ready(&self, key: &FrameKey) -> bool {
        self.done.as_ref().is_some_and(|(k, _)| k == key)
    }

    /// The result for `key`: worked on ahead, or now.
    fn result_for(
        &mut self,
        key: &FrameKey,
        needs: Needs,
    ) -> Result<ContactSummary, PipelineError> {
        // Whatever is older than this set belongs to a set that was refused or skipped.
        if self
            .queued
            .as_ref()
            .is_some_and(|q| older(q.trigger_seq, key.trigger_seq))
        {
            self.queued = None;
        }
        let result = match self.done.take() {
            Some((k, r)) if k == *key => r,
            other => {
                self.done = other.filter(|(k, _)| !older(k.trigger_seq, key.trigger_seq));
                if self.queued.as_ref() == Some(key) {
                    self.queued = None;
                }
                let r = self.pipe.process(&key.jpeg, needs);
                self.last = Some(key.clone());
                r
            }
        };
        self.committed = Some(key.clone());
        result
    }
}

/// Whether trigger sequence `a` comes before `b` (sequences wrap).
fn older(a: u32, b: u32) -> bool {
    (b.wrapping_sub(a) as i32) > 0
}

fn lock(slot: &Mutex<Slot>) -> MutexGuard<'_, Slot> {
    // A panic in a pipeline would poison the slot; its state is still a valid pipeline.
    slot.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The slot's lock if it is free now (never waits: for rayon tasks).
fn try_lock(slot: &Mutex<Slot>) -> Option<MutexGuard<'_, Slot>> {
    match slot.try_lock() {
        Ok(g) => Some(g),
        Err(TryLockError::Poisoned(p)) => Some(p.into_inner()),
        Err(TryLockError::WouldBlock) => None,
    }
}

/// Work on `slot`'s queued frame on the rayon pool, if its lock is free then.
fn spawn_queued(slot: &Arc<Mutex<Slot>>, needs: Needs) {
    let slot = Arc::clone(slot);
    rayon::spawn(move || {
        if let Some(mut s) = try_lock(&slot) {
            s.run_queued(needs);
        }
    });
}

/// Every sensor's pipeline, worked on as frames arrive.
#[derive(Debug)]
pub struct StreamingSensors {
    slots: Vec<Arc<Mutex<Slot>>>,
    /// Per sensor: whether its frames may be worked on ahead (its reference is static).
    ahead: Vec<bool>,
    needs: Needs,
}

impl StreamingSensors {
    /// Stream `pipes` (sensor `i` is `pipes[i]`), each frame processed for `needs`.
    pub fn new(pipes: Vec<SensorPipeline>, needs: Needs) -> Self {
        let ahead = pipes.iter().map(|p| !p.updates_reference()).collect();
        let slots = pipes
            .into_iter()
            .map(|pipe| {
                Arc::new(Mutex::new(Slot {
                    pipe,
                    queued: None,
                    done: None,
                    last: None,
                    committed: None,
                }))
            })
            .collect();
        Self {
            slots,
            ahead,
            needs,
        }
    }

    /// Sensors.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether there are no sensors.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Sensor `sensor`'s frame `key` has arrived: work on it now, on the rayon pool. Does
    /// nothing for an unknown sensor, or one whose reference drifts. Call it from outside
    /// the rayon pool (it may wait for the sensor's frame before to be done).
    pub fn arrive(&self, sensor: usize, key: FrameKey) {
        if !self.ahead.get(sensor).copied().unwrap_or(false) {
            return;
        }
        let Some(slot) = self.slots.get(sensor) else {
            return;
        };
        lock(slot).queued = Some(key);
        spawn_queued(slot, self.needs);
    }

    /// Process the set the gate emitted: `frames[i]` is sensor `i`'s frame (`None`: left
    /// out of the set, and `out[i]` stays as it was). Results worked on ahead for these very
    /// frames are taken; the others are processed now, the sensors in parallel. Call it from
    /// outside the rayon pool: it waits for the frames under way.
    pub fn process(
        &mut self,
        frames: &[Option<FrameKey>],
        out: &mut [Result<ContactSummary, PipelineError>],
    ) {
        use rayon::prelude::*;
        let needs = self.needs;
        {
            // Every lock first, on this thread; then no rayon task waits for one.
            let mut guards: Vec<MutexGuard<'_, Slot>> =
                self.slots.iter().map(|s| lock(s)).collect();
            let mut slots: Vec<&mut Slot> = guards.iter_mut().map(|g| &mut **g).collect();
            // What was not worked on ahead is worked on now: one frame (the set's last, as a
            // rule) on this thread, with no hand-off to the pool and back; more in parallel.
            let pending = slots
                .iter()
                .zip(frames)
                .filter(|(slot, frame)| frame.as_ref().is_some_and(|key| !slot.ready(key)))
                .count();
            let work = |((slot, frame), result): (
                (&mut &mut Slot, &Option<FrameKey>),
                &mut Result<ContactSummary, PipelineError>,
            )| {
                if let Some(key) = frame {
                    *result = slot.result_for(key, needs);
                }
            };
            if pending <= 1 {
                // One frame on this thread, its stages in two halves while a worker polls
                // for the other halves (`halves`).
                let _awake = (pending == 1).then(keep_a_worker_awake);
                slots
                    .iter_mut()
                    .zip(frames)
                    .zip(out.iter_mut())
                    .for_each(work);
            } else {
                slots
                    .par_iter_mut()
                    .zip(frames.par_iter())
                    .zip(out.par_iter_mut())
                    .for_each(work);
            }
        }
        // A frame that arrived for a later set while the locks were held is worked on now.
        for slot in &self.slots {
            self.release(slot, lock(slot));
        }
    }

    /// Run `f` on sensor `sensor`'s pipeline (waiting for its work in flight).
    pub fn with_pipe<R>(&self, sensor: usize, f: impl FnOnce(&SensorPipeline) -> R) -> Option<R> {
        let slot = self.slots.get(sensor)?;
        let guard = lock(slot);
        let out = f(&guard.pipe);
        self.release(slot, guard);
        Some(out)
    }

    /// Let go of `slot`'s lock; a frame whose task found it taken meanwhile is worked on.
    fn release(&self, slot: &Arc<Mutex<Slot>>, guard: MutexGuard<'_, Slot>) {
        let queued = guard.queued.is_some();
        drop(guard);
        if queued {
            spawn_queued(slot, self.needs);
        }
    }

    /// Run `f` on sensor `sensor`'s pipeline, mutably (to reference it). Any frame worked on
    /// ahead is dropped: its result was made with the old state.
    pub fn with_pipe_mut<R>(
        &self,
        sensor: usize,
        f: impl FnOnce(&mut SensorPipeline) -> R,
    ) -> Option<R> {
        self.slots.get(sensor).map(|s| {
            let mut slot = lock(s);
            slot.queued = None;
            slot.done = None;
            f(&mut slot.pipe)
        })
    }

    /// Run `f` on sensor `sensor`'s pipeline when its buffers hold the last frame handed
    /// out in a processed set (not a frame worked on ahead since); `None` otherwise.
    pub fn with_committed_pipe<R>(
        &self,
        sensor: usize,
        f: impl FnOnce(&SensorPipeline) -> R,
    ) -> Option<R> {
        let slot = self.slots.get(sensor)?;
        let guard = lock(slot);
        let out = (guard.last.is_some() && guard.last == guard.committed).then(|| f(&guard.pipe));
        self.release(slot, guard);
        out
    }
}

#[cfg(test)]
mod tests;
