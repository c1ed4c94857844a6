//! Progress on stderr: a bar on a terminal; otherwise (a script, a log file) a plain line at
//! most every few seconds and one at the end, e.g. `treecal: simulate: 40/100 trials (12 s)`.

use indicatif::ProgressBar;
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};
use treecal::workflow::Progress;

/// At most one plain line per this interval (the last line is always printed).
const LINE_INTERVAL: Duration = Duration::from_secs(5);

/// Shows a job's progress; `update` may be called from any thread.
pub struct Display {
    job: &'static str,
    terminal: bool,
    /// A bar on a terminal only for jobs long enough to need one.
    bar_wanted: bool,
    start: Instant,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    bar: Option<(String, ProgressBar)>,
    last_line: Option<Instant>,
}

impl Display {
    /// For the job `job` (`simulate`, `plan`); `bar_wanted`: show a bar on a terminal.
    pub fn new(job: &'static str, bar_wanted: bool) -> Self {
        Self {
            job,
            terminal: std::io::stderr().is_terminal(),
            bar_wanted,
            start: Instant::now(),
            state: Mutex::new(State::default()),
        }
    }

    /// Shows `progress`.
    pub fn update(&self, progress: Progress<'_>) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        let stage = progress.stage.unwrap_or_default();
        if self.terminal {
            if !self.bar_wanted {
                return;
            }
            if state.bar.as_ref().is_none_or(|(s, _)| s != stage) {
                if let Some((_, bar)) = state.bar.take() {
                    bar.finish_and_clear();
                }
                let bar = ProgressBar::new(progress.total as u64);
                bar.set_message(format!("{stage} {}", progress.unit));
                state.bar = Some((stage.to_owned(), bar));
            }
            if let Some((_, bar)) = &state.bar {
                bar.set_position(progress.done as u64);
            }
            return;
        }
        let now = Instant::now();
        let due = state
            .last_line
            .is_none_or(|last| now.duration_since(last) >= LINE_INTERVAL);
        let since_start = now.duration_since(self.start) >= LINE_INTERVAL;
        if progress.done >= progress.total || (due && since_start) {
            let stage = progress.stage.map(|s| format!("{s}: ")).unwrap_or_default();
            crate::output::note(format_args!(
                "{}: {stage}{}/{} {} ({} s)",
                self.job,
                progress.done,
                progress.total,
                progress.unit,
                now.duration_since(self.start).as_secs()
            ));
            state.last_line = Some(now);
        }
    }

    /// Clears the bar, if any.
    pub fn finish(&self) {
        if let Ok(mut state) = self.state.lock() {
            if let Some((_, bar)) = state.bar.take() {
                bar.finish_and_clear();
            }
        }
    }
}
