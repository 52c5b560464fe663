//! `gelgrip servo scan|ping|read|write|check`: field tools for a Dynamixel bus, through
//! gelgrip's own driver (`gelgrip_dynamixel::driver`), so a malformed status packet is an
//! explained error, never a panic. `check` gives each servo's model, firmware and supply
//! voltage, a brown-out warning below the XM430-W350's rated 10.0 V, and whether the servos
//! answer Fast Sync Read. Timeouts, CRC failures and servo errors each get a message that
//! says what happened and what to check.

use clap::{Args, ValueEnum};
use serde_json::json;

use gelgrip_dynamixel::driver::{DriverError, DynamixelBus};

use crate::cli::UsageError;

fn motor_error_name(n: u8) -> &'static str {
    match n {
        1 => "Result Fail: the servo could not run the instruction",
        2 => "Instruction Error: unknown instruction, or action without a registered write",
        3 => "CRC Error: the servo received a corrupt packet",
        4 => "Data Range Error: value out of range",
        5 => "Data Length Error: wrong number of bytes",
        6 => "Data Limit Error: value outside the configured limits",
        7 => {
            "Access Error: read-only address, address outside the table, or EEPROM write with torque on"
        }
        _ => "unknown error number",
    }
}

/// Turn a driver error into a message with the likely cause.
fn explain(e: DriverError) -> anyhow::Error {
    match e {
        DriverError::Timeout { id, .. } => anyhow::anyhow!(
            "no reply from servo {id} before the deadline (reply wire time + 34 ms): check that it is powered, its id, and the baud rate"
        ),
        DriverError::Corrupt { .. } | DriverError::Length { .. } => {
            anyhow::anyhow!("{e} (noise on the bus, or two servos with one id?)")
        }
        DriverError::DataLimit { id, .. }
        | DriverError::Access { id, .. }
        | DriverError::Status { id, .. } => {
            let n = e.status_error().unwrap_or(0);
            anyhow::anyhow!(
                "servo {id} reported error {n:#04x}, {}: {e}",
                motor_error_name(n)
            )
        }
        DriverError::Io(_) => anyhow::anyhow!("bus error: {e}"),
    }
}

fn need<T>(v: Option<T>, flag: &str, action: &str) -> anyhow::Result<T> {
    v.ok_or_else(|| anyhow::Error::new(UsageError(format!("`servo {action}` needs {flag}"))))
}

fn print(args: &ServoArgs, value: serde_json::Value, text: String) {
    if args.json {
        println!("{value}");
    } else {
        println!("{text}");
    }
}

/// Run the command; returns the exit code.
pub fn run(args: ServoArgs) -> anyhow::Result<u8> {
    let ids = args.id.map_or_else(|| args.ids.clone(), |id| vec![id]);
    let mut bus =
        DynamixelBus::open(&args.port, args.baud, &ids, 0.0).map_err(|e| anyhow::anyhow!("{e}"))?;
    match args.action {
        ServoAction::Scan => {
            let found: Vec<serde_json::Value> = bus
                .scan()
                .map_err(explain)?
                .into_iter()
                .map(
                    |(id, model, firmware)| json!({"id": id, "model": model, "firmware": firmware}),
                )
                .collect();
            let text = format!(
                "{} servo(s): {}",
                found.len(),
                serde_json::Value::Array(found.clone())
            );
            print(&args, serde_json::Value::Array(found), text);
        }
        ServoAction::Ping => {
            let id = need(args.id, "--id", "ping")?;
            let (model, firmware) = bus.ping(id).map_err(explain)?;
            let alert = bus.last_alert();
            let text = format!("servo {id}: model {model}, firmware {firmware}");
            print(
                &args,
                json!({"id": id, "model": model, "firmware": firmware, "alert": alert}),
                text,
            );
        }
        ServoAction::Read => {
            let (id, a) = (
                need(args.id, "--id", "read")?,
                need(args.addr, "--addr", "read")?,
            );
            let len = args.len.unwrap_or(1);
            let data = bus.read(id, a, len).map_err(explain)?;
            let alert = bus.last_alert();
            let value =
                (len <= 4).then(|| data.iter().rev().fold(0u64, |v, b| v << 8 | u64::from(*b)));
            let text = format!(
                "servo {id} @{a} [{len}]: {:?}{}",
                data,
                value.map_or(String::new(), |v| format!(" = {v}"))
            );
            print(
                &args,
                json!({"id": id, "addr": a, "len": len, "bytes": data, "value": value, "alert": alert}),
                text,
            );
        }
        ServoAction::Write => {
            let (id, a) = (
                need(args.id, "--id", "write")?,
                need(args.addr, "--addr", "write")?,
            );
            let v = need(args.value, "--value", "write")?;
            let len = usize::from(args.len.unwrap_or(1));
            if !(1..=4).contains(&len) || (len < 4 && v >= 1u64 << (8 * len)) {
                anyhow::bail!(UsageError(format!(
                    "--value {v} does not fit in --len {len} bytes (1 to 4)"
                )));
            }
            let bytes = &v.to_le_bytes()[..len];
            bus.write(id, a, bytes).map_err(explain)?;
            print(
                &args,
                json!({"id": id, "addr": a, "len": len, "value": v}),
                format!("servo {id} @{a} [{len}] <- {v}"),
            );
        }
        ServoAction::Check => return check(&mut bus, &args),
    }
    Ok(0)
}

/// `servo check`: model, firmware and supply of each servo, brown-outs, fast reads.
fn check(bus: &mut DynamixelBus, args: &ServoArgs) -> anyhow::Result<u8> {
    use gelgrip_dynamixel::control_table::RATED_INPUT_V;
    use gelgrip_dynamixel::driver::{STATE_BLOCK, STATE_BLOCK_LEN};
    let supply = bus.check_supply().map_err(explain)?;
    let mut servos = Vec::with_capacity(supply.len());
    let mut lines = Vec::with_capacity(supply.len() + 1);
    for r in &supply {
        let (model, firmware) = bus.ping(r.id).map_err(explain)?;
        servos.push(json!({"id": r.id, "model": model, "firmware": firmware,
            "input_v": r.input_v, "brown_out": r.brown_out}));
        lines.push(format!(
            "servo {}: model {model}, firmware {firmware}, {:.1} V input{}",
            r.id,
            r.input_v,
            if r.brown_out { " (BROWN-OUT)" } else { "" }
        ));
    }
    let fast = bus
        .fast_sync_read(&args.ids, STATE_BLOCK, STATE_BLOCK_LEN)
        .is_ok();
    lines.push(format!(
        "fast sync read: {}",
        if fast { "yes" } else { "no" }
    ));
    let brown_out = supply.iter().any(|r| r.brown_out);
    print(
        args,
        json!({"servos": servos, "rated_min_v": RATED_INPUT_V.0, "brown_out": brown_out,
            "fast_sync_read": fast}),
        lines.join("\n"),
    );
    Ok(0)
}

/// What `gelgrip servo` does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ServoAction {
    /// Broadcast ping: every servo's id, model and firmware.
    Scan,
    /// Ping one servo (reports its model number).
    Ping,
    /// Read bytes from the control table.
    Read,
    /// Write a value (little-endian, --len bytes) to the control table.
    Write,
    /// Each servo of --ids: model, firmware, supply voltage (brown-out below the rated
    /// 10.0 V), and whether they answer Fast Sync Read.
    Check,
}

/// `gelgrip servo`.
#[derive(Debug, Args)]
pub struct ServoArgs {
    /// What to do.
    #[arg(value_enum)]
    pub action: ServoAction,
    /// Serial port of the bus.
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value = "1000000")]
    pub baud: u32,
    /// Servo id.
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=252))]
    pub id: Option<u8>,
    /// Servo ids (`check`; the others use --id).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3", value_parser = clap::value_parser!(u8).range(0..=252))]
    pub ids: Vec<u8>,
    /// Control-table address.
    #[arg(long)]
    pub addr: Option<u16>,
    /// Bytes to read or write.
    #[arg(long)]
    pub len: Option<u16>,
    /// Value to write.
    #[arg(long)]
    pub value: Option<u64>,
    /// Print one JSON value.
    #[arg(long)]
    pub json: bool,
}
