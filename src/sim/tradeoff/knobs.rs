//! The knobs the report turns: every speed-for-accuracy setting of the engine and the
//! rasterizer, each with its values and which one is the default.
//!
//! A knob is a name and a list of values, each a label and a change to a [`Setting`]; adding a
//! knob is one more entry in [`knobs`] (plus the field it sets, when it is new).

use stripmask_raster::{ColorFormat, DepthFormat, Perspective, Precision, Sampler};

use crate::engine::allocation::Allocation;
use crate::engine::cracks::CrackMode;
use crate::engine::error_bound::ErrorBound;
use crate::engine::geomorph::Geomorph;
use crate::engine::render::RenderSettings;

/// The PocketPC's triangle budget in the paper's flyover: the smallest budget swept.
pub const POCKETPC_BUDGET: usize = 3_000;

/// How many triangles a frame may draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Budget {
    /// Shared by the engine's allocation (importance or error), held fixed for the measurement.
    Triangles(usize),
    /// Every drawn tile at mask level 0.
    Full,
}

/// One complete configuration of a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setting {
    /// The triangle budget.
    pub budget: Budget,
    /// The pixel-error bound τ: no tile finer than it needs.
    pub max_error: ErrorBound,
    /// How the tiles share the budget.
    pub allocation: Allocation,
    /// Precision, perspective, texture filter, and the features on or off.
    pub render: RenderSettings,
    /// Colour-buffer format.
    pub color: ColorFormat,
    /// Depth-buffer format.
    pub depth: DepthFormat,
    /// How cracks between levels are hidden.
    pub cracks: CrackMode,
    /// Whether vertices that coarser levels drop glide onto the coarser surface.
    pub geomorph: Geomorph,
    /// Rasterizer threads.
    pub threads: usize,
}

impl Default for Setting {
    /// The engine's defaults on the handheld: [`RenderSettings::default`], RGB565, 16-bit depth,
    /// stitched cracks, one thread (the PocketPC has one core), 20,000 triangles (the budget
    /// controller's starting budget), τ = 1 px ([`ErrorBound::default`]) and the engine's
    /// default allocation.
    fn default() -> Self {
        Setting {
            budget: Budget::Triangles(20_000),
            max_error: ErrorBound::default(),
            allocation: Allocation::default(),
            render: RenderSettings::default(),
            color: ColorFormat::Rgb565,
            depth: DepthFormat::D16,
            cracks: CrackMode::Stitch,
            geomorph: Geomorph::Off,
            threads: 1,
        }
    }
}

/// One value of a knob.
pub struct Value {
    /// Its label in tables, e.g. `spans16`.
    pub label: &'static str,
    /// Sets it.
    pub apply: fn(&mut Setting),
}

/// A named setting with its values.
pub struct Knob {
    /// Its name in tables, e.g. `perspective`.
    pub name: &'static str,
    /// Whether turning it off removes a rendering feature (the feature-cost table).
    pub feature: bool,
    /// Its values; the one [`Setting::default`] has is found by applying each.
    pub values: Vec<Value>,
}

impl Knob {
    fn new(name: &'static str, feature: bool, values: Vec<Value>) -> Knob {
        Knob {
            name,
            feature,
            values,
        }
    }

    /// The value labelled `label`.
    pub fn value(&self, label: &str) -> Option<&Value> {
        self.values.iter().find(|v| v.label == label)
    }
}

macro_rules! value {
    ($label:literal, |$s:ident| $body:expr) => {
        Value {
            label: $label,
            apply: |$s: &mut Setting| $body,
        }
    };
}

/// Every knob, in the order of the report's tables.
pub fn knobs() -> Vec<Knob> {
    [detail(), pipeline(), scene(), features()]
        .into_iter()
        .flatten()
        .collect()
}

/// How much detail a frame asks for: the budget, the error bound and how the budget is shared.
fn detail() -> Vec<Knob> {
    vec![
        Knob::new(
            "budget",
            false,
            vec![
                value!("3000", |s| s.budget = Budget::Triangles(POCKETPC_BUDGET)),
                value!("10000", |s| s.budget = Budget::Triangles(10_000)),
                value!("20000", |s| s.budget = Budget::Triangles(20_000)),
                value!("50000", |s| s.budget = Budget::Triangles(50_000)),
                value!("150000", |s| s.budget = Budget::Triangles(150_000)),
                value!("full", |s| s.budget = Budget::Full),
            ],
        ),
        Knob::new(
            "max-error",
            false,
            vec![
                value!("off", |s| s.max_error = ErrorBound::Off),
                value!("0.5", |s| s.max_error = ErrorBound::Pixels(0.5)),
                value!("1", |s| s.max_error = ErrorBound::Pixels(1.0)),
                value!("2", |s| s.max_error = ErrorBound::Pixels(2.0)),
                value!("4", |s| s.max_error = ErrorBound::Pixels(4.0)),
            ],
        ),
        Knob::new(
            "allocation",
            false,
            vec![
                value!("importance", |s| s.allocation = Allocation::Importance),
                value!("error", |s| s.allocation = Allocation::Error),
            ],
        ),
    ]
}

/// How the rasterizer draws: arithmetic, perspective, texture filter and buffer formats.
fn pipeline() -> Vec<Knob> {
    vec![
        Knob::new(
            "precision",
            false,
            vec![
                value!("fixed", |s| s.render.precision = Precision::Fixed),
                value!("float", |s| s.render.precision = Precision::Float),
            ],
        ),
        Knob::new(
            "perspective",
            false,
            vec![
                value!("exact", |s| s.render.perspective = Perspective::Exact),
                value!("spans8", |s| s.render.perspective = Perspective::Spans(8)),
                value!("spans16", |s| s.render.perspective = Perspective::Spans(16)),
                value!("spans32", |s| s.render.perspective = Perspective::Spans(32)),
                value!("affine", |s| s.render.perspective = Perspective::Affine),
            ],
        ),
        Knob::new(
            "filter",
            false,
            vec![
                value!("nearest", |s| s.render.sampler = Some(Sampler::NEAREST)),
                value!("bilinear", |s| s.render.sampler = Some(Sampler::BILINEAR)),
                value!("mipmapped", |s| s.render.sampler =
                    Some(Sampler::BILINEAR_MIPMAP)),
            ],
        ),
        Knob::new(
            "colour",
            false,
            vec![
                value!("rgb565", |s| s.color = ColorFormat::Rgb565),
                value!("rgba8888", |s| s.color = ColorFormat::Rgba8888),
            ],
        ),
        Knob::new(
            "depth",
            false,
            vec![
                value!("16", |s| s.depth = DepthFormat::D16),
                value!("32", |s| s.depth = DepthFormat::D32),
            ],
        ),
    ]
}

/// How tiles meet and change, and how many threads draw.
fn scene() -> Vec<Knob> {
    vec![
        Knob::new(
            "cracks",
            false,
            vec![
                value!("none", |s| s.cracks = CrackMode::None),
                value!("shadow", |s| s.cracks = CrackMode::Shadow),
                value!("skirts", |s| s.cracks = CrackMode::Skirts),
                value!("stitch", |s| s.cracks = CrackMode::Stitch),
            ],
        ),
        Knob::new(
            "geomorph",
            false,
            vec![
                value!("off", |s| s.geomorph = Geomorph::Off),
                value!("distance4", |s| s.geomorph =
                    Geomorph::Distance { pixels: 4.0 }),
                value!("distance16", |s| s.geomorph =
                    Geomorph::Distance { pixels: 16.0 }),
            ],
        ),
        Knob::new(
            "threads",
            false,
            vec![
                value!("1", |s| s.threads = 1),
                value!("2", |s| s.threads = 2),
            ],
        ),
    ]
}

/// Rendering features a scene may not need (each measured on and off).
fn features() -> Vec<Knob> {
    vec![
        Knob::new(
            "texture",
            true,
            vec![
                value!("on", |s| {
                    s.render.sampler = s.render.sampler.or(Some(Sampler::BILINEAR_MIPMAP))
                }),
                value!("off", |s| s.render.sampler = None),
            ],
        ),
        Knob::new(
            "depth-test",
            true,
            vec![
                value!("on", |s| s.render.depth_test = true),
                value!("off", |s| s.render.depth_test = false),
            ],
        ),
        // Vertex lighting over the shaded texture: off by default, so not a feature to save.
        Knob::new(
            "lighting",
            false,
            vec![
                value!("off", |s| s.render.lighting = false),
                value!("on", |s| s.render.lighting = true),
            ],
        ),
        Knob::new(
            "fog",
            true,
            vec![
                value!("on", |s| s.render.fog = true),
                value!("off", |s| s.render.fog = false),
            ],
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_knob_has_exactly_one_default_value_and_distinct_values() {
        let defaults = Setting::default();
        for knob in knobs() {
            let matching: Vec<_> = knob
                .values
                .iter()
                .filter(|v| {
                    let mut s = defaults;
                    (v.apply)(&mut s);
                    s == defaults
                })
                .map(|v| v.label)
                .collect();
            assert_eq!(matching.len(), 1, "{}: {matching:?}", knob.name);
            for a in &knob.values {
                for b in &knob.values {
                    let (mut sa, mut sb) = (defaults, defaults);
                    (a.apply)(&mut sa);
                    (b.apply)(&mut sb);
                    assert_eq!(sa == sb, a.label == b.label, "{} {}", a.label, b.label);
                }
            }
        }
    }
}
