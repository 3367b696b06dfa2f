//! The default camera (`Camera::framing`) frames what a frame stores, not its bounding box: on
//! two small blocks at opposite corners of a large, otherwise empty region, every corner of
//! every stored box projects inside 80% of the image's half-extents, one of them exactly at 80%
//! (the fit is tight), all lie in front of the eye, and the view is closer than the bounding
//! box's framing (which fits the box's far corners, empty here).

mod common;

use common::*;
use vdbcook_asset::PayloadFormat;
use vdbcook_trace::*;

#[test]
fn framing_fits_the_stored_boxes_tightly() {
    let xf = [
        [0.5, 0.0, 0.0, 1.0],
        [0.0, 0.25, 0.0, -2.0],
        [0.0, 0.0, 0.5, 3.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut f = FrameSpec::default();
    box_leaves([4, 4, 4], [20, 12, 14], 1.0, &mut f.leaves);
    box_leaves([100, 90, 60], [118, 110, 80], 0.5, &mut f.leaves);
    let asset = build([1, 1, 1], xf, 0.0, &[f], PayloadFormat::F32);
    let aspect = 16.0 / 9.0;
    let cam = Camera::framing(&asset, 0, aspect).unwrap();
    let b = cam.basis(16, 9).unwrap();
    let n = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let (r, u, fwd) = (b.right, b.up, b.forward);
    let cells = Affine::cells(&asset.header.index_to_world).unwrap();
    let mut worst = 0.0f64;
    for (lo, hi) in stored_boxes(&asset, 0) {
        for c in 0..8 {
            let p = [0, 1, 2].map(|a| if c >> a & 1 == 0 { lo[a] } else { hi[a] });
            let w = cells.world_of(p);
            let d = [0, 1, 2].map(|a| w[a] - cam.eye[a]);
            let z = d[0] * fwd[0] + d[1] * fwd[1] + d[2] * fwd[2];
            assert!(z > 0.0, "a stored corner behind the eye");
            // Image-plane coordinates in units of the half-extents (|right|, |up|).
            let x = (d[0] * r[0] + d[1] * r[1] + d[2] * r[2]) / (n(r) * n(r)) / z;
            let y = (d[0] * u[0] + d[1] * u[1] + d[2] * u[2]) / (n(u) * n(u)) / z;
            worst = worst.max(x.abs()).max(y.abs());
        }
    }
    assert!(
        (worst - 0.8).abs() < 1e-9,
        "the farthest stored corner projects at {worst} of the half-extent, not 0.8"
    );
    let bbox = stored_bbox(&asset, 0).unwrap();
    let loose = Camera::framing_box(&asset.header.index_to_world, bbox, aspect).unwrap();
    let dist = |c: &Camera| n([0, 1, 2].map(|a| c.eye[a] - c.look_at[a]));
    assert!(
        dist(&cam) < dist(&loose),
        "content framing {} not closer than the bounding box's {}",
        dist(&cam),
        dist(&loose)
    );
}
