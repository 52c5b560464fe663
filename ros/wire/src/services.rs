//! ROS 2 services as REP-2016 describes them, and `std_srvs/srv/Trigger`.
//!
//! A service's type hash (the one rmw_zenoh puts in the service's key and liveliness token)
//! is the hash of a description named after the service (`std_srvs/srv/Trigger`) with three
//! fields: `request_message`, `response_message` and `event_message`; the event message
//! holds a `service_msgs/msg/ServiceEventInfo` and at most one request and one response.
//! A request with no fields (Trigger's) is described, and encoded, as one `uint8`
//! `structure_needs_at_least_one_member`.

use crate::catalog::{TIME, one};
use crate::cdr::CdrWriter;
use crate::cdr_read::{CdrError, CdrReader};
use crate::msgs::Message;
use crate::types::{Constant, Field, FieldType as T, MsgType, Shape};

/// A field of at most one `ty` (`T[<=1]`), as the service event holds its request.
pub(crate) const fn at_most_one(name: &'static str, ty: T) -> Field {
    Field {
        name,
        ty,
        shape: Shape::BoundedSequence(1),
    }
}

/// A fixed array of `n` `ty`.
pub(crate) const fn array(name: &'static str, ty: T, n: u32) -> Field {
    Field {
        name,
        ty,
        shape: Shape::Array(n),
    }
}

/// The three fields of a service's description.
pub(crate) const fn service_fields(
    request: &'static MsgType,
    response: &'static MsgType,
    event: &'static MsgType,
) -> [Field; 3] {
    [
        one("request_message", T::Msg(request)),
        one("response_message", T::Msg(response)),
        one("event_message", T::Msg(event)),
    ]
}

/// The fields of a service's event message.
pub(crate) const fn event_fields(
    request: &'static MsgType,
    response: &'static MsgType,
) -> [Field; 3] {
    [
        one("info", T::Msg(&SERVICE_EVENT_INFO)),
        at_most_one("request", T::Msg(request)),
        at_most_one("response", T::Msg(response)),
    ]
}

/// `service_msgs/msg/ServiceEventInfo` (its `char[16]` is `uint8[16]` to rosidl).
pub static SERVICE_EVENT_INFO: MsgType = MsgType {
    name: "service_msgs/msg/ServiceEventInfo",
    fields: &[
        one("event_type", T::Uint8),
        one("stamp", T::Msg(&TIME)),
        array("client_gid", T::Uint8, 16),
        one("sequence_number", T::Int64),
    ],
    constants: &[
        Constant {
            ty: T::Uint8,
            name: "REQUEST_SENT",
            value: "0",
        },
        Constant {
            ty: T::Uint8,
            name: "REQUEST_RECEIVED",
            value: "1",
        },
        Constant {
            ty: T::Uint8,
            name: "RESPONSE_SENT",
            value: "2",
        },
        Constant {
            ty: T::Uint8,
            name: "RESPONSE_RECEIVED",
            value: "3",
        },
    ],
};

/// `std_srvs/srv/Trigger_Request` (empty).
pub static TRIGGER_REQUEST: MsgType = MsgType {
    name: "std_srvs/srv/Trigger_Request",
    fields: &[one("structure_needs_at_least_one_member", T::Uint8)],
    constants: &[],
};

/// `std_srvs/srv/Trigger_Response`.
pub static TRIGGER_RESPONSE: MsgType = MsgType {
    name: "std_srvs/srv/Trigger_Response",
    fields: &[one("success", T::Bool), one("message", T::String)],
    constants: &[],
};

/// `std_srvs/srv/Trigger_Event`.
pub static TRIGGER_EVENT: MsgType = MsgType {
    name: "std_srvs/srv/Trigger_Event",
    fields: &event_fields(&TRIGGER_REQUEST, &TRIGGER_RESPONSE),
    constants: &[],
};

/// `std_srvs/srv/Trigger`: the service (its hash is the service's).
pub static TRIGGER: MsgType = MsgType {
    name: "std_srvs/srv/Trigger",
    fields: &service_fields(&TRIGGER_REQUEST, &TRIGGER_RESPONSE, &TRIGGER_EVENT),
    constants: &[],
};

/// A Trigger request: checked to be one byte after the header (its value is not looked at).
pub fn decode_trigger_request(bytes: &[u8]) -> Result<(), CdrError> {
    CdrReader::new(bytes)?.u8("structure_needs_at_least_one_member")?;
    Ok(())
}

/// `std_srvs/srv/Trigger_Response`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TriggerResponse {
    /// Whether it was done.
    pub success: bool,
    /// What happened.
    pub message: String,
}

impl Message for TriggerResponse {
    fn msg_type() -> &'static MsgType {
        &TRIGGER_RESPONSE
    }

    fn write(&self, w: &mut CdrWriter) {
        w.bool(self.success);
        w.string(&self.message);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    static EX_REQUEST: MsgType = MsgType {
        name: "example_interfaces/srv/Trigger_Request",
        fields: TRIGGER_REQUEST.fields,
        constants: &[],
    };
    static EX_RESPONSE: MsgType = MsgType {
        name: "example_interfaces/srv/Trigger_Response",
        fields: TRIGGER_RESPONSE.fields,
        constants: &[],
    };
    static EX_EVENT: MsgType = MsgType {
        name: "example_interfaces/srv/Trigger_Event",
        fields: &event_fields(&EX_REQUEST, &EX_RESPONSE),
        constants: &[],
    };
    static EX_TRIGGER: MsgType = MsgType {
        name: "example_interfaces/srv/Trigger",
        fields: &service_fields(&EX_REQUEST, &EX_RESPONSE, &EX_EVENT),
        constants: &[],
    };

    #[test]
    fn services_hash_as_rosidl_generates_them() {
        // rosidl_generator_c's trigger__description.c for example_interfaces/srv/Trigger
        // (the same definition as std_srvs', in another package) and
        // service_event_info__description.c: the hashes ROS itself compiled in.
        assert_eq!(
            EX_TRIGGER.rihs01(),
            "RIHS01_cfeeee47f8105dd7685e4c92d46d4074669cb1c477402be1dea37486542a69e0"
        );
        assert_eq!(
            EX_REQUEST.rihs01(),
            "RIHS01_2521571bb7fb4de94da045720b069b2859084c689ee27382f48414ebf4dd3a8d"
        );
        assert_eq!(
            EX_EVENT.rihs01(),
            "RIHS01_37216e82646e85e9dacb76811000fc4c5e303dd4ef29b4151c189a3fa734296f"
        );
        assert_eq!(
            SERVICE_EVENT_INFO.rihs01(),
            "RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45"
        );
        assert_eq!(TRIGGER.dds_name(), "std_srvs::srv::dds_::Trigger_");
    }

    #[test]
    fn trigger_requests_are_checked() {
        assert_eq!(decode_trigger_request(&[0, 1, 0, 0, 0]), Ok(()));
        assert!(decode_trigger_request(&[0, 1, 0, 0]).is_err());
        assert!(decode_trigger_request(&[]).is_err());
        let r = TriggerResponse {
            success: true,
            message: "ok".into(),
        }
        .to_cdr();
        assert_eq!(r, [0, 1, 0, 0, 1, 0, 0, 0, 3, 0, 0, 0, b'o', b'k', 0]);
    }
}
