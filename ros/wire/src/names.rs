//! rmw_zenoh's naming: ROS names from sensor ids, data keys
//! (`<domain>/<topic>/<DDS type>/RIHS01_<hash>`), liveliness tokens
//! (`@ros2_lv/<domain>/<session>/<node id>/<entity id>/<NN|MP>/<enclave>/<namespace>/<node>[/<topic>/<type>/<hash>/<qos>]`
//! with `/` mangled to `%`), the compact QoS string, and the per-sample attachment
//! (sequence number, source timestamp, GID). Formats as in rmw_zenoh's `docs/design.md` and
//! `liveliness_utils.cpp` (Jazzy, zenoh 1.x).

use sha2::{Digest, Sha256};
use thiserror::Error;

use crate::types::MsgType;

/// A name that ROS would refuse.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum NameError {
    /// A namespace must start with `/`, not end with one (unless it is `/`), and hold only
    /// letters, digits, `_` and `/` separators between non-empty tokens that do not start
    /// with a digit.
    #[error(
        "namespace `{0}` is not a ROS namespace: it must start with `/` and hold only \
         letters, digits and `_` between single slashes, each part not starting with a digit"
    )]
    Namespace(String),
    /// A sensor id that gives no ROS name.
    #[error(
        "sensor id `{0}` gives no ROS name: only letters, digits, `_` and `.` (which becomes `_`)"
    )]
    Sensor(String),
}

/// A sensor id as a ROS name: `.` becomes `_` (`f1.tip` → `f1_tip`).
pub fn ros_name(sensor_id: &str) -> Result<String, NameError> {
    let s: String = sensor_id.replace('.', "_");
    let ok = !s.is_empty()
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !s.starts_with(|c: char| c.is_ascii_digit());
    if ok {
        Ok(s)
    } else {
        Err(NameError::Sensor(sensor_id.to_string()))
    }
}

/// `ns` checked as a ROS namespace (`/gelgrip`, `/robot/left_hand`, or `/`).
pub fn check_namespace(ns: &str) -> Result<(), NameError> {
    let bad = || NameError::Namespace(ns.to_string());
    if ns == "/" {
        return Ok(());
    }
    let rest = ns.strip_prefix('/').ok_or_else(bad)?;
    for part in rest.split('/') {
        let ok = !part.is_empty()
            && part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            && !part.starts_with(|c: char| c.is_ascii_digit());
        if !ok {
            return Err(bad());
        }
    }
    Ok(())
}

/// The fully qualified name of `relative` in namespace `ns`: `/gelgrip/joint_states`.
pub fn qualify(ns: &str, relative: &str) -> String {
    if ns == "/" {
        format!("/{relative}")
    } else {
        format!("{ns}/{relative}")
    }
}

/// A name mangled for a liveliness token: every `/` becomes `%`, and an empty name is `%`.
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

/// The data key of topic `fq_topic` (`/gelgrip/joint_states`) of type `ty` in `domain`:
/// `0/gelgrip/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_…`.
pub fn data_key(domain: u32, fq_topic: &str, ty: &'static MsgType) -> String {
    format!(
        "{domain}/{}/{}/{}",
        fq_topic.trim_matches('/'),
        ty.dds_name(),
        ty.rihs01()
    )
}

/// A publisher's reliability.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reliability {
    /// Reliable (rmw 1).
    Reliable,
    /// Best effort (rmw 2).
    BestEffort,
}

/// A publisher's QoS: volatile, keep last `depth`, reliability as given; deadline, lifespan
/// and liveliness at their defaults.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Reliability.
    pub reliability: Reliability,
    /// Keep-last depth.
    pub depth: u32,
}

impl Qos {
    /// The compact string of a liveliness token:
    /// `<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:<lifespan s>,<ns>:<liveliness>,<s>,<ns>`,
    /// each part empty where it equals rmw_zenoh's default (reliable, transient local, keep
    /// last 42, infinite deadline and lifespan, automatic liveliness, infinite lease).
    pub fn token_text(self) -> String {
        let reliability = match self.reliability {
            Reliability::Reliable => "",
            Reliability::BestEffort => "2",
        };
        // Volatile (2) is not rmw_zenoh's default durability (transient local).
        let depth = if self.depth == 42 {
            String::new()
        } else {
            self.depth.to_string()
        };
        format!("{reliability}:2:,{depth}:,:,:,,")
    }
}

/// The node this process is on the graph: its session, namespace and name, in a domain.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeIdentity {
    /// The ROS domain id.
    pub domain: u32,
    /// The Zenoh session id, as text.
    pub session_id: String,
    /// The namespace (`/gelgrip`).
    pub namespace: String,
    /// The node name (`gelgrip`).
    pub name: String,
}

/// The node's id within its session, and the first publisher's (rmw_zenoh counts the
/// entities of a context from 0).
pub const NODE_ID: u32 = 0;

impl NodeIdentity {
    fn prefix(&self, entity_id: u32, kind: &str) -> String {
        format!(
            "@ros2_lv/{}/{}/{NODE_ID}/{entity_id}/{kind}/%/{}/{}",
            self.domain,
            self.session_id,
            mangle(&self.namespace),
            mangle(&self.name)
        )
    }

    /// The node's liveliness token.
    pub fn node_token(&self) -> String {
        self.prefix(NODE_ID, "NN")
    }

    /// The liveliness token of publisher `entity_id` (from 1) on `fq_topic`.
    pub fn publisher_token(
        &self,
        entity_id: u32,
        fq_topic: &str,
        ty: &'static MsgType,
        qos: Qos,
    ) -> String {
        format!(
            "{}/{}/{}/{}/{}",
            self.prefix(entity_id, "MP"),
            mangle(fq_topic),
            ty.dds_name(),
            ty.rihs01(),
            qos.token_text()
        )
    }
}

impl NodeIdentity {
    /// The liveliness token of service server `entity_id` (`SS`) at `fq_service`
    /// (`/gelgrip/estop`, `/gelgrip/gripper_cmd/_action/send_goal`) of service type `ty`,
    /// with the services' QoS (reliable, volatile, keep last 10).
    pub fn service_token(&self, entity_id: u32, fq_service: &str, ty: &'static MsgType) -> String {
        let qos = Qos {
            reliability: Reliability::Reliable,
            depth: 10,
        };
        format!(
            "{}/{}/{}/{}/{}",
            self.prefix(entity_id, "SS"),
            mangle(fq_service),
            ty.dds_name(),
            ty.rihs01(),
            qos.token_text()
        )
    }
}

/// A request's attachment read back: its sequence number and the client's GID (`None`:
/// not the 33 bytes of [`attachment`]).
pub fn parse_attachment(bytes: &[u8]) -> Option<(i64, [u8; 16])> {
    if bytes.len() != 33 || bytes[16] != 16 {
        return None;
    }
    let mut seq = [0u8; 8];
    seq.copy_from_slice(&bytes[..8]);
    let mut g = [0u8; 16];
    g.copy_from_slice(&bytes[17..]);
    Some((i64::from_le_bytes(seq), g))
}

/// A publisher's GID: the first 16 bytes of the SHA-256 of its liveliness token (unique
/// as the token is; rmw_zenoh hashes the token too, with another hash).
pub fn gid(token: &str) -> [u8; 16] {
    let d = Sha256::digest(token.as_bytes());
    let mut g = [0u8; 16];
    g.copy_from_slice(&d[..16]);
    g
}

/// The attachment of one sample: sequence number (i64 LE), source timestamp (ns since the
/// epoch, i64 LE), the GID's length (16) and the GID.
pub fn attachment(sequence: i64, source_unix_ns: i64, gid: &[u8; 16]) -> [u8; 33] {
    let mut a = [0u8; 33];
    a[..8].copy_from_slice(&sequence.to_le_bytes());
    a[8..16].copy_from_slice(&source_unix_ns.to_le_bytes());
    a[16] = 16;
    a[17..].copy_from_slice(gid);
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog;

    #[test]
    fn sensor_ids_become_ros_names() {
        assert_eq!(ros_name("f1.tip").as_deref(), Ok("f1_tip"));
        assert_eq!(ros_name("palm").as_deref(), Ok("palm"));
        assert!(ros_name("f1-tip").is_err());
        assert!(ros_name("1tip").is_err());
        assert!(ros_name("").is_err());
    }

    #[test]
    fn namespaces_are_checked() {
        for ok in ["/", "/gelgrip", "/robot/left_hand"] {
            assert_eq!(check_namespace(ok), Ok(()), "{ok}");
        }
        for bad in ["gelgrip", "/gelgrip/", "//a", "/a b", "/1a", ""] {
            assert!(check_namespace(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn keys_and_tokens_follow_rmw_zenoh() {
        let topic = qualify("/gelgrip", "joint_states");
        let key = data_key(0, &topic, &catalog::JOINT_STATE);
        let hash = catalog::JOINT_STATE.rihs01();
        assert_eq!(
            key,
            format!("0/gelgrip/joint_states/sensor_msgs::msg::dds_::JointState_/{hash}")
        );
        let node = NodeIdentity {
            domain: 3,
            session_id: "abc".into(),
            namespace: "/gelgrip".into(),
            name: "gelgrip".into(),
        };
        assert_eq!(
            node.node_token(),
            "@ros2_lv/3/abc/0/0/NN/%/%gelgrip/gelgrip"
        );
        let qos = Qos {
            reliability: Reliability::BestEffort,
            depth: 5,
        };
        assert_eq!(
            node.publisher_token(4, &topic, &catalog::JOINT_STATE, qos),
            format!(
                "@ros2_lv/3/abc/0/4/MP/%/%gelgrip/gelgrip/%gelgrip%joint_states/\
                 sensor_msgs::msg::dds_::JointState_/{hash}/2:2:,5:,:,:,,"
            )
        );
        assert_eq!(
            Qos {
                reliability: Reliability::Reliable,
                depth: 42
            }
            .token_text(),
            ":2:,:,:,:,,"
        );
    }

    #[test]
    fn the_attachment_is_33_bytes() {
        let g = gid("x");
        let a = attachment(7, 1_000_000_000, &g);
        assert_eq!(&a[..8], &7i64.to_le_bytes());
        assert_eq!(&a[8..16], &1_000_000_000i64.to_le_bytes());
        assert_eq!(a[16], 16);
        assert_eq!(&a[17..], &g);
        assert_ne!(gid("x"), gid("y"));
        assert_eq!(parse_attachment(&a), Some((7, g)));
        assert_eq!(parse_attachment(&a[..32]), None);
    }

    #[test]
    fn service_tokens_are_ss_with_the_services_qos() {
        let node = NodeIdentity {
            domain: 0,
            session_id: "abc".into(),
            namespace: "/gelgrip".into(),
            name: "gelgrip".into(),
        };
        let t = node.service_token(100, "/gelgrip/estop", &crate::services::TRIGGER);
        assert_eq!(
            t,
            format!(
                "@ros2_lv/0/abc/0/100/SS/%/%gelgrip/gelgrip/%gelgrip%estop/\
                 std_srvs::srv::dds_::Trigger_/{}/:2:,10:,:,:,,",
                crate::services::TRIGGER.rihs01()
            )
        );
    }
}
