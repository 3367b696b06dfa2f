//! Flip-book playback in the main world: each [`VdbPlayback`] advances with Bevy's clock, and
//! the frame time an instance is drawn at follows from it. Pure functions beside the system, so
//! that the wrapping rules are tested without an app.

use bevy::prelude::*;

use crate::asset::VdbAsset;
use crate::component::{FrameBlend, PlayMode, VdbPlayback, VdbVolume};

/// `p`'s time, 0 where it is not finite.
fn finite_time(p: &VdbPlayback) -> f32 {
    if p.time.is_finite() {
        p.time
    } else {
        0.0
    }
}

/// Advances `p` by `dt` seconds through a flip-book of `frames` frames. Ping-pong turns around
/// by negating `speed`. A paused or still playback only has its time brought into range; an
/// empty flip-book is left alone.
pub fn advance(p: &mut VdbPlayback, dt: f32, frames: usize) {
    if frames == 0 {
        return;
    }
    let last = (frames - 1) as f32;
    let step = if p.paused || !dt.is_finite() || !p.fps.is_finite() || !p.speed.is_finite() {
        0.0
    } else {
        dt * p.fps * p.speed
    };
    let t = finite_time(p) + step;
    if step == 0.0 {
        p.time = t.clamp(0.0, last);
        return;
    }
    p.time = match p.mode {
        // Frame `last` shows until the loop comes round to 0 (one frame's time, as every other).
        PlayMode::Loop => t.rem_euclid(frames as f32),
        PlayMode::Once => t.clamp(0.0, last),
        PlayMode::PingPong if last == 0.0 => 0.0,
        PlayMode::PingPong => {
            // Unfold the bounce: position u on a line of period 2·last, forward on [0, last],
            // backward on [last, 2·last]; the sign of the step says which half the time is in,
            // and the bounce turns it by turning `speed` (the step's sign is that of fps·speed).
            let time = finite_time(p).clamp(0.0, last);
            let u = if step < 0.0 { 2.0 * last - time } else { time } + step.abs();
            let m = u.rem_euclid(2.0 * last);
            let forward = m <= last;
            if forward != (step > 0.0) {
                p.speed = -p.speed;
            }
            if forward {
                m
            } else {
                2.0 * last - m
            }
        }
    };
}

/// The time the runtime draws for `p` (its `Instance::time`): within `[0, frames − 1]`, whole
/// frames under [`FrameBlend::Hold`], and the last frame held between it and the loop's return
/// to frame 0 (the runtime crossfades neighbouring frames only).
pub fn drawn_time(p: &VdbPlayback, frames: usize) -> f32 {
    if frames == 0 {
        return 0.0;
    }
    let last = (frames - 1) as f32;
    let t = finite_time(p).clamp(0.0, last);
    match p.blend {
        FrameBlend::Crossfade => t,
        FrameBlend::Hold => t.floor(),
    }
}

/// Whether `p` moves through a flip-book of `frames` frames (not paused, a finite non-zero
/// rate, more than one frame, and under [`PlayMode::Once`] not stopped at the end it heads for):
/// the instance's light may then come from every n-th frame (`VolumeCamera::light_stride`), and
/// a still one gets its exact light.
pub fn playing(p: &VdbPlayback, frames: usize) -> bool {
    let rate = p.fps * p.speed;
    if p.paused || frames < 2 || !rate.is_finite() || rate == 0.0 {
        return false;
    }
    let (t, last) = (finite_time(p), (frames - 1) as f32);
    !(p.mode == PlayMode::Once && (rate > 0.0 && t >= last || rate < 0.0 && t <= 0.0))
}

/// Advances every volume's playback by `Time::delta_secs()` (the virtual clock in `Update`).
pub fn advance_playback(
    time: Res<Time>,
    assets: Res<Assets<VdbAsset>>,
    mut volumes: Query<(&VdbVolume, &mut VdbPlayback)>,
) {
    let dt = time.delta_secs();
    for (volume, mut playback) in &mut volumes {
        let Some(asset) = assets.get(&volume.asset) else {
            continue;
        };
        let frames = asset.frame_count();
        // Touch the component only when it changes (change detection stays meaningful).
        let mut next = playback.clone();
        advance(&mut next, dt, frames);
        playback.set_if_neq(next);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn play(mode: PlayMode) -> VdbPlayback {
        VdbPlayback {
            mode,
            ..Default::default()
        }
    }

    #[test]
    fn loop_wraps_after_the_last_frames_time() {
        // 10 frames at 24 fps: 0.5 s is 12 frames, 2 past the last frame's start (9).
        let mut p = play(PlayMode::Loop);
        advance(&mut p, 0.5, 10);
        assert!((p.time - 2.0).abs() < 1e-5, "{}", p.time);
        // Between the last frame and the loop's return the last frame is drawn.
        p.time = 9.6;
        assert_eq!(drawn_time(&p, 10), 9.0);
        // Backwards wraps to the end.
        let mut b = VdbPlayback {
            speed: -1.0,
            ..play(PlayMode::Loop)
        };
        advance(&mut b, 1.0 / 24.0, 10);
        assert!((b.time - 9.0).abs() < 1e-5, "{}", b.time);
    }

    #[test]
    fn once_stops_at_either_end() {
        let mut p = play(PlayMode::Once);
        advance(&mut p, 100.0, 10);
        assert_eq!(p.time, 9.0);
        p.speed = -2.0;
        advance(&mut p, 100.0, 10);
        assert_eq!(p.time, 0.0);
    }

    #[test]
    fn ping_pong_turns_around() {
        let mut p = play(PlayMode::PingPong);
        // 11 frames of time on 10 frames: 9 forward, then 2 back → frame 7, heading down.
        advance(&mut p, 11.0 / 24.0, 10);
        assert!((p.time - 7.0).abs() < 1e-4, "{}", p.time);
        assert!(p.speed < 0.0);
        // 8 more: down to 0 (7), then up 1.
        advance(&mut p, 8.0 / 24.0, 10);
        assert!((p.time - 1.0).abs() < 1e-4, "{}", p.time);
        assert!(p.speed > 0.0);
        let mut one = play(PlayMode::PingPong);
        advance(&mut one, 1.0, 1);
        assert_eq!(one.time, 0.0);
        // Paused at an end, heading down: nothing turns.
        let mut still = VdbPlayback {
            paused: true,
            speed: -1.0,
            ..play(PlayMode::PingPong)
        };
        advance(&mut still, 1.0, 10);
        assert_eq!((still.time, still.speed), (0.0, -1.0));
        // A negative fps with a positive speed plays backwards and bounces off 0.
        let mut back = VdbPlayback {
            fps: -24.0,
            time: 2.0,
            ..play(PlayMode::PingPong)
        };
        advance(&mut back, 3.0 / 24.0, 10);
        assert!((back.time - 1.0).abs() < 1e-4, "{}", back.time);
        assert!(back.speed < 0.0, "turned: now heading up with fps < 0");
    }

    #[test]
    fn paused_hold_and_bad_numbers() {
        let mut p = VdbPlayback {
            paused: true,
            time: 3.7,
            blend: FrameBlend::Hold,
            ..Default::default()
        };
        advance(&mut p, 1.0, 10);
        assert_eq!(p.time, 3.7);
        assert_eq!(drawn_time(&p, 10), 3.0);
        p.paused = false;
        p.time = f32::NAN;
        advance(&mut p, f32::INFINITY, 10);
        assert_eq!(p.time, 0.0);
        assert_eq!(drawn_time(&p, 0), 0.0);
    }

    #[test]
    fn playing_is_moving_through_frames() {
        let p = play(PlayMode::Loop);
        assert!(playing(&p, 10));
        assert!(!playing(&p, 1), "one frame: nothing to move through");
        let paused = VdbPlayback {
            paused: true,
            ..p.clone()
        };
        assert!(!playing(&paused, 10));
        let still = VdbPlayback {
            speed: 0.0,
            ..p.clone()
        };
        assert!(!playing(&still, 10));
        // Once: stopped at the end it heads for, playing from the other.
        let mut once = play(PlayMode::Once);
        advance(&mut once, 100.0, 10);
        assert!(!playing(&once, 10));
        once.speed = -1.0;
        assert!(playing(&once, 10));
        advance(&mut once, 100.0, 10);
        assert!(!playing(&once, 10));
    }
}
