//! The frames and grids a cook reads: inputs resolved to a numbered sequence
//! (`vdb::sequence::resolve_inputs`), a frame range selected, the grid of a single-grid cook
//! chosen once for the whole sequence, and one grid of one frame read by name.

use vdbcook_asset::FrameInfo;
use vdbcook_vdb::sequence::{self, Frame};
use vdbcook_vdb::{ErrorKind, VdbError, VdbFile};

use crate::error::CookError;
use crate::options::FrameRange;

/// The frames `inputs` name (files, folders, frame patterns or globs), in sequence order, then
/// those `range` selects.
pub fn resolve_frames(
    inputs: &[String],
    allow_gaps: bool,
    range: Option<FrameRange>,
) -> Result<Vec<Frame>, CookError> {
    let frames = sequence::resolve_inputs(inputs, allow_gaps)?;
    match range {
        None => Ok(frames),
        Some(r) => select_frames(frames, r),
    }
}

impl std::fmt::Display for FrameRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let end = |v: Option<i64>| v.map(|x| x.to_string()).unwrap_or_default();
        write!(f, "{}..{}", end(self.first), end(self.last))
    }
}

/// The frames numbered within `range` (both ends included). Every frame must carry a number, and
/// the range must select at least one.
pub fn select_frames(frames: Vec<Frame>, range: FrameRange) -> Result<Vec<Frame>, CookError> {
    let (lo, hi) = (range.first, range.last);
    let (first, last) = (
        frames.iter().filter_map(|f| f.number).min(),
        frames.iter().filter_map(|f| f.number).max(),
    );
    if let Some(f) = frames.iter().find(|f| f.number.is_none()) {
        return Err(CookError::Options(format!(
            "--frames needs numbered frames, and {} has no frame number in its name",
            f.path.display()
        )));
    }
    let picked: Vec<Frame> = frames
        .into_iter()
        .filter(|f| {
            let n = f.number.expect("checked");
            lo.is_none_or(|l| n >= l) && hi.is_none_or(|h| n <= h)
        })
        .collect();
    if picked.is_empty() {
        return Err(CookError::Options(format!(
            "--frames '{range}' selects no frame (the inputs number {} to {})",
            first.map_or("?".into(), |v| v.to_string()),
            last.map_or("?".into(), |v| v.to_string())
        )));
    }
    Ok(picked)
}

/// The grid the whole sequence is cooked from, chosen once: `--grid` as given (an index `#N` is
/// resolved to its label in the first frame), else the first frame's `density`, else its only
/// float grid. Returns the label and how it was chosen (for error messages).
pub fn choose_grid(frames: &[Frame], grid: Option<&str>) -> Result<(String, String), CookError> {
    match grid {
        Some(g) if !g.starts_with('#') => Ok((g.to_string(), "given by --grid".into())),
        _ => {
            let f0 = &frames[0].path;
            let file = VdbFile::open(f0)?;
            let i = file.select(grid)?;
            let how = match grid {
                Some(g) => format!("--grid {g} in the first frame {}", f0.display()),
                None => format!(
                    "chosen from the first frame {} ('density', else its only float grid)",
                    f0.display()
                ),
            };
            Ok((file.grids[i].label.clone(), how))
        }
    }
}

/// Reads grid `name` of one frame from its file, already open (a frame's several grids are read
/// from one open). A frame without it is `Ok(None)` under `allow_missing`, else an error naming
/// the frame (`hint`: mention `--allow-missing-grid`).
pub fn read_named_in(
    file: &VdbFile,
    f: &Frame,
    name: &str,
    how: &str,
    allow_missing: bool,
    hint: bool,
) -> Result<Option<sequence::LoadedFrame>, VdbError> {
    let present = file
        .grids
        .iter()
        .any(|g| g.label == name || g.name == name || g.unique_name == name);
    if !present {
        if allow_missing {
            return Ok(None);
        }
        let floats = file.float_grid_labels();
        return Err(VdbError::new(
            ErrorKind::GridSelection,
            &f.path,
            format!(
                "this frame has no grid '{name}' ({how}; every frame must have it); float grids here: {}{}",
                if floats.is_empty() { "none".into() } else { floats.join(", ") },
                if hint { "; pass --allow-missing-grid to cook such frames as empty frames" } else { "" }
            ),
        ));
    }
    let idx = file.select(Some(name))?;
    let grid = file.read_float_grid(idx)?;
    Ok(Some(sequence::LoadedFrame {
        frame: f.clone(),
        grid_label: file.grids[idx].label.clone(),
        grid,
    }))
}

/// The header's record of one source frame: its number, its file name (no folders, so cooks are
/// reproducible across machines) and its active voxels.
pub fn frame_info(frame: &Frame, active_voxels: u64) -> FrameInfo {
    FrameInfo {
        number: frame.number,
        source: frame
            .path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        active_voxels,
    }
}
