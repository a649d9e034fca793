//! Progress bars on stderr: one for optimisation steps, one for the stages of a long job.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `len` optimisation steps named `prefix`, showing the loss as its message; hidden
/// unless `show`.
#[must_use]
pub fn steps_bar(len: usize, prefix: String, show: bool) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix:>18} {bar:30} {pos}/{len} {msg} [{elapsed_precise}<{eta_precise}]",
        )
        .expect("valid progress template"),
    );
    bar.set_prefix(prefix);
    bar
}

/// A bar of `len` stages, its message naming the current one.
#[must_use]
pub fn stages_bar(len: u64, msg: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg:>28} [{bar:30}] {pos}/{len} {elapsed_precise}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_message(msg.to_string());
    pb
}
