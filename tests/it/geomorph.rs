//! Geomorphing on the crack scene (`stripmask::sim::crack_metric`): stitched tiles stay
//! crack-free when morphed, a mask switch pops less, and a morph factor of 0 draws the plain
//! tiles up to sub-pixel rounding, and `fly` morphs whole tiles in belts and the partial tiles
//! of progressive streaming. (Factor 1 giving exactly the coarse surface is checked on the mesh, in
//! `src/engine/geomorph.rs`.)

use crate::support::cli::{fly_quietly, plain_archive};
use crate::support::crack_scene;

use crack_scene::scene;
use stripmask::engine::EngineSettings;
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::geomorph::Geomorph;
use stripmask::sim::crack_metric::{CrackScene, TILE_SIZE};
use stripmask::sim::popping::{FrameChange, flight_popping, glide, switch_change};
use stripmask::sim::report::StatsTable;
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

const SIZE: (u32, u32) = (320, 240);
const VIEW: usize = 9;
/// A threshold at which this scene's vertices are visibly morphed (its 30 m steps span roughly
/// 10 pixels at 320x240).
const MORPHED: Geomorph = Geomorph::Distance { pixels: 16.0 };

/// The crack scene's settings with `geomorph`, the vertices lit, so that what the morph moves
/// shows in the shading as well as in where the texture lands.
fn settings(geomorph: Geomorph) -> EngineSettings {
    let mut settings = EngineSettings {
        geomorph,
        ..CrackScene::settings(CrackMode::Stitch)
    };
    settings.render.lighting = true;
    settings
}

fn fb() -> Framebuffer {
    Framebuffer::new(SIZE.0, SIZE.1, ColorFormat::Rgb565, DepthFormat::D16).unwrap()
}

/// The crack scene's view `VIEW` with the pair pattern's levels.
fn view(geomorph: Geomorph) -> Framebuffer {
    let mut engine = scene().engine_with(settings(geomorph), SIZE).unwrap();
    let mut fb = fb();
    scene().render(&mut engine, VIEW, &mut fb).unwrap();
    fb
}

#[test]
fn stitch_stays_crack_free_with_geomorph_on_views_with_every_level_pair() {
    let m = scene().measure_with(settings(MORPHED), SIZE, 1).unwrap();
    let levels = TILE_SIZE - 1;
    assert_eq!(m.pairs.len(), levels * (levels + 1) / 2, "{:?}", m.pairs);
    assert_eq!(m.crack_pixels, 0, "{m:?}");
    let moved = FrameChange::between(&view(Geomorph::Off), &view(MORPHED)).unwrap();
    assert!(
        moved.changed_share > 0.2,
        "the morph must be at work in these views: {moved:?}"
    );
}

#[test]
fn a_morph_factor_of_zero_draws_the_plain_tiles_up_to_subpixel_rounding() {
    // A threshold this small gives every vertex factor 0, so the morphed vertices are the
    // tile's own, in 1/256 units (checked exactly in src/engine/geomorph.rs). Their transform has the
    // same matrix with a linear part 256 times smaller, whose shared-exponent mantissas keep 8
    // fewer bits: edges move by sub-pixel rounding (measured: 19 % of pixels, mean 0.72 per
    // channel), far less than the morph itself moves them.
    let plain = view(Geomorph::Off);
    let rounding =
        FrameChange::between(&plain, &view(Geomorph::Distance { pixels: 1e-9 })).unwrap();
    let morphed = FrameChange::between(&plain, &view(MORPHED)).unwrap();
    assert!(
        rounding.mean_abs < 1.0 && rounding.mean_abs * 4.0 < morphed.mean_abs,
        "factor 0: {rounding:?}, morphed: {morphed:?}"
    );
}

#[test]
fn a_switch_on_a_fixed_view_pops_less_with_geomorph() {
    let pop = |geomorph| {
        let mut engine = scene().engine_with(settings(geomorph), SIZE).unwrap();
        let (eye, target) = scene().views[VIEW];
        let camera = engine.camera(eye, target, false);
        let (mut a, mut b) = (fb(), fb());
        switch_change(
            &mut engine,
            &camera,
            &mut a,
            &mut b,
            Box::new(|_| 0),
            Box::new(|_| 1),
        )
        .unwrap()
    };
    let off = pop(Geomorph::Off);
    let on = pop(MORPHED);
    assert!(off.mean_abs > 1.0, "the switch must show: {off:?}");
    assert!(on.mean_abs < off.mean_abs, "on {on:?}, off {off:?}");
}

#[test]
fn in_a_flight_the_budget_s_switches_pop_less_with_geomorph() {
    let popping = |geomorph| {
        let mut s = settings(geomorph);
        s.budget.initial_budget = 1_200;
        let mut engine = scene().engine_with(s, SIZE).unwrap();
        let (mut a, mut b, mut c) = (fb(), fb(), fb());
        flight_popping(&mut engine, &glide(scene(), 120), &mut a, &mut b, &mut c).unwrap()
    };
    let off = popping(Geomorph::Off);
    let on = popping(MORPHED);
    assert!(off.switch_frames > 0 && off.switch_alone > 0.0, "{off:?}");
    assert_eq!(
        (on.switch_frames, on.switches),
        (off.switch_frames, off.switches),
        "the morph does not change the budget's levels"
    );
    assert!(on.switch_alone < off.switch_alone, "on {on:?}, off {off:?}");
}

/// `fly` with geomorphing on a file archive, with whole tiles in belts and partial tiles
/// streamed progressively: runs to the end and morphs partial tiles as it morphs whole ones.
#[test]
fn fly_morphs_whole_and_progressive_tiles_of_a_file_archive() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("plain.smdb");
    plain_archive(&archive);
    for streaming in ["belts", "progressive"] {
        let out = dir.path().join(streaming);
        let (code, err, _) = fly_quietly(
            archive.to_str().unwrap(),
            &out,
            &[
                "--geomorph",
                "distance",
                "--streaming",
                streaming,
                "--clock",
                "simulated",
                "--frames",
                "20",
            ],
        );
        assert_eq!(code, Some(0), "{streaming}: {err}");
        let table = StatsTable::read(&out.join("stats.csv")).unwrap();
        assert_eq!(table.column("holes").unwrap().len(), 20, "{streaming}");
    }
}
