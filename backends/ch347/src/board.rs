//! Emulated sensor boards (feature `emulator`) behind the chip emulator: each answers the
//! hub protocol's I2C register map at `0x20 + i`, captures on its trigger address
//! `0x40 + i` or the general call (`0x0C`), and returns its ready frame over SPI (header,
//! JPEG, CRC-32) while selected. Images come from a [`BoardCameras`] port (the simulator).

use std::sync::{Arc, Mutex};

use gelgrip_controller::camera::BoardCameras;
pub use gelgrip_controller::camera::BoardFaults;
use gelgrip_hubwire::regs::{self, Register, status};
use gelgrip_hubwire::spi_frame::{self, FrameHeader};

use crate::driver::CsLine;
use crate::emu::{Ch347Emulator, I2cTarget, SpiTarget};

#[derive(Debug, Default)]
struct BoardState {
    index: u8,
    next_seq: u32,
    exposure_us: u32,
    status: u8,
    frame: Vec<u8>,
    cursor: usize,
    pointer: u8,
    captures: u64,
    faults: BoardFaults,
}

/// The boards of one hub and the cameras they share.
pub struct Boards {
    states: Vec<Arc<Mutex<BoardState>>>,
    cameras: Arc<Mutex<Box<dyn BoardCameras>>>,
    /// Host time source for captures (the emulator has no clock of its own), µs.
    now_us: Arc<dyn Fn() -> u64 + Send + Sync>,
}

impl std::fmt::Debug for Boards {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Boards")
            .field("boards", &self.states.len())
            .finish()
    }
}

impl Boards {
    /// Attach one board per camera to `emu`: registers at `0x20 + i`, trigger at
    /// `0x40 + i`, SPI on `cs[i]`; `now_us` stamps captures.
    pub fn attach(
        emu: &mut Ch347Emulator,
        cameras: Box<dyn BoardCameras>,
        cs: &[CsLine],
        now_us: Arc<dyn Fn() -> u64 + Send + Sync>,
    ) -> Self {
        let n = cameras
            .boards()
            .min(cs.len())
            .min(usize::from(regs::MAX_BOARDS));
        let cameras = Arc::new(Mutex::new(cameras));
        let states: Vec<_> = (0..n)
            .map(|i| {
                Arc::new(Mutex::new(BoardState {
                    index: i as u8,
                    ..BoardState::default()
                }))
            })
            .collect();
        let boards = Self {
            states,
            cameras,
            now_us,
        };
        for (i, line) in cs.iter().enumerate().take(n) {
            let handle = |trigger: bool| BoardHandle {
                state: boards.states[i].clone(),
                cameras: boards.cameras.clone(),
                now_us: boards.now_us.clone(),
                trigger,
            };
            let index = i as u8;
            if let Some(a) = regs::register_address(index) {
                emu.attach_i2c(a, Box::new(handle(false)));
            }
            if let Some(a) = regs::trigger_address(index) {
                emu.attach_i2c(a, Box::new(handle(true)));
            }
            emu.attach_spi(*line, Box::new(handle(false)));
        }
        boards
    }

    /// Set board `i`'s faults.
    pub fn set_faults(&self, i: usize, faults: BoardFaults) {
        if let Some(s) = self.states.get(i)
            && let Ok(mut s) = s.lock()
        {
            s.faults = faults;
        }
    }
}

/// One board's view, attached at each of its addresses and its chip select.
struct BoardHandle {
    state: Arc<Mutex<BoardState>>,
    cameras: Arc<Mutex<Box<dyn BoardCameras>>>,
    now_us: Arc<dyn Fn() -> u64 + Send + Sync>,
    /// Attached at the trigger address (which alone answers the general call, so a board
    /// captures once per broadcast).
    trigger: bool,
}

impl BoardHandle {
    fn capture(&self, s: &mut BoardState) {
        let now = (self.now_us)();
        let nth = s.captures;
        s.captures += 1;
        let jpeg = match self.cameras.lock() {
            Ok(mut c) => c.capture(usize::from(s.index), nth, now),
            Err(_) => Default::default(),
        };
        if s.status & status::FRAME_READY != 0 {
            s.status |= status::OVERRUN;
        }
        let header = FrameHeader {
            sensor_id: s.index,
            trigger_seq: s.next_seq,
            capture_offset_us: s.faults.capture_delay_us,
            exposure_us: s.exposure_us,
            payload_len: 0,
        };
        s.frame = spi_frame::encode(&header, &jpeg);
        if s.faults.corrupt_every > 0 && nth.is_multiple_of(s.faults.corrupt_every) {
            let at = s.frame.len() / 2;
            s.frame[at] ^= 0x10;
        }
        s.cursor = 0;
        s.status |= status::FRAME_READY;
        s.next_seq = s.next_seq.wrapping_add(1);
    }

    fn register_bytes(s: &BoardState, reg: u8) -> Vec<u8> {
        let mut map = [0u8; 0x40];
        map[Register::WhoAmI as usize] = regs::WHO_AM_I_VALUE;
        map[Register::ProtocolVersion as usize] = gelgrip_hubwire::PROTOCOL_VERSION;
        map[Register::FirmwareVersion as usize] = 1;
        map[Register::Serial as usize..Register::Serial as usize + 4]
            .copy_from_slice(&(0x4747_0000 + u32::from(s.index)).to_le_bytes());
        map[Register::Status as usize] = s.status;
        map[Register::FrameLength as usize..Register::FrameLength as usize + 4]
            .copy_from_slice(&(s.frame.len() as u32).to_le_bytes());
        let seq = s.next_seq.wrapping_sub(1);
        map[Register::FrameSeq as usize..Register::FrameSeq as usize + 4]
            .copy_from_slice(&seq.to_le_bytes());
        map[Register::ExposureUs as usize..Register::ExposureUs as usize + 4]
            .copy_from_slice(&s.exposure_us.to_le_bytes());
        map[Register::NextSeq as usize..Register::NextSeq as usize + 4]
            .copy_from_slice(&s.next_seq.to_le_bytes());
        map[usize::from(reg).min(map.len())..].to_vec()
    }
}

impl I2cTarget for BoardHandle {
    fn present(&self) -> bool {
        self.state.lock().is_ok_and(|s| !s.faults.dead)
    }

    fn write(&mut self, general_call: bool, data: &[u8]) {
        let Ok(mut s) = self.state.lock() else {
            return;
        };
        if s.faults.dead {
            return;
        }
        if general_call {
            if self.trigger && data == [regs::GENERAL_CALL_CAPTURE] {
                self.capture(&mut s);
            }
            return;
        }
        if self.trigger {
            // The trigger address takes address-only writes: capture.
            if data.is_empty() {
                self.capture(&mut s);
            }
            return;
        }
        let Some((&reg, rest)) = data.split_first() else {
            return;
        };
        s.pointer = reg;
        let mut word = [0u8; 4];
        for (i, b) in rest.iter().take(4).enumerate() {
            word[i] = *b;
        }
        let value = u32::from_le_bytes(word);
        match reg {
            r if r == Register::NextSeq as u8 && rest.len() >= 4 => s.next_seq = value,
            r if r == Register::ExposureUs as u8 && rest.len() >= 4 => s.exposure_us = value,
            r if r == Register::Control as u8
                && value & u32::from(regs::control::CLEAR_OVERRUN) != 0 =>
            {
                s.status &= !status::OVERRUN;
            }
            _ => {}
        }
    }

    fn read(&mut self, n: usize) -> Vec<u8> {
        let Ok(mut s) = self.state.lock() else {
            return vec![0xFF; n];
        };
        let mut out = Self::register_bytes(&s, s.pointer);
        out.resize(n, 0);
        s.pointer = s.pointer.wrapping_add(n as u8);
        out
    }
}

impl SpiTarget for BoardHandle {
    fn select(&mut self) {
        if let Ok(mut s) = self.state.lock() {
            s.cursor = 0;
        }
    }

    fn transfer(&mut self, mosi: &[u8]) -> Vec<u8> {
        let Ok(mut s) = self.state.lock() else {
            return vec![0xFF; mosi.len()];
        };
        if s.faults.dead {
            return vec![0xFF; mosi.len()];
        }
        let start = s.cursor;
        let end = (start + mosi.len()).min(s.frame.len());
        let mut out: Vec<u8> = s.frame.get(start..end).unwrap_or_default().to_vec();
        out.resize(mosi.len(), 0xFF);
        s.cursor = start + mosi.len();
        if s.cursor >= s.frame.len() && !s.frame.is_empty() {
            s.status &= !status::FRAME_READY;
        }
        out
    }
}
