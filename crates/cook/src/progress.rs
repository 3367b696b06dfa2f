//! Progress of `cook`'s long stages (read+build+dedup, size search, cluster, encode, write) and
//! its notes, reported through a [`ProgressSink`]: a program linking the library passes its own
//! (`cook::Args::progress`); the CLI uses [`StderrProgress`], so a 100-second BC7 encode is not a
//! silent stall. On a terminal: one line redrawn a few times a second with the stage, its count,
//! rate and ETA where the stage counts its work (frames, compressed blocks), else the elapsed
//! time. Not on a terminal (or with `CI` set): one plain line per stage when it ends. Nothing
//! under `--json` or for in-memory cooks (`render`, `report`, `manifest`), which report for
//! themselves; notes (stated decisions such as a capped k) still go to stderr there.
//!
//! Work is counted through two process-wide counters (`add_total`, `advance`) so deep code (the
//! block compressor's strips) can report without threading a handle through every call; two cooks
//! running at once in one process therefore share the counts a sink sees (their results are not
//! affected).

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

static DONE: AtomicU64 = AtomicU64::new(0);
static TOTAL: AtomicU64 = AtomicU64::new(0);

/// Announces `n` more units of work in the current stage.
pub fn add_total(n: u64) {
    TOTAL.fetch_add(n, Ordering::Relaxed);
}

/// Marks `n` units of the current stage done.
pub fn advance(n: u64) {
    DONE.fetch_add(n, Ordering::Relaxed);
}

/// Lets the block compressor report its strips (announced, done).
pub fn hook_block_compressor() {
    let _ = crate::bcenc::PROGRESS_HOOK.set(|total, done| {
        add_total(total);
        advance(done);
    });
}

/// Receives a cook's progress. Every method has a default that ignores it.
pub trait ProgressSink: Send + Sync {
    /// A stage begins; `unit` is what it counts.
    fn started(&self, _stage: &str, _unit: &str) {}
    /// A few times a second while a stage runs: `done` of `total` units (`total` 0: the stage does
    /// not count its work), `seconds` since it began.
    fn update(&self, _stage: &str, _unit: &str, _done: u64, _total: u64, _seconds: f64) {}
    /// A stage ended.
    fn finished(&self, _stage: &str, _unit: &str, _done: u64, _total: u64, _seconds: f64) {}
    /// A note or warning the user should see (a decision the cook made, e.g. a capped `k`).
    fn note(&self, _message: &str) {}
}

/// The CLI's display on stderr (see the module docs).
pub struct StderrProgress {
    terminal: bool,
}

impl StderrProgress {
    /// Redrawn lines on a terminal (without `CI` set), plain lines otherwise.
    pub fn detect() -> StderrProgress {
        StderrProgress {
            terminal: std::io::stderr().is_terminal() && std::env::var_os("CI").is_none(),
        }
    }
}

impl ProgressSink for StderrProgress {
    fn update(&self, stage: &str, unit: &str, done: u64, total: u64, seconds: f64) {
        if self.terminal {
            eprint!("\r{}\x1b[K", line(stage, unit, seconds, done, total, false));
            let _ = std::io::stderr().flush();
        }
    }
    fn finished(&self, stage: &str, unit: &str, done: u64, total: u64, seconds: f64) {
        let l = line(stage, unit, seconds, done, total, true);
        if self.terminal {
            eprintln!("\r{l}\x1b[K");
        } else {
            eprintln!("{l}");
        }
    }
    fn note(&self, message: &str) {
        eprintln!("{message}");
    }
}

/// Where progress and notes go for this run.
pub struct Progress {
    sink: Option<Arc<dyn ProgressSink>>,
    /// Notes without a sink: to stderr unless the caller is quiet.
    print_notes: bool,
}

/// A running stage; reports its end when dropped (or `finish`ed).
pub struct Stage {
    sink: Option<Arc<dyn ProgressSink>>,
    name: &'static str,
    unit: &'static str,
    start: Instant,
    stop: Arc<AtomicBool>,
    ticker: Option<std::thread::JoinHandle<()>>,
}

fn line(name: &str, unit: &str, elapsed: f64, done: u64, total: u64, end: bool) -> String {
    let mut s = format!("  {name}: ");
    if total > 0 {
        let rate = done as f64 / elapsed.max(1e-9);
        s += &format!("{done}/{total} {unit} ({rate:.1} {unit}/s");
        if !end && done > 0 && done < total {
            let eta = (total - done) as f64 / rate.max(1e-9);
            s += &format!(", ETA {eta:.0} s");
        }
        s += ")";
        s += &format!(", {elapsed:.1} s");
    } else {
        s += &format!("{elapsed:.1} s");
    }
    s
}

impl Progress {
    /// Progress into `sink` when given (stages and notes); otherwise [`StderrProgress`] unless
    /// `silent`, and notes on stderr when `print_notes`.
    pub fn with(sink: Option<Arc<dyn ProgressSink>>, silent: bool, print_notes: bool) -> Progress {
        // Library callers have no `main` to install it; installing twice is a no-op.
        hook_block_compressor();
        match sink {
            Some(s) => Progress {
                sink: Some(s),
                print_notes: false,
            },
            None => Progress {
                sink: (!silent)
                    .then(|| Arc::new(StderrProgress::detect()) as Arc<dyn ProgressSink>),
                print_notes,
            },
        }
    }

    /// A note for the user: to the sink, or stderr.
    pub fn note(&self, message: &str) {
        match &self.sink {
            Some(s) => s.note(message),
            None if self.print_notes => eprintln!("{message}"),
            None => {}
        }
    }

    /// Starts a stage counting `unit`s (its total is announced with `add_total`).
    pub fn stage(&self, name: &'static str, unit: &'static str) -> Stage {
        DONE.store(0, Ordering::Relaxed);
        TOTAL.store(0, Ordering::Relaxed);
        let stop = Arc::new(AtomicBool::new(false));
        let start = Instant::now();
        if let Some(s) = &self.sink {
            s.started(name, unit);
        }
        let ticker = self.sink.clone().map(|sink| {
            let stop = stop.clone();
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    // Parked, not slept: the stage's end unparks it, so ending a stage never
                    // waits for the next tick.
                    std::thread::park_timeout(Duration::from_millis(250));
                    if stop.load(Ordering::Relaxed) {
                        break;
                    }
                    sink.update(
                        name,
                        unit,
                        DONE.load(Ordering::Relaxed),
                        TOTAL.load(Ordering::Relaxed),
                        start.elapsed().as_secs_f64(),
                    );
                }
            })
        });
        Stage {
            sink: self.sink.clone(),
            name,
            unit,
            start,
            stop,
            ticker,
        }
    }
}

impl Stage {
    /// Ends the stage now (the same as dropping it).
    pub fn finish(self) {}
}

impl Drop for Stage {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.ticker.take() {
            t.thread().unpark();
            let _ = t.join();
        }
        if std::thread::panicking() {
            return;
        }
        if let Some(s) = &self.sink {
            s.finished(
                self.name,
                self.unit,
                DONE.load(Ordering::Relaxed),
                TOTAL.load(Ordering::Relaxed),
                self.start.elapsed().as_secs_f64(),
            );
        }
    }
}
