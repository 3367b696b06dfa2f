//! `vdbcook cook --manifest volumes.toml [--cache-dir DIR]`: batch cooking for build pipelines,
//! with a content-addressed cache so an unchanged asset is never cooked twice.
//!
//! The manifest is a list of `[[asset]]` tables (keys: `docs/cli.md`, "Batch cooking"), each one
//! `vdbcook cook` with its input, output and options; relative paths are relative to the
//! manifest's folder. Everything is checked before anything is cooked or written: unknown keys,
//! bad values, missing inputs, two entries writing one output, and an output that another entry
//! reads (each error names the manifest line). Then every entry gets a **key**: xxh3-128 over the
//! cooker's version, the options that shape the bytes, and each input frame's file name, number
//! and content hash. The cache folder holds `KEY.vdbc` (the asset) and `KEY.json` (its cook
//! report); a key whose asset is there and loads (every section's hash checked) is **cached**
//! (its bytes are copied to the output if it differs); a damaged entry is named in a note and
//! cooked again; the others are **cooked** (in parallel over the thread pool), stored (report
//! first, then asset, each through a temporary file renamed into place, so concurrent runs
//! sharing a cache see whole entries), then written (output folders are created as needed).
//! Cooks are deterministic, so a cached asset is byte-identical to a fresh cook (tested).
//!
//! Content hashes are remembered per file in `files.json` in the cache folder under the file's
//! size, modification time (ns) and inode: a second run re-hashes only files whose metadata
//! changed, which keeps an unchanged run to a stat per file. (Like make, it trusts that a content
//! change moves the size or the mtime.)

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use toml::Spanned;
use vdbcook_vdb::sequence::Frame;
use xxhash_rust::xxh3::Xxh3;

use vdbcook_cook::progress::Progress;
use vdbcook_cook::{Context, CookOptions};

use crate::cook::Args;
use crate::errors::CliError;
use crate::spell;

/// The manifest file: `[[asset]]` tables.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestFile {
    asset: Vec<Spanned<Entry>>,
}

/// `input` as one string or a list.
#[derive(Deserialize, Clone)]
#[serde(untagged)]
enum Inputs {
    One(String),
    Many(Vec<String>),
}

/// `max-bytes` as a number of bytes or a size string ("32MiB").
#[derive(Deserialize, Clone)]
#[serde(untagged)]
enum Size {
    Bytes(u64),
    Text(String),
}

/// `grids` as `"auto"`, `"density,temperature"` or a list.
#[derive(Deserialize, Clone)]
#[serde(untagged)]
enum GridList {
    Text(String),
    Many(Vec<String>),
}

/// `max-error` as one bound, `"density=0.01,5"` as the flag spells it, or a table of bounds per
/// channel (`{ density = 0.01, temperature = 5 }`).
#[derive(Deserialize, Clone)]
#[serde(untagged)]
enum MaxError {
    All(f32),
    Text(String),
    Per(BTreeMap<String, f32>),
}

/// `lod` as a level count or `"all"`.
#[derive(Deserialize, Clone)]
#[serde(untagged)]
enum LodLevels {
    Count(u32),
    Text(String),
}

/// One `[[asset]]`: the options of `vdbcook cook`, spelt as its flags.
#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
struct Entry {
    input: Inputs,
    output: String,
    format: Option<String>,
    max_error: Option<MaxError>,
    max_bytes: Option<Size>,
    grid: Option<String>,
    grids: Option<GridList>,
    clusters: Option<usize>,
    iterations: Option<usize>,
    variance_threshold: Option<f32>,
    frames: Option<String>,
    range: Option<String>,
    bc7_quality: Option<String>,
    no_packed: Option<bool>,
    lod: Option<LodLevels>,
    lod_from: Option<u32>,
    allow_gaps: Option<bool>,
    allow_missing_grid: Option<bool>,
    keep_empty_channels: Option<bool>,
    replace_non_finite: Option<f32>,
}

/// A checked entry, ready to cook.
struct Job {
    line: usize,
    opts: CookOptions,
    frames: Vec<Frame>,
    /// As the manifest names it (relative to the manifest's folder), and canonical.
    output_given: PathBuf,
    output: PathBuf,
    key: String,
}

/// Remembered content hash of one file (`files.json`).
#[derive(Serialize, Deserialize, Clone, PartialEq)]
struct FileStamp {
    size: u64,
    mtime_ns: i128,
    inode: u64,
    hash: String,
}

fn manifest_err(path: &Path, line: usize, m: impl std::fmt::Display) -> CliError {
    CliError::Usage(format!("{}:{line}: {m}", path.display()))
}

/// 1-based line of byte offset `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text[..at.min(text.len())].matches('\n').count() + 1
}

/// `p` relative to `base` unless absolute, with `.` and `..` folded (no file-system access).
fn rel(base: &Path, p: &str) -> PathBuf {
    let joined = if Path::new(p).is_absolute() {
        PathBuf::from(p)
    } else {
        base.join(p)
    };
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// The path with its existing ancestors resolved (symlinks, `..`), for comparing outputs and
/// inputs that may not exist yet.
fn canonical(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    match (p.parent(), p.file_name()) {
        (Some(dir), Some(name)) => canonical(dir).join(name),
        _ => p.to_path_buf(),
    }
}

fn hex128(h: u128) -> String {
    format!("{h:032x}")
}

/// The content hash of `path` (whose canonical name is `name`), from `stamps` when its size,
/// mtime and inode are unchanged.
fn content_hash(
    path: &Path,
    name: &str,
    stamps: &BTreeMap<String, FileStamp>,
) -> std::io::Result<FileStamp> {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::metadata(path)?;
    let (size, mtime_ns, inode) = (
        m.len(),
        m.mtime() as i128 * 1_000_000_000 + m.mtime_nsec() as i128,
        m.ino(),
    );
    if let Some(s) = stamps.get(name) {
        if s.size == size && s.mtime_ns == mtime_ns && s.inode == inode {
            return Ok(s.clone());
        }
    }
    let mut h = Xxh3::new();
    let mut f = std::fs::File::open(path)?;
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = std::io::Read::read(&mut f, &mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(FileStamp {
        size,
        mtime_ns,
        inode,
        hash: hex128(h.digest128()),
    })
}

/// The inputs, output and cook options of one entry (paths resolved against `base`), checked as
/// the CLI checks its flags: each key goes through the same parser as its flag.
fn entry_options(e: &Entry, base: &Path) -> Result<(Vec<String>, PathBuf, CookOptions), String> {
    let inputs = match &e.input {
        Inputs::One(s) => vec![s.clone()],
        Inputs::Many(v) => v.clone(),
    };
    if inputs.is_empty() {
        return Err("`input` is empty".into());
    }
    let inputs = inputs
        .iter()
        .map(|i| rel(base, i).to_string_lossy().into_owned())
        .collect();
    let (max_error, max_bytes) = (
        match &e.max_error {
            None => None,
            Some(MaxError::All(v)) => Some(spell::MaxErrorArg::All(*v)),
            Some(MaxError::Text(t)) => Some(spell::parse_max_error(t)?),
            Some(MaxError::Per(m)) => Some(spell::MaxErrorArg::Per {
                all: None,
                per: m.iter().map(|(k, v)| (k.clone(), *v)).collect(),
            }),
        },
        match &e.max_bytes {
            None => None,
            Some(Size::Bytes(n)) => Some(*n),
            Some(Size::Text(t)) => Some(spell::parse_size(t)?),
        },
    );
    if let Some(f) = &e.format {
        if vdbcook_asset::PayloadFormat::parse(f).is_none() {
            return Err(format!(
                "format '{f}' (f32, f16, unorm8, bc4, bc7, packed1 .. packed7)"
            ));
        }
    }
    if let Some(r) = &e.range {
        if !["brick", "global"].contains(&r.as_str()) {
            return Err(format!("range '{r}' (brick, global)"));
        }
    }
    if e.grid.is_some() && e.grids.is_some() {
        return Err("give `grid` or `grids`, not both".into());
    }
    let args = Args {
        inputs: Vec::new(),
        output: None,
        frames: e.frames.as_deref().map(spell::parse_frames).transpose()?,
        manifest: None,
        cache_dir: None,
        format: e.format.clone(),
        max_error,
        max_bytes,
        range: e.range.clone().unwrap_or_else(|| "brick".into()),
        bc7_quality: e.bc7_quality.clone().unwrap_or_else(|| "fast".into()),
        no_packed: e.no_packed.unwrap_or(false),
        grid: e.grid.clone(),
        grids: match &e.grids {
            None => Vec::new(),
            Some(GridList::Text(t)) => t.split(',').map(|g| g.trim().to_string()).collect(),
            Some(GridList::Many(v)) => v.clone(),
        },
        json: false,
        allow_gaps: e.allow_gaps.unwrap_or(false),
        clusters: e.clusters,
        iterations: e.iterations,
        variance_threshold: e.variance_threshold,
        allow_missing_grid: e.allow_missing_grid.unwrap_or(false),
        keep_empty_channels: e.keep_empty_channels.unwrap_or(false),
        lod: match &e.lod {
            None => None,
            Some(LodLevels::Count(n)) => Some(spell::parse_levels(&n.to_string())?),
            Some(LodLevels::Text(t)) => Some(spell::parse_levels(t)?),
        },
        lod_from: e
            .lod_from
            .map(|k| spell::parse_first(&k.to_string()))
            .transpose()?,
        replace_non_finite: e.replace_non_finite,
    };
    let opts = args.options().map_err(|e| e.to_string())?;
    Ok((inputs, rel(base, &e.output), opts))
}

/// The cache key of an entry: the cooker's version, its options and its frames' contents.
fn key_of(
    opts: &CookOptions,
    frames: &[Frame],
    stamps: &mut BTreeMap<String, FileStamp>,
) -> std::io::Result<String> {
    let mut h = Xxh3::new();
    h.update(b"vdbcook cook cache v2\n");
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    // Every option that shapes the bytes, as Rust prints it (floats exactly: shortest
    // round-trip); the frame range is in the frames themselves.
    let shaping = CookOptions {
        frames: None,
        ..opts.clone()
    };
    h.update(format!("{shaping:?}").as_bytes());
    for f in frames {
        let canonical_name = canonical(&f.path).to_string_lossy().into_owned();
        let stamp = content_hash(&f.path, &canonical_name, stamps)?;
        let name = f
            .path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        h.update(format!("\n{name}\t{:?}\t{}", f.number, stamp.hash).as_bytes());
        stamps.insert(canonical_name, stamp);
    }
    Ok(hex128(h.digest128()))
}

/// The cached asset of `key`, if the cache holds one that loads: every section's hash checked
/// (`Asset::from_bytes`). A corrupt or truncated entry is reported by `note` and not served.
fn cached_entry(cache_dir: &Path, key: &str, note: &dyn Fn(String)) -> Option<Vec<u8>> {
    let path = cache_dir.join(format!("{key}.vdbc"));
    let bytes = std::fs::read(&path).ok()?;
    match vdbcook_asset::Asset::from_bytes(&bytes) {
        Ok(_) => Some(bytes),
        Err(e) => {
            note(format!(
                "note: cache entry {} is damaged ({}); cooking it again",
                path.display(),
                e.0
            ));
            None
        }
    }
}

/// Runs `vdbcook cook --manifest` (`a.manifest` set; `a.json` and `--cache-dir` honoured).
pub fn run(a: &Args) -> Result<(), CliError> {
    let t0 = Instant::now();
    let path = a.manifest.as_deref().expect("manifest mode");
    let text = std::fs::read_to_string(path).map_err(|e| {
        CliError::Usage(format!("{}: cannot read the manifest: {e}", path.display()))
    })?;
    let file: ManifestFile = toml::from_str(&text).map_err(|e| {
        let line = e.span().map(|s| line_of(&text, s.start)).unwrap_or(1);
        manifest_err(path, line, e.message())
    })?;
    if file.asset.is_empty() {
        return Err(manifest_err(path, 1, "no [[asset]] entries"));
    }
    let base = path
        .parent()
        .map(|p| {
            if p.as_os_str().is_empty() {
                Path::new(".")
            } else {
                p
            }
        })
        .unwrap_or(Path::new("."))
        .to_path_buf();
    let cache_dir = a
        .cache_dir
        .clone()
        .unwrap_or_else(|| base.join(".vdbcook-cache"));
    let stamps_path = cache_dir.join("files.json");
    let mut stamps: BTreeMap<String, FileStamp> = std::fs::read(&stamps_path)
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .unwrap_or_default();

    // Check everything first: nothing is cooked or written unless every entry is sound.
    let mut jobs: Vec<Job> = Vec::new();
    for s in &file.asset {
        let line = line_of(&text, s.span().start);
        let e = s.get_ref();
        let (inputs, output_given, opts) =
            entry_options(e, &base).map_err(|m| manifest_err(path, line, m))?;
        let frames = vdbcook_cook::frames::resolve_frames(&inputs, opts.allow_gaps, opts.frames)
            .map_err(|err| manifest_err(path, line, CliError::from(err)))?;
        crate::output::refuse_inputs(&output_given, &frames, &inputs, "asset")
            .map_err(|err| manifest_err(path, line, err))?;
        let output = canonical(&output_given);
        if let Some(o) = jobs.iter().find(|j| j.output == output) {
            return Err(manifest_err(
                path,
                line,
                format!(
                    "this entry and the one at line {} both write {}",
                    o.line,
                    output_given.display()
                ),
            ));
        }
        let key = key_of(&opts, &frames, &mut stamps)
            .map_err(|err| manifest_err(path, line, format!("cannot read an input: {err}")))?;
        jobs.push(Job {
            line,
            opts,
            frames,
            output_given,
            output,
            key,
        });
    }
    for j in &jobs {
        for k in &jobs {
            if let Some(f) = k.frames.iter().find(|f| canonical(&f.path) == j.output) {
                return Err(manifest_err(
                    path,
                    j.line,
                    format!(
                        "this entry writes {}, which the entry at line {} reads: outputs cannot \
                         be inputs",
                        f.path.display(),
                        k.line
                    ),
                ));
            }
        }
    }
    std::fs::create_dir_all(&cache_dir).map_err(|e| {
        CliError::Usage(format!(
            "{}: cannot create the cache folder: {e}",
            cache_dir.display()
        ))
    })?;

    // Entries the cache holds intact are served from it; the others (missing, truncated or
    // corrupt) are cooked, each key once, in parallel, and stored: the report first, then the
    // asset (whose presence marks the entry), each written to a temporary and renamed, so a run
    // beside this one sees a whole entry or none.
    let note = |m: String| eprintln!("{m}");
    let mut held: Vec<Option<Vec<u8>>> = jobs
        .iter()
        .map(|j| cached_entry(&cache_dir, &j.key, &note))
        .collect();
    let mut todo: Vec<usize> = (0..jobs.len()).filter(|&i| held[i].is_none()).collect();
    let mut seen = std::collections::BTreeSet::new();
    todo.retain(|i| seen.insert(jobs[*i].key.clone()));
    let n = jobs.len();
    // Per cooked job: its index, seconds and asset bytes.
    type Done = Result<(usize, f64, Vec<u8>), CliError>;
    let cooked: Vec<Done> = todo
        .par_iter()
        .map(|&i| {
            let j = &jobs[i];
            let t = Instant::now();
            let cx = Context {
                progress: Progress::with(None, true, !a.json),
                ..Context::quiet()
            };
            let c = vdbcook_cook::cook(&j.opts, j.frames.clone(), &cx)
                .map_err(|err| manifest_err(path, j.line, CliError::from(err)))?;
            let doc = serde_json::to_vec_pretty(&c.report).expect("json");
            crate::output::write(
                &cache_dir.join(format!("{}.json", j.key)),
                &doc,
                "cook report",
            )?;
            crate::output::write(
                &cache_dir.join(format!("{}.vdbc", j.key)),
                &c.bytes,
                "cached asset",
            )?;
            if !a.json {
                eprintln!(
                    "cooked {} ({:.2} s)",
                    j.output_given.display(),
                    t.elapsed().as_secs_f64()
                );
            }
            Ok((i, t.elapsed().as_secs_f64(), c.bytes))
        })
        .collect();
    let mut seconds = vec![0.0; n];
    let mut fresh = vec![false; n];
    for r in cooked {
        let (i, s, bytes) = r?;
        seconds[i] = s;
        fresh[i] = true;
        // Entries of the same key share the cook.
        for k in 0..n {
            if jobs[k].key == jobs[i].key {
                held[k] = Some(bytes.clone());
            }
        }
    }
    let mut assets = Vec::with_capacity(n);
    for (i, j) in jobs.iter().enumerate() {
        let bytes = held[i].take().expect("cooked or cached");
        if std::fs::read(&j.output_given).ok().as_deref() != Some(&bytes[..]) {
            // A build's output folders may not exist yet: make them (only now, all checks done).
            if let Some(dir) = j
                .output_given
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
            {
                std::fs::create_dir_all(dir).map_err(|e| {
                    CliError::Usage(format!("{}: cannot create the folder: {e}", dir.display()))
                })?;
            }
            crate::output::write(&j.output_given, &bytes, "asset")?;
        }
        let report: Value = std::fs::read(cache_dir.join(format!("{}.json", j.key)))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or(Value::Null);
        let status = if fresh[i] { "cooked" } else { "cached" };
        if !a.json && status == "cached" {
            eprintln!("cached {}", j.output_given.display());
        }
        assets.push(json!({
            "line": j.line,
            "output": j.output_given.display().to_string(),
            "status": status,
            "key": j.key,
            "bytes": bytes.len(),
            "seconds": seconds[i],
            "cook": report,
        }));
    }
    let stamps_json = serde_json::to_vec_pretty(&stamps).expect("json");
    crate::output::write(&stamps_path, &stamps_json, "file hash index")?;
    let n_cooked = assets.iter().filter(|x| x["status"] == "cooked").count();
    let doc = json!({
        "manifest": path.display().to_string(),
        "cache_dir": cache_dir.display().to_string(),
        "assets": assets,
        "cooked": n_cooked,
        "cached": n - n_cooked,
        "seconds": t0.elapsed().as_secs_f64(),
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
    } else {
        println!(
            "{n} asset(s) from {}: {n_cooked} cooked, {} cached, in {:.2} s (cache {})",
            path.display(),
            n - n_cooked,
            t0.elapsed().as_secs_f64(),
            cache_dir.display()
        );
    }
    Ok(())
}
