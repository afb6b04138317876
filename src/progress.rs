//! Progress of a long run: LinuxCNC's `FILTER_PROGRESS` protocol (see
//! [`crate::input::FilterProgress`], unchanged) and, on a terminal, a
//! progress bar on standard error (indicatif). The bar stays off when
//! standard error is not a terminal (pipes, files, LinuxCNC), under
//! `--quiet`, and when LinuxCNC's progress protocol is on.

use crate::input::FilterProgress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

/// Bytes between two updates of the bar (the bar redraws itself at most a
/// few times a second; this keeps the per-line cost to a comparison).
const BAR_STEP: u64 = 1 << 16;

/// Whether progress is drawn: standard error is a terminal and LinuxCNC's
/// progress protocol is not in use.
fn draws_on_terminal() -> bool {
    std::env::var_os("AXIS_PROGRESS_BAR").is_none() && std::io::stderr().is_terminal()
}

/// Progress reporting of one run over an input of `size` bytes (if known).
pub struct RunProgress {
    filter: FilterProgress,
    bar: Option<ProgressBar>,
    shown: u64,
}

impl RunProgress {
    /// Progress for an input of `size` bytes; the bar only when `quiet` is
    /// off, standard error is a terminal and LinuxCNC's protocol is not in use.
    pub fn new(size: Option<u64>, quiet: bool, what: &str) -> Self {
        let bar = (!quiet && draws_on_terminal()).then(|| {
            let bar = match size {
                Some(s) => ProgressBar::with_draw_target(Some(s), ProgressDrawTarget::stderr())
                    .with_style(
                        ProgressStyle::with_template(
                            "{msg} [{bar:40}] {bytes}/{total_bytes} ({bytes_per_sec}, {eta} left)",
                        )
                        .unwrap_or_else(|_| ProgressStyle::default_bar())
                        .progress_chars("=> "),
                    ),
                None => ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
                    .with_style(
                        ProgressStyle::with_template("{spinner} {msg} {bytes} ({bytes_per_sec})")
                            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
                    ),
            };
            bar.set_message(what.to_string());
            bar
        });
        RunProgress {
            filter: FilterProgress::new(size),
            bar,
            shown: 0,
        }
    }

    /// Reports that `done` bytes of the input have been read.
    #[inline]
    pub fn update(&mut self, done: u64) {
        self.filter.update(done);
        if let Some(bar) = &self.bar
            && done >= self.shown + BAR_STEP
        {
            self.shown = done;
            bar.set_position(done);
        }
    }

    /// Removes the bar (before the run's summary is printed).
    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl Drop for RunProgress {
    fn drop(&mut self) {
        self.finish();
    }
}

/// A spinner with the elapsed time on standard error while a run without
/// a byte count works (`diagnose`'s searches take minutes on a long
/// recording): only where standard error is a terminal and LinuxCNC's
/// progress protocol is not in use; removed when dropped.
pub struct Spinner(Option<ProgressBar>);

impl Spinner {
    /// Starts the spinner with `what` beside it.
    pub fn start(what: &str) -> Self {
        Spinner(draws_on_terminal().then(|| {
            let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr()).with_style(
                ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            );
            bar.set_message(what.to_string());
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
            bar
        }))
    }
}

impl Drop for Spinner {
    fn drop(&mut self) {
        if let Some(bar) = self.0.take() {
            bar.finish_and_clear();
        }
    }
}
