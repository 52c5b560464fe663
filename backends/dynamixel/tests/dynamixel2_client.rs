//! The wire codec against a real Protocol 2.0 client: `dynamixel2::Bus` on the slave end of
//! a pseudo-terminal pair, the servo emulator on the master end. Every packet dynamixel2
//! sends must decode, and every reply the emulator encodes must be accepted.

use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use gelgrip_dynamixel::emu::ServoBusEmulator;
use gelgrip_dynamixel::protocol::{Packet, PacketDecoder};
use serialport::{SerialPort, TTYPort};

/// The emulated bus on the master end: decode, dispatch, reply.
fn serve(mut master: TTYPort, stop: Arc<AtomicBool>) -> Vec<Packet> {
    let mut bus = ServoBusEmulator::new(&[1]);
    let mut seen = Vec::new();
    let mut dec = PacketDecoder::new();
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::SeqCst) {
        let n = match master.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(_) => break,
        };
        dec.push(&buf[..n]);
        while let Some(Ok(p)) = dec.next_packet() {
            for reply in bus.handle(&p) {
                master.write_all(&reply.encode()).expect("reply written");
            }
            seen.push(p);
        }
    }
    seen
}

#[test]
fn dynamixel2_client_accepts_our_packets_over_a_pty() {
    let (mut master, slave) = TTYPort::pair().expect("pseudo-terminal pair");
    master
        .set_timeout(Duration::from_millis(20))
        .expect("timeout");
    let path = slave.name().expect("slave path");
    let stop = Arc::new(AtomicBool::new(false));
    let device = std::thread::spawn({
        let stop = stop.clone();
        move || serve(master, stop)
    });
    let mut bus = dynamixel2::Bus::open(&path, 1_000_000).expect("bus opens");
    let ping = bus.ping(1).expect("ping answered");
    assert_eq!(ping.data.model, 1020);
    assert_eq!(ping.data.firmware, 45);
    bus.write_u8(1, 11, 5).expect("operating mode, torque off");
    bus.write_u32(1, 116, 0xFFFD_FFFF).expect("write answered"); // -131073, LE bytes FF FF FD FF: stuffed both ways
    assert_eq!(
        bus.read_u32(1, 116).expect("read answered").data,
        0xFFFD_FFFF
    );
    assert_eq!(bus.read_u16(1, 0).expect("model").data, 1020);
    let err = bus.action(1).expect_err("instruction error");
    assert!(err.to_string().contains("0x2"), "{err}");
    stop.store(true, Ordering::SeqCst);
    drop(bus);
    let seen = device.join().expect("device thread");
    assert_eq!(seen.len(), 6);
    assert_eq!(seen[2].params, vec![116, 0, 0xFF, 0xFF, 0xFD, 0xFF]);
    drop(slave);
}
