//! Protocol 2.0 conformance of the emulator's dispatcher (the wire-level cases, stuffing and
//! bad CRCs, are in `protocol`).

use super::*;
use crate::protocol::{BROADCAST_ID, FastSegment, instruction as ins};

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
    assert_eq!(
        values,
        vec![100, 2048, 300],
        "2: its goal at boot, the shaft"
    );
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

fn read_u32(bus: &mut ServoBusEmulator, id: u8, a: u16) -> (u8, i32) {
    let r = bus.handle(&pkt(id, ins::READ, &[a as u8, (a >> 8) as u8, 4, 0]));
    let p = &r[0].params;
    (p[0], i32::from_le_bytes([p[1], p[2], p[3], p[4]]))
}

#[test]
fn goal_position_beyond_the_limit_is_a_data_limit_error_in_modes_3_4_and_5() {
    let mut bus = ServoBusEmulator::new(&[1]);
    let write = |bus: &mut ServoBusEmulator, v: i32| {
        let mut p = vec![116, 0];
        p.extend(v.to_le_bytes());
        error_of(&bus.handle(&pkt(1, ins::WRITE, &p))[0])
    };
    assert_eq!(
        write(&mut bus, 5000),
        err::DATA_LIMIT,
        "mode 3, Max Position Limit 4095"
    );
    assert_eq!(
        read_u32(&mut bus, 1, 116).1,
        2048,
        "the refused goal was not written"
    );
    for mode in [4u8, 5] {
        bus.handle(&pkt(1, ins::WRITE, &[11, 0, mode]));
        assert_eq!(write(&mut bus, 5000), 0, "mode {mode}: multi-turn");
        assert_eq!(write(&mut bus, 1_048_576), err::DATA_LIMIT, "mode {mode}");
    }
}

#[test]
fn present_input_voltage_follows_the_supply_and_a_brown_out_raises_the_alert() {
    let mut bus = ServoBusEmulator::new(&[1, 2]);
    let volts = |bus: &mut ServoBusEmulator| bus.handle(&pkt(2, ins::READ, &[144, 0, 2, 0]));
    assert_eq!(volts(&mut bus)[0].params, vec![0, 120, 0]);
    bus.set_supply_v(9.6);
    assert_eq!(
        volts(&mut bus)[0].params,
        vec![0, 96, 0],
        "above Min Voltage Limit 9.5 V"
    );
    bus.set_supply_v(9.0);
    let r = volts(&mut bus);
    assert_eq!(r[0].params, vec![err::ALERT, 90, 0]);
    let hw = bus.handle(&pkt(2, ins::READ, &[70, 0, 1, 0]));
    assert_eq!(
        hw[0].params[1],
        control_table::hardware_error::INPUT_VOLTAGE
    );
}

#[test]
fn a_quarter_turn_takes_the_no_load_time_however_the_clock_is_sliced() {
    let expected_s = 0.25 / (46.0 / 60.0);
    for slice_s in [0.0005, 0.02, 0.11] {
        let mut bus = ServoBusEmulator::new(&[1]);
        bus.handle(&pkt(1, ins::WRITE, &[116, 0, 0, 12, 0, 0])); // 3072
        bus.handle(&pkt(1, ins::WRITE, &[64, 0, 1]));
        let mut t = 0.0;
        while bus.servo_mut(1).expect("servo").position() != 3072.0 && t < 2.0 {
            bus.advance(slice_s);
            t += slice_s;
        }
        assert!(
            (t - expected_s).abs() <= slice_s + 0.002,
            "slices of {slice_s} s: {t} s"
        );
        let moving = bus.handle(&pkt(1, ins::READ, &[122, 0, 1, 0]));
        assert_eq!(moving[0].params, vec![0, 0]);
    }
}

#[test]
fn fast_sync_and_fast_bulk_read_answer_in_one_packet() {
    let mut bus = ServoBusEmulator::new(&[1, 2, 3]);
    let r = bus.handle(&pkt(
        BROADCAST_ID,
        ins::FAST_SYNC_READ,
        &[132, 0, 4, 0, 1, 2, 3],
    ));
    assert_eq!(r.len(), 1);
    assert_eq!(r[0].id, BROADCAST_ID);
    let segments = FastSegment::split(&r[0], &[4, 4, 4]).expect("three segments");
    assert_eq!(
        segments.iter().map(|s| s.id).collect::<Vec<_>>(),
        vec![1, 2, 3]
    );
    assert!(segments.iter().all(|s| s.data == 2048i32.to_le_bytes()));
    let plan = [1, 144, 0, 2, 0, 3, 146, 0, 1, 0];
    let r = bus.handle(&pkt(BROADCAST_ID, ins::FAST_BULK_READ, &plan));
    let segments = FastSegment::split(&r[0], &[2, 1]).expect("two segments");
    assert_eq!(segments[0].data, vec![120, 0]);
    assert_eq!(segments[1].data, vec![25]);
    let absent = bus.handle(&pkt(
        BROADCAST_ID,
        ins::FAST_SYNC_READ,
        &[132, 0, 4, 0, 1, 9],
    ));
    assert!(absent.is_empty(), "the chain breaks at a missing servo");
}

#[test]
fn indirect_data_reads_and_writes_its_target() {
    let mut bus = ServoBusEmulator::new(&[1]);
    // Indirect Address 1 -> LED (65); write Indirect Data 1, read LED.
    assert_eq!(
        error_of(&bus.handle(&pkt(1, ins::WRITE, &[168, 0, 65, 0]))[0]),
        0
    );
    assert_eq!(
        error_of(&bus.handle(&pkt(1, ins::WRITE, &[224, 0, 1]))[0]),
        0
    );
    assert_eq!(
        bus.handle(&pkt(1, ins::READ, &[65, 0, 1, 0]))[0].params,
        vec![0, 1]
    );
    assert_eq!(
        bus.handle(&pkt(1, ins::READ, &[224, 0, 1, 0]))[0].params,
        vec![0, 1]
    );
}
