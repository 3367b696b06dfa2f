//! How the CLI and the batch manifest spell cook options (`--max-error density=0.01,5`,
//! `--max-bytes 32MiB`, `--frames 10..90`, `--lod all`): the parsers that turn those strings into
//! the typed values of `vdbcook_cook::CookOptions`, shared by both, so a manifest key and its flag
//! accept the same text.

use vdbcook_asset::MAX_LOD_LEVELS;
use vdbcook_cook::{FrameRange, Levels};

/// `--max-error`: one budget, or budgets per channel (`NAME=E`, plus at most one bare `E` for
/// the channels not named).
#[derive(Debug, Clone, PartialEq)]
pub enum MaxErrorArg {
    All(f32),
    Per {
        all: Option<f32>,
        per: Vec<(String, f32)>,
    },
}

/// Parses `--max-error`: `E` or `NAME=E[,NAME=E..]` (with at most one bare `E` among them).
pub fn parse_max_error(s: &str) -> Result<MaxErrorArg, String> {
    let num = |t: &str| -> Result<f32, String> {
        t.trim()
            .parse::<f32>()
            .map_err(|_| format!("'{t}' is not a number (expected E or NAME=E,..)"))
    };
    if !s.contains('=') {
        return num(s).map(MaxErrorArg::All);
    }
    let (mut all, mut per) = (None, Vec::new());
    for part in s.split(',') {
        match part.split_once('=') {
            Some((name, e)) => {
                let name = name.trim();
                if name.is_empty() {
                    return Err(format!("'{part}': a channel name is missing before '='"));
                }
                if per.iter().any(|(n, _)| n == name) {
                    return Err(format!("channel '{name}' is given twice"));
                }
                per.push((name.to_string(), num(e)?));
            }
            None if all.is_none() => all = Some(num(part)?),
            None => return Err("at most one budget without a channel name".into()),
        }
    }
    Ok(MaxErrorArg::Per { all, per })
}

/// Parses `A..B`, `A..` or `..B` (both ends included).
pub fn parse_frames(spec: &str) -> Result<FrameRange, String> {
    parse_frame_range(spec).map(|(first, last)| FrameRange { first, last })
}

/// Parses `A..B`, `A..` or `..B` (both ends included) into bounds.
pub fn parse_frame_range(spec: &str) -> Result<(Option<i64>, Option<i64>), String> {
    let bad = || format!("--frames '{spec}': expected A..B, A.. or ..B with frame numbers");
    let (a, b) = spec.split_once("..").ok_or_else(bad)?;
    let num = |t: &str| -> Result<Option<i64>, String> {
        let t = t.trim();
        if t.is_empty() {
            Ok(None)
        } else {
            t.parse().map(Some).map_err(|_| bad())
        }
    };
    let (lo, hi) = (num(a)?, num(b)?);
    if let (Some(l), Some(h)) = (lo, hi) {
        if l > h {
            return Err(format!(
                "--frames '{spec}': the first frame is after the last"
            ));
        }
    }
    Ok((lo, hi))
}

/// Parses a size: `123`, `64K`/`64KB` (10³), `32M`/`32MB`, `1G`/`1GB`, `64KiB` (2¹⁰), `32MiB`,
/// `1GiB` (case-insensitive suffix, optional space, integer or decimal number).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let n: f64 = num
        .parse()
        .map_err(|_| format!("'{s}' is not a size (e.g. 500000, 64KiB, 32MiB, 1.5GB)"))?;
    let mult: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" => 1e3,
        "m" | "mb" => 1e6,
        "g" | "gb" => 1e9,
        "kib" => 1024.0,
        "mib" => 1024.0 * 1024.0,
        "gib" => 1024.0 * 1024.0 * 1024.0,
        u => {
            return Err(format!(
                "unknown size unit '{u}' in '{s}' (B, K, M, G, KiB, MiB, GiB)"
            ))
        }
    };
    let v = n * mult;
    if !(v.is_finite() && (1.0..1.8e19).contains(&v)) {
        return Err(format!(
            "'{s}' is out of range: SIZE must be 1 byte to 16 EiB"
        ));
    }
    Ok(v.round() as u64)
}

/// Parses `--lod`: `all` or a count 1..=12.
pub fn parse_levels(s: &str) -> Result<Levels, String> {
    if s == "all" {
        return Ok(Levels::All);
    }
    match s.parse::<u32>() {
        Ok(n) if (1..=MAX_LOD_LEVELS).contains(&n) => Ok(Levels::Count(n)),
        _ => Err(format!(
            "'{s}' is not a level count: give 'all' (down to one brick) or 1 to {MAX_LOD_LEVELS}"
        )),
    }
}

/// Parses `--lod-from`: the first coarser level stored, 1 to 12.
pub fn parse_first(s: &str) -> Result<u32, String> {
    match s.parse::<u32>() {
        Ok(n) if (1..=MAX_LOD_LEVELS).contains(&n) => Ok(n),
        _ => Err(format!(
            "'{s}' is not a level: give 1 to {MAX_LOD_LEVELS} (level K's voxels are 2^K wide)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_decimal_and_binary_units() {
        assert_eq!(parse_size("500000"), Ok(500_000));
        assert_eq!(parse_size("64KiB"), Ok(65_536));
        assert_eq!(parse_size("32MiB"), Ok(32 * 1024 * 1024));
        assert_eq!(parse_size("1.5GB"), Ok(1_500_000_000));
        assert_eq!(parse_size("2 mb"), Ok(2_000_000));
        for bad in ["", "MiB", "12 parsecs", "-5", "0", "1e400", "nan"] {
            assert!(parse_size(bad).is_err(), "{bad:?} should be refused");
        }
    }

    #[test]
    fn levels_parse() {
        assert_eq!(parse_levels("all"), Ok(Levels::All));
        assert_eq!(parse_levels("3"), Ok(Levels::Count(3)));
        assert!(parse_levels("0").is_err());
        assert!(parse_levels("13").is_err());
        assert!(parse_levels("two").is_err());
        assert_eq!(parse_first("2"), Ok(2));
        assert!(parse_first("0").is_err());
    }

    #[test]
    fn frame_ranges_parse() {
        assert_eq!(
            parse_frames("10..90"),
            Ok(FrameRange {
                first: Some(10),
                last: Some(90)
            })
        );
        assert_eq!(
            parse_frames("..5"),
            Ok(FrameRange {
                first: None,
                last: Some(5)
            })
        );
        assert!(parse_frames("9..3").is_err());
        assert!(parse_frames("nine").is_err());
    }
}
