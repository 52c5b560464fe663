//! `gelgrip check-config FILE`: validate a configuration; errors name the file, the field and
//! the allowed range, and exit 2.

use clap::Args;
use gelgrip::wiring;
use std::path::PathBuf;

/// Run the command; returns the exit code.
pub fn run(args: CheckConfigArgs) -> anyhow::Result<u8> {
    let registry = wiring::registry();
    let config = wiring::load_config(Some(&args.file), &registry)?;
    println!(
        "{}: ok ({} sensors in layout `{}`, hub transport `{}`, {} trigger)",
        args.file.display(),
        config.layout.sensors.len(),
        config.layout.name,
        config.hub.transport,
        config.hub.trigger.as_str()
    );
    Ok(0)
}

/// `gelgrip check-config`.
#[derive(Debug, Args)]
pub struct CheckConfigArgs {
    /// The file to validate.
    pub file: PathBuf,
}
