//! [`ServoBusEmulator`]: the instruction dispatcher of a bus of emulated servos, and the
//! wire bytes it answers with.

use super::EmulatedServo;
use crate::protocol::status_error as err;
use crate::protocol::{BROADCAST_ID, FastSegment, Packet, instruction as ins};

fn u16_at(p: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*p.get(at)?, *p.get(at + 1)?]))
}

/// A bus of emulated servos.
#[derive(Debug)]
pub struct ServoBusEmulator {
    servos: Vec<EmulatedServo>,
    cut_next_reply: Option<usize>,
}

impl ServoBusEmulator {
    /// Servos with `ids`, factory-fresh.
    pub fn new(ids: &[u8]) -> Self {
        Self::from_servos(ids.iter().map(|id| EmulatedServo::new(*id)).collect())
    }

    /// Servos built by the caller (for example with motors).
    pub fn from_servos(servos: Vec<EmulatedServo>) -> Self {
        Self {
            servos,
            cut_next_reply: None,
        }
    }

    /// Every servo's supply voltage, V.
    pub fn set_supply_v(&mut self, supply_v: f64) {
        for s in &mut self.servos {
            s.set_supply_v(supply_v);
        }
    }

    /// Fault hook: of the next reply [`Self::respond`] produces, send only the first
    /// `keep_bytes` wire bytes, and nothing more for that instruction (the line goes silent
    /// mid-transfer, as when a cable is pulled). Replies after that are whole again.
    pub fn cut_next_reply(&mut self, keep_bytes: usize) {
        self.cut_next_reply = Some(keep_bytes);
    }

    /// The wire bytes answering `p`, one entry per status packet, in order: [`Self::handle`]
    /// encoded, with a pending [`Self::cut_next_reply`] applied.
    pub fn respond(&mut self, p: &Packet) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        for reply in self.handle(p) {
            let mut bytes = reply.encode();
            if let Some(keep) = self.cut_next_reply.take() {
                bytes.truncate(keep);
                out.push(bytes);
                break;
            }
            out.push(bytes);
        }
        out
    }

    /// Integrate every servo's motion over `dt_s` of clock time (no external load).
    pub fn advance(&mut self, dt_s: f64) {
        for s in &mut self.servos {
            s.advance(dt_s, 0.0);
        }
    }

    /// The servo with `id`.
    pub fn servo_mut(&mut self, id: u8) -> Option<&mut EmulatedServo> {
        self.servos.iter_mut().find(|s| s.id() == id)
    }

    fn find(&self, id: u8) -> Option<usize> {
        self.servos.iter().position(|s| s.id() == id)
    }

    /// Handle one instruction packet; returns the status packets to send, in order. A Fast
    /// Sync/Bulk Read's reply is one packet from the broadcast id.
    pub fn handle(&mut self, p: &Packet) -> Vec<Packet> {
        match p.instruction {
            ins::PING => self.ping(p.id),
            ins::SYNC_READ => self.sync_read(p),
            ins::FAST_SYNC_READ => self.fast(self.sync_plan(p)).into_iter().collect(),
            ins::SYNC_WRITE => {
                self.sync_write(p);
                Vec::new()
            }
            ins::BULK_READ => self.bulk_read(p),
            ins::FAST_BULK_READ => self.fast(Some(bulk_plan(p))).into_iter().collect(),
            ins::BULK_WRITE => {
                self.bulk_write(p);
                Vec::new()
            }
            _ if p.id == BROADCAST_ID => {
                for i in 0..self.servos.len() {
                    let _ = self.unicast(i, p);
                }
                Vec::new()
            }
            _ => match self.find(p.id) {
                Some(i) => self.unicast(i, p).into_iter().collect(),
                None => Vec::new(),
            },
        }
    }

    fn ping(&self, id: u8) -> Vec<Packet> {
        self.servos
            .iter()
            .filter(|s| id == BROADCAST_ID || s.id() == id)
            .map(|s| {
                let mut params = s.table[0..2].to_vec();
                params.push(s.table[usize::from(crate::control_table::addr::FIRMWARE_VERSION)]);
                s.status(0, &params)
            })
            .collect()
    }

    fn unicast(&mut self, i: usize, p: &Packet) -> Option<Packet> {
        let s = &mut self.servos[i];
        let data = p.params.get(2..).unwrap_or(&[]);
        let result: Result<Vec<u8>, u8> = match p.instruction {
            ins::READ => match (u16_at(&p.params, 0), u16_at(&p.params, 2)) {
                (Some(a), Some(n)) => s.read(a, usize::from(n)),
                _ => Err(err::DATA_LENGTH),
            },
            ins::WRITE => match u16_at(&p.params, 0) {
                Some(a) => s.write(a, data).map(|()| Vec::new()),
                None => Err(err::DATA_LENGTH),
            },
            ins::REG_WRITE => match u16_at(&p.params, 0) {
                Some(a) => s.check_write(a, data).map(|()| {
                    s.registered = Some((a, data.to_vec()));
                    s.table[usize::from(crate::control_table::addr::REGISTERED_INSTRUCTION)] = 1;
                    Vec::new()
                }),
                None => Err(err::DATA_LENGTH),
            },
            ins::ACTION => match s.registered.take() {
                Some((a, data)) => {
                    s.table[usize::from(crate::control_table::addr::REGISTERED_INSTRUCTION)] = 0;
                    s.write(a, &data).map(|()| Vec::new())
                }
                None => Err(err::INSTRUCTION),
            },
            ins::REBOOT => {
                s.reboot();
                Ok(Vec::new())
            }
            ins::FACTORY_RESET => match p.params.first() {
                Some(option) => s.factory_reset(*option).map(|()| Vec::new()),
                None => Err(err::DATA_LENGTH),
            },
            ins::CLEAR => s.clear(&p.params).map(|()| Vec::new()),
            _ => Err(err::INSTRUCTION),
        };
        let reply = match result {
            Ok(data) => s.status(0, &data),
            Err(e) => s.status(e, &[]),
        };
        (s.replies_to(p.instruction) && p.id != BROADCAST_ID).then_some(reply)
    }

    fn read_reply(s: &EmulatedServo, a: u16, n: u16) -> Packet {
        match s.read(a, usize::from(n)) {
            Ok(d) => s.status(0, &d),
            Err(e) => s.status(e, &[]),
        }
    }

    fn sync_read(&self, p: &Packet) -> Vec<Packet> {
        let Some(plan) = self.sync_plan(p) else {
            return Vec::new();
        };
        plan.into_iter()
            .filter_map(|(id, a, n)| {
                let s = &self.servos[self.find(id)?];
                s.replies_to(ins::SYNC_READ)
                    .then(|| Self::read_reply(s, a, n))
            })
            .collect()
    }

    /// The (id, address, count) a sync read asks for.
    fn sync_plan(&self, p: &Packet) -> Option<Vec<(u8, u16, u16)>> {
        let (a, n) = (u16_at(&p.params, 0)?, u16_at(&p.params, 2)?);
        Some(
            p.params
                .get(4..)
                .unwrap_or(&[])
                .iter()
                .map(|id| (*id, a, n))
                .collect(),
        )
    }

    /// The one combined reply of a fast read, or none when a listed servo is absent or
    /// silent (the chain of segments breaks there, and the client times out).
    fn fast(&self, plan: Option<Vec<(u8, u16, u16)>>) -> Option<Packet> {
        let plan = plan?;
        let mut segments = Vec::with_capacity(plan.len());
        for (id, a, n) in plan {
            let s = &self.servos[self.find(id)?];
            if !s.replies_to(ins::FAST_SYNC_READ) {
                return None;
            }
            let (error, data) = match s.read(a, usize::from(n)) {
                Ok(d) => (0, d),
                Err(e) => (e, vec![0; usize::from(n)]),
            };
            segments.push(FastSegment {
                id,
                error: error | s.alert(),
                data,
            });
        }
        (!segments.is_empty()).then(|| FastSegment::reply(&segments))
    }

    fn sync_write(&mut self, p: &Packet) {
        let (Some(a), Some(n)) = (u16_at(&p.params, 0), u16_at(&p.params, 2)) else {
            return;
        };
        let n = usize::from(n);
        for chunk in p.params.get(4..).unwrap_or(&[]).chunks_exact(n + 1) {
            if let Some(i) = self.find(chunk[0]) {
                let _ = self.servos[i].write(a, &chunk[1..]);
            }
        }
    }

    fn bulk_read(&self, p: &Packet) -> Vec<Packet> {
        bulk_plan(p)
            .into_iter()
            .filter_map(|(id, a, n)| {
                let s = &self.servos[self.find(id)?];
                s.replies_to(ins::BULK_READ)
                    .then(|| Self::read_reply(s, a, n))
            })
            .collect()
    }

    fn bulk_write(&mut self, p: &Packet) {
        let mut rest = p.params.as_slice();
        while rest.len() >= 5 {
            let (id, a, n) = (
                rest[0],
                u16_at(rest, 1).unwrap_or(0),
                usize::from(u16_at(rest, 3).unwrap_or(0)),
            );
            let Some(data) = rest.get(5..5 + n) else {
                return;
            };
            if let Some(i) = self.find(id) {
                let _ = self.servos[i].write(a, data);
            }
            rest = &rest[5 + n..];
        }
    }
}

/// The (id, address, count) entries of a bulk read.
fn bulk_plan(p: &Packet) -> Vec<(u8, u16, u16)> {
    p.params
        .chunks_exact(5)
        .filter_map(|c| Some((c[0], u16_at(c, 1)?, u16_at(c, 3)?)))
        .collect()
}
