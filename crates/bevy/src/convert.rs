//! Bevy's values in the runtime's terms: glam 0.32 (Bevy 0.19) to the runtime's glam 0.34 by
//! their arrays, Bevy's camera (reversed-Z projection, TAA jitter) to a runtime `View`, and
//! Bevy's light units to the runtime's `Lighting`. Pure functions, tested without a GPU.

use bevy::prelude::{Color, GlobalTransform, LinearRgba, Mat4, Vec2};
use bevy::render::camera::TemporalJitter;
use vdbcook_runtime::glam as rt;
use vdbcook_runtime::{Lighting, RuntimeError, View};

/// A Bevy matrix as the runtime's.
pub fn mat4(m: &Mat4) -> rt::Mat4 {
    rt::Mat4::from_cols_array(&m.to_cols_array())
}

/// A Bevy transform as the runtime's affine map.
pub fn affine(t: &GlobalTransform) -> rt::Affine3A {
    rt::Affine3A::from_mat4(mat4(&t.to_matrix()))
}

/// The runtime view of a Bevy camera: the view matrix from its world transform, its projection
/// (reversed Z, as Bevy's) with the TAA jitter applied exactly as Bevy applies it to its own
/// meshes (`TemporalJitter::jitter_projection` on the main pass's viewport), and the viewport.
pub fn view(
    world_from_view: &GlobalTransform,
    clip_from_view: &Mat4,
    jitter: Option<&TemporalJitter>,
    viewport: (u32, u32),
) -> Result<View, RuntimeError> {
    let mut proj = *clip_from_view;
    if let Some(j) = jitter {
        j.jitter_projection(&mut proj, Vec2::new(viewport.0 as f32, viewport.1 as f32));
    }
    View::new(
        mat4(&world_from_view.to_matrix().inverse()),
        mat4(&proj),
        viewport,
    )
}

/// Linear RGB of a Bevy colour times `scale`.
pub fn linear(color: Color, scale: f32) -> [f32; 3] {
    let c = LinearRgba::from(color);
    [c.red * scale, c.green * scale, c.blue * scale]
}

/// The sun and sky of the scene, in the runtime's terms.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SceneLight {
    /// Toward the sun (world, unit) and its linear colour times illuminance (lux), or none.
    pub sun: Option<([f32; 3], [f32; 3])>,
    /// The ambient light's linear colour times brightness (cd/m²).
    pub sky: [f32; 3],
}

/// `base` with the scene's sun and sky, pre-exposed: Bevy multiplies its meshes' lit colour by
/// the camera's `exposure`, so the volume's irradiance (the sun) and radiance (the sky) are
/// multiplied by it too, and the two composite in the same units.
pub fn lighting(base: &Lighting, light: &SceneLight, exposure: f32) -> Lighting {
    let mut l = base.clone();
    let x = |c: [f32; 3]| c.map(|v| v * exposure);
    match light.sun {
        Some((dir, color)) => {
            l.light_dir = dir;
            l.light_color = x(color);
        }
        None => {
            // The direction must be a direction even without a sun.
            l.light_dir = [0.0, 1.0, 0.0];
            l.light_color = [0.0; 3];
        }
    }
    l.sky = x(light.sky);
    l
}

/// The integrator's seed for a camera's frame: `seed` itself, or on a camera with TAA jitter
/// `seed` mixed with this frame's jitter offset, so the lit march's per-pixel jitter and a
/// dithered crossfade's grain (`LitCrossfade::Dither`) change with the jitter and TAA averages
/// them; a camera without TAA keeps one pattern (no flicker).
pub fn frame_seed(seed: u32, jitter: Option<&TemporalJitter>) -> u32 {
    match jitter {
        Some(j) => seed ^ j.offset.x.to_bits().rotate_left(16) ^ j.offset.y.to_bits(),
        None => seed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::prelude::{Quat, Transform, Vec3};

    /// No jitter keeps the seed; each of TAA's jitter offsets (Bevy's 8-point Halton cycle,
    /// within ±0.5 pixel) gives its own seed, so the patterns differ from frame to frame.
    #[test]
    fn taa_jitter_varies_the_seed_and_no_jitter_keeps_it() {
        assert_eq!(frame_seed(7, None), 7);
        let halton = [
            (0.5, 0.333_333),
            (0.25, 0.666_667),
            (0.75, 0.111_111),
            (0.125, 0.444_444),
            (0.625, 0.777_778),
            (0.375, 0.222_222),
            (0.875, 0.555_556),
            (0.0625, 0.888_889),
        ];
        let seeds: Vec<u32> = halton
            .iter()
            .map(|&(x, y)| {
                let j = TemporalJitter {
                    offset: Vec2::new(x - 0.5, y - 0.5),
                };
                frame_seed(7, Some(&j))
            })
            .collect();
        let mut unique = seeds.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), seeds.len(), "{seeds:?}");
    }

    /// Bevy's perspective (infinite reversed Z) seen through the runtime's rays: the world point
    /// that Bevy's own (jittered) clip transform puts at a pixel's centre lies on the runtime's
    /// ray of that pixel, and does not without the jitter (the negative control).
    #[test]
    fn bevy_cameras_become_runtime_views() {
        let eye = Vec3::new(1.0, 2.0, 5.0);
        let t =
            GlobalTransform::from(Transform::from_translation(eye).looking_at(Vec3::ZERO, Vec3::Y));
        let (w, h) = (160u32, 90u32);
        let proj = Mat4::perspective_infinite_reverse_rh(0.8, w as f32 / h as f32, 0.1);
        let jitter = TemporalJitter {
            offset: Vec2::new(0.3, -0.2),
        };
        // Distance (in pixels at its depth) from the point Bevy draws at (px, py)'s centre to
        // the runtime's ray of that pixel.
        let miss = |bevy_jitter: Option<&TemporalJitter>, ours: Option<&TemporalJitter>| {
            let mut p = proj;
            if let Some(j) = bevy_jitter {
                j.jitter_projection(&mut p, Vec2::new(w as f32, h as f32));
            }
            let world_from_clip = (p * t.to_matrix().inverse()).as_dmat4().inverse();
            let (px, py) = (37u32, 61u32);
            let ndc = bevy::math::DVec4::new(
                (px as f64 + 0.5) / w as f64 * 2.0 - 1.0,
                1.0 - (py as f64 + 0.5) / h as f64 * 2.0,
                0.05,
                1.0,
            );
            let q = world_from_clip * ndc;
            let world = rt::DVec3::new(q.x / q.w, q.y / q.w, q.z / q.w);
            let rays = view(&t, &proj, ours, (w, h)).unwrap().rays().unwrap();
            let (o, d) = rays.ray(px, py);
            let to = world - o;
            let along = to.dot(d);
            let pixel = along * 2.0 * 0.4f64.tan() / h as f64;
            assert!(along > 0.0);
            (to - d * along).length() / pixel
        };
        assert!(miss(None, None) < 1e-2, "{}", miss(None, None));
        assert!(miss(Some(&jitter), Some(&jitter)) < 1e-2);
        assert!(
            miss(Some(&jitter), None) > 0.3,
            "{}",
            miss(Some(&jitter), None)
        );
    }

    #[test]
    fn light_is_exposed_as_bevy_exposes_meshes() {
        let base = Lighting::default();
        let light = SceneLight {
            sun: Some(([0.0, 0.6, 0.8], [10_000.0, 9_000.0, 8_000.0])),
            sky: [80.0, 80.0, 80.0],
        };
        let l = lighting(&base, &light, 1e-3);
        assert_eq!(l.light_dir, [0.0, 0.6, 0.8]);
        assert!((l.light_color[0] - 10.0).abs() < 1e-4 && (l.sky[2] - 0.08).abs() < 1e-6);
        assert_eq!(l.light_res, base.light_res);
        let dark = lighting(&base, &SceneLight::default(), 1.0);
        assert_eq!(dark.light_color, [0.0; 3]);
        let q = Quat::from_rotation_x(0.3);
        assert!(affine(&GlobalTransform::from(Transform::from_rotation(q)))
            .matrix3
            .x_axis
            .abs_diff_eq(rt::Vec3A::X, 1e-6));
    }
}
