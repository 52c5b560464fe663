//! Hardware test: the driver on a real CH347 (T in mode 1, or F), with nothing it could harm:
//! read the firmware version, write the SPI configuration (mode 0, 30 MHz) and read it
//! acknowledged, toggle no pins, read the GPIO status, and show that an address-only I2C
//! write to an empty address is a NACK, not a hang.
//!
//! `GELGRIP_CH347=1a86:55de cargo test -p gelgrip-ch347 --features hardware-tests --test hardware`
//! (`GELGRIP_CH347` is VID:PID, a bus-port path such as `1-4.2`, or `auto`). With the feature
//! on, a missing `GELGRIP_CH347` fails loudly; without it the test is ignored.

use std::time::Duration;

use gelgrip_ch347::frames::SpiConfig;
use gelgrip_ch347::usb::{DeviceSelector, RusbBulk};
use gelgrip_ch347::{Ch347, Ch347Error};

#[test]
#[cfg_attr(not(feature = "hardware-tests"), ignore)]
fn a_real_ch347_answers_version_spi_config_gpio_and_nacks() {
    let selector = std::env::var("GELGRIP_CH347").unwrap_or_else(|_| {
        panic!(
            "GELGRIP_CH347 is not set: hardware tests need a CH347, e.g. GELGRIP_CH347=1a86:55de \
             cargo test -p gelgrip-ch347 --features hardware-tests --test hardware"
        )
    });
    let selector: DeviceSelector = selector
        .parse()
        .unwrap_or_else(|e| panic!("GELGRIP_CH347={selector}: {e}"));
    let usb = RusbBulk::open(&selector).unwrap_or_else(|e| panic!("{e}"));
    let mut ch = Ch347::new(usb).with_timeout(Duration::from_millis(1000));
    let version = ch.version().expect("version");
    assert!(version > 0, "firmware version {version:#06x}");
    ch.spi_configure(SpiConfig::default())
        .expect("SPI configuration acknowledged");
    ch.gpio_read().expect("GPIO status");
    ch.i2c_speed(2).expect("400 kHz");
    match ch.i2c_write(0x7F, &[]) {
        Err(Ch347Error::Nack { index: 0, .. }) | Ok(()) => {}
        Err(e) => panic!("an address-only write must answer: {e}"),
    }
}
