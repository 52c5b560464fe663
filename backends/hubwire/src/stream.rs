//! A resynchronising decoder for a byte stream of SPI frames.
//!
//! Bytes arrive in arbitrary chunks. The decoder yields every valid frame, in order, and one
//! [`StreamEvent::Error`] for each frame it had to reject or each run of bytes it skipped to
//! find the next magic. After any error it resumes the search one byte after the rejected
//! magic, so a truncated frame never swallows the frame that follows it. It never panics and
//! never waits for more than one maximum-size frame of bytes.

use crate::spi_frame::{self, FrameError, FrameHeader, HEADER_LEN, MAGIC, SpiFrame};

/// What the decoder found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StreamEvent {
    /// A frame whose header and CRC checked.
    Frame(SpiFrame),
    /// Something was rejected.
    Error(StreamError),
}

/// A rejected part of the stream.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum StreamError {
    /// Bytes that did not start a frame were skipped.
    #[error("skipped {bytes} bytes of garbage before the next frame magic")]
    Garbage {
        /// How many bytes were skipped.
        bytes: usize,
    },
    /// A magic was found but the frame did not decode.
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// The stream ended inside a frame.
    #[error("stream ended {available} bytes into a frame of {needed}")]
    TruncatedAtEnd {
        /// Bytes the frame needed.
        needed: usize,
        /// Bytes that arrived.
        available: usize,
    },
}

/// Incremental frame-stream decoder.
#[derive(Debug, Default)]
pub struct FrameStreamDecoder {
    buf: Vec<u8>,
    pos: usize,
    /// Bytes skipped since the last event that are not part of a rejected frame.
    garbage: usize,
    /// After a rejected frame, skip its remaining bytes without reporting them again.
    resyncing: bool,
}

impl FrameStreamDecoder {
    /// A decoder with an empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Append received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.pos > 0 && self.pos * 2 >= self.buf.len() {
            self.buf.drain(..self.pos);
            self.pos = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// Bytes buffered but not yet decoded.
    pub fn pending(&self) -> usize {
        self.buf.len() - self.pos
    }

    fn skip(&mut self, n: usize) {
        self.pos += n;
        if !self.resyncing {
            self.garbage += n;
        }
    }

    fn take_garbage(&mut self) -> Option<StreamEvent> {
        (self.garbage > 0).then(|| {
            let bytes = std::mem::take(&mut self.garbage);
            StreamEvent::Error(StreamError::Garbage { bytes })
        })
    }

    fn reject(&mut self, error: StreamError) -> Option<StreamEvent> {
        self.pos += 1;
        self.resyncing = true;
        Some(StreamEvent::Error(error))
    }

    /// The next event, or `None` when more bytes are needed.
    pub fn next_event(&mut self) -> Option<StreamEvent> {
        let rest = &self.buf[self.pos..];
        match find_magic(rest) {
            Some(at) => self.skip(at),
            None => {
                // Keep a possible partial magic at the end; report garbage once a magic shows.
                let keep = partial_magic_suffix(rest);
                self.skip(rest.len() - keep);
                return None;
            }
        }
        self.resyncing = false;
        if let Some(event) = self.take_garbage() {
            return Some(event);
        }
        let rest = &self.buf[self.pos..];
        if rest.len() < HEADER_LEN {
            return None;
        }
        let header = match FrameHeader::decode(rest) {
            Ok(h) => h,
            Err(e) => return self.reject(e.into()),
        };
        if rest.len() < header.frame_len() {
            return None;
        }
        match spi_frame::decode(rest) {
            Ok((frame, used)) => {
                self.pos += used;
                Some(StreamEvent::Frame(frame))
            }
            Err(e) => self.reject(e.into()),
        }
    }

    /// Flush at the end of the stream. Call it until it returns `None`: it reports a trailing
    /// partial frame or garbage, and keeps decoding whatever followed a partial frame's magic.
    pub fn finish(&mut self) -> Option<StreamEvent> {
        if let Some(event) = self.next_event() {
            return Some(event);
        }
        let rest = &self.buf[self.pos..];
        if rest.starts_with(&MAGIC) {
            let available = rest.len();
            let needed = FrameHeader::decode(rest)
                .map(|h| h.frame_len())
                .unwrap_or(HEADER_LEN);
            return self.reject(StreamError::TruncatedAtEnd { needed, available });
        }
        let tail = rest.len();
        self.skip(tail);
        self.take_garbage()
    }
}

fn find_magic(bytes: &[u8]) -> Option<usize> {
    bytes.windows(MAGIC.len()).position(|w| w == MAGIC)
}

fn partial_magic_suffix(bytes: &[u8]) -> usize {
    (1..MAGIC.len())
        .rev()
        .find(|&k| bytes.len() >= k && bytes[bytes.len() - k..] == MAGIC[..k])
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spi_frame::{TRAILER_LEN, encode};
    use proptest::prelude::*;

    fn frame(seq: u32, payload: Vec<u8>) -> (FrameHeader, Vec<u8>) {
        let header = FrameHeader {
            sensor_id: (seq % 7) as u8,
            trigger_seq: seq,
            payload_len: payload.len() as u32,
            ..Default::default()
        };
        (header, payload)
    }

    fn drain(dec: &mut FrameStreamDecoder, out: &mut Vec<StreamEvent>) {
        while let Some(e) = dec.next_event() {
            out.push(e);
        }
    }

    fn decode_all(bytes: &[u8], chunk: usize) -> Vec<StreamEvent> {
        let mut dec = FrameStreamDecoder::new();
        let mut out = Vec::new();
        for c in bytes.chunks(chunk.max(1)) {
            dec.push(c);
            drain(&mut dec, &mut out);
        }
        while let Some(e) = dec.finish() {
            out.push(e);
        }
        out
    }

    fn frames_of(events: &[StreamEvent]) -> Vec<&SpiFrame> {
        events
            .iter()
            .filter_map(|e| match e {
                StreamEvent::Frame(f) => Some(f),
                StreamEvent::Error(_) => None,
            })
            .collect()
    }

    #[test]
    fn truncated_frame_does_not_swallow_the_next() {
        let (h1, p1) = frame(1, vec![7; 300]);
        let (h2, p2) = frame(2, vec![9; 10]);
        let mut bytes = encode(&h1, &p1);
        bytes.truncate(100);
        bytes.extend(encode(&h2, &p2));
        let events = decode_all(&bytes, 64);
        let frames = frames_of(&events);
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].header.trigger_seq, 2);
        assert!(events.iter().any(|e| matches!(e, StreamEvent::Error(_))));
    }

    #[test]
    fn trailing_partial_frame_is_reported() {
        let (h, p) = frame(1, vec![1; 50]);
        let bytes = encode(&h, &p);
        let events = decode_all(&bytes[..40], 7);
        assert_eq!(events.len(), 1, "{events:?}");
        assert!(matches!(
            events[0],
            StreamEvent::Error(StreamError::TruncatedAtEnd {
                needed: 82,
                available: 40
            })
        ));
    }

    fn garbage_without_magic() -> impl Strategy<Value = Vec<u8>> {
        proptest::collection::vec(any::<u8>(), 0..64).prop_map(|mut g| {
            // Break any accidental 'G' runs so no magic can form across the boundary.
            for b in g.iter_mut() {
                if *b == b'G' {
                    *b = 0;
                }
            }
            g
        })
    }

    proptest! {
        /// Valid frames with garbage between them, in any chunking: every frame comes out,
        /// in order, and each garbage run is counted.
        #[test]
        fn garbage_between_frames_is_skipped_and_counted(
            parts in proptest::collection::vec(
                (proptest::collection::vec(any::<u8>(), 0..200), garbage_without_magic()), 1..8),
            chunk in 1usize..97,
        ) {
            let mut bytes = Vec::new();
            let mut expected = Vec::new();
            let mut garbage_runs = 0;
            for (i, (payload, garbage)) in parts.into_iter().enumerate() {
                if !garbage.is_empty() { garbage_runs += 1; }
                bytes.extend(&garbage);
                let (h, p) = frame(i as u32, payload);
                bytes.extend(encode(&h, &p));
                expected.push(p);
            }
            let events = decode_all(&bytes, chunk);
            let got: Vec<Vec<u8>> = frames_of(&events).iter().map(|f| f.jpeg.clone()).collect();
            prop_assert_eq!(got, expected);
            let errors = events.iter().filter(|e| matches!(e, StreamEvent::Error(_))).count();
            prop_assert_eq!(errors, garbage_runs);
        }

        /// Bit flips, truncations and random bytes: no panic, no invented frame, every valid
        /// frame that was left intact is recovered, and every damaged frame costs an error.
        #[test]
        fn damaged_streams_yield_valid_frames_and_errors(
            payloads in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..120), 1..8),
            damage in proptest::collection::vec((any::<u8>(), any::<usize>()), 8),
            chunk in 1usize..97,
        ) {
            let mut bytes = Vec::new();
            let mut intact = Vec::new();
            let mut damaged = 0;
            for (i, payload) in payloads.into_iter().enumerate() {
                let (h, p) = frame(i as u32, payload);
                let mut enc = encode(&h, &p);
                let (kind, at) = damage[i];
                match kind % 4 {
                    0 => intact.push(p),
                    1 => { let bit = at % (enc.len() * 8); enc[bit / 8] ^= 1 << (bit % 8); damaged += 1; }
                    // Cut at least the whole CRC: a frame short by fewer bytes can be completed by the
                    // next frame's bytes if they happen to equal the missing ones (then the damage
                    // has moved to that next frame, which no framing can tell apart).
                    2 => { enc.truncate(1 + at % (enc.len() - TRAILER_LEN)); damaged += 1; }
                    _ => { let n = at % 40; enc.splice(0..0, std::iter::repeat_n(0xA5u8, n)); intact.push(p); if n > 0 { damaged += 1; } }
                }
                bytes.extend(enc);
            }
            let events = decode_all(&bytes, chunk);
            let got: Vec<Vec<u8>> = frames_of(&events).iter().map(|f| f.jpeg.clone()).collect();
            prop_assert_eq!(got, intact);
            let errors = events.iter().filter(|e| matches!(e, StreamEvent::Error(_))).count();
            prop_assert!(errors >= damaged.min(1), "errors {} damaged {}", errors, damaged);
        }

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..4096), chunk in 1usize..300) {
            let events = decode_all(&bytes, chunk);
            prop_assert!(events.len() <= bytes.len() + 1);
        }
    }
}
