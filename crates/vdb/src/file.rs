//! The file level of the VDB format: header (magic, version, UUID), file metadata, grid
//! descriptors, and each grid's compression flags, metadata and transform. Opening a file parses
//! exactly that much (cheap); the tree of a chosen grid is read on demand.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::cursor::Cursor;
use crate::error::{ErrorKind, PResult, ParseError, VdbError};
use crate::grid::FloatGrid;
use crate::metadata::{read_meta_map, MetaMap};
use crate::transform::{read_transform, Transform};
use crate::tree::{TreeFormat, TreeReader, COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC, COMPRESS_ZIP};

/// The magic number at the start of every VDB file ("VDB " as a little-endian int64).
const MAGIC: i64 = 0x5644_4220;
/// Oldest and newest file format versions read.
pub const MIN_VERSION: u32 = 220;
pub const MAX_VERSION: u32 = 224;
/// OpenVDB separates a duplicate grid name from its index with this character.
const NAME_SEP: char = '\u{1e}';

/// One grid as listed in the file.
#[derive(Debug, Clone)]
pub struct GridInfo {
    /// Name as stored, including OpenVDB's duplicate suffix (`name\x1eN`).
    pub unique_name: String,
    /// Name without the suffix.
    pub name: String,
    /// `name` or, for duplicates, `name[N]` (how OpenVDB prints it and how `--grid` selects it).
    pub label: String,
    /// Tree type, e.g. `Tree_float_5_4_3` (without the `_HalfFloat` suffix).
    pub grid_type: String,
    /// Value type parsed from the tree type: `float`, `double`, `int32`, `vec3s`, ...
    pub value_type: String,
    pub half_float: bool,
    pub instance_parent: Option<String>,
    pub compression: u32,
    pub metadata: MetaMap,
    pub transform: Transform,
    /// Offset where this grid's tree starts (for instances: none of their own).
    tree_pos: Option<usize>,
    pub end_pos: u64,
}

impl GridInfo {
    /// Float or double tree with the 5-4-3 configuration: something vdbcook can read values of.
    pub fn is_float(&self) -> bool {
        self.is_543() && (self.value_type == "float" || self.value_type == "double")
    }

    fn is_543(&self) -> bool {
        self.grid_type.ends_with("_5_4_3")
    }

    /// `fog volume`, `level set`, `staggered` or `unknown`.
    pub fn class(&self) -> &str {
        self.metadata.get_str("class").unwrap_or("unknown")
    }

    /// Compression flags as text, e.g. `blosc+active_mask`, `none`.
    pub fn compression_name(&self) -> String {
        compression_name(self.compression)
    }
}

pub fn compression_name(c: u32) -> String {
    let mut parts = Vec::new();
    if c & COMPRESS_BLOSC != 0 {
        parts.push("blosc");
    }
    if c & COMPRESS_ZIP != 0 {
        parts.push("zip");
    }
    if c & COMPRESS_ACTIVE_MASK != 0 {
        parts.push("active_mask");
    }
    if parts.is_empty() {
        "none".into()
    } else {
        parts.join("+")
    }
}

/// An opened VDB file: header, metadata and grid list; the bytes are kept for reading trees.
#[derive(Debug, Clone)]
pub struct VdbFile {
    pub path: PathBuf,
    pub file_version: u32,
    pub library_version: (u32, u32),
    pub uuid: String,
    pub metadata: MetaMap,
    pub grids: Vec<GridInfo>,
    data: Arc<Vec<u8>>,
}

impl VdbFile {
    /// Reads the file and parses everything but the trees.
    pub fn open(path: impl AsRef<Path>) -> Result<VdbFile, VdbError> {
        let path = path.as_ref();
        let data = std::fs::read(path)
            .map_err(|e| VdbError::new(ErrorKind::Io, path, format!("cannot read: {e}")))?;
        Self::from_bytes(path, data)
    }

    /// Parses an in-memory file (`path` is used in messages only).
    pub fn from_bytes(path: &Path, data: Vec<u8>) -> Result<VdbFile, VdbError> {
        let data = Arc::new(data);
        parse_file(&data)
            .map(
                |(file_version, library_version, uuid, metadata, grids)| VdbFile {
                    path: path.to_path_buf(),
                    file_version,
                    library_version,
                    uuid,
                    metadata,
                    grids,
                    data: data.clone(),
                },
            )
            .map_err(|e| VdbError::from_parse(path, e))
    }

    pub fn float_grid_labels(&self) -> Vec<String> {
        self.grids
            .iter()
            .filter(|g| g.is_float())
            .map(|g| format!("'{}'", g.label))
            .collect()
    }

    /// Picks a grid: by label (`density`, `smoke[1]`), by name (first match), by index (`#2`), or
    /// by default `density`, else the only float grid. Non-float choices are refused with the
    /// list of float grids that do exist.
    pub fn select(&self, name: Option<&str>) -> Result<usize, VdbError> {
        let err = |m: String| VdbError::new(ErrorKind::GridSelection, &self.path, m);
        let floats = self.float_grid_labels();
        let float_list = if floats.is_empty() {
            "this file has no float grids".to_string()
        } else {
            format!("float grids here: {}", floats.join(", "))
        };
        let idx = match name {
            Some(n) => {
                let by_index = n
                    .strip_prefix('#')
                    .and_then(|i| i.parse::<usize>().ok())
                    .filter(|&i| i < self.grids.len());
                by_index
                    .or_else(|| self.grids.iter().position(|g| g.label == n))
                    .or_else(|| self.grids.iter().position(|g| g.name == n))
                    .or_else(|| self.grids.iter().position(|g| g.unique_name == n))
                    .ok_or_else(|| err(format!("no grid named '{n}' ({float_list})")))?
            }
            None => {
                let dens = self
                    .grids
                    .iter()
                    .position(|g| g.name == "density" && g.is_float());
                match dens {
                    Some(i) => i,
                    None => {
                        let fl: Vec<usize> = (0..self.grids.len())
                            .filter(|&i| self.grids[i].is_float())
                            .collect();
                        match fl.as_slice() {
                            [only] => *only,
                            [] => {
                                let all: Vec<String> = self
                                    .grids
                                    .iter()
                                    .map(|g| format!("'{}' ({})", g.label, g.value_type))
                                    .collect();
                                return Err(err(format!(
                                    "no float grid to cook (grids: {})",
                                    if all.is_empty() {
                                        "none".into()
                                    } else {
                                        all.join(", ")
                                    }
                                )));
                            }
                            _ => {
                                return Err(err(format!(
                                    "no grid named 'density' and several float grids; choose one with --grid ({float_list})"
                                )))
                            }
                        }
                    }
                }
            }
        };
        let g = &self.grids[idx];
        if !g.is_float() {
            return Err(err(format!(
                "grid '{}' has type {} ({}); vdbcook reads float and double grids only ({float_list})",
                g.label, g.value_type, g.grid_type
            )));
        }
        Ok(idx)
    }

    /// Reads the tree of grid `idx` (a float or double grid; instances read their parent's tree).
    pub fn read_float_grid(&self, idx: usize) -> Result<FloatGrid, VdbError> {
        self.read_float_grid_with_stats(idx).map(|(g, _)| g)
    }

    /// As `read_float_grid`, also returning which per-node compression codes were decoded.
    pub fn read_float_grid_with_stats(
        &self,
        idx: usize,
    ) -> Result<(FloatGrid, crate::tree::CodeStats), VdbError> {
        let g = &self.grids[idx];
        if !g.is_float() {
            return Err(VdbError::new(
                ErrorKind::GridSelection,
                &self.path,
                format!("grid '{}' is {}, not a float grid", g.label, g.value_type),
            ));
        }
        // Instances share the tree of their parent (resolved by unique name).
        let src = match &g.instance_parent {
            Some(p) => self
                .grids
                .iter()
                .find(|o| &o.unique_name == p && o.instance_parent.is_none())
                .ok_or_else(|| {
                    VdbError::new(
                        ErrorKind::Corrupt,
                        &self.path,
                        format!("grid '{}' is an instance of missing grid '{p}'", g.label),
                    )
                })?,
            None => g,
        };
        if src.grid_type != g.grid_type || src.half_float != g.half_float {
            return Err(VdbError::new(
                ErrorKind::Corrupt,
                &self.path,
                format!("instance '{}' and its parent have different types", g.label),
            ));
        }
        let pos = src
            .tree_pos
            .ok_or_else(|| VdbError::new(ErrorKind::Corrupt, &self.path, "grid has no tree"))?;
        let fmt = TreeFormat {
            version: self.file_version,
            compression: src.compression,
            half: src.half_float,
            double: src.value_type == "double",
        };
        let mut r = TreeReader::new(Cursor::new(&self.data, pos), fmt);
        let grid = r
            .read(g.transform.clone())
            .map_err(|e| VdbError::from_parse(&self.path, e))?;
        Ok((grid, r.codes.clone()))
    }

    pub fn len_bytes(&self) -> usize {
        self.data.len()
    }
}

type Parsed = (u32, (u32, u32), String, MetaMap, Vec<GridInfo>);

fn parse_file(data: &[u8]) -> PResult<Parsed> {
    let mut cur = Cursor::new(data, 0);
    if data.len() < 8 || i64::from_le_bytes(data[..8].try_into().unwrap()) != MAGIC {
        return Err(ParseError::corrupt(
            0,
            "not a VDB file (the magic number 'VDB ' is missing)",
        ));
    }
    cur.take(8, "magic")?;
    let version = cur.u32("file version")?;
    if version < MIN_VERSION {
        return Err(ParseError::unsupported(
            8,
            format!(
                "file format version {version} is older than {MIN_VERSION} (OpenVDB 2.0); re-save it with a newer OpenVDB"
            ),
        ));
    }
    if version > MAX_VERSION {
        return Err(ParseError::unsupported(
            8,
            format!("file format version {version} is newer than {MAX_VERSION}, the newest this reader knows"),
        ));
    }
    let lib = (cur.u32("library version")?, cur.u32("library version")?);
    let has_offsets = cur.u8("grid offsets flag")? != 0;
    let mut header_compression = COMPRESS_ZIP | COMPRESS_ACTIVE_MASK;
    if version < crate::tree::V_NODE_MASK_COMPRESSION {
        // 220..221 store one compression flag for the whole file.
        header_compression = if cur.u8("compression flag")? != 0 {
            COMPRESS_ZIP
        } else {
            0
        };
    }
    let uuid = String::from_utf8_lossy(cur.take(36, "UUID")?).into_owned();
    let metadata = read_meta_map(&mut cur)?;
    let at = cur.offset();
    let count = cur.i32("grid count")?;
    if count < 0 {
        return Err(ParseError::corrupt(
            at,
            format!("negative grid count {count}"),
        ));
    }
    cur.check_count(count as u64, 12, "grid count")?;
    let mut grids = Vec::with_capacity(count as usize);
    for _ in 0..count {
        let g = read_grid_info(
            &mut cur,
            version,
            header_compression,
            has_offsets,
            data.len(),
        )?;
        grids.push(g);
    }
    Ok((version, lib, uuid, metadata, grids))
}

fn read_grid_info(
    cur: &mut Cursor<'_>,
    version: u32,
    header_compression: u32,
    has_offsets: bool,
    file_len: usize,
) -> PResult<GridInfo> {
    let at = cur.offset();
    let unique_name = cur.string("grid name")?;
    let mut grid_type = cur.string("grid type")?;
    let half_float = grid_type.ends_with("_HalfFloat");
    if half_float {
        grid_type.truncate(grid_type.len() - "_HalfFloat".len());
    }
    let parent = cur.string("instance parent name")?;
    let grid_pos = cur.i64("grid position")?;
    let _block_pos = cur.i64("block position")?;
    let end_pos = cur.i64("grid end position")?;
    let in_file = |p: i64| p >= 0 && (p as u64) <= file_len as u64;
    if has_offsets && (!in_file(grid_pos) || !in_file(end_pos) || end_pos < grid_pos) {
        return Err(ParseError::corrupt(
            at,
            format!(
                "grid '{unique_name}' has offsets {grid_pos}..{end_pos} outside the file ({file_len} bytes)"
            ),
        ));
    }
    let (name, label) = match unique_name.split_once(NAME_SEP) {
        Some((n, suffix)) => (n.to_string(), format!("{n}[{suffix}]")),
        None => (unique_name.clone(), unique_name.clone()),
    };
    let value_type = grid_type
        .strip_prefix("Tree_")
        .map(|s| s.split('_').next().unwrap_or(s).to_string())
        .unwrap_or_else(|| grid_type.clone());
    let mut g = GridInfo {
        unique_name,
        name,
        label,
        grid_type,
        value_type,
        half_float,
        instance_parent: (!parent.is_empty()).then_some(parent),
        compression: header_compression,
        metadata: MetaMap::default(),
        transform: Transform {
            kind: crate::transform::MapKind::UniformScale,
            index_to_world: [[0.0; 4]; 4],
            frustum: None,
        },
        tree_pos: None,
        end_pos: end_pos.max(0) as u64,
    };
    // The grid itself: compression flags (≥ 222), metadata, transform, then the tree.
    let resume = cur.pos();
    if has_offsets {
        cur.seek(grid_pos as u64, "grid")?;
    }
    if version >= crate::tree::V_NODE_MASK_COMPRESSION {
        let c_at = cur.offset();
        g.compression = cur.u32("grid compression flags")?;
        if g.compression & !(COMPRESS_ZIP | COMPRESS_ACTIVE_MASK | COMPRESS_BLOSC) != 0 {
            return Err(ParseError::corrupt(
                c_at,
                format!("unknown compression flags {:#x}", g.compression),
            ));
        }
    }
    g.metadata = read_meta_map(cur)?;
    g.transform = read_transform(cur)?;
    if g.instance_parent.is_none() {
        g.tree_pos = Some(cur.pos());
    }
    if has_offsets {
        cur.seek(end_pos as u64, "grid end")?;
        let _ = resume;
    } else if g.instance_parent.is_none() {
        // Stream without offsets: the next grid starts where this tree ends, so parse it.
        if !g.is_float() {
            return Err(ParseError::unsupported(
                at,
                format!(
                    "grid '{}' of type {} in a stream without grid offsets cannot be skipped",
                    g.label, g.value_type
                ),
            ));
        }
        let fmt = TreeFormat {
            version,
            compression: g.compression,
            half: g.half_float,
            double: g.value_type == "double",
        };
        let mut r = TreeReader::new(cur.clone(), fmt);
        r.read(g.transform.clone())?;
        cur.seek(r.end() as u64, "grid end")?;
        g.end_pos = r.end() as u64;
    }
    Ok(g)
}
