//! Progress of `cook`'s long stages (read+build+dedup, cluster, encode, write) on stderr, so a
//! 100-second BC7 encode is not a silent stall. On a terminal: one line redrawn a few times a
//! second with the stage, its count, rate and ETA where the stage counts its work (frames,
//! compressed blocks), else the elapsed time. Not on a terminal (or with `CI` set): one plain
//! line per stage when it ends. Nothing under `--json` or for in-memory cooks (`render`,
//! `report`), which report for themselves.
//!
//! Work is counted through two process-wide counters (`add_total`, `advance`) so deep code (the
//! block compressor's strips) can report without threading a handle through every call.

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

#[derive(Clone, Copy, PartialEq)]
enum Mode {
    Off,
    Terminal,
    Lines,
}

/// Where progress goes for this run.
pub struct Progress {
    mode: Mode,
}

/// A running stage; reports its end when dropped (or `finish`ed).
pub struct Stage {
    mode: Mode,
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
    /// `silent`: `--json` or an in-memory cook.
    pub fn new(silent: bool) -> Progress {
        let mode = if silent {
            Mode::Off
        } else if std::io::stderr().is_terminal() && std::env::var_os("CI").is_none() {
            Mode::Terminal
        } else {
            Mode::Lines
        };
        Progress { mode }
    }

    /// Starts a stage counting `unit`s (its total is announced with `add_total`).
    pub fn stage(&self, name: &'static str, unit: &'static str) -> Stage {
        DONE.store(0, Ordering::Relaxed);
        TOTAL.store(0, Ordering::Relaxed);
        let stop = Arc::new(AtomicBool::new(false));
        let start = Instant::now();
        let ticker = (self.mode == Mode::Terminal).then(|| {
            let stop = stop.clone();
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(250));
                    if stop.load(Ordering::Relaxed) {
                        break;
                    }
                    let l = line(
                        name,
                        unit,
                        start.elapsed().as_secs_f64(),
                        DONE.load(Ordering::Relaxed),
                        TOTAL.load(Ordering::Relaxed),
                        false,
                    );
                    eprint!("\r{l}\x1b[K");
                    let _ = std::io::stderr().flush();
                }
            })
        });
        Stage {
            mode: self.mode,
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
            let _ = t.join();
        }
        if self.mode == Mode::Off || std::thread::panicking() {
            return;
        }
        let l = line(
            self.name,
            self.unit,
            self.start.elapsed().as_secs_f64(),
            DONE.load(Ordering::Relaxed),
            TOTAL.load(Ordering::Relaxed),
            true,
        );
        match self.mode {
            Mode::Terminal => eprintln!("\r{l}\x1b[K"),
            _ => eprintln!("{l}"),
        }
    }
}
