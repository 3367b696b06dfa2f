//! Choosing a grid: default `density`, the only float grid, duplicate labels, unnamed grids,
//! instances, index selection, double conversion, and clear refusals for non-float grids and
//! frustum transforms. Files are fixtures written by OpenVDB.

mod common;

use vdbcook_vdb::{ErrorKind, MapKind, VdbFile};

fn fixture(name: &str) -> VdbFile {
    VdbFile::open(common::fixtures().join("vdb").join(name)).unwrap()
}

#[test]
fn default_is_density_and_labels_select_duplicates() {
    let f = fixture("multi_grids.vdb");
    let d = f.select(None).unwrap();
    assert_eq!(f.grids[d].name, "density");
    let s0 = f.select(Some("smoke[0]")).unwrap();
    let s1 = f.select(Some("smoke[1]")).unwrap();
    assert_ne!(s0, s1);
    assert_eq!(f.grids[s1].unique_name, "smoke\u{1e}1");
    // The bare name picks the first, as OpenVDB's File::readGrid does.
    assert_eq!(f.select(Some("smoke")).unwrap(), s0);
    // Two different trees.
    let a = f.read_float_grid(s0).unwrap().stats();
    let b = f.read_float_grid(s1).unwrap().stats();
    assert_ne!(a, b);
    // Unnamed grid: selectable by the empty name; index selection works too.
    let u = f.select(Some("")).unwrap();
    assert_eq!(f.grids[u].name, "");
    assert_eq!(f.select(Some(&format!("#{u}"))).unwrap(), u);
}

#[test]
fn instances_read_their_parents_tree() {
    let f = fixture("multi_grids.vdb");
    let i = f.select(Some("density_instance")).unwrap();
    assert!(
        f.grids[i].instance_parent.is_some(),
        "fixture must hold a real instance"
    );
    let d = f.select(Some("density")).unwrap();
    let gi = f.read_float_grid(i).unwrap();
    let gd = f.read_float_grid(d).unwrap();
    assert_eq!(gi.stats(), gd.stats());
    assert_eq!(gi.values, gd.values);
}

#[test]
fn non_float_grids_are_refused_naming_the_float_grids() {
    let f = fixture("multi_grids.vdb");
    for name in ["vel", "labels_i32", "ids_i64", "flags", "mask"] {
        let e = f.select(Some(name)).unwrap_err();
        assert_eq!(e.kind, ErrorKind::GridSelection);
        let m = e.to_string();
        assert!(
            m.contains(name) && m.contains("'density'") && m.contains("'temperature'"),
            "{m}"
        );
    }
    let e = f.select(Some("nope")).unwrap_err();
    assert!(e.to_string().contains("no grid named 'nope'"), "{e}");
    let nf = fixture("no_float.vdb");
    let e = nf.select(None).unwrap_err();
    assert!(e.to_string().contains("no float grid"), "{e}");
}

#[test]
fn several_float_grids_without_density_need_a_choice() {
    // multi_grids minus its density: emulate by asking the sample with three `density` grids,
    // where the default must pick the first.
    if let Some(s) = common::samples() {
        let f = VdbFile::open(s.join("arnold-usd/grids.vdb")).unwrap();
        let d = f.select(None).unwrap();
        assert_eq!(f.grids[d].name, "density");
    }
    let f = fixture("xform_scale.vdb");
    assert!(f.select(None).is_ok());
}

#[test]
fn double_grids_convert_to_f32_and_say_so() {
    let f = fixture("double_only.vdb");
    let g = f.read_float_grid(f.select(None).unwrap()).unwrap();
    assert!(g.converted_from_double);
    assert!(g.stats().active_voxels > 0);
    let m = fixture("multi_grids.vdb");
    let h = m
        .read_float_grid(m.select(Some("heat_d")).unwrap())
        .unwrap();
    assert!(h.converted_from_double);
}

#[test]
fn every_map_kind_is_recognised_and_frustum_is_not_linear() {
    let cases = [
        ("xform_uniform_scale.vdb", MapKind::UniformScale),
        (
            "xform_uniform_scale_translate.vdb",
            MapKind::UniformScaleTranslate,
        ),
        ("xform_scale.vdb", MapKind::Scale),
        ("xform_scale_translate.vdb", MapKind::ScaleTranslate),
        ("xform_translation.vdb", MapKind::Translation),
        ("xform_affine.vdb", MapKind::Affine),
        ("xform_unitary.vdb", MapKind::Unitary),
        ("xform_frustum.vdb", MapKind::NonlinearFrustum),
    ];
    for (file, kind) in cases {
        let f = fixture(file);
        let g = &f.grids[f.select(None).unwrap()];
        assert_eq!(g.transform.kind, kind, "{file}");
        assert_eq!(kind.is_linear(), kind != MapKind::NonlinearFrustum);
    }
    let fr = fixture("xform_frustum.vdb");
    assert!(fr.grids[0]
        .transform
        .frustum
        .as_ref()
        .is_some_and(|f| f.taper > 0.0));
}
