//! Progress bars for long work (MLP training, benchmarks that calibrate), on stderr. They
//! draw only on a terminal; in logs and pipes a line every tenth of the work stands in
//! for them.

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

/// Move `bar` over `what` (the items it counts) by one; when the bar cannot draw (no
/// terminal), log a line every tenth of its length instead, with the time so far and the
/// time left at that pace.
pub fn advance(bar: &ProgressBar, what: &str) {
    bar.inc(1);
    let (done, len) = (bar.position(), bar.length().unwrap_or(0));
    if bar.is_hidden() && tenth_reached(done, len) {
        let elapsed_s = bar.elapsed().as_secs_f64();
        let left_s = elapsed_s / done as f64 * len.saturating_sub(done) as f64;
        eprintln!("  {done}/{len} {what} ({elapsed_s:.0} s, about {left_s:.0} s left)");
    }
}

/// Whether `done` of `len` items is a tenth of the way further than `done − 1` was (and the
/// last item always).
fn tenth_reached(done: u64, len: u64) -> bool {
    done > 0 && (done >= len || done * 10 / len.max(1) > (done - 1) * 10 / len.max(1))
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

#[cfg(test)]
mod tests {
    use super::tenth_reached;

    #[test]
    fn a_hidden_bar_logs_every_tenth_and_the_end() {
        let logged: Vec<u64> = (1..=270).filter(|&d| tenth_reached(d, 270)).collect();
        assert_eq!(logged, [27, 54, 81, 108, 135, 162, 189, 216, 243, 270]);
        let few: Vec<u64> = (1..=3).filter(|&d| tenth_reached(d, 3)).collect();
        assert_eq!(few, [1, 2, 3]);
        assert!(!tenth_reached(0, 10));
        assert!(tenth_reached(5, 0), "past an unknown length: the end");
    }
}
