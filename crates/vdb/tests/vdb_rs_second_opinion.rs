//! vdb-rs 0.6 as a second opinion, on the files it is known to read correctly (float values, no
//! half + compression, no root tiles; active voxels only, since it reads inactive values as 0).
//! Both readers must produce the same active voxels with bit-identical values.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

fn ours(path: &Path, grid: &str) -> BTreeMap<[i32; 3], u32> {
    let f = vdbcook_vdb::VdbFile::open(path).unwrap();
    let g = f.read_float_grid(f.select(Some(grid)).unwrap()).unwrap();
    let mut m = BTreeMap::new();
    g.for_each_active_leaf_voxel(|ijk, v| {
        m.insert(ijk, v.to_bits());
    });
    for t in g.tiles.iter().filter(|t| t.active) {
        let d = t.level.dim();
        assert!(d <= 8, "test expands only small tiles");
        for x in 0..d {
            for y in 0..d {
                for z in 0..d {
                    m.insert(
                        [t.origin[0] + x, t.origin[1] + y, t.origin[2] + z],
                        t.value.to_bits(),
                    );
                }
            }
        }
    }
    m
}

fn theirs(path: &Path, grid: &str) -> BTreeMap<[i32; 3], u32> {
    let mut r = vdb_rs::VdbReader::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()))
        .unwrap();
    let g = r.read_grid::<f32>(grid).unwrap();
    let mut m = BTreeMap::new();
    for (p, v, level) in g.iter() {
        let d = level.scale() as i32;
        let o = [p.x as i32, p.y as i32, p.z as i32];
        for x in 0..d {
            for y in 0..d {
                for z in 0..d {
                    m.insert([o[0] + x, o[1] + y, o[2] + z], v.to_bits());
                }
            }
        }
    }
    m
}

fn agree(path: &Path, grid: &str) {
    let a = ours(path, grid);
    let b = theirs(path, grid);
    assert!(!a.is_empty(), "{}: no voxels", path.display());
    assert_eq!(a.len(), b.len(), "{}: active voxel count", path.display());
    let diff = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(diff, 0, "{}: {diff} voxels differ", path.display());
}

#[test]
fn agrees_with_vdb_rs_on_fixtures_it_reads() {
    let dir = common::fixtures().join("vdb");
    let mut n = 0;
    for name in [
        "fog_f32_none_mask",
        "fog_f32_none_nomask",
        "fog_f32_zip_mask",
        "fog_f32_zip_nomask",
        "fog_f32_blosc_mask",
        "fog_f32_blosc_nomask",
        "fog_f16_none_nomask",
        "negative_coords",
    ] {
        let p = dir.join(format!("{name}.vdb"));
        if p.exists() {
            agree(&p, "density");
            n += 1;
        }
    }
    assert!(n >= 6, "expected the float fixture matrix, found {n} files");
}

#[test]
fn agrees_with_vdb_rs_on_real_samples() {
    let Some(s) = common::samples() else {
        return;
    };
    agree(&s.join("wdas-cloud/wdas_cloud_sixteenth.vdb"), "density");
    for i in [0, 57, 199] {
        let p = s.join(format!(
            "stormscape-cloud-seq/output_cube_fluid_70_frame_{i:04}.vdb"
        ));
        // The grid is unnamed.
        agree(&p, "\u{1e}0");
    }
}
