//! Frame sequences: turning `INPUT...` (files, folders, `smoke.####.vdb` / `smoke.%04d.vdb`
//! patterns, globs) into an ordered list of frames with their numbers, checking for gaps, and
//! reading the chosen grid of every frame in parallel with matching transforms.

use std::cmp::Ordering;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::error::{ErrorKind, VdbError};
use crate::file::VdbFile;
use crate::grid::FloatGrid;

/// One input file and its frame number (when its name has one).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    pub path: PathBuf,
    pub number: Option<i64>,
}

/// Resolves inputs in the order given. Folders, patterns and globs are expanded in natural frame
/// order and their numbering is checked for gaps (an error unless `allow_gaps`); plain files are
/// taken as they are.
pub fn resolve_inputs(
    inputs: &[impl AsRef<str>],
    allow_gaps: bool,
) -> Result<Vec<Frame>, VdbError> {
    let mut out = Vec::new();
    for input in inputs {
        let input = input.as_ref();
        let p = Path::new(input);
        let expanded = if p.is_dir() {
            let mut files = Vec::new();
            let rd =
                std::fs::read_dir(p).map_err(|e| seq_err(p, format!("cannot list folder: {e}")))?;
            for entry in rd {
                let path = entry
                    .map_err(|e| seq_err(p, format!("cannot list folder: {e}")))?
                    .path();
                if path.is_file()
                    && path
                        .extension()
                        .is_some_and(|x| x.eq_ignore_ascii_case("vdb"))
                {
                    files.push(path);
                }
            }
            if files.is_empty() {
                return Err(seq_err(p, "folder has no .vdb files"));
            }
            Some(number_and_sort(files, None))
        } else if let Some(pat) = FramePattern::parse(input) {
            let frames = pat.expand()?;
            if frames.is_empty() {
                return Err(seq_err(p, "no files match this frame pattern"));
            }
            Some(frames)
        } else if input.contains(['*', '?', '[']) && !p.exists() {
            let paths =
                glob::glob(input).map_err(|e| seq_err(p, format!("bad glob pattern: {e}")))?;
            let files: Vec<PathBuf> = paths
                .filter_map(Result::ok)
                .filter(|f| f.is_file())
                .collect();
            if files.is_empty() {
                return Err(seq_err(p, "no files match this glob"));
            }
            Some(number_and_sort(files, None))
        } else {
            if !p.is_file() {
                return Err(VdbError::new(ErrorKind::Io, p, "no such file"));
            }
            out.push(Frame {
                path: p.to_path_buf(),
                number: frame_number(p),
            });
            None
        };
        if let Some(frames) = expanded {
            check_gaps(p, &frames, allow_gaps)?;
            out.extend(frames);
        }
    }
    Ok(out)
}

fn seq_err(p: &Path, m: impl Into<String>) -> VdbError {
    VdbError::new(ErrorKind::Sequence, p, m)
}

/// Missing or repeated frame numbers in an expanded input.
fn check_gaps(input: &Path, frames: &[Frame], allow_gaps: bool) -> Result<(), VdbError> {
    let nums: Vec<i64> = frames.iter().filter_map(|f| f.number).collect();
    if nums.len() != frames.len() || nums.len() < 2 {
        return Ok(());
    }
    for w in frames.windows(2) {
        if w[0].number == w[1].number {
            return Err(seq_err(
                input,
                format!(
                    "frame {} appears twice: {} and {}",
                    w[0].number.unwrap_or(0),
                    w[0].path.display(),
                    w[1].path.display()
                ),
            ));
        }
    }
    // A uniform stride (every frame, or every 2nd frame exported) is not a gap.
    let step = nums
        .windows(2)
        .map(|w| w[1] - w[0])
        .min()
        .unwrap_or(1)
        .max(1);
    let missing: Vec<i64> = nums
        .windows(2)
        .flat_map(|w| {
            (1..)
                .map(move |k| w[0] + k * step)
                .take_while(move |&n| n < w[1])
        })
        .collect();
    if !missing.is_empty() && !allow_gaps {
        let shown: Vec<String> = missing.iter().take(10).map(|n| n.to_string()).collect();
        return Err(seq_err(
            input,
            format!(
                "gap in the frame numbering: {} missing frame(s) ({}{}) between {} and {}; pass --allow-gaps to cook what is there",
                missing.len(),
                shown.join(", "),
                if missing.len() > 10 { ", ..." } else { "" },
                nums[0],
                nums[nums.len() - 1]
            ),
        ));
    }
    Ok(())
}

/// The last run of digits in the file stem, with a leading '-' if there is one.
pub fn frame_number(p: &Path) -> Option<i64> {
    let stem = p.file_stem()?.to_str()?;
    let b = stem.as_bytes();
    let end = b.iter().rposition(|c| c.is_ascii_digit())? + 1;
    let mut start = end;
    while start > 0 && b[start - 1].is_ascii_digit() {
        start -= 1;
    }
    let digits = &stem[start..end];
    if digits.len() > 18 {
        return None;
    }
    let n: i64 = digits.parse().ok()?;
    // "smoke.-0005" is frame -5; "smoke_v2-0005" keeps the dash as a separator.
    let negative =
        start >= 1 && b[start - 1] == b'-' && (start == 1 || !b[start - 2].is_ascii_alphanumeric());
    Some(if negative { -n } else { n })
}

fn number_and_sort(files: Vec<PathBuf>, _pat: Option<&FramePattern>) -> Vec<Frame> {
    let mut frames: Vec<Frame> = files
        .into_iter()
        .map(|path| {
            let number = frame_number(&path);
            Frame { path, number }
        })
        .collect();
    frames.sort_by(|a, b| {
        let sa = a.path.to_string_lossy();
        let sb = b.path.to_string_lossy();
        match (a.number, b.number) {
            (Some(x), Some(y)) => prefix_of(&sa)
                .cmp(prefix_of(&sb))
                .then(x.cmp(&y))
                .then_with(|| natural_cmp(&sa, &sb)),
            _ => natural_cmp(&sa, &sb),
        }
    });
    frames
}

/// The part of a path before its frame number (so `a.10` sorts after `a.9`, and sequences with
/// different prefixes stay apart).
fn prefix_of(s: &str) -> &str {
    let b = s.as_bytes();
    match b.iter().rposition(|c| c.is_ascii_digit()) {
        Some(end) => {
            let mut start = end;
            while start > 0 && b[start - 1].is_ascii_digit() {
                start -= 1;
            }
            &s[..start]
        }
        None => s,
    }
}

/// Natural order: digit runs compare as numbers.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let la = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let lb = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let (da, db) = (&a[..la], &b[..lb]);
                let ta = trim_zeros(da);
                let tb = trim_zeros(db);
                let o = ta.len().cmp(&tb.len()).then(ta.cmp(tb)).then(la.cmp(&lb));
                if o != Ordering::Equal {
                    return o;
                }
                a = &a[la..];
                b = &b[lb..];
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                a = &a[1..];
                b = &b[1..];
            }
        }
    }
}

fn trim_zeros(d: &[u8]) -> &[u8] {
    let z = d.iter().take_while(|&&c| c == b'0').count();
    &d[z.min(d.len().saturating_sub(1))..]
}

/// `dir/prefix####suffix` or `dir/prefix%04dsuffix`: the frame digits' minimum width.
#[derive(Debug, Clone)]
struct FramePattern {
    dir: PathBuf,
    prefix: String,
    suffix: String,
    width: usize,
}

impl FramePattern {
    fn parse(input: &str) -> Option<FramePattern> {
        let p = Path::new(input);
        let name = p.file_name()?.to_str()?;
        let dir = p
            .parent()
            .map(|d| {
                if d.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    d
                }
            })?
            .to_path_buf();
        if let Some(start) = name.find('#') {
            let width = name[start..].bytes().take_while(|&c| c == b'#').count();
            let (prefix, suffix) = (&name[..start], &name[start + width..]);
            if suffix.contains('#') {
                return None;
            }
            return Some(FramePattern {
                dir,
                prefix: prefix.into(),
                suffix: suffix.into(),
                width,
            });
        }
        let start = name.find('%')?;
        let rest = &name[start + 1..];
        let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        let after = &rest[digits.len()..];
        let suffix = after.strip_prefix('d')?;
        let width = digits.trim_start_matches('0').parse().unwrap_or(1).max(1);
        Some(FramePattern {
            dir,
            prefix: name[..start].into(),
            suffix: suffix.into(),
            width,
        })
    }

    fn expand(&self) -> Result<Vec<Frame>, VdbError> {
        let rd = std::fs::read_dir(&self.dir)
            .map_err(|e| seq_err(&self.dir, format!("cannot list folder: {e}")))?;
        let mut frames = Vec::new();
        for entry in rd.flatten() {
            let fname = entry.file_name();
            let Some(name) = fname.to_str() else { continue };
            let Some(mid) = name
                .strip_prefix(self.prefix.as_str())
                .and_then(|r| r.strip_suffix(self.suffix.as_str()))
            else {
                continue;
            };
            let (neg, digits) = match mid.strip_prefix('-') {
                Some(d) => (true, d),
                None => (false, mid),
            };
            if digits.len() < self.width
                || digits.len() > 18
                || !digits.bytes().all(|c| c.is_ascii_digit())
            {
                continue;
            }
            // Wider than the pattern only without zero padding (frame 10000 of `####`).
            if digits.len() > self.width && digits.starts_with('0') {
                continue;
            }
            let n: i64 = digits.parse().unwrap_or(0);
            frames.push(Frame {
                path: self.dir.join(name),
                number: Some(if neg { -n } else { n }),
            });
        }
        frames.sort_by_key(|f| f.number);
        Ok(frames)
    }
}

/// One frame's chosen grid.
#[derive(Debug, Clone)]
pub struct LoadedFrame {
    pub frame: Frame,
    pub grid_label: String,
    pub grid: FloatGrid,
}

/// Reads the chosen grid of one frame.
pub fn read_frame(frame: &Frame, grid: Option<&str>) -> Result<LoadedFrame, VdbError> {
    let file = VdbFile::open(&frame.path)?;
    let idx = file.select(grid)?;
    let g = file.read_float_grid(idx)?;
    Ok(LoadedFrame {
        frame: frame.clone(),
        grid_label: file.grids[idx].label.clone(),
        grid: g,
    })
}

/// Reads every frame in parallel (rayon), reporting the first failing frame in sequence order,
/// and checks that all frames share the first frame's transform.
pub fn read_sequence(frames: &[Frame], grid: Option<&str>) -> Result<Vec<LoadedFrame>, VdbError> {
    let results: Vec<Result<LoadedFrame, VdbError>> =
        frames.par_iter().map(|f| read_frame(f, grid)).collect();
    let loaded = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    check_transforms(&loaded)?;
    Ok(loaded)
}

/// All frames must have the first frame's index→world transform (to a relative 1e-9).
pub fn check_transforms(frames: &[LoadedFrame]) -> Result<(), VdbError> {
    let Some(first) = frames.first() else {
        return Ok(());
    };
    for f in &frames[1..] {
        if !f.grid.transform.approx_eq(&first.grid.transform, 1e-9) {
            return Err(seq_err(
                &f.frame.path,
                format!(
                    "grid '{}' has a different transform (voxel size {:?}, {}) from frame {} (voxel size {:?}, {}); all frames must share one transform",
                    f.grid_label,
                    f.grid.transform.voxel_size(),
                    f.grid.transform.kind.type_name(),
                    first.frame.path.display(),
                    first.grid.transform.voxel_size(),
                    first.grid.transform.kind.type_name(),
                ),
            ));
        }
    }
    Ok(())
}
