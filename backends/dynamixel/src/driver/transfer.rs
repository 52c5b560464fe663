//! The Protocol 2.0 instructions [`DynamixelBus`] sends through its [`Link`]: ping, read,
//! write, reboot, Sync Read, Fast Sync Read and Fast Bulk Read, each reply checked and a
//! status error turned into a [`DriverError`] that names servo, register and value; and the
//! bus time a state read takes.

use super::error::DriverError;
use super::link::STATUS_OVERHEAD;
use super::{DynamixelBus, STATE_BLOCK, STATE_BLOCK_LEN};
use crate::control_table::item_at;
use crate::protocol::{BROADCAST_ID, FastSegment, Packet, instruction as ins, status_error};

/// The bus time of one state read of `ids` at `baud`, µs: the instruction, the replies and
/// the servos' Return Delay Time (`return_delay_us` each; one for a Fast Sync Read, whose
/// servos append their segments back to back), 10 bits a byte. From the encoded packets.
pub fn state_read_bus_time_us(ids: &[u8], fast: bool, baud: u32, return_delay_us: f64) -> f64 {
    let instruction = if fast {
        ins::FAST_SYNC_READ
    } else {
        ins::SYNC_READ
    };
    let request = DynamixelBus::sync_read_packet(instruction, ids, STATE_BLOCK, STATE_BLOCK_LEN);
    let data = vec![0u8; usize::from(STATE_BLOCK_LEN)];
    let (reply_bytes, delays) = if fast {
        let segments: Vec<FastSegment> = ids
            .iter()
            .map(|&id| FastSegment {
                id,
                error: 0,
                data: data.clone(),
            })
            .collect();
        (FastSegment::reply(&segments).encode().len(), 1.0)
    } else {
        let one = Packet::status(1, 0, &data).encode().len();
        (one * ids.len(), ids.len() as f64)
    };
    let bytes = request.encode().len() + reply_bytes;
    bytes as f64 * 10.0 * 1e6 / f64::from(baud.max(1)) + delays * return_delay_us
}

/// The value `bytes` written at `address` stand for (signed where the item is).
fn value_of(address: u16, bytes: &[u8]) -> i64 {
    let n = bytes.len().min(8);
    let mut b = [0u8; 8];
    b[..n].copy_from_slice(&bytes[..n]);
    let v = i64::from_le_bytes(b);
    let signed = item_at(address).is_some_and(|i| i.signed && usize::from(i.size) == n);
    if signed && n > 0 {
        let shift = 64 - 8 * n as u32;
        (v << shift) >> shift
    } else {
        v
    }
}

/// The typed error for status error byte `error` from servo `id` after an access of
/// `address` (with `value` for a write).
fn status_error_of(id: u8, error: u8, address: u16, value: Option<i64>, what: &str) -> DriverError {
    let register = crate::control_table::name_of(address);
    match error & 0x7F {
        status_error::DATA_LIMIT => DriverError::DataLimit {
            id,
            register,
            address,
            value: value.unwrap_or(0),
        },
        status_error::ACCESS => DriverError::Access {
            id,
            register,
            address,
            value,
        },
        n => DriverError::Status {
            id,
            error: n,
            what: what.to_string(),
        },
    }
}

impl DynamixelBus {
    /// One instruction to `id` and its status packet, with the status error checked.
    fn transact(
        &mut self,
        p: &Packet,
        reply_params: usize,
        address: u16,
        value: Option<i64>,
        what: &str,
    ) -> Result<Vec<u8>, DriverError> {
        self.link.send(p)?;
        let deadline = self.link.reply_deadline(STATUS_OVERHEAD + reply_params);
        let reply = self.link.receive(Some(p.id), p.id, deadline, what)?;
        let error = reply.params[0];
        self.last_alert = error & status_error::ALERT != 0;
        if error & 0x7F != 0 {
            return Err(status_error_of(p.id, error, address, value, what));
        }
        Ok(reply.params[1..].to_vec())
    }

    /// Whether the last status packet of a ping, read, write or reboot had the hardware
    /// alert bit set (read Hardware Error Status, address 70).
    pub fn last_alert(&self) -> bool {
        self.last_alert
    }

    /// Broadcast ping: (id, model, firmware) of every servo that answers before the
    /// deadline: 253 replies' wire time plus the padding, as ROBOTIS's SDK waits.
    pub fn scan(&mut self) -> Result<Vec<(u8, u16, u8)>, DriverError> {
        let p = Packet {
            id: BROADCAST_ID,
            instruction: ins::PING,
            params: vec![],
        };
        self.link.send(&p)?;
        let until =
            std::time::Instant::now() + self.link.reply_deadline(253 * (STATUS_OVERHEAD + 3));
        let mut found = Vec::new();
        loop {
            let left = until.saturating_duration_since(std::time::Instant::now());
            match self
                .link
                .receive(None, BROADCAST_ID, left, "broadcast ping")
            {
                Ok(r) => match r.params[..] {
                    [_, lo, hi, fw] => found.push((r.id, u16::from_le_bytes([lo, hi]), fw)),
                    _ => {
                        return Err(DriverError::Corrupt {
                            id: r.id,
                            detail: format!("{} ping bytes", r.params.len()),
                        });
                    }
                },
                Err(DriverError::Timeout { .. }) => return Ok(found),
                Err(e) => return Err(e),
            }
        }
    }

    /// Ping `id`: its model number and firmware version.
    pub fn ping(&mut self, id: u8) -> Result<(u16, u8), DriverError> {
        let p = Packet {
            id,
            instruction: ins::PING,
            params: vec![],
        };
        let d = self.transact(&p, 3, 0, None, "ping")?;
        match d[..] {
            [lo, hi, fw] => Ok((u16::from_le_bytes([lo, hi]), fw)),
            _ => Err(DriverError::Corrupt {
                id,
                detail: format!("{} ping bytes", d.len()),
            }),
        }
    }

    /// Write `bytes` at `address` of servo `id`.
    pub fn write(&mut self, id: u8, address: u16, bytes: &[u8]) -> Result<(), DriverError> {
        let mut params = address.to_le_bytes().to_vec();
        params.extend_from_slice(bytes);
        let p = Packet {
            id,
            instruction: ins::WRITE,
            params,
        };
        let what = format!("write of {}", crate::control_table::name_of(address));
        self.transact(&p, 0, address, Some(value_of(address, bytes)), &what)
            .map(|_| ())
    }

    /// Read `len` bytes at `address` of servo `id`.
    pub fn read(&mut self, id: u8, address: u16, len: u16) -> Result<Vec<u8>, DriverError> {
        let mut params = address.to_le_bytes().to_vec();
        params.extend_from_slice(&len.to_le_bytes());
        let p = Packet {
            id,
            instruction: ins::READ,
            params,
        };
        let what = format!("read of {}", crate::control_table::name_of(address));
        let d = self.transact(&p, usize::from(len), address, None, &what)?;
        if d.len() != usize::from(len) {
            return Err(DriverError::Corrupt {
                id,
                detail: format!("{} bytes, expected {len}", d.len()),
            });
        }
        Ok(d)
    }

    /// Reboot servo `id`.
    pub fn reboot_servo(&mut self, id: u8) -> Result<(), DriverError> {
        let p = Packet {
            id,
            instruction: ins::REBOOT,
            params: vec![],
        };
        self.transact(&p, 0, 0, None, "reboot").map(|_| ())
    }

    /// Sync Read of `len` bytes at `address` from `ids`: one status packet each, in order.
    pub fn sync_read(
        &mut self,
        ids: &[u8],
        address: u16,
        len: u16,
    ) -> Result<Vec<Vec<u8>>, DriverError> {
        let p = Self::sync_read_packet(ins::SYNC_READ, ids, address, len);
        self.link.send(&p)?;
        let deadline = self.link.reply_deadline(STATUS_OVERHEAD + usize::from(len));
        ids.iter()
            .map(|&id| {
                let r = self.link.receive(Some(id), id, deadline, "sync read")?;
                self.check_data(id, r.params[0], &r.params[1..], address, len)
            })
            .collect()
    }

    /// Fast Sync Read of `len` bytes at `address` from `ids`: one combined status packet.
    pub fn fast_sync_read(
        &mut self,
        ids: &[u8],
        address: u16,
        len: u16,
    ) -> Result<Vec<Vec<u8>>, DriverError> {
        let plan: Vec<(u8, u16, u16)> = ids.iter().map(|&id| (id, address, len)).collect();
        let p = Self::sync_read_packet(ins::FAST_SYNC_READ, ids, address, len);
        self.fast_read(&p, &plan, "fast sync read")
    }

    /// Fast Bulk Read of (id, address, len) entries: one combined status packet.
    pub fn fast_bulk_read(&mut self, plan: &[(u8, u16, u16)]) -> Result<Vec<Vec<u8>>, DriverError> {
        let mut params = Vec::with_capacity(plan.len() * 5);
        for (id, a, n) in plan {
            params.push(*id);
            params.extend_from_slice(&a.to_le_bytes());
            params.extend_from_slice(&n.to_le_bytes());
        }
        let p = Packet {
            id: BROADCAST_ID,
            instruction: ins::FAST_BULK_READ,
            params,
        };
        self.fast_read(&p, plan, "fast bulk read")
    }

    fn sync_read_packet(instruction: u8, ids: &[u8], address: u16, len: u16) -> Packet {
        let mut params = address.to_le_bytes().to_vec();
        params.extend_from_slice(&len.to_le_bytes());
        params.extend_from_slice(ids);
        Packet {
            id: BROADCAST_ID,
            instruction,
            params,
        }
    }

    fn fast_read(
        &mut self,
        p: &Packet,
        plan: &[(u8, u16, u16)],
        what: &str,
    ) -> Result<Vec<Vec<u8>>, DriverError> {
        let first = plan.first().map_or(0, |e| e.0);
        self.link.send(p)?;
        let lens: Vec<usize> = plan.iter().map(|e| usize::from(e.2)).collect();
        let bytes = 8 + lens.iter().map(|n| n + 4).sum::<usize>();
        let deadline = self.link.reply_deadline(bytes);
        let reply = self
            .link
            .receive(Some(BROADCAST_ID), first, deadline, what)?;
        let segments = FastSegment::split(&reply, &lens).ok_or_else(|| DriverError::Corrupt {
            id: first,
            detail: format!("{what}: segments or their CRCs do not match {lens:?}"),
        })?;
        plan.iter()
            .zip(segments)
            .map(|(&(id, a, n), s)| {
                if s.id != id {
                    return Err(DriverError::Corrupt {
                        id,
                        detail: format!("{what}: segment of id {}", s.id),
                    });
                }
                self.check_data(id, s.error, &s.data, a, n)
            })
            .collect()
    }

    fn check_data(
        &self,
        id: u8,
        error: u8,
        data: &[u8],
        address: u16,
        len: u16,
    ) -> Result<Vec<u8>, DriverError> {
        if error & 0x7F != 0 {
            return Err(status_error_of(id, error, address, None, "read"));
        }
        if data.len() != usize::from(len) {
            return Err(DriverError::Corrupt {
                id,
                detail: format!("{} bytes, expected {len}", data.len()),
            });
        }
        Ok(data.to_vec())
    }
}
