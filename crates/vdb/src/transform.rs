//! OpenVDB transforms (maps), decoded into one index→world 4×4 matrix plus voxel size.
//!
//! OpenVDB stores matrices for row vectors (`world = [i j k 1] · M`, translation in the last row).
//! vdbcook exposes the transpose: `index_to_world[r][c]`, row-major, for column vectors
//! (`world = A · [i j k 1]ᵀ`, translation in the last column).

use crate::cursor::Cursor;
use crate::error::{PResult, ParseError};

/// The map kinds OpenVDB writes, by their registered type names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapKind {
    UniformScale,
    UniformScaleTranslate,
    Scale,
    ScaleTranslate,
    Translation,
    Affine,
    Unitary,
    NonlinearFrustum,
}

impl MapKind {
    pub fn type_name(self) -> &'static str {
        match self {
            MapKind::UniformScale => "UniformScaleMap",
            MapKind::UniformScaleTranslate => "UniformScaleTranslateMap",
            MapKind::Scale => "ScaleMap",
            MapKind::ScaleTranslate => "ScaleTranslateMap",
            MapKind::Translation => "TranslationMap",
            MapKind::Affine => "AffineMap",
            MapKind::Unitary => "UnitaryMap",
            MapKind::NonlinearFrustum => "NonlinearFrustumMap",
        }
    }

    fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "UniformScaleMap" => MapKind::UniformScale,
            "UniformScaleTranslateMap" => MapKind::UniformScaleTranslate,
            "ScaleMap" => MapKind::Scale,
            "ScaleTranslateMap" => MapKind::ScaleTranslate,
            "TranslationMap" => MapKind::Translation,
            "AffineMap" => MapKind::Affine,
            "UnitaryMap" => MapKind::Unitary,
            "NonlinearFrustumMap" => MapKind::NonlinearFrustum,
            _ => return None,
        })
    }

    /// Only linear maps can be cooked: the asset stores one matrix.
    pub fn is_linear(self) -> bool {
        self != MapKind::NonlinearFrustum
    }
}

/// Parameters of a frustum map, kept for listing only.
#[derive(Debug, Clone, PartialEq)]
pub struct Frustum {
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
    pub taper: f64,
    pub depth: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Transform {
    pub kind: MapKind,
    /// Column-vector index→world matrix (for frustum maps: the linear part that follows the frustum).
    pub index_to_world: [[f64; 4]; 4],
    pub frustum: Option<Frustum>,
}

impl Transform {
    /// World-space length of one index step along each axis (OpenVDB's `voxelSize()` for linear maps).
    pub fn voxel_size(&self) -> [f64; 3] {
        let m = &self.index_to_world;
        let col = |c: usize| (m[0][c] * m[0][c] + m[1][c] * m[1][c] + m[2][c] * m[2][c]).sqrt();
        [col(0), col(1), col(2)]
    }

    pub fn translation(&self) -> [f64; 3] {
        let m = &self.index_to_world;
        [m[0][3], m[1][3], m[2][3]]
    }

    pub fn index_to_world(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.index_to_world;
        let mut out = [0.0; 3];
        for (r, o) in out.iter_mut().enumerate() {
            *o = m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3];
        }
        out
    }

    /// Same map up to a relative tolerance (used to check that frames of a sequence line up).
    pub fn approx_eq(&self, other: &Transform, rel: f64) -> bool {
        if self.kind.is_linear() != other.kind.is_linear() || self.frustum != other.frustum {
            return false;
        }
        let scale = self
            .index_to_world
            .iter()
            .flatten()
            .chain(other.index_to_world.iter().flatten())
            .fold(0.0f64, |a, &b| a.max(b.abs()))
            .max(1e-300);
        self.index_to_world
            .iter()
            .flatten()
            .zip(other.index_to_world.iter().flatten())
            .all(|(a, b)| (a - b).abs() <= rel * scale)
    }
}

fn scale_translate(kind: MapKind, s: [f64; 3], t: [f64; 3]) -> Transform {
    Transform {
        kind,
        index_to_world: [
            [s[0], 0.0, 0.0, t[0]],
            [0.0, s[1], 0.0, t[1]],
            [0.0, 0.0, s[2], t[2]],
            [0.0, 0.0, 0.0, 1.0],
        ],
        frustum: None,
    }
}

fn read_mat4(cur: &mut Cursor<'_>) -> PResult<[[f64; 4]; 4]> {
    // OpenVDB row-vector matrix M (row-major); we return its transpose.
    let mut m = [[0.0; 4]; 4];
    for r in 0..4 {
        for row in m.iter_mut() {
            row[r] = cur.f64("affine matrix")?;
        }
    }
    Ok(m)
}

/// Reads `Transform::read` for file versions ≥ 219: map type name, then the map's fields.
pub(crate) fn read_transform(cur: &mut Cursor<'_>) -> PResult<Transform> {
    let at = cur.offset();
    let name = cur.string("transform type")?;
    read_map(cur, &name, at, 0)
}

fn read_map(cur: &mut Cursor<'_>, name: &str, at: u64, depth: u32) -> PResult<Transform> {
    let kind = MapKind::from_name(name).ok_or_else(|| {
        ParseError::unsupported(at, format!("unknown transform map type '{name}'"))
    })?;
    let t = match kind {
        MapKind::UniformScale | MapKind::Scale => {
            let s = cur.vec3d("scale")?;
            cur.take(4 * 24, "scale map fields")?; // voxel size, inverse, inv sq, inv twice
            scale_translate(kind, s, [0.0; 3])
        }
        MapKind::UniformScaleTranslate | MapKind::ScaleTranslate => {
            let t = cur.vec3d("translation")?;
            let s = cur.vec3d("scale")?;
            cur.take(4 * 24, "scale map fields")?;
            scale_translate(kind, s, t)
        }
        MapKind::Translation => scale_translate(kind, [1.0; 3], cur.vec3d("translation")?),
        MapKind::Affine | MapKind::Unitary => Transform {
            kind,
            index_to_world: read_mat4(cur)?,
            frustum: None,
        },
        MapKind::NonlinearFrustum => {
            if depth > 0 {
                return Err(ParseError::corrupt(at, "nested frustum maps"));
            }
            let bbox_min = cur.vec3d("frustum bbox")?;
            let bbox_max = cur.vec3d("frustum bbox")?;
            let taper = cur.f64("frustum taper")?;
            let fdepth = cur.f64("frustum depth")?;
            let at2 = cur.offset();
            let second = cur.string("frustum second map type")?;
            let lin = read_map(cur, &second, at2, depth + 1)?;
            Transform {
                kind,
                index_to_world: lin.index_to_world,
                frustum: Some(Frustum {
                    bbox_min,
                    bbox_max,
                    taper,
                    depth: fdepth,
                }),
            }
        }
    };
    if t.index_to_world.iter().flatten().any(|v| !v.is_finite()) {
        return Err(ParseError::corrupt(at, "transform has non-finite entries"));
    }
    Ok(t)
}
