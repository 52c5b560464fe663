//! Type descriptions of ROS 2 messages, and what is derived from them: the REP-2016 type
//! hash (`RIHS01_` + SHA-256 of the canonical JSON of the type and every type it refers
//! to), the DDS type name rmw_zenoh puts in keys (`pkg::msg::dds_::Name_`), and the `.msg`
//! text (alone, or with its dependencies as an MCAP `ros2msg` schema).
//!
//! Only what gelgrip's messages use is modelled: primitive fields, nested messages and
//! unbounded sequences of either, and constants (which appear in the `.msg` text but not in
//! the hash).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use sha2::{Digest, Sha256};

/// A field's element type.
#[derive(Debug, Clone, Copy)]
pub enum FieldType {
    /// `bool`.
    Bool,
    /// `byte`.
    Byte,
    /// `int8`.
    Int8,
    /// `uint8` (and `char`, which rosidl maps to `uint8`).
    Uint8,
    /// `int32`.
    Int32,
    /// `uint32`.
    Uint32,
    /// `int64`.
    Int64,
    /// `float64`.
    Float64,
    /// `string` (unbounded).
    String,
    /// A nested message.
    Msg(&'static MsgType),
}

impl FieldType {
    /// The `type_id` of `type_description_interfaces/msg/FieldType` for one element.
    fn type_id(self) -> u8 {
        match self {
            Self::Msg(_) => 1,
            Self::Int8 => 2,
            Self::Uint8 => 3,
            Self::Int32 => 6,
            Self::Uint32 => 7,
            Self::Int64 => 8,
            Self::Float64 => 11,
            Self::Bool => 15,
            Self::Byte => 16,
            Self::String => 17,
        }
    }

    /// The type as a `.msg` file in package `package` spells it.
    fn msg_spelling(self, package: &str) -> String {
        match self {
            Self::Bool => "bool".into(),
            Self::Byte => "byte".into(),
            Self::Int8 => "int8".into(),
            Self::Uint8 => "uint8".into(),
            Self::Int32 => "int32".into(),
            Self::Uint32 => "uint32".into(),
            Self::Int64 => "int64".into(),
            Self::Float64 => "float64".into(),
            Self::String => "string".into(),
            Self::Msg(t) if t.package() == package => t.short_name().into(),
            Self::Msg(t) => format!("{}/{}", t.package(), t.short_name()),
        }
    }
}

/// How many elements of its type a field holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// One (`T`).
    One,
    /// An unbounded sequence (`T[]`).
    Sequence,
    /// A sequence of at most this many (`T[<=N]`).
    BoundedSequence(u32),
    /// A fixed array (`T[N]`).
    Array(u32),
}

impl Shape {
    /// What REP-2016 adds to the element's `type_id`, and the capacity it records.
    fn type_id_offset_and_capacity(self) -> (u32, u32) {
        match self {
            Self::One => (0, 0),
            Self::Array(n) => (48, n),
            Self::BoundedSequence(n) => (96, n),
            Self::Sequence => (144, 0),
        }
    }

    /// The brackets a `.msg` file writes after the type.
    fn brackets(self) -> String {
        match self {
            Self::One => String::new(),
            Self::Sequence => "[]".into(),
            Self::BoundedSequence(n) => format!("[<={n}]"),
            Self::Array(n) => format!("[{n}]"),
        }
    }
}

/// One field.
#[derive(Debug, Clone, Copy)]
pub struct Field {
    /// Its name.
    pub name: &'static str,
    /// Its element type.
    pub ty: FieldType,
    /// One, a sequence or an array of `ty`.
    pub shape: Shape,
}

/// A constant (`byte OK=0`).
#[derive(Debug, Clone, Copy)]
pub struct Constant {
    /// Its type (a primitive).
    pub ty: FieldType,
    /// Its name.
    pub name: &'static str,
    /// Its value as the `.msg` spells it.
    pub value: &'static str,
}

/// A message type: `pkg/msg/Name`, its fields in order and its constants.
#[derive(Debug)]
pub struct MsgType {
    /// The full name, `pkg/msg/Name`.
    pub name: &'static str,
    /// The fields, in order.
    pub fields: &'static [Field],
    /// The constants.
    pub constants: &'static [Constant],
}

impl MsgType {
    /// The package (`sensor_msgs`).
    pub fn package(&self) -> &'static str {
        self.name.split('/').next().unwrap_or(self.name)
    }

    /// The name within the package (`JointState`).
    pub fn short_name(&self) -> &'static str {
        self.name.rsplit('/').next().unwrap_or(self.name)
    }

    /// The interface kind in the name: `msg`, `srv` or `action`.
    pub fn kind(&self) -> &'static str {
        self.name.split('/').nth(1).unwrap_or("msg")
    }

    /// The DDS type name rmw_zenoh puts in keys and tokens: `pkg::msg::dds_::Name_`
    /// (`pkg::srv::dds_::Name_` for a service, `pkg::action::dds_::Name_SendGoal_` for an
    /// action's service or message).
    pub fn dds_name(&self) -> String {
        format!(
            "{}::{}::dds_::{}_",
            self.package(),
            self.kind(),
            self.short_name()
        )
    }

    /// The REP-2016 type hash, `RIHS01_` and 64 hex digits.
    pub fn rihs01(&self) -> String {
        let digest = Sha256::digest(self.description_json().as_bytes());
        let mut s = String::with_capacity(7 + 64);
        s.push_str("RIHS01_");
        for b in digest {
            let _ = write!(s, "{b:02x}");
        }
        s
    }

    /// Every message type this one refers to, directly or not, by name (itself excluded).
    pub fn dependencies(&self) -> BTreeMap<&'static str, &'static MsgType> {
        let mut out = BTreeMap::new();
        let mut stack: Vec<&'static [Field]> = vec![self.fields];
        while let Some(fields) = stack.pop() {
            for f in fields {
                if let FieldType::Msg(n) = f.ty
                    && n.name != self.name
                    && out.insert(n.name, n).is_none()
                {
                    stack.push(n.fields);
                }
            }
        }
        out
    }

    /// The canonical JSON of the type description REP-2016 hashes: the type, then the types
    /// it refers to sorted by name; each field's name, `type_id` (element id, +144 for an
    /// unbounded sequence), capacities and nested type name; no default values. The spacing
    /// is Python's `json.dumps` default (`", "` and `": "`), as rosidl hashes it.
    pub fn description_json(&self) -> String {
        let mut s = String::with_capacity(2048);
        s.push_str("{\"type_description\": ");
        self.write_struct_json(&mut s);
        s.push_str(", \"referenced_type_descriptions\": [");
        for (i, t) in self.dependencies().values().enumerate() {
            if i > 0 {
                s.push_str(", ");
            }
            t.write_struct_json(&mut s);
        }
        s.push_str("]}");
        s
    }

    fn write_struct_json(&self, s: &mut String) {
        s.push_str("{\"type_name\": ");
        json_string(s, self.name);
        s.push_str(", \"fields\": [");
        for (i, f) in self.fields.iter().enumerate() {
            if i > 0 {
                s.push_str(", ");
            }
            let (offset, capacity) = f.shape.type_id_offset_and_capacity();
            let id = u32::from(f.ty.type_id()) + offset;
            let nested = match f.ty {
                FieldType::Msg(t) => t.name,
                _ => "",
            };
            s.push_str("{\"name\": ");
            json_string(s, f.name);
            let _ = write!(
                s,
                ", \"type\": {{\"type_id\": {id}, \"capacity\": {capacity}, \
                 \"string_capacity\": 0, \"nested_type_name\": "
            );
            json_string(s, nested);
            s.push_str("}}");
        }
        s.push_str("]}");
    }

    /// The `.msg` text: one line per constant (`byte OK=0`) and per field (`float64[] x`).
    pub fn msg_text(&self) -> String {
        let mut s = String::new();
        for c in self.constants {
            let _ = writeln!(
                s,
                "{} {}={}",
                c.ty.msg_spelling(self.package()),
                c.name,
                c.value
            );
        }
        for f in self.fields {
            let brackets = f.shape.brackets();
            let _ = writeln!(
                s,
                "{}{brackets} {}",
                f.ty.msg_spelling(self.package()),
                f.name
            );
        }
        s
    }

    /// The MCAP `ros2msg` schema: the `.msg` text, then each dependency's after a line of
    /// 80 `=` and `MSG: pkg/msg/Name`.
    pub fn schema_text(&self) -> String {
        let mut s = self.msg_text();
        for t in self.dependencies().values() {
            s.push_str(&"=".repeat(80));
            let _ = writeln!(s, "\nMSG: {}", t.name);
            s.push_str(&t.msg_text());
        }
        s
    }
}

/// `v` as a JSON string (quotes, backslashes and control characters escaped).
fn json_string(s: &mut String, v: &str) {
    s.push('"');
    for c in v.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            c if u32::from(c) < 0x20 => {
                let _ = write!(s, "\\u{:04x}", u32::from(c));
            }
            c => s.push(c),
        }
    }
    s.push('"');
}
