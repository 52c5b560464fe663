//! The simulated cameras' renderer on its own thread, off the run loop's critical path.
//!
//! At a trigger the hub takes the world's height maps at once (the world is stepped to the
//! trigger's time on the caller's thread, so the frames show what they showed before) and
//! hands them here; the JPEGs are made while the loop works on the sets before. The jobs are
//! rendered in order, one at a time, so the noise variants cycle as before and a run on the
//! virtual clock gives the same frames. The renderer's parallel work runs on a rayon pool of
//! its own, one thread: on the global pool its JPEGs would queue ahead of the tactile
//! pipelines' work, and a set's last frame would wait for the next set's pictures.

use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

use bytes::Bytes;

use crate::pool::EncodeError;
use crate::scene_frames::SceneFrames;
use crate::scene_frames::TouchedPad;

/// One capture to render: the pads' height maps and the capture count.
type Job = (Option<Vec<Option<TouchedPad>>>, u64);

/// A rendered capture: every sensor's JPEG.
pub type Rendered = Result<Vec<Bytes>, EncodeError>;

/// The renderer's thread.
#[derive(Debug)]
pub struct RenderThread {
    jobs: Option<Sender<(Job, Sender<Rendered>)>>,
    thread: Option<JoinHandle<()>>,
}

impl RenderThread {
    /// Render `frames`' captures on a thread of its own.
    pub fn spawn(mut frames: SceneFrames) -> std::io::Result<Self> {
        let (jobs, rx) = channel::<(Job, Sender<Rendered>)>();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .thread_name(|_| "sim-render-pool".into())
            .build()
            .map_err(std::io::Error::other)?;
        let thread = std::thread::Builder::new()
            .name("sim-render".into())
            .spawn(move || {
                for ((maps, nth), reply) in rx {
                    // The hub may have gone: nobody to tell.
                    let _ = reply.send(pool.install(|| frames.render(maps, nth)));
                }
            })?;
        Ok(Self {
            jobs: Some(jobs),
            thread: Some(thread),
        })
    }

    /// Queue capture `nth` of `maps`; its frames come through the receiver returned.
    pub fn render(&self, maps: Option<Vec<Option<TouchedPad>>>, nth: u64) -> Receiver<Rendered> {
        let (reply, frames) = channel();
        if let Some(jobs) = &self.jobs {
            // A renderer that has gone drops the reply: the receiver then says so.
            let _ = jobs.send(((maps, nth), reply));
        }
        frames
    }
}

impl Drop for RenderThread {
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
