//! The cooker as a library (issue 17, issue 31): a program calls `vdbcook_cook::cook_inputs` with
//! typed options, gets the typed report back, and receives progress and notes through its own
//! `ProgressSink` — nothing is printed, nothing is written.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use vdbcook_asset::PayloadFormat;
use vdbcook_cook::{Clustering, Context, CookOptions, ProgressSink};

#[derive(Default)]
struct Collect {
    events: Mutex<Vec<String>>,
}

impl ProgressSink for Collect {
    fn started(&self, stage: &str, _unit: &str) {
        self.events.lock().unwrap().push(format!("start {stage}"));
    }
    fn finished(&self, stage: &str, _unit: &str, done: u64, total: u64, _seconds: f64) {
        self.events
            .lock()
            .unwrap()
            .push(format!("end {stage} {done}/{total}"));
    }
    fn note(&self, message: &str) {
        self.events.lock().unwrap().push(format!("note {message}"));
    }
}

fn smoke5() -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/seq/smoke5")
        .to_string_lossy()
        .into_owned()
}

#[test]
fn a_program_cooks_in_memory_with_its_own_progress_sink() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("never-written.vdbc");
    let a = CookOptions {
        format: Some(PayloadFormat::Bc7),
        // More clusters than candidate bricks: the cook caps k and says so (a note).
        clustering: Some(Clustering {
            variance_threshold: 10.0,
            ..Clustering::new(100_000)
        }),
        ..Default::default()
    };
    let sink = Arc::new(Collect::default());
    let cx = Context::with_sink(Some(sink.clone()));
    let cooked = vdbcook_cook::cook_inputs(&[smoke5()], &a, &cx).unwrap();
    let ev = sink.events.lock().unwrap().clone();
    assert!(
        ev.contains(&"start read, build, dedup".to_string()),
        "{ev:?}"
    );
    assert!(
        ev.contains(&"end read, build, dedup 5/5".to_string()),
        "{ev:?}"
    );
    assert!(ev.iter().any(|e| e.starts_with("end cluster")), "{ev:?}");
    assert!(
        ev.iter()
            .any(|e| e.starts_with("end encode") && !e.ends_with(" 0/0")),
        "the encode stage counts its blocks: {ev:?}"
    );
    assert!(
        ev.iter()
            .any(|e| e.starts_with("note") && e.contains("capped")),
        "{ev:?}"
    );
    // The typed report, and nothing on disk.
    assert_eq!(cooked.report.frames, 5);
    assert_eq!(cooked.report.max_error_source.as_deref(), Some("default"));
    assert!(cooked.report.clustering.is_some());
    assert_eq!(cooked.bytes.len() as u64, cooked.report.bytes.file);
    assert!(!out.exists());
}
