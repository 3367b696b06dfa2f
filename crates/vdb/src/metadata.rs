//! OpenVDB metadata maps (file-level and per-grid): typed name/value pairs, each with a byte size
//! so unknown types can be skipped safely.

use crate::cursor::Cursor;
use crate::error::{PResult, ParseError};

/// A decoded metadata value. Types vdbcook does not interpret keep only their type name.
#[derive(Debug, Clone, PartialEq)]
pub enum MetaValue {
    Str(String),
    Bool(bool),
    I32(i32),
    I64(i64),
    F32(f32),
    F64(f64),
    Vec3i([i32; 3]),
    Vec3f([f32; 3]),
    Vec3d([f64; 3]),
    /// A type vdbcook does not decode (e.g. `__delayedload`), with its size in bytes.
    Other {
        type_name: String,
        size: u32,
    },
}

/// Metadata in file order.
#[derive(Debug, Clone, Default)]
pub struct MetaMap {
    pub entries: Vec<(String, MetaValue)>,
}

impl MetaMap {
    pub fn get(&self, key: &str) -> Option<&MetaValue> {
        self.entries.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }

    pub fn get_str(&self, key: &str) -> Option<&str> {
        match self.get(key) {
            Some(MetaValue::Str(s)) => Some(s),
            _ => None,
        }
    }

    pub fn get_bool(&self, key: &str) -> Option<bool> {
        match self.get(key) {
            Some(MetaValue::Bool(b)) => Some(*b),
            _ => None,
        }
    }
}

/// Reads a `MetaMap` (`int32 count`, then `name, type name, u32 size, payload` per entry).
pub(crate) fn read_meta_map(cur: &mut Cursor<'_>) -> PResult<MetaMap> {
    let at = cur.offset();
    let count = cur.i32("metadata count")?;
    if count < 0 {
        return Err(ParseError::corrupt(
            at,
            format!("negative metadata count {count}"),
        ));
    }
    // Each entry needs at least two string lengths and a size: 12 bytes.
    cur.check_count(count as u64, 12, "metadata count")?;
    let mut entries = Vec::with_capacity(count as usize);
    for _ in 0..count {
        let name = cur.string("metadata name")?;
        let type_name = cur.string("metadata type name")?;
        let size_at = cur.offset();
        let size = cur.u32("metadata size")?;
        let payload = cur.take(size as usize, "metadata value")?;
        let value = decode(&type_name, payload).ok_or_else(|| {
            ParseError::corrupt(
                size_at,
                format!("metadata '{name}' of type {type_name} has a bad size {size}"),
            )
        })?;
        entries.push((name, value));
    }
    Ok(MetaMap { entries })
}

fn decode(type_name: &str, p: &[u8]) -> Option<MetaValue> {
    let f32_at = |i: usize| f32::from_le_bytes(p[i..i + 4].try_into().unwrap());
    let i32_at = |i: usize| i32::from_le_bytes(p[i..i + 4].try_into().unwrap());
    let f64_at = |i: usize| f64::from_le_bytes(p[i..i + 8].try_into().unwrap());
    let want = |n: usize| if p.len() == n { Some(()) } else { None };
    Some(match type_name {
        "string" => MetaValue::Str(String::from_utf8_lossy(p).into_owned()),
        "bool" => {
            want(1)?;
            MetaValue::Bool(p[0] != 0)
        }
        "int32" => {
            want(4)?;
            MetaValue::I32(i32_at(0))
        }
        "int64" => {
            want(8)?;
            MetaValue::I64(i64::from_le_bytes(p.try_into().ok()?))
        }
        "float" => {
            want(4)?;
            MetaValue::F32(f32_at(0))
        }
        "double" => {
            want(8)?;
            MetaValue::F64(f64_at(0))
        }
        "vec3i" => {
            want(12)?;
            MetaValue::Vec3i([i32_at(0), i32_at(4), i32_at(8)])
        }
        "vec3s" => {
            want(12)?;
            MetaValue::Vec3f([f32_at(0), f32_at(4), f32_at(8)])
        }
        "vec3d" => {
            want(24)?;
            MetaValue::Vec3d([f64_at(0), f64_at(8), f64_at(16)])
        }
        other => MetaValue::Other {
            type_name: other.to_string(),
            size: p.len() as u32,
        },
    })
}
