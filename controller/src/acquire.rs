//! The acquisition loop: keep triggers queued on the hub, feed its events to the gate, and
//! hand out the sets the gate emits.
//!
//! Two triggers are kept outstanding so the hub can fire the next one the moment its bus is
//! free, as a free-running coordinator does; the host's USB latency then adds latency but
//! not period.

use std::sync::Arc;

use crate::actuator::XM430_W350;
use crate::clock::Clock;
use crate::config::{GatePolicy, GateSettings, Limit};
use crate::frame::{FrameSet, ReceivedFrame};
use crate::gate::window::control_spread;
use crate::gate::{Gate, GateLimits, SetDecision};
use crate::grasp::Tuning;
use crate::hub::{BusPrediction, HubError, HubEvent, HubTransport};
use crate::layout::HandLayout;

/// Triggers kept queued on the hub.
const TRIGGERS_IN_FLIGHT: u32 = 2;

/// The fastest a servo turns once its finger is in contact, deg/s: the XM430-W350's no-load
/// speed (the largest approach speed a grasp may ask for) times the controller's contact
/// speed share.
pub fn contact_servo_deg_s() -> f64 {
    XM430_W350.no_load_deg_s() * Tuning::default().contact_speed_share
}

/// The gate window for `settings` on `layout`, with `auto` limits:
/// - spread: what the control tolerates, the time the fastest pad in contact takes to move
///   one pixel ([`control_spread`] at [`contact_servo_deg_s`]), but never below 1.5 × the
///   bus's predicted trigger spread (a bus cannot capture tighter than it does); 1.5 × the
///   bus's spread alone for a layout without finger mechanics;
/// - age: 2 × the predicted set latency; for `approximate`, plus 2 set periods: it waits
///   up to a period for the frames that prove a set minimal, and a capture later than a
///   period (a board triggered every other time) doubles the period.
pub fn gate_limits(
    settings: &GateSettings,
    layout: &HandLayout,
    prediction: &BusPrediction,
) -> GateLimits {
    let bus_spread_us = 1.5 * prediction.trigger_spread_us;
    GateLimits {
        max_spread_us: match settings.max_spread_us {
            Limit::Fixed(us) => us,
            Limit::Auto => {
                let control = control_spread(layout, contact_servo_deg_s());
                let us = control.map_or(bus_spread_us, |c| c.spread_us.max(bus_spread_us));
                us.ceil().min(f64::from(u32::MAX)) as u32
            }
        },
        max_age_us: match settings.max_age_us {
            Limit::Fixed(us) => us,
            Limit::Auto => {
                let proof_us = match settings.policy {
                    GatePolicy::Approximate => 2.0 * prediction.set_period_us,
                    GatePolicy::Trigger | GatePolicy::Latest => 0.0,
                };
                (2.0 * prediction.set_latency_us + proof_us).ceil() as u64
            }
        },
    }
}

/// The gate `settings` ask for, for `layout`'s sensors on a bus with `prediction`.
pub fn make_gate(settings: &GateSettings, layout: &HandLayout, prediction: &BusPrediction) -> Gate {
    let limits = gate_limits(settings, layout, prediction);
    let sensors = layout.sensors.len();
    let gate = match settings.policy {
        GatePolicy::Trigger => Gate::new(sensors, limits),
        GatePolicy::Approximate => Gate::approximate(sensors, limits, settings.queue_size),
        GatePolicy::Latest => Gate::latest(sensors, limits),
    };
    if settings.exclude_failing_sensors {
        gate
    } else {
        gate.without_exclusion()
    }
}

/// CPU time this thread has used, in ns (for measuring the receive path alone).
pub type CpuClock = fn() -> u64;

/// What a recorder sees of the acquisition: every hub event with the host time the gate was
/// given it at, and every decision the gate made on a set. It must not block.
pub trait AcquisitionTap: Send {
    /// A hub event, about to go to the gate at `gate_host_us`.
    fn event(&mut self, event: &HubEvent, gate_host_us: u64);
    /// A decision on a set, made at `host_us`.
    fn decision(&mut self, decision: &SetDecision, host_us: u64);
}

/// Drives a hub and a gate.
pub struct Acquisition {
    hub: Box<dyn HubTransport>,
    gate: Gate,
    clock: Arc<dyn Clock>,
    next_seq: u32,
    outstanding: u32,
    cpu_clock: Option<CpuClock>,
    receive_cpu_ns: u64,
    tap: Option<Box<dyn AcquisitionTap>>,
    /// The frame the last step brought, until taken.
    arrived: Option<ReceivedFrame>,
}

impl std::fmt::Debug for Acquisition {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Acquisition")
            .field("hub", self.hub.describe())
            .field("gate", &self.gate)
            .field("next_seq", &self.next_seq)
            .finish()
    }
}

impl Acquisition {
    /// Acquire from `hub` through `gate`, starting at trigger sequence `first_seq`.
    pub fn new(
        hub: Box<dyn HubTransport>,
        gate: Gate,
        clock: Arc<dyn Clock>,
        first_seq: u32,
    ) -> Self {
        Self {
            hub,
            gate,
            clock,
            next_seq: first_seq,
            outstanding: 0,
            cpu_clock: None,
            receive_cpu_ns: 0,
            tap: None,
            arrived: None,
        }
    }

    /// Show every hub event and gate decision to `tap` (a recorder).
    pub fn with_tap(mut self, tap: Box<dyn AcquisitionTap>) -> Self {
        self.gate.log_decisions();
        self.tap = Some(tap);
        self
    }

    /// Take the tap back (to close a recorder at the end of a run).
    pub fn take_tap(&mut self) -> Option<Box<dyn AcquisitionTap>> {
        self.tap.take()
    }

    /// Measure the CPU time of the gate's work with `cpu_clock`.
    pub fn with_cpu_clock(mut self, cpu_clock: CpuClock) -> Self {
        self.cpu_clock = Some(cpu_clock);
        self
    }

    /// The gate (for its statistics).
    pub fn gate(&self) -> &Gate {
        &self.gate
    }

    /// The hub transport.
    pub fn hub(&self) -> &dyn HubTransport {
        self.hub.as_ref()
    }

    /// CPU time spent in the gate so far, in ns (0 without a CPU clock).
    pub fn receive_cpu_ns(&self) -> u64 {
        self.receive_cpu_ns
    }

    async fn top_up_triggers(&mut self) -> Result<(), HubError> {
        while self.outstanding < TRIGGERS_IN_FLIGHT {
            self.hub.trigger(self.next_seq).await?;
            self.next_seq = self.next_seq.wrapping_add(1);
            self.outstanding += 1;
        }
        Ok(())
    }

    /// Process one hub event (waiting for it on the clock); returns the set it completed if
    /// the gate emitted one. Callers check their own deadlines between steps, so a run in
    /// which no set ever passes the gate still ends.
    pub async fn step(&mut self) -> Result<Option<FrameSet>, HubError> {
        self.top_up_triggers().await?;
        let event = self.hub.next_event().await?;
        if matches!(event, HubEvent::SetEnd { .. }) {
            self.outstanding = self.outstanding.saturating_sub(1);
        }
        let now = self.clock.now_us();
        if let Some(tap) = self.tap.as_mut() {
            tap.event(&event, now);
        }
        self.arrived = match &event {
            HubEvent::Frame(f) => Some(f.clone()),
            _ => None,
        };
        let cpu_start = self.cpu_clock.map(|c| c());
        let emitted = self.gate.push(event, now);
        self.gate.tick(now);
        if let Some(tap) = self.tap.as_mut() {
            for d in self.gate.take_decisions() {
                tap.decision(&d, now);
            }
        }
        if let (Some(c), Some(start)) = (self.cpu_clock, cpu_start) {
            self.receive_cpu_ns += c().saturating_sub(start);
        }
        Ok(emitted)
    }

    /// The frame the last [`Acquisition::step`] brought (whatever the gate made of it),
    /// once: for the pipelines to work on it before its set is complete.
    pub fn take_arrived(&mut self) -> Option<ReceivedFrame> {
        self.arrived.take()
    }

    /// Step until the gate emits a set or the clock passes `deadline_us`.
    pub async fn next_set_before(
        &mut self,
        deadline_us: u64,
    ) -> Result<Option<FrameSet>, HubError> {
        while self.clock.now_us() < deadline_us {
            if let Some(set) = self.step().await? {
                return Ok(Some(set));
            }
        }
        Ok(None)
    }
}
