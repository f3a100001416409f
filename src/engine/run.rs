//! The one run loop: a render's long sequence of dispatches in submissions whose size
//! adapts to about a quarter second each, with the time limit, interruption by a signal,
//! the progress bar and progressive snapshots. Integrators describe their work (what to
//! dispatch for units first..first+count, how to resolve a snapshot); the loop knows none
//! of them.
use super::dispatch::{Dispatch, SubmitTimes};
use super::Engine;
use crate::io::Image;
use crate::trace::Trace;
use anyhow::Result;
use std::time::Instant;

/// Writes a snapshot: the image so far and its samples per pixel.
pub type SnapshotWriter = Box<dyn FnMut(&Image, u64) -> Result<()> + Send>;

/// Progressive output: every `every` seconds of rendering, `write` gets the image so far
/// and its samples per pixel (MMLT: mutations per pixel).
pub struct Snapshots {
    pub every: f64,
    pub write: SnapshotWriter,
    pub last: Option<Instant>,
}

/// What a run repeats: `total` units (passes, or mutations per chain), dispatched a batch
/// at a time.
pub trait Work {
    /// Units to do.
    fn total(&self) -> u64;
    /// The dispatches of units `first .. first + count`.
    fn dispatches(&mut self, first: u64, count: u64) -> Result<Vec<Dispatch>>;
    /// More dispatches for the units of the last `dispatches`, asked after each
    /// submission until it returns `None` (work whose length the device decides: the
    /// wavefront path tracer's bounces at unbounded depth). The units count as done then.
    fn more(&mut self) -> Result<Option<Vec<Dispatch>>> {
        Ok(None)
    }
    /// The image after `done` units and its samples per pixel, for a snapshot; `None`
    /// when this work writes none.
    fn snapshot(&self, _done: u64) -> Result<Option<(Image, u64)>> {
        Ok(None)
    }
}

/// How a run batches and reports its units.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// The progress bar's label and unit ("pt", "passes").
    pub label: String,
    pub unit: &'static str,
    /// The progress bar counts units × this (MMLT: mutations of every chain).
    pub progress_scale: u64,
    /// Units in the first submission, and at most per submission.
    pub first_batch: u64,
    pub max_batch: u64,
    /// Whether the engine's time limit applies (repeats of work already done ignore it).
    pub time_limited: bool,
    /// When the render started, for the time limit (default: when the run starts).
    pub started: Option<Instant>,
}

impl RunOptions {
    pub fn passes(label: &str) -> RunOptions {
        RunOptions {
            label: label.to_string(),
            unit: "passes",
            progress_scale: 1,
            first_batch: 1,
            max_batch: 64,
            time_limited: true,
            started: None,
        }
    }
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct RunResult {
    /// Units done (fewer than the total when the time limit or a signal stopped it).
    pub done: u64,
    /// Device seconds by span.
    pub times: SubmitTimes,
}

impl Engine {
    /// Run `work` to its end, or until the time limit (after the first batch) or a signal.
    /// Stops only between submissions, so the units done are whole.
    pub fn run(
        &mut self,
        work: &mut dyn Work,
        options: &RunOptions,
        trace: &mut Trace,
    ) -> Result<RunResult> {
        let total = work.total();
        let progress = if self.control.show_progress {
            let bar = indicatif::ProgressBar::new(total * options.progress_scale);
            let template = format!(
                "{{msg}} [{{bar:30}}] {{pos}}/{{len}} {}, {{elapsed}} elapsed, {{eta}} left",
                options.unit
            );
            bar.set_style(
                indicatif::ProgressStyle::with_template(&template)
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            bar.set_message(options.label.clone());
            Some(bar)
        } else {
            None
        };
        let start = options.started.unwrap_or_else(Instant::now);
        let mut result = RunResult::default();
        let mut batch = options.first_batch.max(1);
        while result.done < total {
            let out_of_time = options.time_limited
                && self
                    .control
                    .time_limit
                    .is_some_and(|t| result.done > 0 && start.elapsed().as_secs_f64() >= t);
            if self.interrupted() || out_of_time {
                break;
            }
            let n = batch.min(total - result.done);
            let list = work.dispatches(result.done, n)?;
            let stage = format!(
                "running {} {} {}..{}",
                options.label,
                options.unit,
                result.done,
                result.done + n
            );
            let t0 = Instant::now();
            let times = self.submit(&list, &stage, trace)?;
            result.times.merge(&times);
            while let Some(list) = work.more()? {
                let times = self.submit(&list, &stage, trace)?;
                result.times.merge(&times);
            }
            let wall = t0.elapsed().as_secs_f64();
            result.done += n;
            if self.snapshot_due() {
                if let Some((image, samples)) =
                    trace.cpu("snapshot", || work.snapshot(result.done))?
                {
                    self.write_snapshot(&image, samples)?;
                }
            }
            if let Some(bar) = &progress {
                bar.set_position(result.done * options.progress_scale);
            }
            // Aim for submissions of about a quarter second: short enough for the
            // progress bar and for watchdogs, long enough to keep the device busy.
            if wall < 0.25 && batch < options.max_batch {
                batch = (batch * 2).min(options.max_batch);
            } else if wall > 1.0 && batch > 1 {
                batch /= 2;
            }
        }
        if let Some(bar) = progress {
            bar.finish_and_clear();
        }
        Ok(result)
    }

    /// Whether a progressive snapshot is due (the first after `every` seconds).
    fn snapshot_due(&mut self) -> bool {
        match &mut self.control.snapshots {
            Some(s) => {
                let last = *s.last.get_or_insert_with(Instant::now);
                last.elapsed().as_secs_f64() >= s.every
            }
            None => false,
        }
    }

    fn write_snapshot(&mut self, image: &Image, samples: u64) -> Result<()> {
        if let Some(s) = &mut self.control.snapshots {
            (s.write)(image, samples)?;
            s.last = Some(Instant::now());
        }
        Ok(())
    }
}
