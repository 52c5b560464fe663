//! The message types gelgrip publishes and records, and the types they refer to, as ROS 2
//! defines them (Jazzy): `builtin_interfaces`, `std_msgs`, `geometry_msgs`, `sensor_msgs`,
//! `diagnostic_msgs`, and this repository's `gelgrip_msgs` (`ros/gelgrip_msgs/msg/`, whose
//! files a test compares with these definitions).

use crate::types::{Constant, Field, FieldType as T, MsgType, Shape};

pub(crate) const fn one(name: &'static str, ty: T) -> Field {
    Field {
        name,
        ty,
        shape: Shape::One,
    }
}

pub(crate) const fn seq(name: &'static str, ty: T) -> Field {
    Field {
        name,
        ty,
        shape: Shape::Sequence,
    }
}

/// `builtin_interfaces/msg/Time`.
pub static TIME: MsgType = MsgType {
    name: "builtin_interfaces/msg/Time",
    fields: &[one("sec", T::Int32), one("nanosec", T::Uint32)],
    constants: &[],
};

/// `std_msgs/msg/Header`.
pub static HEADER: MsgType = MsgType {
    name: "std_msgs/msg/Header",
    fields: &[one("stamp", T::Msg(&TIME)), one("frame_id", T::String)],
    constants: &[],
};

/// `sensor_msgs/msg/JointState`.
pub static JOINT_STATE: MsgType = MsgType {
    name: "sensor_msgs/msg/JointState",
    fields: &[
        one("header", T::Msg(&HEADER)),
        seq("name", T::String),
        seq("position", T::Float64),
        seq("velocity", T::Float64),
        seq("effort", T::Float64),
    ],
    constants: &[],
};

/// `sensor_msgs/msg/CompressedImage`.
pub static COMPRESSED_IMAGE: MsgType = MsgType {
    name: "sensor_msgs/msg/CompressedImage",
    fields: &[
        one("header", T::Msg(&HEADER)),
        one("format", T::String),
        seq("data", T::Uint8),
    ],
    constants: &[],
};

/// `sensor_msgs/msg/Image`.
pub static IMAGE: MsgType = MsgType {
    name: "sensor_msgs/msg/Image",
    fields: &[
        one("header", T::Msg(&HEADER)),
        one("height", T::Uint32),
        one("width", T::Uint32),
        one("encoding", T::String),
        one("is_bigendian", T::Uint8),
        one("step", T::Uint32),
        seq("data", T::Uint8),
    ],
    constants: &[],
};

/// `geometry_msgs/msg/Vector3`.
pub static VECTOR3: MsgType = MsgType {
    name: "geometry_msgs/msg/Vector3",
    fields: &[
        one("x", T::Float64),
        one("y", T::Float64),
        one("z", T::Float64),
    ],
    constants: &[],
};

/// `geometry_msgs/msg/Point`.
pub static POINT: MsgType = MsgType {
    name: "geometry_msgs/msg/Point",
    fields: &[
        one("x", T::Float64),
        one("y", T::Float64),
        one("z", T::Float64),
    ],
    constants: &[],
};

/// `geometry_msgs/msg/Wrench`.
pub static WRENCH: MsgType = MsgType {
    name: "geometry_msgs/msg/Wrench",
    fields: &[
        one("force", T::Msg(&VECTOR3)),
        one("torque", T::Msg(&VECTOR3)),
    ],
    constants: &[],
};

/// `geometry_msgs/msg/WrenchStamped`.
pub static WRENCH_STAMPED: MsgType = MsgType {
    name: "geometry_msgs/msg/WrenchStamped",
    fields: &[
        one("header", T::Msg(&HEADER)),
        one("wrench", T::Msg(&WRENCH)),
    ],
    constants: &[],
};

/// `diagnostic_msgs/msg/KeyValue`.
pub static KEY_VALUE: MsgType = MsgType {
    name: "diagnostic_msgs/msg/KeyValue",
    fields: &[one("key", T::String), one("value", T::String)],
    constants: &[],
};

/// `diagnostic_msgs/msg/DiagnosticStatus`.
pub static DIAGNOSTIC_STATUS: MsgType = MsgType {
    name: "diagnostic_msgs/msg/DiagnosticStatus",
    fields: &[
        one("level", T::Byte),
        one("name", T::String),
        one("message", T::String),
        one("hardware_id", T::String),
        seq("values", T::Msg(&KEY_VALUE)),
    ],
    constants: &[
        Constant {
            ty: T::Byte,
            name: "OK",
            value: "0",
        },
        Constant {
            ty: T::Byte,
            name: "WARN",
            value: "1",
        },
        Constant {
            ty: T::Byte,
            name: "ERROR",
            value: "2",
        },
        Constant {
            ty: T::Byte,
            name: "STALE",
            value: "3",
        },
    ],
};

/// `diagnostic_msgs/msg/DiagnosticArray`.
pub static DIAGNOSTIC_ARRAY: MsgType = MsgType {
    name: "diagnostic_msgs/msg/DiagnosticArray",
    fields: &[
        one("header", T::Msg(&HEADER)),
        seq("status", T::Msg(&DIAGNOSTIC_STATUS)),
    ],
    constants: &[],
};

/// `gelgrip_msgs/msg/TactileContact` (`ros/gelgrip_msgs/msg/TactileContact.msg`).
pub static TACTILE_CONTACT: MsgType = MsgType {
    name: "gelgrip_msgs/msg/TactileContact",
    fields: &[
        one("sensor", T::String),
        one("in_contact", T::Bool),
        one("area_m2", T::Float64),
        one("max_depth_m", T::Float64),
        one("mean_depth_m", T::Float64),
        one("centroid", T::Msg(&POINT)),
        one("volume_m3", T::Float64),
        one("force_n", T::Float64),
    ],
    constants: &[],
};

/// `gelgrip_msgs/msg/TactileContacts` (`ros/gelgrip_msgs/msg/TactileContacts.msg`).
pub static TACTILE_CONTACTS: MsgType = MsgType {
    name: "gelgrip_msgs/msg/TactileContacts",
    fields: &[
        one("header", T::Msg(&HEADER)),
        seq("contacts", T::Msg(&TACTILE_CONTACT)),
    ],
    constants: &[],
};

/// `gelgrip_msgs/msg/TactileSlip` (`ros/gelgrip_msgs/msg/TactileSlip.msg`): every sensor's
/// slip of one set, in parallel arrays as `JointState` has them, and the grasp's.
pub static TACTILE_SLIP: MsgType = MsgType {
    name: "gelgrip_msgs/msg/TactileSlip",
    fields: &[
        one("header", T::Msg(&HEADER)),
        seq("sensor", T::String),
        seq("state", T::Uint8),
        seq("stick_ratio", T::Float64),
        seq("shear", T::Msg(&VECTOR3)),
        one("grasp_state", T::Uint8),
    ],
    constants: &[
        Constant {
            ty: T::Uint8,
            name: "UNKNOWN",
            value: "0",
        },
        Constant {
            ty: T::Uint8,
            name: "NONE",
            value: "1",
        },
        Constant {
            ty: T::Uint8,
            name: "INCIPIENT",
            value: "2",
        },
        Constant {
            ty: T::Uint8,
            name: "GROSS",
            value: "3",
        },
    ],
};

/// The types gelgrip publishes, one per topic kind.
pub static PUBLISHED: [&MsgType; 7] = [
    &JOINT_STATE,
    &COMPRESSED_IMAGE,
    &IMAGE,
    &WRENCH_STAMPED,
    &TACTILE_CONTACTS,
    &TACTILE_SLIP,
    &DIAGNOSTIC_ARRAY,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_package_files_are_these_definitions() {
        let contact = include_str!("../../gelgrip_msgs/msg/TactileContact.msg");
        let contacts = include_str!("../../gelgrip_msgs/msg/TactileContacts.msg");
        let slip = include_str!("../../gelgrip_msgs/msg/TactileSlip.msg");
        assert_eq!(TACTILE_CONTACT.msg_text(), contact);
        assert_eq!(TACTILE_CONTACTS.msg_text(), contacts);
        assert_eq!(TACTILE_SLIP.msg_text(), slip);
    }

    #[test]
    fn dds_names_follow_rmw_zenoh() {
        assert_eq!(
            JOINT_STATE.dds_name(),
            "sensor_msgs::msg::dds_::JointState_"
        );
        assert_eq!(
            TACTILE_CONTACTS.dds_name(),
            "gelgrip_msgs::msg::dds_::TactileContacts_"
        );
    }

    #[test]
    fn schemas_carry_every_dependency_once() {
        let s = DIAGNOSTIC_ARRAY.schema_text();
        for dep in [
            "builtin_interfaces/msg/Time",
            "std_msgs/msg/Header",
            "diagnostic_msgs/msg/DiagnosticStatus",
            "diagnostic_msgs/msg/KeyValue",
        ] {
            assert_eq!(s.matches(&format!("MSG: {dep}\n")).count(), 1, "{dep}");
        }
        assert!(s.starts_with("std_msgs/Header header\nDiagnosticStatus[] status\n"));
    }

    #[test]
    fn hashes_differ_by_type_and_are_well_formed() {
        let hashes: Vec<String> = PUBLISHED.iter().map(|t| t.rihs01()).collect();
        for h in &hashes {
            assert_eq!(h.len(), 7 + 64);
            assert!(h.starts_with("RIHS01_"));
        }
        let mut unique = hashes.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), hashes.len());
    }
}
