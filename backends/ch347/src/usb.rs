//! The libusb transport ([`RusbBulk`]): find a CH347 by VID:PID or by bus-port path (stock
//! units share one serial number, §1), claim its vendor interface (2 on a CH347T in mode 1,
//! 4 on a CH347F) after detaching any kernel driver, and drain stale IN data.
//!
//! It uses an explicit `rusb::Context`: on a machine without USB, libusb's global helpers
//! panic, while `Context::new` returns an error, which becomes [`OpenError::NoUsb`].

use std::time::Duration;

use rusb::UsbContext;

use crate::error::{OpenError, UsbError};
use crate::transport::UsbBulk;

/// WCH's vendor id.
pub const VID: u16 = 0x1A86;
/// CH347T in mode 1 (UART + SPI + I2C + GPIO).
pub const PID_CH347T: u16 = 0x55DB;
/// CH347F.
pub const PID_CH347F: u16 = 0x55DE;
/// Bulk OUT endpoint of the vendor interface.
pub const EP_OUT: u8 = 0x06;
/// Bulk IN endpoint of the vendor interface.
pub const EP_IN: u8 = 0x86;

/// Which device to open.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DeviceSelector {
    /// The only device with this VID:PID.
    VidPid(u16, u16),
    /// The device at this bus and port chain (`1-4.2`: bus 1, port 4, then port 2).
    Path {
        /// Bus number.
        bus: u8,
        /// Port numbers from the root.
        ports: Vec<u8>,
    },
    /// The only CH347 (T in mode 1, or F) present.
    Any,
}

impl std::fmt::Display for DeviceSelector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::VidPid(v, p) => write!(f, "{v:04x}:{p:04x}"),
            Self::Path { bus, ports } => write!(f, "{}", path_text(*bus, ports)),
            Self::Any => f.write_str("any CH347"),
        }
    }
}

fn path_text(bus: u8, ports: &[u8]) -> String {
    let ports: Vec<String> = ports.iter().map(u8::to_string).collect();
    format!("{bus}-{}", ports.join("."))
}

impl std::str::FromStr for DeviceSelector {
    type Err = OpenError;

    /// `auto`, `VID:PID` in hex (`1a86:55de`), or a bus-port path (`1-4.2`).
    fn from_str(s: &str) -> Result<Self, OpenError> {
        let bad = || OpenError::BadSelector {
            selector: s.to_string(),
            expected: "`auto`, VID:PID in hex (1a86:55de) or a bus-port path (1-4.2)",
        };
        if s == "auto" || s.is_empty() {
            return Ok(Self::Any);
        }
        if let Some((v, p)) = s.split_once(':') {
            let v = u16::from_str_radix(v, 16).map_err(|_| bad())?;
            let p = u16::from_str_radix(p, 16).map_err(|_| bad())?;
            return Ok(Self::VidPid(v, p));
        }
        let (bus, ports) = s.split_once('-').ok_or_else(bad)?;
        let bus = bus.parse().map_err(|_| bad())?;
        let ports = ports
            .split('.')
            .map(|p| p.parse().map_err(|_| bad()))
            .collect::<Result<Vec<u8>, _>>()?;
        Ok(Self::Path { bus, ports })
    }
}

/// The vendor interface of a CH347 with product id `pid`.
pub fn vendor_interface(pid: u16) -> Option<u8> {
    match pid {
        PID_CH347T => Some(2),
        PID_CH347F => Some(4),
        _ => None,
    }
}

/// An open CH347 vendor interface.
pub struct RusbBulk {
    handle: rusb::DeviceHandle<rusb::Context>,
    interface: u8,
    /// Where it sits (`bus-ports`).
    pub path: String,
    /// Its product id.
    pub pid: u16,
}

impl std::fmt::Debug for RusbBulk {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RusbBulk")
            .field("path", &self.path)
            .field("pid", &format_args!("{:#06x}", self.pid))
            .field("interface", &self.interface)
            .finish()
    }
}

fn usb_error(operation: &'static str, e: rusb::Error, timeout: Duration) -> UsbError {
    match e {
        rusb::Error::Timeout => UsbError::Timeout {
            direction: operation,
            timeout_ms: timeout.as_millis() as u64,
        },
        rusb::Error::NoDevice | rusb::Error::Io | rusb::Error::Pipe => UsbError::Disconnected {
            detail: format!("{operation}: {e}"),
        },
        other => UsbError::Io {
            operation,
            detail: other.to_string(),
        },
    }
}

impl RusbBulk {
    /// Find and open the device `selector` names, claim its vendor interface and drain
    /// what its IN endpoint still holds.
    pub fn open(selector: &DeviceSelector) -> Result<Self, OpenError> {
        let context = rusb::Context::new().map_err(|e| OpenError::NoUsb {
            detail: e.to_string(),
        })?;
        let devices = context.devices().map_err(|e| OpenError::NoUsb {
            detail: e.to_string(),
        })?;
        let mut found = Vec::new();
        let mut matches = Vec::new();
        for device in devices.iter() {
            let Ok(desc) = device.device_descriptor() else {
                continue;
            };
            let (vid, pid) = (desc.vendor_id(), desc.product_id());
            let ports = device.port_numbers().unwrap_or_default();
            let path = path_text(device.bus_number(), &ports);
            let is_ch347 = vid == VID && vendor_interface(pid).is_some();
            if is_ch347 {
                found.push(format!("{path} ({vid:04x}:{pid:04x})"));
            }
            let wanted = match selector {
                DeviceSelector::Any => is_ch347,
                DeviceSelector::VidPid(v, p) => vid == *v && pid == *p,
                DeviceSelector::Path { bus, ports: want } => {
                    device.bus_number() == *bus && ports == *want
                }
            };
            if wanted {
                matches.push((device, pid, path));
            }
        }
        let found_text = if found.is_empty() {
            "none".to_string()
        } else {
            found.join(", ")
        };
        let (device, pid, path) = match matches.len() {
            0 => {
                return Err(OpenError::NotFound {
                    selector: selector.to_string(),
                    found: found_text,
                });
            }
            1 => matches.remove(0),
            count => {
                return Err(OpenError::Ambiguous {
                    selector: selector.to_string(),
                    count,
                    found: matches
                        .iter()
                        .map(|m| m.2.clone())
                        .collect::<Vec<_>>()
                        .join(", "),
                });
            }
        };
        let interface = vendor_interface(pid).ok_or_else(|| OpenError::NotFound {
            selector: format!("{selector} (product {pid:04x} is not a CH347 in a vendor mode)"),
            found: found_text.clone(),
        })?;
        let fail = |operation: String, e: rusb::Error| OpenError::Usb {
            operation,
            device: path.clone(),
            detail: e.to_string(),
        };
        let handle = device.open().map_err(|e| fail("open".into(), e))?;
        if handle.kernel_driver_active(interface).unwrap_or(false) {
            handle.detach_kernel_driver(interface).map_err(|e| {
                fail(
                    format!("detach the kernel driver from interface {interface}"),
                    e,
                )
            })?;
        }
        handle
            .claim_interface(interface)
            .map_err(|e| fail(format!("claim interface {interface}"), e))?;
        let mut bulk = Self {
            handle,
            interface,
            path,
            pid,
        };
        let mut buf = [0u8; 512];
        while matches!(bulk.read(&mut buf, Duration::from_millis(20)), Ok(n) if n > 0) {}
        Ok(bulk)
    }
}

impl Drop for RusbBulk {
    fn drop(&mut self) {
        let _ = self.handle.release_interface(self.interface);
    }
}

impl UsbBulk for RusbBulk {
    fn write(&mut self, data: &[u8], timeout: Duration) -> Result<usize, UsbError> {
        self.handle
            .write_bulk(EP_OUT, data, timeout)
            .map_err(|e| usb_error("write", e, timeout))
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, UsbError> {
        self.handle
            .read_bulk(EP_IN, buf, timeout)
            .map_err(|e| usb_error("read", e, timeout))
    }
}
