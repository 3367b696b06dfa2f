//! Drawing the extracted instances on each volume camera: `prepare_volume_draws` (in Bevy's
//! prepare step, once the view's targets, depth, jitter and the uploaded assets exist) groups
//! the instances by asset and glow, keeps one runtime `VolumeDrawer` per asset and camera
//! (its light volumes and `(L, T)` texture are per view), and prepares each group's draw;
//! `volume_pass` (a system of Bevy's `Core3d` schedule, after the main pass, before
//! post-processing) records them far group first onto the camera's main texture. The march,
//! the light and the composite are the runtime's: nothing of them is written here.

use std::collections::HashMap;

use bevy::asset::AssetId;
use bevy::camera::{CompositingSpace, Exposure, MainPassResolutionOverride};
use bevy::diagnostic::FrameCount;
use bevy::prelude::*;
use bevy::render::camera::{ExtractedCamera, TemporalJitter};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::view::{ExtractedView, Msaa, ViewDepthTexture, ViewTarget};
use vdbcook_runtime::{
    wgpu, DrawTarget, Emission, Instance, PreparedDraw, Shading, VolumeDrawer, DRAW_COLOR_FORMATS,
};

use crate::asset::VdbAsset;
use crate::component::VolumeEmission;
use crate::convert;
use crate::render::{
    ExtractedSceneLight, ExtractedShading, ExtractedVolumeCamera, ExtractedVolumes, GpuVdbVolume,
};
use bevy::render::render_asset::RenderAssets;

/// Which drawer draws a group: one per camera, asset upload and colour format (instances of one
/// asset with different glows are separate draws of one drawer: its light volumes do not
/// depend on the glow, and an animated glow must not make new drawers).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct DrawerKey {
    view: Entity,
    asset: AssetId<VdbAsset>,
    generation: u64,
    format: wgpu::TextureFormat,
}

struct KeptDrawer {
    drawer: VolumeDrawer,
    /// The frame it last drew (drawers unused for `DROP_AFTER` frames are dropped).
    used: u32,
}

/// One draw of a camera: the instances of one asset with one glow.
struct Group {
    key: DrawerKey,
    emission: Option<Emission>,
    volume: std::sync::Arc<vdbcook_runtime::GpuVolume>,
    shading: Shading,
    instances: Vec<Instance>,
    /// Distance from the eye to its farthest instance's content (draws go far first).
    distance: f32,
}

/// Frames a drawer is kept without drawing (a camera switched off, an asset despawned).
const DROP_AFTER: u32 = 120;

/// The runtime drawers, by group and camera.
#[derive(Resource, Default)]
pub struct VolumeDrawers {
    drawers: HashMap<DrawerKey, KeptDrawer>,
    /// Messages already logged (each refusal or error is logged once, not every frame).
    logged: std::collections::HashSet<String>,
}

impl VolumeDrawers {
    fn warn_once(&mut self, message: String) {
        // Bounded: messages can carry sizes (a window resized many times).
        if self.logged.len() > 256 {
            self.logged.clear();
        }
        if !self.logged.contains(&message) {
            log::warn!("vdbcook: {message}");
            self.logged.insert(message);
        }
    }
}

/// This frame's prepared draws per camera (render entity), far group first.
#[derive(Resource, Default)]
pub struct ViewVolumeDraws(HashMap<Entity, Vec<(DrawerKey, PreparedDraw)>>);

/// Prepares every volume camera's draws (see the module's doc). A camera the drawer cannot draw
/// on (multisampled, a sub-rectangle viewport, a colour format the drawer does not blend onto)
/// gets a warning once and no volumes.
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub fn prepare_volume_draws(
    views: Query<(
        Entity,
        &ExtractedView,
        &ExtractedCamera,
        &ViewTarget,
        &ViewDepthTexture,
        &Msaa,
        Option<&TemporalJitter>,
        Has<MainPassResolutionOverride>,
        &ExtractedVolumeCamera,
    )>,
    volumes: Res<ExtractedVolumes>,
    light: Res<ExtractedSceneLight>,
    shading: Res<ExtractedShading>,
    gpu: Res<RenderAssets<GpuVdbVolume>>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    frame: Res<FrameCount>,
    mut drawers: ResMut<VolumeDrawers>,
    mut out: ResMut<ViewVolumeDraws>,
) {
    // Last frame's draws were submitted with last frame's render: they may go.
    out.0.clear();
    let device = device.wgpu_device();
    let queue: &wgpu::Queue = &queue;
    for (entity, view, camera, target, depth, msaa, jitter, resized, vc) in &views {
        let format = target.main_texture_format();
        let refusal = if resized {
            Some("a MainPassResolutionOverride (upscaling: not supported yet)".to_string())
        } else if !matches!(
            target.compositing_space,
            None | Some(CompositingSpace::Linear)
        ) {
            Some(format!(
                "compositing space {:?} (the drawer blends linear radiance)",
                target.compositing_space
            ))
        } else if msaa.samples() != 1 {
            Some(format!(
                "{} MSAA samples (volume cameras need Msaa::Off)",
                msaa.samples()
            ))
        } else if camera.viewport.is_some() {
            Some("a sub-rectangle viewport (not supported yet)".to_string())
        } else if !DRAW_COLOR_FORMATS.contains(&format) {
            Some(format!(
                "main texture format {format:?} (the drawer blends onto {DRAW_COLOR_FORMATS:?})"
            ))
        } else {
            None
        };
        if let Some(why) = refusal {
            drawers.warn_once(format!("camera {entity}: no volumes drawn: {why}"));
            continue;
        }
        let size = (view.viewport.z, view.viewport.w);
        let rt_view = match convert::view(&view.world_from_view, &view.clip_from_view, jitter, size)
        {
            Ok(v) => v,
            Err(e) => {
                drawers.warn_once(format!("camera {entity}: no volumes drawn: {e}"));
                continue;
            }
        };
        let color = target.main_texture_view();
        let draw_target = DrawTarget {
            color,
            depth: Some(depth.view()),
        };
        let sky = vc.sky.unwrap_or(light.0.sky);
        let scene = convert::SceneLight { sky, ..light.0 };
        let base = &shading.0;
        let lighting = base
            .lit
            .then(|| convert::lighting(&base.lighting, &scene, camera.exposure));

        // Groups (one draw each): one per asset and glow, in order of first appearance, with
        // the distance of their farthest instance's content.
        let mut groups: Vec<Group> = Vec::new();
        let eye = rt_view.view.inverse().w_axis.truncate();
        for v in &volumes.0 {
            let Some(gv) = gpu.get(v.asset) else { continue };
            let Ok(volume) = &gv.volume else { continue };
            // The group's glow in cd/m² (before the camera's exposure).
            let emission = match &v.emission {
                VolumeEmission::Auto => gv.auto_emission.map(|mut e| {
                    // As bright at Bevy's default exposure (EV100 9.7) as the cooker's renders
                    // (exposure 1).
                    e.intensity /= Exposure::default().exposure();
                    e
                }),
                VolumeEmission::Off => None,
                VolumeEmission::Custom(e) => Some(*e),
            }
            .map(|mut e| {
                e.intensity *= v.emission_scale;
                e
            });
            let key = DrawerKey {
                view: entity,
                asset: v.asset,
                generation: gv.generation,
                format,
            };
            let content = gv.content_centre(v.time);
            let distance = (v.world_from_volume.transform_point3(content) - eye).length();
            let instance = Instance {
                world_from_volume: v.world_from_volume,
                time: v.time,
                density_scale: v.density_scale,
                tint: v.tint,
                asset: 0,
                light_stride: if v.playing {
                    vc.settings.light_stride
                } else {
                    1
                },
            };
            match groups
                .iter_mut()
                .find(|g| g.key == key && g.emission == emission)
            {
                Some(g) => {
                    g.instances.push(instance);
                    g.distance = g.distance.max(distance);
                }
                None => {
                    let mut medium = base.medium.clone();
                    medium.emission = emission.map(|mut e| {
                        e.intensity *= camera.exposure;
                        e
                    });
                    let mut integrator = base.integrator.clone();
                    integrator.seed = convert::frame_seed(integrator.seed, jitter);
                    let shading = Shading {
                        medium,
                        lighting: lighting.clone(),
                        integrator,
                    };
                    groups.push(Group {
                        key,
                        emission,
                        volume: volume.clone(),
                        shading,
                        instances: vec![instance],
                        distance,
                    });
                }
            }
        }
        // Far group first: groups composite in record order.
        groups.sort_by(|a, b| b.distance.total_cmp(&a.distance));

        let mut draws = Vec::new();
        for Group {
            key,
            volume,
            shading,
            instances,
            ..
        } in groups
        {
            let kept = match drawers.drawers.entry(key.clone()) {
                std::collections::hash_map::Entry::Occupied(o) => o.into_mut(),
                std::collections::hash_map::Entry::Vacant(slot) => {
                    match VolumeDrawer::new(device, &volume, format) {
                        Ok(drawer) => slot.insert(KeptDrawer { drawer, used: 0 }),
                        Err(e) => {
                            let m =
                                format!("camera {entity}: a volume drawer could not be made: {e}");
                            drawers.warn_once(m);
                            continue;
                        }
                    }
                }
            };
            kept.used = frame.0;
            kept.drawer
                .set_march_resolution(vc.settings.march_resolution);
            kept.drawer.set_interleave(vc.settings.interleave);
            kept.drawer.set_lit_crossfade(vc.settings.lit_crossfade);
            kept.drawer.set_light_ahead(vc.settings.light_ahead);
            match kept
                .drawer
                .prepare(device, queue, &draw_target, &rt_view, &instances, &shading)
            {
                Ok(draw) => draws.push((key, draw)),
                Err(e) => drawers.warn_once(format!("camera {entity}: volumes not drawn: {e}")),
            }
        }
        if !draws.is_empty() {
            out.0.insert(entity, draws);
        }
    }
    let now = frame.0;
    drawers
        .drawers
        .retain(|_, d| now.wrapping_sub(d.used) <= DROP_AFTER);
}

/// Records the camera's prepared draws onto its main texture (a `Core3d` system: Bevy runs it
/// per camera, after the main pass and before post-processing).
pub fn volume_pass(
    view: ViewQuery<&ViewTarget, With<ExtractedVolumeCamera>>,
    draws: Res<ViewVolumeDraws>,
    drawers: Res<VolumeDrawers>,
    mut warned: Local<bool>,
    mut ctx: RenderContext,
) {
    let entity = view.entity();
    let target = view.into_inner();
    let Some(list) = draws.0.get(&entity) else {
        return;
    };
    // Onto the main texture current now: another camera on the same target may have flipped
    // Bevy's two main textures since the draws were prepared.
    let color = target.main_texture_view();
    let encoder = ctx.command_encoder();
    for (key, draw) in list {
        if let Some(kept) = drawers.drawers.get(key) {
            if let Err(e) = kept.drawer.record_onto(encoder, draw, color) {
                if !std::mem::replace(&mut *warned, true) {
                    log::warn!("vdbcook: volumes not drawn: {e}");
                }
            }
        }
    }
}
