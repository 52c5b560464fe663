//! The messages, as plain Rust values with units in their names, and their CDR encoding.
//! Each implements [`Message`]: its type ([`MsgType`]) and its fields written in the
//! declared order.

use crate::catalog;
use crate::cdr::CdrWriter;
use crate::types::MsgType;

/// A message that encodes to CDR.
pub trait Message {
    /// Its type.
    fn msg_type() -> &'static MsgType
    where
        Self: Sized;

    /// Write the fields (no header) into `w`.
    fn write(&self, w: &mut CdrWriter);

    /// The CDR bytes, encapsulation header included.
    fn to_cdr(&self) -> Vec<u8> {
        let mut w = CdrWriter::with_capacity(self.size_hint());
        self.write(&mut w);
        w.into_bytes()
    }

    /// About how many bytes the encoding takes (to size the buffer once).
    fn size_hint(&self) -> usize {
        128
    }
}

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the UNIX epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// The time `unix_us` µs after the epoch (seconds saturate in 2038, as `int32` does).
    pub fn from_unix_us(unix_us: u64) -> Self {
        Self {
            sec: i32::try_from(unix_us / 1_000_000).unwrap_or(i32::MAX),
            nanosec: u32::try_from((unix_us % 1_000_000) * 1000).unwrap_or(0),
        }
    }

    /// Nanoseconds since the epoch.
    pub fn unix_ns(self) -> u64 {
        u64::try_from(self.sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.nanosec)
    }

    fn write(self, w: &mut CdrWriter) {
        w.i32(self.sec);
        w.u32(self.nanosec);
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Header {
    /// Capture time on the system clock.
    pub stamp: Time,
    /// The frame (a sensor's ROS name, or empty).
    pub frame_id: String,
}

impl Header {
    fn write(&self, w: &mut CdrWriter) {
        self.stamp.write(w);
        w.string(&self.frame_id);
    }
}

/// `sensor_msgs/msg/JointState`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JointState {
    /// Header.
    pub header: Header,
    /// The joints' names.
    pub name: Vec<String>,
    /// Positions, rad.
    pub position_rad: Vec<f64>,
    /// Velocities, rad/s.
    pub velocity_rad_s: Vec<f64>,
    /// Efforts, N·m.
    pub effort_nm: Vec<f64>,
}

impl Message for JointState {
    fn msg_type() -> &'static MsgType {
        &catalog::JOINT_STATE
    }
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.string_seq(&self.name);
        w.f64_seq(&self.position_rad);
        w.f64_seq(&self.velocity_rad_s);
        w.f64_seq(&self.effort_nm);
    }
}

/// `sensor_msgs/msg/CompressedImage`, borrowing the compressed bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct CompressedImage<'a> {
    /// Header.
    pub header: Header,
    /// `jpeg`.
    pub format: &'a str,
    /// The compressed image.
    pub data: &'a [u8],
}

impl Message for CompressedImage<'_> {
    fn msg_type() -> &'static MsgType {
        &catalog::COMPRESSED_IMAGE
    }
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.string(self.format);
        w.bytes(self.data);
    }
    fn size_hint(&self) -> usize {
        64 + self.header.frame_id.len() + self.data.len()
    }
}

/// `sensor_msgs/msg/Image` with encoding `32FC1`: one `float32` per pixel, row major,
/// little endian.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage<'a> {
    /// Header.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Depth per pixel, m (`height × width`).
    pub depth_m: &'a [f32],
}

impl Message for DepthImage<'_> {
    fn msg_type() -> &'static MsgType {
        &catalog::IMAGE
    }
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.u32(self.height);
        w.u32(self.width);
        w.string("32FC1");
        w.u8(0);
        w.u32(self.width.saturating_mul(4));
        w.f32_as_bytes(self.depth_m);
    }
    fn size_hint(&self) -> usize {
        64 + self.header.frame_id.len() + 4 * self.depth_m.len()
    }
}

/// `geometry_msgs/msg/WrenchStamped`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WrenchStamped {
    /// Header.
    pub header: Header,
    /// Force (x, y, z), N.
    pub force_n: [f64; 3],
    /// Torque (x, y, z), N·m.
    pub torque_nm: [f64; 3],
}

impl Message for WrenchStamped {
    fn msg_type() -> &'static MsgType {
        &catalog::WRENCH_STAMPED
    }
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        for v in self.force_n.iter().chain(&self.torque_nm) {
            w.f64(*v);
        }
    }
}

/// `gelgrip_msgs/msg/TactileContact`: one sensor's contact summary, SI units.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TactileContact {
    /// The sensor's ROS name.
    pub sensor: String,
    /// In contact.
    pub in_contact: bool,
    /// Contact area, m².
    pub area_m2: f64,
    /// Deepest indentation, m.
    pub max_depth_m: f64,
    /// Mean indentation over the contact, m.
    pub mean_depth_m: f64,
    /// Contact centroid in the sensor's frame (x, y, z), m.
    pub centroid_m: [f64; 3],
    /// Indentation volume, m³.
    pub volume_m3: f64,
    /// Force proxy, N.
    pub force_n: f64,
}

impl TactileContact {
    fn write(&self, w: &mut CdrWriter) {
        w.string(&self.sensor);
        w.bool(self.in_contact);
        w.f64(self.area_m2);
        w.f64(self.max_depth_m);
        w.f64(self.mean_depth_m);
        for v in self.centroid_m {
            w.f64(v);
        }
        w.f64(self.volume_m3);
        w.f64(self.force_n);
    }
}

/// `gelgrip_msgs/msg/TactileContacts`: every sensor's contact summary of one set.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TactileContacts {
    /// Header.
    pub header: Header,
    /// One per sensor, in layout order.
    pub contacts: Vec<TactileContact>,
}

impl Message for TactileContacts {
    fn msg_type() -> &'static MsgType {
        &catalog::TACTILE_CONTACTS
    }
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.len(self.contacts.len());
        for c in &self.contacts {
            c.write(w);
        }
    }
    fn size_hint(&self) -> usize {
        64 + self.contacts.len() * 96
    }
}

/// `gelgrip_msgs/msg/TactileSlip`'s states (its `UNKNOWN`, `NONE`, `INCIPIENT`, `GROSS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SlipCode {
    /// The sensor cannot tell (a plain gel, no marker dots under the contact, no reading).
    #[default]
    Unknown = 0,
    /// Sticking.
    None = 1,
    /// Its rim slides, its centre sticks.
    Incipient = 2,
    /// It slides.
    Gross = 3,
}

/// `gelgrip_msgs/msg/TactileSlip`: every sensor's slip of one set, in parallel arrays (one
/// entry per sensor, in layout order), and the grasp's (the most advanced state).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TactileSlip {
    /// Header.
    pub header: Header,
    /// The sensors' ROS names.
    pub sensor: Vec<String>,
    /// Each sensor's state.
    pub state: Vec<SlipCode>,
    /// Each sensor's estimated stick ratio c/a (1 where the state is unknown).
    pub stick_ratio: Vec<f64>,
    /// Each sensor's shear, the mean shift of the gel's dots in the contact, in the
    /// sensor's frame (x, y, z), m (0 where the state is unknown).
    pub shear_m: Vec<[f64; 3]>,
    /// The grasp's state.
    pub grasp_state: SlipCode,
}

impl Message for TactileSlip {
    fn msg_type() -> &'static MsgType {
        &catalog::TACTILE_SLIP
    }
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.string_seq(&self.sensor);
        let codes: Vec<u8> = self.state.iter().map(|s| *s as u8).collect();
        w.bytes(&codes);
        w.f64_seq(&self.stick_ratio);
        w.len(self.shear_m.len());
        for v in self.shear_m.iter().flatten() {
            w.f64(*v);
        }
        w.u8(self.grasp_state as u8);
    }
    fn size_hint(&self) -> usize {
        64 + self.sensor.len() * 56
    }
}

/// `diagnostic_msgs/msg/DiagnosticStatus` levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// `OK`.
    Ok = 0,
    /// `WARN`.
    Warn = 1,
    /// `ERROR`.
    Error = 2,
    /// `STALE`.
    Stale = 3,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosticStatus {
    /// Level.
    pub level: Level,
    /// Name (`gelgrip: sync`).
    pub name: String,
    /// A sentence.
    pub message: String,
    /// The hardware (the hub's transport, a servo id).
    pub hardware_id: String,
    /// Key-value pairs.
    pub values: Vec<(String, String)>,
}

/// `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DiagnosticArray {
    /// Header.
    pub header: Header,
    /// The statuses.
    pub status: Vec<DiagnosticStatus>,
}

impl Message for DiagnosticArray {
    fn msg_type() -> &'static MsgType {
        &catalog::DIAGNOSTIC_ARRAY
    }
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.len(self.status.len());
        for s in &self.status {
            w.u8(s.level as u8);
            w.string(&s.name);
            w.string(&s.message);
            w.string(&s.hardware_id);
            w.len(s.values.len());
            for (k, v) in &s.values {
                w.string(k);
                w.string(v);
            }
        }
    }
    fn size_hint(&self) -> usize {
        512
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_splits_microseconds() {
        let t = Time::from_unix_us(1_700_000_000_123_456);
        assert_eq!(t.sec, 1_700_000_000);
        assert_eq!(t.nanosec, 123_456_000);
        assert_eq!(t.unix_ns(), 1_700_000_000_123_456_000);
    }

    #[test]
    fn a_depth_image_declares_its_row_size() {
        let d = [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0];
        let img = DepthImage {
            header: Header::default(),
            height: 2,
            width: 3,
            depth_m: &d,
        };
        let b = img.to_cdr();
        // stamp 8, frame_id "" (4 + 1, pad 3), height, width, "32FC1" (4 + 6), is_bigendian,
        // pad 1, step, count, data
        let step_at = 4 + 8 + 8 + 8 + 10 + 2;
        assert_eq!(&b[step_at..step_at + 4], &12u32.to_le_bytes());
        assert_eq!(&b[step_at + 4..step_at + 8], &24u32.to_le_bytes());
        assert_eq!(b.len(), step_at + 8 + 24);
    }
}
