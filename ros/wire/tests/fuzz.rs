//! Property tests of what the ROS 2 bridge reads from the network (issue 45): the CDR of
//! the requests it serves (the GripperCommand action's `SendGoal`, `CancelGoal` and
//! `GetResult`, and the `Trigger` services release, stop and e-stop) and the rmw_zenoh
//! attachment each request carries. Random bytes and mutations of valid requests (cut,
//! extended, bytes changed, another encapsulation) must decode to a value or a typed
//! [`CdrError`], never a panic; a valid request decodes to what was encoded. None of these
//! requests has a length field (no strings or sequences), so no claimed length can make the
//! decoder allocate.
//!
//! Case counts: `PROPTEST_CASES` (proptest's 256 when unset), capped per test so that
//! `scripts/test`'s 30 000-case step stays short; `GELGRIP_FUZZ_CASES` sets the exact count
//! for a long run outside CI (docs/reliability.md).

use proptest::prelude::*;

use gelgrip_ros_wire::actions::{
    SendGoalRequest, decode_cancel_goal, decode_get_result, decode_send_goal,
};
use gelgrip_ros_wire::cdr::CdrWriter;
use gelgrip_ros_wire::cdr_read::{CdrError, CdrReader};
use gelgrip_ros_wire::names::{attachment, parse_attachment};
use gelgrip_ros_wire::services::decode_trigger_request;

/// Cases per test in CI: all of `scripts/test`'s 30 000 (a decode takes nanoseconds).
const CI_CASES: u32 = 30_000;

#[path = "../../../testsupport/fuzz_runner.rs"]
mod fuzz_runner;
use fuzz_runner::check;

/// Every request decoder on `bytes`: each a value or a typed error; the ones that
/// accept must agree with a reader's own view of the same bytes.
fn decode_all(bytes: &[u8]) {
    let header_ok = bytes.len() >= 4 && bytes[0] == 0 && bytes[1] == 1;
    let body = bytes.len().saturating_sub(4);
    let send = decode_send_goal(bytes);
    // uint8[16], then two float64 aligned to 8 after the header: 16 + 16 bytes.
    assert_eq!(send.is_ok(), header_ok && body >= 32, "{send:?}");
    if let Ok(r) = send {
        assert_eq!(&r.goal_id[..], &bytes[4..20]);
        assert_eq!(r.position.to_bits(), read_f64(&bytes[20..28]).to_bits());
    }
    let cancel = decode_cancel_goal(bytes);
    assert_eq!(cancel.is_ok(), header_ok && body >= 24, "{cancel:?}");
    let result = decode_get_result(bytes);
    assert_eq!(result.is_ok(), header_ok && body >= 16, "{result:?}");
    let trigger = decode_trigger_request(bytes);
    assert_eq!(trigger.is_ok(), header_ok && body >= 1, "{trigger:?}");
    for e in [send.err(), cancel.err(), result.err(), trigger.err()]
        .into_iter()
        .flatten()
    {
        let typed = matches!(
            e,
            CdrError::NoHeader { .. } | CdrError::Encapsulation(..) | CdrError::Truncated { .. }
        );
        assert!(typed && !e.to_string().is_empty(), "{e:?}");
    }
}

fn read_f64(b: &[u8]) -> f64 {
    f64::from_le_bytes(b.try_into().expect("8 bytes"))
}

/// A `SendGoal` request as a client encodes it.
fn send_goal(r: &SendGoalRequest) -> Vec<u8> {
    let mut w = CdrWriter::default();
    for b in r.goal_id {
        w.u8(b);
    }
    w.f64(r.position);
    w.f64(r.max_effort);
    w.into_bytes()
}

fn request() -> impl Strategy<Value = SendGoalRequest> {
    (any::<[u8; 16]>(), any::<f64>(), any::<f64>()).prop_map(|(goal_id, position, max_effort)| {
        SendGoalRequest {
            goal_id,
            position,
            max_effort,
        }
    })
}

#[test]
fn random_bytes_decode_or_fail_with_a_typed_error() {
    let bytes = prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..64),
        // A plausible header in front, so the bodies get read.
        proptest::collection::vec(any::<u8>(), 0..64).prop_map(|mut b| {
            b.splice(0..0, [0, 1, 0, 0]);
            b
        }),
    ];
    check(CI_CASES, bytes, |b| decode_all(&b));
}

#[test]
fn valid_requests_decode_to_what_was_sent() {
    check(CI_CASES, request(), |r| {
        let got = decode_send_goal(&send_goal(&r)).expect("a valid request");
        assert_eq!(got.goal_id, r.goal_id);
        assert_eq!(got.position.to_bits(), r.position.to_bits());
        assert_eq!(got.max_effort.to_bits(), r.max_effort.to_bits());
    });
}

#[test]
fn mutated_requests_decode_or_fail_with_a_typed_error() {
    let strategy = (
        request(),
        proptest::collection::vec((any::<usize>(), any::<u8>()), 0..4),
        proptest::option::of(any::<usize>()),
        proptest::collection::vec(any::<u8>(), 0..12),
    );
    check(CI_CASES, strategy, |(r, edits, cut, tail)| {
        let mut b = send_goal(&r);
        for (at, v) in edits {
            let n = b.len();
            b[at % n] = v;
        }
        if let Some(c) = cut {
            b.truncate(c % (b.len() + 1));
        }
        b.extend_from_slice(&tail);
        decode_all(&b);
    });
}

/// One read of a message's field.
#[derive(Debug, Clone, Copy)]
enum Read {
    U8,
    Bool,
    I32,
    U32,
    F64,
    Bytes16,
}

#[test]
fn any_sequence_of_reads_stays_in_bounds() {
    let read = prop_oneof![
        Just(Read::U8),
        Just(Read::Bool),
        Just(Read::I32),
        Just(Read::U32),
        Just(Read::F64),
        Just(Read::Bytes16),
    ];
    let strategy = (
        proptest::collection::vec(any::<u8>(), 4..80),
        proptest::collection::vec(read, 0..12),
    );
    check(CI_CASES, strategy, |(mut bytes, reads)| {
        bytes[..2].copy_from_slice(&[0, 1]);
        let mut r = CdrReader::new(&bytes).expect("header");
        for read in reads {
            let out = match read {
                Read::U8 => r.u8("u8").map(drop),
                Read::Bool => r.bool("bool").map(drop),
                Read::I32 => r.i32("i32").map(drop),
                Read::U32 => r.u32("u32").map(drop),
                Read::F64 => r.f64("f64").map(drop),
                Read::Bytes16 => r.bytes16("bytes16").map(drop),
            };
            if let Err(CdrError::Truncated {
                offset, need, len, ..
            }) = out
            {
                assert!(offset + need > len, "{offset} + {need} <= {len}");
            }
        }
    });
}

#[test]
fn attachments_parse_only_when_well_formed() {
    let strategy = (
        proptest::collection::vec(any::<u8>(), 0..48),
        any::<i64>(),
        any::<i64>(),
        any::<[u8; 16]>(),
    );
    check(CI_CASES, strategy, |(bytes, seq, t, gid)| {
        let parsed = parse_attachment(&bytes);
        assert_eq!(parsed.is_some(), bytes.len() == 33 && bytes[16] == 16);
        assert_eq!(
            parse_attachment(&attachment(seq, t, &gid)),
            Some((seq, gid))
        );
    });
}
