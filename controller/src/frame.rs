//! Frames from the tactile sensors and the synchronized sets the gate emits.

use bytes::Bytes;

/// A sensor's position in the layout, which is also its hub board index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SensorIndex(pub u8);

/// One captured image as the hub delivers it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// Which sensor.
    pub sensor: SensorIndex,
    /// The trigger that caused the capture (u32, wraps).
    pub trigger_seq: u32,
    /// Capture time in the hub's timebase (u32 µs, wraps every 71.6 min).
    pub capture_ts_us: u32,
    /// Exposure used, in µs.
    pub exposure_us: u32,
    /// The JPEG image.
    pub jpeg: Bytes,
}

/// A frame plus the host-side times the transport attached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReceivedFrame {
    /// The frame.
    pub frame: Frame,
    /// Its capture time mapped to host time, in µs.
    pub capture_host_us: u64,
    /// When the host received it, in µs.
    pub received_host_us: u64,
}

/// A set the gate emitted: one frame per sensor (from one trigger, within the window, under
/// the synchronized policies; each sensor's latest frame under `latest`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameSet {
    /// The trigger sequence (`approximate`: the gate's own count of sets; `latest`: the
    /// trigger whose hub `SetEnd` fused it).
    pub trigger_seq: u32,
    /// Frames in sensor-index order, one per sensor.
    pub frames: Vec<ReceivedFrame>,
    /// Latest minus earliest capture time, in µs.
    pub spread_us: u32,
    /// Earliest capture time in host time, in µs.
    pub earliest_capture_host_us: u64,
    /// When the gate emitted the set, in host µs.
    pub emitted_host_us: u64,
}

impl FrameSet {
    /// Age of the set at emission: emission minus earliest capture, in µs.
    pub fn latency_us(&self) -> u64 {
        self.emitted_host_us
            .saturating_sub(self.earliest_capture_host_us)
    }

    /// Per sensor of a hand of `sensors`, whether the gate left it out of this set (an
    /// excluded sensor has no frame in it).
    pub fn left_out(&self, sensors: usize) -> Vec<bool> {
        let mut out = vec![true; sensors];
        for f in &self.frames {
            if let Some(slot) = out.get_mut(usize::from(f.frame.sensor.0)) {
                *slot = false;
            }
        }
        out
    }

    /// Each frame's age at fusion, in sensor order: emission minus its capture, in µs
    /// (0 for a capture stamped after the emission).
    pub fn frame_ages_us(&self) -> Vec<u64> {
        self.frames
            .iter()
            .map(|f| self.emitted_host_us.saturating_sub(f.capture_host_us))
            .collect()
    }
}
