//! gelgrip's MCU hub on USB-CDC: [`hub::CdcHub`], the host transport over `serialport`
//! (version handshake, clock sync, free-running sets, reconnect and `Resume` after an
//! unplug), and [`emu`] (feature `emulator`), the hub firmware emulator that serves the same
//! protocol on a pseudo-terminal from the simulator's cameras, paced at the modelled USB
//! link rate. The wire format is `hubwire::cdc` (docs/protocol.md §5).

pub mod config;
#[cfg(feature = "emulator")]
pub mod emu;
pub mod factory;
pub mod hub;

/// Whether an I/O error only means "not now" (a timeout, a full or empty non-blocking pty,
/// a signal), as opposed to the other side being gone.
pub fn transient(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::TimedOut
            | std::io::ErrorKind::WouldBlock
            | std::io::ErrorKind::Interrupted
    )
}
