//! Progress bars for long work (MLP training, benchmarks that calibrate), on stderr. They
//! draw only on a terminal; in logs and pipes they stay silent.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar over `epochs` training epochs, with the loss as its message.
pub fn epochs(epochs: u64) -> ProgressBar {
    let bar = ProgressBar::new(epochs);
    if let Ok(style) = ProgressStyle::with_template(
        "  epoch {pos}/{len} [{bar:30}] {elapsed_precise} (eta {eta}) {msg}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// A bar over `n` items of `what` (presses, sets).
pub fn bar(n: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(n);
    if let Ok(style) = ProgressStyle::with_template(&format!(
        "  {{pos}}/{{len}} {what} [{{bar:30}}] {{elapsed_precise}} (eta {{eta}})"
    )) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// A training callback that moves `bar`; when the bar cannot draw (no terminal), it logs a
/// line every tenth of the epochs instead.
pub fn epoch_reporter(
    bar: &ProgressBar,
) -> impl FnMut(&gelgrip_plugins::mlp::train::EpochReport) + '_ {
    move |e| {
        bar.set_position(e.epoch as u64);
        bar.set_message(format!("L1 loss {:.4}", e.loss));
        let every = (e.epochs / 10).max(1);
        if bar.is_hidden() && (e.epoch % every == 0 || e.epoch == e.epochs) {
            eprintln!(
                "  epoch {}/{}: L1 loss {:.4} ({:.0} s)",
                e.epoch,
                e.epochs,
                e.loss,
                bar.elapsed().as_secs_f64()
            );
        }
    }
}
