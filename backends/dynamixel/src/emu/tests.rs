//! Protocol 2.0 conformance of the emulator's dispatcher (the wire-level cases, stuffing and
//! bad CRCs, are in `protocol`).

use super::*;

fn pkt(id: u8, instruction: u8, params: &[u8]) -> Packet {
    Packet {
        id,
        instruction,
        params: params.to_vec(),
    }
}

fn error_of(p: &Packet) -> u8 {
    p.params[0]
}

#[test]
fn broadcast_ping_answers_every_servo_in_order() {
    let mut bus = ServoBusEmulator::new(&[1, 2, 3]);
    let r = bus.handle(&pkt(BROADCAST_ID, ins::PING, &[]));
    assert_eq!(r.iter().map(|p| p.id).collect::<Vec<_>>(), vec![1, 2, 3]);
    assert_eq!(r[0].params, vec![0, 0xFC, 0x03, 45]);
}

#[test]
fn unknown_instruction_is_an_instruction_error() {
    let mut bus = ServoBusEmulator::new(&[1]);
    let r = bus.handle(&pkt(1, 0x7A, &[]));
    assert_eq!(error_of(&r[0]), err::INSTRUCTION);
}

#[test]
fn access_errors() {
    let mut bus = ServoBusEmulator::new(&[1]);
    let r = bus.handle(&pkt(1, ins::READ, &[0x90, 0x02, 8, 0])); // 656 + 8 > table
    assert_eq!(error_of(&r[0]), err::ACCESS);
    let r = bus.handle(&pkt(1, ins::WRITE, &[132, 0, 1, 2, 3, 4])); // Present Position
    assert_eq!(error_of(&r[0]), err::ACCESS);
    assert_eq!(
        error_of(&bus.handle(&pkt(1, ins::WRITE, &[64, 0, 1]))[0]),
        0
    ); // torque on
    let r = bus.handle(&pkt(1, ins::WRITE, &[11, 0, 5])); // Operating Mode (EEPROM)
    assert_eq!(error_of(&r[0]), err::ACCESS);
    bus.handle(&pkt(1, ins::WRITE, &[64, 0, 0]));
    assert_eq!(
        error_of(&bus.handle(&pkt(1, ins::WRITE, &[11, 0, 5]))[0]),
        0
    );
}

#[test]
fn sync_and_bulk_read_and_write() {
    let mut bus = ServoBusEmulator::new(&[1, 2, 3]);
    // sync write Goal Position: 1 ← 100, 3 ← 300
    let mut params = vec![116, 0, 4, 0];
    params.extend([1, 100, 0, 0, 0, 3, 44, 1, 0, 0]);
    assert!(
        bus.handle(&pkt(BROADCAST_ID, ins::SYNC_WRITE, &params))
            .is_empty()
    );
    let r = bus.handle(&pkt(BROADCAST_ID, ins::SYNC_READ, &[116, 0, 4, 0, 1, 2, 3]));
    let values: Vec<u32> = r
        .iter()
        .map(|p| u32::from_le_bytes([p.params[1], p.params[2], p.params[3], p.params[4]]))
        .collect();
    assert_eq!(values, vec![100, 0, 300]);
    // bulk write LED on 2, Goal Current 50 on 3; bulk read them back
    let w = [2, 65, 0, 1, 0, 1, 3, 102, 0, 2, 0, 50, 0];
    assert!(
        bus.handle(&pkt(BROADCAST_ID, ins::BULK_WRITE, &w))
            .is_empty()
    );
    let r = bus.handle(&pkt(
        BROADCAST_ID,
        ins::BULK_READ,
        &[2, 65, 0, 1, 0, 3, 102, 0, 2, 0],
    ));
    assert_eq!(r[0].params, vec![0, 1]);
    assert_eq!(r[1].params, vec![0, 50, 0]);
}

#[test]
fn reboot_clears_hardware_errors_and_keeps_the_id() {
    let mut bus = ServoBusEmulator::new(&[7]);
    bus.handle(&pkt(7, ins::WRITE, &[64, 0, 1]));
    bus.servo_mut(7)
        .expect("servo")
        .inject_hardware_error(control_table::hardware_error::OVERLOAD);
    let r = bus.handle(&pkt(7, ins::READ, &[70, 0, 1, 0]));
    assert_eq!(
        r[0].params,
        vec![err::ALERT, control_table::hardware_error::OVERLOAD]
    );
    let torque = bus.handle(&pkt(7, ins::READ, &[64, 0, 1, 0]));
    assert_eq!(
        torque[0].params[1], 0,
        "overload is a shutdown error: torque is cut"
    );
    let r = bus.handle(&pkt(7, ins::REBOOT, &[]));
    assert_eq!(r[0].params, vec![0]);
    let r = bus.handle(&pkt(7, ins::READ, &[70, 0, 1, 0]));
    assert_eq!(r[0].params, vec![0, 0]);
}

#[test]
fn reboot_keeps_eeprom_and_resets_ram() {
    let mut bus = ServoBusEmulator::new(&[7]);
    // Max Position Limit (EEPROM) and LED (RAM), then a reboot.
    bus.handle(&pkt(7, ins::WRITE, &[48, 0, 0xA0, 0x0F, 0, 0]));
    bus.handle(&pkt(7, ins::WRITE, &[65, 0, 1]));
    bus.handle(&pkt(7, ins::REBOOT, &[]));
    let limit = bus.handle(&pkt(7, ins::READ, &[48, 0, 4, 0]));
    assert_eq!(limit[0].params, vec![0, 0xA0, 0x0F, 0, 0], "EEPROM kept");
    let led = bus.handle(&pkt(7, ins::READ, &[65, 0, 1, 0]));
    assert_eq!(led[0].params, vec![0, 0], "RAM reset");
}

#[test]
fn a_stuck_fault_comes_back_after_every_reboot() {
    let mut bus = ServoBusEmulator::new(&[2]);
    let heat = control_table::hardware_error::OVERHEATING;
    bus.servo_mut(2)
        .expect("servo")
        .set_stuck_hardware_error(heat);
    for _ in 0..3 {
        bus.handle(&pkt(2, ins::REBOOT, &[]));
        let r = bus.handle(&pkt(2, ins::READ, &[70, 0, 1, 0]));
        assert_eq!(r[0].params, vec![err::ALERT, heat]);
    }
    bus.servo_mut(2).expect("servo").set_stuck_hardware_error(0);
    bus.handle(&pkt(2, ins::REBOOT, &[]));
    let r = bus.handle(&pkt(2, ins::READ, &[70, 0, 1, 0]));
    assert_eq!(r[0].params, vec![0, 0]);
}

#[test]
fn a_cut_reply_is_truncated_and_the_rest_of_the_instruction_is_silent() {
    let mut bus = ServoBusEmulator::new(&[1, 2, 3]);
    let sync_read = pkt(BROADCAST_ID, ins::SYNC_READ, &[132, 0, 4, 0, 1, 2, 3]);
    let whole = bus.respond(&sync_read);
    assert_eq!(whole.iter().map(Vec::len).collect::<Vec<_>>(), vec![15; 3]);
    bus.cut_next_reply(9);
    let cut = bus.respond(&sync_read);
    assert_eq!(cut, vec![whole[0][..9].to_vec()]);
    assert_eq!(bus.respond(&sync_read), whole, "the cut applies once");
}

#[test]
fn registered_write_waits_for_action_and_status_level_is_honoured() {
    let mut bus = ServoBusEmulator::new(&[1]);
    bus.handle(&pkt(1, ins::REG_WRITE, &[65, 0, 1]));
    assert_eq!(
        bus.handle(&pkt(1, ins::READ, &[65, 0, 1, 0]))[0].params,
        vec![0, 0]
    );
    bus.handle(&pkt(1, ins::ACTION, &[]));
    assert_eq!(
        bus.handle(&pkt(1, ins::READ, &[65, 0, 1, 0]))[0].params,
        vec![0, 1]
    );
    assert_eq!(
        error_of(&bus.handle(&pkt(1, ins::ACTION, &[]))[0]),
        err::INSTRUCTION
    );
    bus.handle(&pkt(1, ins::WRITE, &[68, 0, 1])); // reply to ping and read only
    assert!(bus.handle(&pkt(1, ins::WRITE, &[65, 0, 0])).is_empty());
    assert_eq!(
        bus.handle(&pkt(1, ins::READ, &[65, 0, 1, 0]))[0].params,
        vec![0, 0]
    );
}
