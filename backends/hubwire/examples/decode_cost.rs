//! How long the host takes to decode one CDC set of 7 × 20 KB frames (COBS, message CRC,
//! SPI frame CRC), in release: `cargo run --release -p gelgrip-hubwire --example decode_cost`.
use gelgrip_hubwire::cdc::{CdcStreamDecoder, Message};
use gelgrip_hubwire::spi_frame::{self, FrameHeader};
use std::time::Instant;

fn main() {
    let jpeg: Vec<u8> = (0..20_000u32).map(|i| (i * 7 % 251) as u8).collect();
    let mut wire = Vec::new();
    for b in 0..7u8 {
        let header = FrameHeader {
            sensor_id: b,
            ..FrameHeader::default()
        };
        let frame = spi_frame::encode(&header, &jpeg);
        wire.extend(
            Message::Frame {
                capture_ts_us: 0,
                spi_frame: frame,
            }
            .encode(),
        );
    }
    let rounds = 200;
    let t = Instant::now();
    let mut n = 0;
    for _ in 0..rounds {
        let mut d = CdcStreamDecoder::new();
        for chunk in wire.chunks(4095) {
            d.push(chunk, |m| {
                if let Ok(Message::Frame { spi_frame, .. }) = m {
                    n += spi_frame::decode(&spi_frame)
                        .map(|(f, _)| f.jpeg.len())
                        .unwrap_or(0);
                }
            });
        }
    }
    let per_set = t.elapsed() / rounds;
    println!(
        "{} bytes per set: {per_set:?} per set ({n} payload bytes)",
        wire.len()
    );
}
