//! What gelgrip publishes, topic by topic, from its own data: the table of docs/ros.md
//! turned into CDR samples. The live publisher (an observer of the run) and the MCAP export
//! (a replay of a recording) both feed this, so both carry the same messages at the same
//! rates. Rates are kept on the sets' capture times, so a replay decimates as the run did.

use gelgrip_controller::actuator::XM430_W350;
use gelgrip_controller::fusion::{SensorReading, SlipState};
use gelgrip_controller::runtime::report::DepthWindow;
use gelgrip_ros_wire::catalog;
use gelgrip_ros_wire::msgs::{
    CompressedImage, DepthImage, DiagnosticArray, DiagnosticStatus, Header, JointState, Level,
    SlipCode, TactileContact, TactileContacts, TactileSlip, Time, WrenchStamped,
};
use gelgrip_ros_wire::names::{NameError, Reliability, qualify, ros_name};
use gelgrip_ros_wire::{Message, MsgType};

use super::config::{DepthMode, RosConfig};

/// One topic gelgrip publishes.
#[derive(Debug, Clone)]
pub struct Topic {
    /// Fully qualified name (`/gelgrip/joint_states`).
    pub name: String,
    /// Its type.
    pub ty: &'static MsgType,
    /// Reliable, or best effort (may drop).
    pub reliability: Reliability,
}

/// One encoded message for a topic.
#[derive(Debug, Clone)]
pub struct Sample {
    /// Index into [`Feed::topics`].
    pub topic: usize,
    /// The header's stamp (capture time on the system clock).
    pub stamp: Time,
    /// CDR bytes.
    pub cdr: Vec<u8>,
}

/// One servo's reading, as the publisher needs it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ServoSample {
    /// Position, degrees.
    pub position_deg: f64,
    /// Velocity, rpm (`None`: not known, as in recordings).
    pub velocity_rpm: Option<f64>,
    /// Current, mA.
    pub current_ma: f64,
}

/// The figures of the `diagnostics` topic.
#[derive(Debug, Clone, Default)]
pub struct DiagnosticsInput {
    /// The hub's transport.
    pub transport: String,
    /// Sets emitted so far.
    pub sets: u64,
    /// Set rate, Hz.
    pub set_rate_hz: f64,
    /// Spread p99, µs.
    pub spread_us_p99: u64,
    /// Frames dropped, by reason.
    pub drops: Vec<(String, u64)>,
    /// Each servo's fault names (empty: none), by finger.
    pub servo_faults: Vec<(String, Vec<String>)>,
}

const TOPIC_JOINTS: usize = 0;
const TOPIC_DIAGNOSTICS: usize = 1;
const TOPIC_CONTACTS: usize = 2;
const TOPIC_SLIP: usize = 3;
/// Per sensor: image, depth, wrench, from this index on.
const FIRST_SENSOR_TOPIC: usize = 4;

/// Turns gelgrip's data into the topics' samples, keeping each topic's rate.
#[derive(Debug)]
pub struct Feed {
    topics: Vec<Topic>,
    sensors: Vec<String>,
    joints: Vec<String>,
    image_period_us: Option<u64>,
    depth_period_us: Option<u64>,
    /// Whether depth images are the whole frame (else the window).
    depth_full: bool,
    next_image_us: Vec<Option<u64>>,
    next_depth_us: Vec<Option<u64>>,
    next_diagnostics_us: Option<u64>,
}

/// The period of a rate (`None`: 0 Hz, never).
fn period_us(rate_hz: f64) -> Option<u64> {
    (rate_hz > 0.0).then(|| (1e6 / rate_hz).round() as u64)
}

/// Whether a topic whose next send is due at `next` is due at `now`.
fn due(next: Option<u64>, period: Option<u64>, now: u64) -> bool {
    period.is_some() && next.is_none_or(|n| now >= n)
}

/// The next due time after a send at `now`: one period after the last due time, so a 10 Hz
/// topic keeps 10 Hz on average on a 34 Hz hub; one period after `now` after a gap.
fn next_due(next: Option<u64>, period: Option<u64>, now: u64) -> Option<u64> {
    let p = period?;
    Some(match next {
        Some(n) if now.saturating_sub(n) < p => n + p,
        _ => now + p,
    })
}

impl Feed {
    /// The topics of a hand with these sensor ids and finger (joint) names.
    pub fn new(
        config: &RosConfig,
        sensor_ids: &[String],
        joints: &[String],
    ) -> Result<Self, NameError> {
        let ns = config.namespace.as_str();
        let mut topics = vec![
            Topic {
                name: qualify(ns, "joint_states"),
                ty: &catalog::JOINT_STATE,
                reliability: Reliability::Reliable,
            },
            Topic {
                name: qualify(ns, "diagnostics"),
                ty: &catalog::DIAGNOSTIC_ARRAY,
                reliability: Reliability::Reliable,
            },
            Topic {
                name: qualify(ns, "tactile/contacts"),
                ty: &catalog::TACTILE_CONTACTS,
                reliability: Reliability::Reliable,
            },
            Topic {
                name: qualify(ns, "tactile/slip"),
                ty: &catalog::TACTILE_SLIP,
                reliability: Reliability::Reliable,
            },
        ];
        let mut sensors = Vec::new();
        for id in sensor_ids {
            let s = ros_name(id)?;
            topics.push(Topic {
                name: qualify(ns, &format!("tactile/{s}/image/compressed")),
                ty: &catalog::COMPRESSED_IMAGE,
                reliability: Reliability::BestEffort,
            });
            topics.push(Topic {
                name: qualify(ns, &format!("tactile/{s}/depth")),
                ty: &catalog::IMAGE,
                reliability: Reliability::BestEffort,
            });
            topics.push(Topic {
                name: qualify(ns, &format!("tactile/{s}/wrench")),
                ty: &catalog::WRENCH_STAMPED,
                reliability: Reliability::Reliable,
            });
            sensors.push(s);
        }
        let depth_rate = match config.depth {
            DepthMode::Window | DepthMode::Full => config.depth_rate_hz,
            DepthMode::Off => 0.0,
        };
        Ok(Self {
            topics,
            next_image_us: vec![None; sensors.len()],
            next_depth_us: vec![None; sensors.len()],
            sensors,
            joints: joints.to_vec(),
            image_period_us: period_us(config.image_rate_hz),
            depth_period_us: period_us(depth_rate),
            depth_full: config.depth == DepthMode::Full,
            next_diagnostics_us: None,
        })
    }

    /// The topics, in a fixed order (samples refer to them by index).
    pub fn topics(&self) -> &[Topic] {
        &self.topics
    }

    /// Whether sensor `i`'s depth image is due at `capture_host_us` (so the caller copies
    /// the depth window only when it is).
    pub fn depth_due(&self, i: usize, capture_host_us: u64) -> bool {
        due(
            self.next_depth_us.get(i).copied().flatten(),
            self.depth_period_us,
            capture_host_us,
        )
    }

    /// `joint_states` from one servo read.
    pub fn joint_states(&self, stamp: Time, servos: &[ServoSample]) -> Sample {
        let n = servos.len().min(self.joints.len());
        let servos = &servos[..n];
        let msg = JointState {
            header: Header {
                stamp,
                frame_id: String::new(),
            },
            name: self.joints[..n].to_vec(),
            position_rad: servos.iter().map(|s| s.position_deg.to_radians()).collect(),
            // Empty when any velocity is unknown (ROS allows an empty `velocity`).
            velocity_rad_s: servos
                .iter()
                .map(|s| s.velocity_rpm.map(|v| v * std::f64::consts::TAU / 60.0))
                .collect::<Option<Vec<f64>>>()
                .unwrap_or_default(),
            effort_nm: servos
                .iter()
                .map(|s| s.current_ma * XM430_W350.torque_nm_per_ma())
                .collect(),
        };
        Sample {
            topic: TOPIC_JOINTS,
            stamp,
            cdr: msg.to_cdr(),
        }
    }

    /// A gated set's compressed images (those due), as the hub delivered them: `frames` are
    /// (sensor index, JPEG).
    pub fn images(
        &mut self,
        stamp: Time,
        capture_host_us: u64,
        frames: &[(usize, &[u8])],
        out: &mut Vec<Sample>,
    ) {
        for &(i, jpeg) in frames {
            let Some(next) = self.next_image_us.get_mut(i) else {
                continue;
            };
            if !due(*next, self.image_period_us, capture_host_us) {
                continue;
            }
            *next = next_due(*next, self.image_period_us, capture_host_us);
            let msg = CompressedImage {
                header: self.header(stamp, i),
                format: "jpeg",
                data: jpeg,
            };
            out.push(Sample {
                topic: FIRST_SENSOR_TOPIC + 3 * i,
                stamp,
                cdr: msg.to_cdr(),
            });
        }
    }

    /// Sensor `i`'s depth image from its window (call when [`Feed::depth_due`]): the window
    /// itself, or with `depth = "full"` the whole frame, zero outside the window. `None`
    /// for a window that does not fit its frame.
    pub fn depth(
        &mut self,
        stamp: Time,
        capture_host_us: u64,
        i: usize,
        w: &DepthWindow,
    ) -> Option<Sample> {
        let next = self.next_depth_us.get_mut(i)?;
        *next = next_due(*next, self.depth_period_us, capture_host_us);
        let (width, height, depth_m) = if self.depth_full {
            full_frame_m(w)?
        } else {
            let depth_m: Vec<f32> = w.depth_mm.iter().map(|d| d * 1e-3).collect();
            (w.width, w.height, depth_m)
        };
        let msg = DepthImage {
            header: self.header(stamp, i),
            height: u32::try_from(height).ok()?,
            width: u32::try_from(width).ok()?,
            depth_m: &depth_m,
        };
        Some(Sample {
            topic: FIRST_SENSOR_TOPIC + 3 * i + 1,
            stamp,
            cdr: msg.to_cdr(),
        })
    }

    /// A sensed set's wrenches (one per sensor with a reading), contacts and slip.
    pub fn readings(&self, stamp: Time, readings: &[Option<SensorReading>], out: &mut Vec<Sample>) {
        let mut contacts = Vec::with_capacity(self.sensors.len());
        for (i, name) in self.sensors.iter().enumerate() {
            let r = readings.get(i).copied().flatten();
            if let Some(r) = r {
                let msg = WrenchStamped {
                    header: self.header(stamp, i),
                    force_n: [0.0, 0.0, r.force_n],
                    torque_nm: [0.0; 3],
                };
                out.push(Sample {
                    topic: FIRST_SENSOR_TOPIC + 3 * i + 2,
                    stamp,
                    cdr: msg.to_cdr(),
                });
            }
            contacts.push(contact(name, r));
        }
        let header = Header {
            stamp,
            frame_id: String::new(),
        };
        let slip = slip(&self.sensors, readings, header.clone());
        let msg = TactileContacts { header, contacts };
        out.push(Sample {
            topic: TOPIC_CONTACTS,
            stamp,
            cdr: msg.to_cdr(),
        });
        out.push(Sample {
            topic: TOPIC_SLIP,
            stamp,
            cdr: slip.to_cdr(),
        });
    }

    /// `diagnostics`, once a second of host time.
    pub fn diagnostics(
        &mut self,
        stamp: Time,
        now_us: u64,
        d: &DiagnosticsInput,
    ) -> Option<Sample> {
        if !due(self.next_diagnostics_us, Some(1_000_000), now_us) {
            return None;
        }
        self.next_diagnostics_us = next_due(self.next_diagnostics_us, Some(1_000_000), now_us);
        let dropped: u64 = d.drops.iter().map(|(_, n)| n).sum();
        let mut values = vec![
            ("sets".to_string(), d.sets.to_string()),
            ("set_rate_hz".into(), format!("{:.2}", d.set_rate_hz)),
            ("spread_us_p99".into(), d.spread_us_p99.to_string()),
        ];
        values.extend(
            d.drops
                .iter()
                .map(|(k, n)| (format!("drops_{k}"), n.to_string())),
        );
        let sync = DiagnosticStatus {
            level: if dropped > 0 { Level::Warn } else { Level::Ok },
            name: "gelgrip: sync".into(),
            message: format!("{:.1} sets/s, {dropped} frames dropped", d.set_rate_hz),
            hardware_id: d.transport.clone(),
            values,
        };
        let faulty: Vec<String> = d
            .servo_faults
            .iter()
            .filter(|(_, f)| !f.is_empty())
            .map(|(finger, f)| format!("{finger}: {}", f.join(", ")))
            .collect();
        let servos = DiagnosticStatus {
            level: if faulty.is_empty() {
                Level::Ok
            } else {
                Level::Error
            },
            name: "gelgrip: servos".into(),
            message: if faulty.is_empty() {
                "no faults".into()
            } else {
                faulty.join("; ")
            },
            hardware_id: "dynamixel".into(),
            values: d
                .servo_faults
                .iter()
                .map(|(finger, f)| (finger.clone(), f.join(",")))
                .collect(),
        };
        let msg = DiagnosticArray {
            header: Header {
                stamp,
                frame_id: String::new(),
            },
            status: vec![sync, servos],
        };
        Some(Sample {
            topic: TOPIC_DIAGNOSTICS,
            stamp,
            cdr: msg.to_cdr(),
        })
    }

    fn header(&self, stamp: Time, sensor: usize) -> Header {
        Header {
            stamp,
            frame_id: self.sensors.get(sensor).cloned().unwrap_or_default(),
        }
    }
}

/// The gate's drop counts by reason key.
pub fn drop_counts(counts: &gelgrip_controller::gate::ReasonCounts) -> Vec<(String, u64)> {
    serde_json::to_value(counts)
        .ok()
        .and_then(|v| v.as_object().cloned())
        .map(|m| {
            m.into_iter()
                .map(|(k, v)| (k, v.as_u64().unwrap_or(0)))
                .collect()
        })
        .unwrap_or_default()
}

/// The window `w` placed in its whole frame, in metres, zero outside it: `(width, height,
/// depth)`. `None` when the window's depth does not fill it or it does not fit the frame.
fn full_frame_m(w: &DepthWindow) -> Option<(usize, usize, Vec<f32>)> {
    let (fw, fh) = w.frame_px;
    let (x0, y0) = w.origin_px;
    if w.depth_mm.len() != w.width.checked_mul(w.height)?
        || x0.checked_add(w.width)? > fw
        || y0.checked_add(w.height)? > fh
    {
        return None;
    }
    let mut depth_m = vec![0.0f32; fw.checked_mul(fh)?];
    if w.width > 0 {
        for (row, src) in w.depth_mm.chunks_exact(w.width).enumerate() {
            let start = (y0 + row) * fw + x0;
            for (d, s) in depth_m[start..start + w.width].iter_mut().zip(src) {
                *d = s * 1e-3;
            }
        }
    }
    Some((fw, fh, depth_m))
}

/// One sensor's contact summary in SI units (zeros, not in contact, without a reading).
fn contact(name: &str, r: Option<SensorReading>) -> TactileContact {
    let Some(r) = r else {
        return TactileContact {
            sensor: name.to_string(),
            ..TactileContact::default()
        };
    };
    let (cx_mm, cy_mm) = r.centroid_mm.unwrap_or((0.0, 0.0));
    TactileContact {
        sensor: name.to_string(),
        in_contact: r.in_contact,
        area_m2: r.area_mm2 * 1e-6,
        max_depth_m: r.max_depth_mm * 1e-3,
        // Volume over area is the mean indentation over the contact.
        mean_depth_m: if r.area_mm2 > 0.0 {
            r.volume_mm3 / r.area_mm2 * 1e-3
        } else {
            0.0
        },
        centroid_m: [cx_mm * 1e-3, cy_mm * 1e-3, 0.0],
        volume_m3: r.volume_mm3 * 1e-9,
        force_n: r.force_n,
    }
}

/// `tactile/slip` of one set: each sensor's slip (unknown where its reading is missing or
/// cannot tell), and the grasp's, the most advanced state of any sensor's.
fn slip(sensors: &[String], readings: &[Option<SensorReading>], header: Header) -> TactileSlip {
    let mut msg = TactileSlip {
        header,
        ..TactileSlip::default()
    };
    for (i, name) in sensors.iter().enumerate() {
        let known = readings.get(i).copied().flatten().and_then(|r| r.slip);
        let (state, stick_ratio, shear_m) = match known {
            Some(s) => (
                slip_code(s.state),
                s.stick_ratio,
                [s.shear_mm[0] * 1e-3, s.shear_mm[1] * 1e-3, 0.0],
            ),
            None => (SlipCode::Unknown, 1.0, [0.0; 3]),
        };
        msg.sensor.push(name.clone());
        msg.state.push(state);
        msg.stick_ratio.push(stick_ratio);
        msg.shear_m.push(shear_m);
        if state as u8 > msg.grasp_state as u8 {
            msg.grasp_state = state;
        }
    }
    msg
}

fn slip_code(state: SlipState) -> SlipCode {
    match state {
        SlipState::None => SlipCode::None,
        SlipState::Incipient => SlipCode::Incipient,
        SlipState::Gross => SlipCode::Gross,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gelgrip_controller::fusion::SensorSlip;

    fn feed(image_rate_hz: f64) -> Feed {
        let config = RosConfig {
            image_rate_hz,
            ..RosConfig::default()
        };
        let ids = ["f1.tip".to_string(), "palm".to_string()];
        Feed::new(&config, &ids, &["f1".into(), "f2".into(), "f3".into()]).expect("names")
    }

    #[test]
    fn topics_are_named_under_the_namespace() {
        let f = feed(10.0);
        let names: Vec<&str> = f.topics().iter().map(|t| t.name.as_str()).collect();
        assert!(names.contains(&"/gelgrip/tactile/f1_tip/image/compressed"));
        assert!(names.contains(&"/gelgrip/tactile/palm/wrench"));
        assert!(names.contains(&"/gelgrip/tactile/contacts"));
        assert!(names.contains(&"/gelgrip/tactile/slip"));
        assert_eq!(names.len(), 4 + 2 * 3);
    }

    #[test]
    fn images_keep_their_rate_on_a_34_hz_hub() {
        let mut f = feed(10.0);
        let jpeg = [1u8, 2, 3];
        let mut out = Vec::new();
        // 10 s of sets at 34 Hz.
        for k in 0..340u64 {
            let t = k * 1_000_000 / 34;
            f.images(Time::default(), t, &[(0, &jpeg), (1, &jpeg)], &mut out);
        }
        let per_sensor = out.iter().filter(|s| s.topic == FIRST_SENSOR_TOPIC).count();
        assert!(
            (95..=101).contains(&per_sensor),
            "{per_sensor} images in 10 s"
        );
        let mut none = feed(0.0);
        out.clear();
        none.images(Time::default(), 0, &[(0, &jpeg)], &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn a_full_frame_depth_image_holds_the_window_at_its_origin() {
        let w = DepthWindow {
            depth_mm: vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            width: 3,
            height: 2,
            origin_px: (1, 2),
            frame_px: (5, 4),
            contact_mm: 0.05,
        };
        let (fw, fh, d) = full_frame_m(&w).expect("it fits");
        assert_eq!((fw, fh, d.len()), (5, 4, 20));
        let at = |x: usize, y: usize| d[y * fw + x];
        assert!((at(1, 2) - 1e-3).abs() < 1e-9 && (at(3, 3) - 6e-3).abs() < 1e-9);
        let inside = (2..4).flat_map(|y| (1..4).map(move |x| (x, y)));
        let sum_inside: f32 = inside.map(|(x, y)| at(x, y)).sum();
        assert!(
            (d.iter().sum::<f32>() - sum_inside).abs() < 1e-9,
            "zero outside"
        );
        // A window past the frame's edge, or short of its pixels, is not placed.
        let past = DepthWindow {
            origin_px: (3, 2),
            ..w.clone()
        };
        assert!(full_frame_m(&past).is_none());
        let short = DepthWindow {
            depth_mm: vec![1.0],
            ..w
        };
        assert!(full_frame_m(&short).is_none());
    }

    #[test]
    fn contacts_are_in_si_units() {
        let r = SensorReading {
            in_contact: true,
            area_mm2: 20.0,
            max_depth_mm: 0.5,
            volume_mm3: 4.0,
            force_n: 1.5,
            centroid_mm: Some((1.0, -2.0)),
            slip: None,
        };
        let c = contact("f1_tip", Some(r));
        assert!((c.area_m2 - 2e-5).abs() < 1e-12);
        assert!((c.mean_depth_m - 2e-4).abs() < 1e-12);
        assert!((c.volume_m3 - 4e-9).abs() < 1e-18);
        assert_eq!(c.centroid_m, [1e-3, -2e-3, 0.0]);
        assert!(!contact("palm", None).in_contact);
    }

    #[test]
    fn slip_is_per_sensor_in_si_units_and_the_grasp_takes_the_worst() {
        let reading = |slip| SensorReading {
            in_contact: true,
            slip,
            ..SensorReading::default()
        };
        let incipient = SensorSlip {
            shear_mm: [0.25, -0.5],
            stick_ratio: 0.5,
            state: SlipState::Incipient,
        };
        let names = ["f1_tip".to_string(), "f1_base".into(), "palm".into()];
        let readings = [
            Some(reading(Some(SensorSlip::default()))),
            Some(reading(Some(incipient))),
            Some(reading(None)),
        ];
        let m = slip(&names, &readings, Header::default());
        assert_eq!(m.sensor, names);
        assert_eq!(
            m.state,
            [SlipCode::None, SlipCode::Incipient, SlipCode::Unknown]
        );
        assert_eq!(m.stick_ratio, [0.0, 0.5, 1.0]);
        assert_eq!(m.shear_m[1], [2.5e-4, -5e-4, 0.0]);
        assert_eq!(m.grasp_state, SlipCode::Incipient);
        // A missing reading is unknown; with none known the grasp is unknown.
        let none = slip(&names[..1], &[None], Header::default());
        assert_eq!(
            (none.state[0], none.grasp_state),
            (SlipCode::Unknown, SlipCode::Unknown)
        );
    }

    #[test]
    fn every_sensed_set_carries_a_slip_message() {
        let f = feed(10.0);
        let mut out = Vec::new();
        f.readings(Time::default(), &[None, None], &mut out);
        let slip: Vec<_> = out.iter().filter(|s| s.topic == TOPIC_SLIP).collect();
        assert_eq!(slip.len(), 1);
        assert_eq!(f.topics()[TOPIC_SLIP].name, "/gelgrip/tactile/slip");
    }
}
