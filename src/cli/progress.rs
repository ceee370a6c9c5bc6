//! Progress of long batches of runs on stderr.

use indicatif::{ProgressBar, ProgressStyle};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts finished runs of a batch, from any thread: a bar with the time
/// left when stderr is a terminal, otherwise (a log, CI) a line at each
/// tenth of the batch.
pub struct Progress {
    bar: ProgressBar,
    done: AtomicUsize,
    what: &'static str,
}

impl Progress {
    /// A batch of `total` runs of `what` ("runs").
    pub fn new(total: usize, what: &'static str) -> Self {
        let bar = ProgressBar::new(total as u64);
        let template = "{bar:40} {pos}/{len} {msg} ({elapsed}, {eta} left)";
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_message(what);
        Self {
            bar,
            done: AtomicUsize::new(0),
            what,
        }
    }

    /// One run finished.
    pub fn inc(&self) {
        self.bar.inc(1);
        let done = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        let total = self.bar.length().unwrap_or(0) as usize;
        if self.bar.is_hidden() && at_a_tenth(done, total) {
            eprintln!("  {done}/{total} {}", self.what);
        }
    }

    /// Prints `line` on stderr without tearing the bar.
    pub fn note(&self, line: &str) {
        self.bar.suspend(|| eprintln!("{line}"));
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// Whether `done` of `total` is the first count at or past a tenth of it.
fn at_a_tenth(done: usize, total: usize) -> bool {
    total > 0 && done * 10 / total != (done - 1) * 10 / total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_fall_at_each_tenth_and_at_the_end() {
        for total in [1, 7, 10, 95, 600] {
            let lines: Vec<usize> = (1..=total).filter(|&n| at_a_tenth(n, total)).collect();
            assert_eq!(lines.last(), Some(&total), "{total}");
            assert_eq!(lines.len(), total.min(10), "{total}: {lines:?}");
            // Each line is the first count past its tenth.
            for &n in &lines {
                assert!(n * 10 / total > (n - 1) * 10 / total);
            }
        }
        assert!(!at_a_tenth(1, 0));
    }
}
