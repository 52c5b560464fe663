//! The ROS 2 publisher as an observer of the run: each servo read the reports carry
//! becomes `joint_states` (the runtime reads the servos after every gated set's goals, and
//! between sets after each refused set and each quiet period); each gated set its images
//! (at `image_rate_hz`), depth images (at `depth_rate_hz`), wrenches and contacts; once a
//! second the diagnostics. Stamps are the set's capture time (the servo read's time for
//! joints) on the system clock: host µs plus the offset between the system clock and the
//! run's clock, taken at the first report.
//!
//! It never waits: samples go to the [`LiveLink`]'s bounded queue (best-effort topics drop
//! when the publisher thread is behind).

use gelgrip_controller::actuator::hardware_error_names;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::runtime::ports::{Observer, ObserverError};
use gelgrip_controller::runtime::report::SetReport;
use gelgrip_ros_wire::msgs::Time;

use crate::BridgeError;
use crate::config::RosConfig;
use crate::feed::{DiagnosticsInput, Feed, Sample, ServoSample, drop_counts};
use crate::live::LiveLink;

/// The run's ROS 2 publisher.
#[derive(Debug)]
pub struct RosPublisher {
    feed: Feed,
    link: LiveLink,
    transport: String,
    joints: Vec<String>,
    /// System-clock µs minus run-clock µs (set at the first report).
    unix_offset_us: Option<i128>,
    /// The servo read count of the last `joint_states` published.
    published_reads: Option<u64>,
    out: Vec<Sample>,
}

fn unix_now_us() -> i128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i128::try_from(d.as_micros()).unwrap_or(0))
}

impl RosPublisher {
    /// Open the link for `config`'s hand, publishing as `ros` says.
    pub fn start(
        config: &AppConfig,
        ros: &RosConfig,
        transport: String,
    ) -> Result<Self, BridgeError> {
        let ids = config.layout.sensor_ids();
        let joints = config.layout.finger_ids();
        let feed = Feed::new(ros, &ids, &joints)?;
        let link = LiveLink::start(ros, feed.topics().to_vec())?;
        tracing::info!(
            namespace = ros.namespace,
            domain = ros.domain_id,
            connect = ros.connect.join(","),
            session = link.session_id,
            "publishing to ROS 2 over Zenoh"
        );
        Ok(Self {
            feed,
            link,
            transport,
            joints,
            unix_offset_us: None,
            published_reads: None,
            out: Vec::new(),
        })
    }

    /// The publisher of a `gelgrip run`: when `[ros] enabled`, `--ros` or a namespace
    /// given on the command line (`None` otherwise). A bad namespace is a usage error.
    pub fn for_run(
        config: &AppConfig,
        flag: bool,
        namespace: Option<&str>,
    ) -> Result<Option<Self>, BridgeError> {
        let mut ros = RosConfig::from_section(&config.ros).map_err(BridgeError::Config)?;
        if let Some(ns) = namespace {
            gelgrip_ros_wire::names::check_namespace(ns).map_err(BridgeError::Namespace)?;
            ros.namespace = ns.to_string();
        }
        if !(ros.enabled || flag || namespace.is_some()) {
            return Ok(None);
        }
        Self::start(config, &ros, config.hub.transport.clone()).map(Some)
    }

    /// The live link (the command side shares its session).
    pub fn link(&self) -> &LiveLink {
        &self.link
    }

    fn stamp(&mut self, host_us: u64, now_us: u64) -> Time {
        let offset = *self
            .unix_offset_us
            .get_or_insert_with(|| unix_now_us() - i128::from(now_us));
        let unix = (i128::from(host_us) + offset).max(0);
        Time::from_unix_us(u64::try_from(unix).unwrap_or(0))
    }

    fn publish(&mut self, report: &SetReport<'_>) {
        let now = report.now_us;
        if let Some(read) = report.servos
            && self.published_reads != Some(read.reads)
        {
            self.published_reads = Some(read.reads);
            let servos: Vec<ServoSample> = read
                .states
                .iter()
                .map(|s| ServoSample {
                    position_deg: s.position_deg,
                    velocity_rpm: Some(s.velocity_rpm),
                    current_ma: s.current_ma,
                })
                .collect();
            if !servos.is_empty() {
                let stamp = self.stamp(now, now);
                self.out.push(self.feed.joint_states(stamp, &servos));
            }
        }
        if let Some(set) = report.set {
            let capture = set.earliest_capture_host_us;
            let stamp = self.stamp(capture, now);
            let frames: Vec<(usize, &[u8])> = set
                .frames
                .iter()
                .map(|f| (usize::from(f.frame.sensor.0), &f.frame.jpeg[..]))
                .collect();
            self.feed.images(stamp, capture, &frames, &mut self.out);
            if let Some(g) = &report.gripper
                && g.sensed_seq == Some(set.trigger_seq)
                && let Some(fused) = g.fused
            {
                self.feed.readings(stamp, &fused.sensors, &mut self.out);
                for i in 0..fused.sensors.len() {
                    if self.feed.depth_due(i, capture)
                        && let Some(w) = g.depth_window(i)
                        && let Some(s) = self.feed.depth(stamp, capture, i, &w)
                    {
                        self.out.push(s);
                    }
                }
            }
        }
        let stamp = self.stamp(now, now);
        let input = self.diagnostics_input(report);
        if let Some(s) = self.feed.diagnostics(stamp, now, &input) {
            self.out.push(s);
        }
        for s in self.out.drain(..) {
            self.link.offer(s);
        }
    }

    fn diagnostics_input(&self, report: &SetReport<'_>) -> DiagnosticsInput {
        let stats = report.gate;
        let drops = drop_counts(&stats.drops);
        let servo_faults = report.servos.map_or_else(Vec::new, |read| {
            read.states
                .iter()
                .zip(&self.joints)
                .map(|(s, j)| {
                    (
                        j.clone(),
                        hardware_error_names(s.hardware_error)
                            .into_iter()
                            .map(str::to_string)
                            .collect(),
                    )
                })
                .collect()
        });
        DiagnosticsInput {
            transport: self.transport.clone(),
            sets: stats.sets,
            set_rate_hz: stats.set_rate_hz(),
            spread_us_p99: stats.spread_us_p99().unwrap_or(0),
            drops,
            servo_faults,
        }
    }
}

impl Observer for RosPublisher {
    /// Never fails and never waits (see the module's doc).
    fn observe(&mut self, report: &SetReport<'_>) -> Result<(), ObserverError> {
        self.publish(report);
        Ok(())
    }

    fn finish(&mut self) -> Result<(), ObserverError> {
        let c = self.link.counters();
        let (published, be, rel) = (
            c.published.load(std::sync::atomic::Ordering::Relaxed),
            c.dropped_best_effort
                .load(std::sync::atomic::Ordering::Relaxed),
            c.dropped_reliable
                .load(std::sync::atomic::Ordering::Relaxed),
        );
        self.link.finish();
        tracing::info!(
            published,
            dropped_best_effort = be,
            dropped_reliable = rel,
            "ROS 2 publisher finished"
        );
        Ok(())
    }
}
