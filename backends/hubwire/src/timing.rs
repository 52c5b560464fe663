//! The paper's closed-form bus model (section II-A) and the trigger terms it leaves out.
//!
//! Paper: `f = 1 / (N·t_spi + t_buf)` and `latency = N·t_spi + t_buf + t_usb`, with
//! `t_spi = S·8 / f_spi` for a frame of `S` bytes. The model omits the I2C trigger transfer;
//! [`BusModel::trigger_us`] gives it from [`crate::i2c`], so callers can show the difference.

use crate::i2c::{self, TriggerMode};

/// Inputs of the bus model for one hub.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusModel {
    /// Number of sensor boards N.
    pub sensors: u8,
    /// How the trigger is sent.
    pub trigger: TriggerMode,
    /// I2C clock in Hz (400 kHz Fast-mode).
    pub i2c_hz: u32,
    /// SPI clock in Hz.
    pub spi_clock_hz: u32,
    /// Mean SPI frame length S in bytes (header + JPEG + CRC).
    pub mean_frame_bytes: f64,
    /// Board buffering time t_buf in µs.
    pub t_buf_us: f64,
    /// USB forwarding time t_usb in µs.
    pub t_usb_us: f64,
    /// Bound on a board's trigger-to-capture latency jitter in µs (its interrupt latency).
    pub capture_jitter_us: f64,
}

impl BusModel {
    /// SPI transfer time of one mean frame, t_spi, in µs.
    pub fn t_spi_us(&self) -> f64 {
        self.mean_frame_bytes * 8.0 / f64::from(self.spi_clock_hz.max(1)) * 1e6
    }

    /// The paper's frame-set rate f = 1 / (N·t_spi + t_buf), in Hz.
    pub fn paper_rate_hz(&self) -> f64 {
        1e6 / (f64::from(self.sensors) * self.t_spi_us() + self.t_buf_us)
    }

    /// The paper's latency N·t_spi + t_buf + t_usb, in µs.
    pub fn paper_latency_us(&self) -> f64 {
        f64::from(self.sensors) * self.t_spi_us() + self.t_buf_us + self.t_usb_us
    }

    /// I2C time from the first START to the first board's capture, in µs.
    pub fn trigger_us(&self) -> f64 {
        i2c::capture_instants_ns(self.trigger, self.sensors.max(1), self.i2c_hz)
            .first()
            .copied()
            .unwrap_or(0) as f64
            / 1e3
    }

    /// Predicted capture spread of one set: the trigger stagger plus the capture jitter
    /// bound plus 1 µs of timestamp quantisation, in µs.
    pub fn trigger_spread_us(&self) -> f64 {
        let at = i2c::capture_instants_ns(self.trigger, self.sensors, self.i2c_hz);
        let stagger = match (at.first(), at.last()) {
            (Some(first), Some(last)) => (last - first) as f64 / 1e3,
            _ => 0.0,
        };
        stagger + self.capture_jitter_us + 1.0
    }

    /// Predicted set period including the trigger transfer, in µs.
    pub fn set_period_us(&self) -> f64 {
        self.trigger_us() + f64::from(self.sensors) * self.t_spi_us() + self.t_buf_us
    }

    /// Predicted latency from capture to the last frame at the host, in µs.
    pub fn set_latency_us(&self) -> f64 {
        self.paper_latency_us() + self.trigger_spread_us()
    }
}

impl From<&BusModel> for gelgrip_controller::hub::BusPrediction {
    /// The model's predictions, as transports describe them.
    fn from(model: &BusModel) -> Self {
        Self {
            mean_frame_bytes: model.mean_frame_bytes,
            t_spi_us: model.t_spi_us(),
            trigger_spread_us: model.trigger_spread_us(),
            trigger_us: model.trigger_us(),
            paper_rate_hz: model.paper_rate_hz(),
            paper_latency_us: model.paper_latency_us(),
            set_period_us: model.set_period_us(),
            set_latency_us: model.set_latency_us(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper() -> BusModel {
        BusModel {
            sensors: 7,
            trigger: TriggerMode::Sequential,
            i2c_hz: i2c::FAST_MODE_HZ,
            spi_clock_hz: 40_000_000,
            mean_frame_bytes: 20_000.0,
            t_buf_us: 1000.0,
            t_usb_us: 500.0,
            capture_jitter_us: 0.0,
        }
    }

    #[test]
    fn reproduces_the_papers_figures() {
        let m = paper();
        assert!((m.t_spi_us() - 4000.0).abs() < 1e-9);
        assert!((m.paper_rate_hz() - 34.48).abs() < 0.01);
        assert!((m.paper_latency_us() - 29_500.0).abs() < 1e-9);
    }

    #[test]
    fn broadcast_removes_the_stagger() {
        let seq = paper();
        let bc = BusModel {
            trigger: TriggerMode::Broadcast,
            ..seq
        };
        assert!((seq.trigger_spread_us() - 151.0).abs() < 1e-9);
        assert!((bc.trigger_spread_us() - 1.0).abs() < 1e-9);
    }
}
