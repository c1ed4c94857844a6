//! How far a long job is, for a progress bar or a log line (the library prints nothing).

/// `done` of `total` `unit` (e.g. 40 of 100 trials); `stage` names the part of a job with
/// several (a planning stage).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress<'a> {
    /// The part of the job, if it has several.
    pub stage: Option<&'a str>,
    /// Units done.
    pub done: usize,
    /// Units in all.
    pub total: usize,
    /// What is counted (`trials`, `candidates`).
    pub unit: &'a str,
}

/// A progress callback; called from worker threads.
pub type ProgressFn<'a> = &'a (dyn Fn(Progress<'_>) + Sync);

/// The callback that shows nothing.
pub fn no_progress(_: Progress<'_>) {}
