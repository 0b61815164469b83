//! Popping: how much the picture jumps when tiles switch strip-mask levels.
//!
//! The measure: the mean absolute pixel change between consecutive frames,
//! per colour channel (0 ..= 255), with the share of pixels that changed at all. Two settings:
//!
//! - [`switch_change`]: one camera, the tiles drawn at one set of levels and then at another
//!   (pinned with [`Engine::force_levels`]): everything that changes is popping.
//! - [`flight_popping`]: a short flight with the budget choosing the levels; every frame is
//!   compared with the one before, and the frames in which some tile switched level are averaged
//!   apart from the frames in which none did (whose change is the camera's motion alone).

use glam::DVec3;
use stripmask_raster::Framebuffer;

use crate::db::grid::{TileId, TileMap};
use crate::engine::camera::Camera;
use crate::engine::{Engine, FrameReport};
use crate::error::{Error, Result};
use crate::sim::crack_metric::CrackScene;

/// How much one frame differs from another of the same size.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameChange {
    /// Mean absolute difference per colour channel over all pixels, 0 ..= 255.
    pub mean_abs: f64,
    /// Share of pixels with any channel changed, 0 ..= 1.
    pub changed_share: f64,
}

impl FrameChange {
    /// The change from `before` to `after`; frames of different sizes are refused.
    pub fn between(before: &Framebuffer, after: &Framebuffer) -> Result<FrameChange> {
        let (w, h) = (before.width(), before.height());
        if (w, h) != (after.width(), after.height()) {
            return Err(Error::setting(
                "frame size",
                format!("{}x{}", after.width(), after.height()),
                format!("{w}x{h}, the size of the frame it is compared with"),
            ));
        }
        let (mut sum, mut changed) = (0u64, 0u64);
        for y in 0..h {
            for x in 0..w {
                let (a, b) = (before.pixel(x, y), after.pixel(x, y));
                let d: u64 = (0..3).map(|c| u64::from(a[c].abs_diff(b[c]))).sum();
                sum += d;
                changed += u64::from(d > 0);
            }
        }
        let pixels = (u64::from(w) * u64::from(h)).max(1) as f64;
        Ok(FrameChange {
            mean_abs: sum as f64 / (3.0 * pixels),
            changed_share: changed as f64 / pixels,
        })
    }
}

/// Levels per tile, for [`Engine::force_levels`].
pub type LevelOf = Box<dyn Fn(TileId) -> usize + Send>;

/// Renders `camera` into `before` with every tile at `from(tile)`, then into `after` at
/// `to(tile)`, and returns the change: the popping of that switch. Leaves the levels pinned to
/// `to`.
pub fn switch_change(
    engine: &mut Engine,
    camera: &Camera,
    before: &mut Framebuffer,
    after: &mut Framebuffer,
    from: LevelOf,
    to: LevelOf,
) -> Result<FrameChange> {
    engine.force_levels(Some(from));
    engine.render(camera, before)?;
    engine.force_levels(Some(to));
    engine.render(camera, after)?;
    FrameChange::between(before, after)
}

/// The popping of a flight: frames with a level switch against frames without.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FlightPopping {
    /// Frames compared with the one before (one fewer than the frames rendered).
    pub frames: usize,
    /// Of those, frames in which some tile drawn in both switched level.
    pub switch_frames: usize,
    /// Level switches over the flight (a tile switching twice counts twice).
    pub switches: usize,
    /// Mean of [`FrameChange::mean_abs`] over the switch frames.
    pub at_switch: f64,
    /// Mean of [`FrameChange::mean_abs`] over the other frames: the motion alone.
    pub steady: f64,
    /// Mean over the switch frames of the switch alone: the frame against the same camera drawn
    /// at the previous frame's levels.
    pub switch_alone: f64,
}

/// Flies `engine` through `views` (eye and target, terrain-frame metres), rendering into `a`
/// and `b` in turn, and sorts the frame-to-frame changes by whether a tile switched level; at a
/// switch it renders the frame once more at the previous levels (into `scratch`) to isolate the
/// switch from the motion. The levels are the engine's own choice: any pinned levels are
/// released.
pub fn flight_popping(
    engine: &mut Engine,
    views: &[(DVec3, DVec3)],
    a: &mut Framebuffer,
    b: &mut Framebuffer,
    scratch: &mut Framebuffer,
) -> Result<FlightPopping> {
    engine.force_levels(None);
    let (mut previous, mut current) = (a, b);
    let mut levels_before: Option<TileMap<usize>> = None;
    let mut popping = FlightPopping::default();
    let (mut switch_sum, mut steady_sum, mut alone_sum) = (0.0, 0.0, 0.0);
    for &(eye, target) in views {
        let camera = engine.camera(eye, target, false);
        let report = engine.render(&camera, current)?;
        let levels = levels_of(&report);
        if let Some(before) = &levels_before {
            let change = FrameChange::between(previous, current)?;
            let switches = levels
                .iter()
                .filter(|(id, level)| before.get(id).is_some_and(|l| l != *level))
                .count();
            popping.frames += 1;
            popping.switches += switches;
            if switches > 0 {
                popping.switch_frames += 1;
                switch_sum += change.mean_abs;
                let pinned = before.clone();
                let fallback = levels.clone();
                engine.force_levels(Some(Box::new(move |id| {
                    pinned.get(&id).or(fallback.get(&id)).copied().unwrap_or(0)
                })));
                engine.render(&camera, scratch)?;
                engine.force_levels(None);
                alone_sum += FrameChange::between(scratch, current)?.mean_abs;
            } else {
                steady_sum += change.mean_abs;
            }
        }
        levels_before = Some(levels);
        std::mem::swap(&mut previous, &mut current);
    }
    popping.at_switch = switch_sum / popping.switch_frames.max(1) as f64;
    popping.switch_alone = alone_sum / popping.switch_frames.max(1) as f64;
    popping.steady = steady_sum / (popping.frames - popping.switch_frames).max(1) as f64;
    Ok(popping)
}

/// A slow turn over the crack scene: `frames` views from its tenth view, the gaze turning
/// half a degree a frame while the eye drifts north 2 m a frame. Small motion between frames,
/// so that a switch stands out, and tiles entering and leaving the view, so that importance, and
/// with it the budget's levels, moves.
pub fn glide(scene: &CrackScene, frames: usize) -> Vec<(DVec3, DVec3)> {
    let (eye, target) = scene.views[9.min(scene.views.len() - 1)];
    let gaze = target - eye;
    (0..frames)
        .map(|k| {
            let (sin, cos) = (0.5 * k as f64).to_radians().sin_cos();
            let turned = DVec3::new(
                gaze.x * cos - gaze.z * sin,
                gaze.y,
                gaze.x * sin + gaze.z * cos,
            );
            let at = eye + DVec3::new(0.0, 0.0, -2.0 * k as f64);
            (at, at + turned)
        })
        .collect()
}

fn levels_of(report: &FrameReport) -> TileMap<usize> {
    report.rendered.iter().map(|t| (t.id, t.level)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use stripmask_raster::{ColorFormat, DepthFormat};

    #[test]
    fn the_change_counts_channels_and_changed_pixels() {
        let fb = || Framebuffer::new(4, 2, ColorFormat::Rgba8888, DepthFormat::None).unwrap();
        let (mut a, mut b) = (fb(), fb());
        a.clear([10, 20, 30]);
        b.clear([10, 20, 30]);
        assert_eq!(
            FrameChange::between(&a, &b).unwrap(),
            FrameChange::default()
        );
        b.clear([16, 20, 30]);
        let c = FrameChange::between(&a, &b).unwrap();
        assert_eq!(c.mean_abs, 2.0);
        assert_eq!(c.changed_share, 1.0);
        let small = Framebuffer::new(2, 2, ColorFormat::Rgba8888, DepthFormat::None).unwrap();
        let err = FrameChange::between(&a, &small).unwrap_err().to_string();
        assert!(err.contains("4x2") && err.contains("2x2"), "{err}");
    }
}
