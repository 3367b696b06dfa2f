//! What a cook is asked to do, as typed values: [`CookOptions`]. No strings are parsed here (the
//! CLI and the batch manifest parse their spellings into these), and every option composes with
//! every other: a single grid is the one-channel case of several, so clustering, a size budget,
//! levels of detail and frame ranges mean the same with one grid or eight.
//! [`CookOptions::validate`] checks ranges and combinations before any file is opened.

use vdbcook_asset::{PayloadFormat, RangeMode, MAX_CHANNELS, MAX_LOD_LEVELS};

use crate::bcenc::Bc7Quality;
use crate::error::CookError;

/// Which grids every frame gives the asset (one channel each, in order).
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Grids {
    /// The first frame's `density`, else its only float grid.
    #[default]
    Default,
    /// One grid: a name, `name[N]` for the N-th of several with that name, or `#N` (the N-th
    /// grid of the first frame).
    One(String),
    /// Several grids on one shared topology, channel 0 first (the one plain renders show).
    Several(Vec<String>),
    /// Picked by name from the first frame: a density, a temperature and a flame grid of
    /// Blender, Houdini or EmberGen caches ([`crate::grid_pick`]).
    Auto,
}

/// The error bound every voxel is held to.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Budget {
    /// None for a lossless cook; a lossy format (or clustering) gets the default artefact guard,
    /// 10% of each channel's value range ([`crate::encode::default_budget`]).
    #[default]
    Default,
    /// Every voxel of channel `c` decodes within its bound on any GPU: the bound
    /// `per` names for it, else `all` (else the default guard).
    MaxError {
        all: Option<f32>,
        per: Vec<(String, f32)>,
    },
    /// The smallest bound whose asset's GPU bytes (topology + atlas) fit: one fraction of every
    /// channel's value range, searched.
    MaxBytes(u64),
}

/// k-means brick clustering (lossy; always guarded by the budget).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clustering {
    /// Centroids: with several channels, shared among the groups of bricks that the same
    /// channels read, in proportion to their sizes.
    pub clusters: usize,
    pub iterations: usize,
    /// Bricks whose normalized variance (variance / |mean|) exceeds this keep their own data.
    pub variance_threshold: f32,
}

impl Clustering {
    /// `clusters` centroids with the default iterations (5) and variance threshold (0.1).
    pub fn new(clusters: usize) -> Clustering {
        Clustering {
            clusters,
            iterations: 5,
            variance_threshold: 0.1,
        }
    }
}

/// How many coarser levels `--lod` stores.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Levels {
    /// Down to the level whose extent fits one 8³ brick.
    All,
    /// This many (capped at `All`'s count).
    Count(u32),
}

/// Levels of detail: every frame's mip chain over the same brick pool.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Lod {
    /// The last level (`All`: down to one brick).
    pub levels: Levels,
    /// The first level stored (1 to 12): the finer ones are built and dropped.
    pub first: u32,
}

/// Frames numbered `first..=last` as their file names number them (`None`: unbounded).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameRange {
    pub first: Option<i64>,
    pub last: Option<i64>,
}

/// Largest `clusters` (centroid indices stay far inside the asset's 31-bit brick references).
pub const MAX_CLUSTERS: usize = 1 << 24;
/// Largest `iterations`.
pub const MAX_ITERATIONS: usize = 1000;

/// Everything a cook is asked to do besides its frames.
#[derive(Debug, Clone, PartialEq)]
pub struct CookOptions {
    pub grids: Grids,
    /// The payload to start from (`None`: f32, or BC7 under a budget).
    pub format: Option<PayloadFormat>,
    pub budget: Budget,
    /// Quantization range of unorm8/BC bricks (one grid only for `Global`).
    pub range: RangeMode,
    pub bc7_quality: Bc7Quality,
    /// An error budget may store a brick packed at its own bit depth (1–7 bits a voxel, asset
    /// format 7); `false` (`--no-packed`) keeps to BC7, BC4, unorm8, f16 and f32.
    pub packed: bool,
    pub clustering: Option<Clustering>,
    pub lod: Option<Lod>,
    /// Frames to cook (`None`: all the inputs resolve to).
    pub frames: Option<FrameRange>,
    /// Accept gaps in the frame numbering.
    pub allow_gaps: bool,
    /// A frame without a grid is cooked as that grid's background.
    pub allow_missing_grid: bool,
    /// Keep a channel after the first that carries nothing within its budget.
    pub keep_empty_channels: bool,
    /// Replace NaN and ±Inf active values with this (by default they are an error).
    pub replace_non_finite: Option<f32>,
}

impl Default for CookOptions {
    /// `vdbcook cook INPUT -o OUT`: the default grid, bit-exact f32, per-brick range.
    fn default() -> CookOptions {
        CookOptions {
            grids: Grids::Default,
            format: None,
            budget: Budget::Default,
            range: RangeMode::Brick,
            bc7_quality: Bc7Quality::Fast,
            packed: true,
            clustering: None,
            lod: None,
            frames: None,
            allow_gaps: false,
            allow_missing_grid: false,
            keep_empty_channels: false,
            replace_non_finite: None,
        }
    }
}

impl CookOptions {
    /// The bound named for channel `name`, else the one for every channel.
    pub fn max_error_of(&self, name: &str) -> Option<f32> {
        match &self.budget {
            Budget::MaxError { all, per } => per
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, e)| *e)
                .or(*all),
            _ => None,
        }
    }

    /// Whether any bound is given (the payload then starts at BC7 unless a format is given).
    pub fn bounded(&self) -> bool {
        match &self.budget {
            Budget::Default => false,
            Budget::MaxError { all, per } => all.is_some() || !per.is_empty(),
            Budget::MaxBytes(_) => true,
        }
    }

    /// Checks every option's range and combination (each message names the option as the CLI
    /// spells it, and its range).
    pub fn validate(&self) -> Result<(), CookError> {
        let bad = |m: String| Err(CookError::Options(m));
        match &self.grids {
            Grids::Several(g) => {
                if g.is_empty() {
                    return bad("--grids names no grid".into());
                }
                if g.len() > MAX_CHANNELS {
                    return bad(format!(
                        "--grids names {} grids; an asset holds at most {MAX_CHANNELS}",
                        g.len()
                    ));
                }
                for (i, name) in g.iter().enumerate() {
                    if name.trim().is_empty() {
                        return bad("--grids has an empty name".into());
                    }
                    if g[..i].contains(name) {
                        return bad(format!("--grids names '{name}' twice"));
                    }
                }
            }
            Grids::One(name) if name.trim().is_empty() => {
                return bad("--grid has an empty name".into())
            }
            _ => {}
        }
        let several =
            matches!(&self.grids, Grids::Several(g) if g.len() > 1) || self.grids == Grids::Auto;
        if let Budget::MaxError { all, per } = &self.budget {
            if let Some(e) = all {
                if !(e.is_finite() && *e > 0.0) {
                    return bad(format!(
                        "--max-error {e} is out of range: E must be a finite number > 0 (for a lossless asset use --format f32)"
                    ));
                }
            }
            for (i, (name, e)) in per.iter().enumerate() {
                if per[..i].iter().any(|(n, _)| n == name) {
                    return bad(format!("--max-error names channel '{name}' twice"));
                }
                let known = match &self.grids {
                    Grids::Auto => true,
                    Grids::Several(g) => g.contains(name),
                    Grids::One(g) => g == name,
                    Grids::Default => name == "density",
                };
                if !known {
                    return bad(format!(
                        "--max-error {name}={e}: '{name}' is not a cooked grid{}",
                        match &self.grids {
                            Grids::Several(g) => format!(" (--grids {})", g.join(",")),
                            _ => " (per-channel budgets name grids of --grids)".to_string(),
                        }
                    ));
                }
                if !(e.is_finite() && *e > 0.0) {
                    return bad(format!(
                        "--max-error {name}={e} is out of range: E must be a finite number > 0"
                    ));
                }
            }
            if !several && per.len() > 1 {
                return bad("budgets for several grids need --grids naming them".into());
            }
        }
        if let Budget::MaxBytes(0) = self.budget {
            return bad("--max-bytes 0 is out of range: SIZE must be > 0".into());
        }
        if let Some(c) = &self.clustering {
            if !(1..=MAX_CLUSTERS).contains(&c.clusters) {
                return bad(format!(
                    "--clusters {} is out of range: K must be 1 to {MAX_CLUSTERS} (and is capped at the number of candidate bricks)",
                    c.clusters
                ));
            }
            if !(1..=MAX_ITERATIONS).contains(&c.iterations) {
                return bad(format!(
                    "--iterations {} is out of range: N must be 1 to {MAX_ITERATIONS}",
                    c.iterations
                ));
            }
            if !(c.variance_threshold.is_finite() && c.variance_threshold >= 0.0) {
                return bad(format!(
                    "--variance-threshold {} is out of range: T must be a finite number >= 0",
                    c.variance_threshold
                ));
            }
        }
        if let Some(l) = &self.lod {
            if !(1..=MAX_LOD_LEVELS).contains(&l.first) {
                return bad(format!(
                    "--lod-from {} is out of range: K must be 1 to {MAX_LOD_LEVELS}",
                    l.first
                ));
            }
            match l.levels {
                Levels::Count(n) if !(1..=MAX_LOD_LEVELS).contains(&n) => {
                    return bad(format!(
                        "--lod {n} is out of range: give 'all' or 1 to {MAX_LOD_LEVELS}"
                    ))
                }
                Levels::Count(n) if l.first > n => {
                    return bad(format!(
                        "--lod-from {} starts past --lod {n}, the last level stored (give --lod {} or more, or --lod all)",
                        l.first, l.first
                    ))
                }
                _ => {}
            }
        }
        if let Some(r) = &self.frames {
            if let (Some(a), Some(b)) = (r.first, r.last) {
                if a > b {
                    return bad(format!(
                        "--frames '{a}..{b}': the first frame is after the last"
                    ));
                }
            }
        }
        if several && self.range == RangeMode::Global {
            return bad(
                "--range global quantizes every brick to one value range, which several grids \
                 (--grids) do not share: cook them with --range brick"
                    .into(),
            );
        }
        if let Some(v) = self.replace_non_finite {
            if !v.is_finite() {
                return bad(format!(
                    "--replace-non-finite {v}: VALUE must be a finite number"
                ));
            }
        }
        Ok(())
    }
}
