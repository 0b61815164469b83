//! Device profiles: the screen, memory, frame rate, threads, link and CPU speed of a target device,
//! so that a run on this machine behaves as the paper's runs did on theirs.
//!
//! Three are built in. The paper's two machines: [`DeviceProfile::pocketpc`] (a 400 MHz PocketPC
//! with 20 MB free, 320x240 RGB565, 7 fps, tiles over a 1 Mbit/s line) and
//! [`DeviceProfile::workstation`] (this machine as it is, 1280x720 at 25 fps); and
//! [`DeviceProfile::native`], the PocketPC's screen on this machine's CPU. A TOML file
//! describes others, starting from a built-in one and changing what it names:
//!
//! ```toml
//! base = "pocketpc"        # or "workstation" (the default)
//! name = "pocketpc over wifi"
//! memory_mb = 32.0
//! [link]
//! bandwidth_kbps = 5000.0
//! latency_ms = 20.0
//! jitter_ms = 10.0
//! ```
//!
//! Fields: `name`, `width`, `height`, `color` (`"rgb565"` or `"rgba8888"`), `depth_bits` (16 or
//! 32), `memory_mb`, `target_fps`, `max_error_px` (the pixel-error bound τ, 0: off),
//! `allocation` (`"importance"` or `"error"`: how tiles share the triangle budget), `threads`
//! (0: all cores), `cpu_slowdown`, and `[link]` with
//! `bandwidth_kbps` (absent: unlimited), `latency_ms`, `jitter_ms`, `drop_rate`.
//!
//! The CPU slowdown factor multiplies the cost of every frame — measured on the wall clock, or
//! modelled by [`crate::sim::clock::CostModel`] on the simulated clock — before the budget
//! controller and the flight clock see it. See `docs/pocketpc.md` for how the PocketPC's factor
//! was chosen and what it does and does not model.

use std::path::Path;
use std::time::Duration;

use serde::Deserialize;
use stripmask_raster::{ColorFormat, DepthFormat};

use crate::db::source::throttle::LinkProfile;
use crate::engine::allocation::Allocation;
use crate::engine::budget::BudgetSettings;
use crate::engine::error_bound::ErrorBound;
use crate::error::{Error, Result};
use crate::named::Named;
use crate::sim::clock::Clock;

/// The link between the device and the tile server.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Link {
    /// Kilobits (1000 bits) per second; `None` is unlimited.
    pub bandwidth_kbps: Option<f64>,
    /// Mean delay before the first byte of every request, milliseconds.
    pub latency_ms: f64,
    /// Each request's delay varies uniformly within `latency_ms ± jitter_ms` (seeded).
    pub jitter_ms: f64,
    /// Fraction of requests that fail, 0 ..= 1.
    pub drop_rate: f64,
}

impl Link {
    /// No bandwidth cap, no latency, no drops.
    pub const UNLIMITED: Link = Link {
        bandwidth_kbps: None,
        latency_ms: 0.0,
        jitter_ms: 0.0,
        drop_rate: 0.0,
    };

    /// Whether the link changes nothing (tiles come straight from the source).
    pub fn is_unlimited(&self) -> bool {
        *self == Link::UNLIMITED
    }

    /// The link as the simulated link's profile, with `seed` for its delays and drops.
    pub fn to_link_profile(self, seed: u64) -> LinkProfile {
        LinkProfile {
            bandwidth_kbps: self.bandwidth_kbps,
            latency: Duration::from_secs_f64(self.latency_ms / 1e3),
            jitter: Duration::from_secs_f64(self.jitter_ms / 1e3),
            drop_rate: self.drop_rate,
            seed,
        }
    }
}

/// What a device is: the settings a run takes from it.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceProfile {
    /// Name for reports.
    pub name: String,
    /// Screen width, pixels.
    pub width: u32,
    /// Screen height, pixels.
    pub height: u32,
    /// Pixel format of the screen.
    pub color: ColorFormat,
    /// Depth buffer format.
    pub depth: DepthFormat,
    /// Memory limit on loaded tiles, MB (10^6 bytes).
    pub memory_mb: f64,
    /// The frame rate the triangle budget aims at.
    pub target_fps: f64,
    /// The pixel-error bound τ: no tile finer than this many pixels of error needs (0: off).
    pub max_error_px: f64,
    /// How the tiles in view share the triangle budget.
    pub allocation: Allocation,
    /// Rasterizer threads (0: all cores).
    pub threads: usize,
    /// The link tiles come over.
    pub link: Link,
    /// How many times slower than one core of this machine the device's CPU renders a frame.
    pub cpu_slowdown: f64,
}

/// The PocketPC's CPU slowdown: the paper's 400 MHz PocketPC drew about 3,000 triangles per
/// frame at 7 fps (143 ms); [`crate::sim::clock::CostModel::HOST`] puts such a frame (with the
/// 54,000 pixels a 320x240 flyover writes) at 3.4 ms on one core of this machine: 42 times less.
/// See `docs/pocketpc.md`.
pub const POCKETPC_SLOWDOWN: f64 = 42.0;

/// The smallest CPU slowdown (the fastest device, relative to this machine) a profile may
/// have: below it, a flight on the simulated clock would take too many frames to end.
pub const MIN_CPU_SLOWDOWN: f64 = 1e-3;

impl DeviceProfile {
    /// The paper's handheld: 400 MHz PocketPC, 320x240 RGB565 with 16-bit depth, 20 MB for
    /// tiles, 7 fps, one thread, tiles over a 1 Mbit/s line with 50 ms latency.
    pub fn pocketpc() -> Self {
        DeviceProfile {
            name: "pocketpc".into(),
            width: 320,
            height: 240,
            color: ColorFormat::Rgb565,
            depth: DepthFormat::D16,
            memory_mb: 20.0,
            target_fps: 7.0,
            max_error_px: ErrorBound::DEFAULT_PIXELS,
            allocation: Allocation::default(),
            threads: 1,
            link: Link {
                bandwidth_kbps: Some(1000.0),
                latency_ms: 50.0,
                jitter_ms: 0.0,
                drop_rate: 0.0,
            },
            cpu_slowdown: POCKETPC_SLOWDOWN,
        }
    }

    /// The paper's workstation, played by this machine: 1280x720 RGBA8888 with 32-bit depth,
    /// 25 fps, 256 MB for tiles, all cores, a local disk (no link limits), no slowdown.
    pub fn workstation() -> Self {
        DeviceProfile {
            name: "workstation".into(),
            width: 1280,
            height: 720,
            color: ColorFormat::Rgba8888,
            depth: DepthFormat::D32,
            memory_mb: 256.0,
            target_fps: 25.0,
            max_error_px: ErrorBound::DEFAULT_PIXELS,
            allocation: Allocation::default(),
            threads: 0,
            link: Link::UNLIMITED,
            cpu_slowdown: 1.0,
        }
    }

    /// The PocketPC's screen, memory and frame rate on this machine as it is: all cores, no
    /// slowdown, tiles straight from the source (what `fly` does without a profile).
    pub fn native() -> Self {
        DeviceProfile {
            name: "native".into(),
            threads: 0,
            link: Link::UNLIMITED,
            cpu_slowdown: 1.0,
            ..Self::pocketpc()
        }
    }

    /// The names of the built-in profiles.
    pub const BUILTIN: [&str; 3] = ["pocketpc", "workstation", "native"];

    /// A built-in profile by name (one of [`DeviceProfile::BUILTIN`]).
    pub fn builtin(name: &str) -> Option<Self> {
        match name {
            "pocketpc" => Some(Self::pocketpc()),
            "workstation" => Some(Self::workstation()),
            "native" => Some(Self::native()),
            _ => None,
        }
    }

    /// The built-in profile `name`, or the TOML profile `file` when given, with `overrides`
    /// applied and checked.
    pub fn resolve(name: &str, file: Option<&Path>, overrides: &Overrides) -> Result<Self> {
        let mut p = match file {
            Some(path) => Self::from_toml(path)?,
            None => Self::builtin(name).ok_or_else(|| {
                Error::setting(
                    "device profile",
                    name,
                    format!("one of {}", Self::BUILTIN.join(", ")),
                )
            })?,
        };
        overrides.apply(&mut p);
        p.check()?;
        Ok(p)
    }

    /// Reads a TOML profile (format in the module documentation).
    pub fn from_toml(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(&name, e))?;
        Self::parse_toml(&text, &name)
    }

    /// Parses a TOML profile; `name` (the file) goes into error messages.
    pub fn parse_toml(text: &str, name: &str) -> Result<Self> {
        let file: ProfileFile =
            toml::from_str(text).map_err(|e| Error::invalid(name, e.to_string()))?;
        let base = file.base.as_deref().unwrap_or("workstation");
        let mut p = Self::builtin(base).ok_or_else(|| {
            Error::invalid(
                name,
                format!("base {base:?} is not a built-in profile (pocketpc, workstation)"),
            )
        })?;
        if let Some(v) = file.name {
            p.name = v;
        }
        if let Some(v) = file.width {
            p.width = v;
        }
        if let Some(v) = file.height {
            p.height = v;
        }
        if let Some(v) = file.color {
            p.color =
                ColorFormat::from_name(&v).map_err(|e| Error::invalid(name, e.to_string()))?;
        }
        if let Some(v) = file.depth_bits {
            p.depth = depth_format(v).map_err(|e| Error::invalid(name, e.to_string()))?;
        }
        if let Some(v) = file.memory_mb {
            p.memory_mb = v;
        }
        if let Some(v) = file.target_fps {
            p.target_fps = v;
        }
        if let Some(v) = file.max_error_px {
            p.max_error_px = v;
        }
        if let Some(v) = file.allocation {
            p.allocation =
                Allocation::from_name(&v).map_err(|e| Error::invalid(name, e.to_string()))?;
        }
        if let Some(v) = file.threads {
            p.threads = v;
        }
        if let Some(v) = file.cpu_slowdown {
            p.cpu_slowdown = v;
        }
        if let Some(link) = file.link {
            if link.bandwidth_kbps.is_some() {
                p.link.bandwidth_kbps = link.bandwidth_kbps;
            }
            if let Some(v) = link.latency_ms {
                p.link.latency_ms = v;
            }
            if let Some(v) = link.jitter_ms {
                p.link.jitter_ms = v;
            }
            if let Some(v) = link.drop_rate {
                p.link.drop_rate = v;
            }
        }
        p.check().map_err(|e| Error::invalid(name, e.to_string()))?;
        Ok(p)
    }

    /// Checks that every value is in range: an [`Error::InvalidSetting`] naming the field
    /// otherwise.
    pub fn check(&self) -> Result<()> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let at_least_zero = |v: f64| v.is_finite() && v >= 0.0;
        if !(1..=8192).contains(&self.width) || !(1..=8192).contains(&self.height) {
            return Err(Error::setting(
                "screen",
                format!("{}x{}", self.width, self.height),
                "sides 1 ..= 8192",
            ));
        }
        // Each within what a run can finish with: a slowdown of 1e-30 on the simulated clock
        // would never reach the end of a flight, a latency of 1e300 ms never starts it.
        for (name, value, most) in [
            ("memory_mb", self.memory_mb, 1e9),
            ("target_fps", self.target_fps, 1e4),
            ("cpu_slowdown", self.cpu_slowdown, 1e4),
        ] {
            if !(positive(value) && value <= most) {
                return Err(Error::setting(
                    name,
                    value,
                    format!("a positive number up to {most}"),
                ));
            }
        }
        self.max_error()?;
        if self.cpu_slowdown < MIN_CPU_SLOWDOWN {
            return Err(Error::setting(
                "cpu_slowdown",
                self.cpu_slowdown,
                format!("at least {MIN_CPU_SLOWDOWN}"),
            ));
        }
        let slowest = LinkProfile::MIN_BANDWIDTH_KBPS;
        if let Some(b) = self
            .link
            .bandwidth_kbps
            .filter(|&b| !(b.is_finite() && b >= slowest))
        {
            return Err(Error::setting(
                "link bandwidth_kbps",
                b,
                format!("a finite number of at least {slowest}"),
            ));
        }
        let longest = LinkProfile::MAX_DELAY.as_secs_f64() * 1e3;
        for (name, value) in [
            ("link latency_ms", self.link.latency_ms),
            ("link jitter_ms", self.link.jitter_ms),
        ] {
            if !(at_least_zero(value) && value <= longest) {
                return Err(Error::setting(name, value, format!("0 ..= {longest}")));
            }
        }
        if !(0.0..=1.0).contains(&self.link.drop_rate) {
            return Err(Error::setting(
                "link drop_rate",
                self.link.drop_rate,
                "a fraction between 0 and 1",
            ));
        }
        Ok(())
    }

    /// The memory limit in bytes.
    pub fn memory_limit_bytes(&self) -> usize {
        (self.memory_mb * 1e6) as usize
    }

    /// The budget controller's settings on this device: its target frame rate, and what the
    /// `clock` at this device's CPU slowdown expects a frame on its screen to cost, where the
    /// controller starts instead of learning it from the first frames.
    pub fn budget(&self, clock: Clock) -> BudgetSettings {
        let clock = clock.with_slowdown(self.cpu_slowdown);
        BudgetSettings {
            target_fps: self.target_fps,
            expected: Some(clock.expected_cost(self.width, self.height)),
            ..BudgetSettings::default()
        }
    }

    /// The pixel-error bound τ of `max_error_px`.
    pub fn max_error(&self) -> Result<ErrorBound> {
        ErrorBound::from_pixels("max_error_px", self.max_error_px)
    }
}

/// Values given on the command line, which win over the profile's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Overrides {
    /// Screen width and height.
    pub size: Option<(u32, u32)>,
    /// Pixel format.
    pub color: Option<ColorFormat>,
    /// Depth format.
    pub depth: Option<DepthFormat>,
    /// Memory limit, MB.
    pub memory_mb: Option<f64>,
    /// Target frame rate.
    pub target_fps: Option<f64>,
    /// The pixel-error bound τ, pixels (0: off).
    pub max_error_px: Option<f64>,
    /// How tiles share the budget.
    pub allocation: Option<Allocation>,
    /// Rasterizer threads.
    pub threads: Option<usize>,
    /// CPU slowdown factor.
    pub cpu_slowdown: Option<f64>,
    /// Link bandwidth, kbit/s.
    pub bandwidth_kbps: Option<f64>,
    /// Link latency, ms.
    pub latency_ms: Option<f64>,
    /// Link jitter, ms.
    pub jitter_ms: Option<f64>,
    /// Link drop rate.
    pub drop_rate: Option<f64>,
}

impl Overrides {
    /// Writes every value given into `p`.
    pub fn apply(&self, p: &mut DeviceProfile) {
        if let Some((w, h)) = self.size {
            (p.width, p.height) = (w, h);
        }
        p.color = self.color.unwrap_or(p.color);
        p.depth = self.depth.unwrap_or(p.depth);
        p.memory_mb = self.memory_mb.unwrap_or(p.memory_mb);
        p.target_fps = self.target_fps.unwrap_or(p.target_fps);
        p.max_error_px = self.max_error_px.unwrap_or(p.max_error_px);
        p.allocation = self.allocation.unwrap_or(p.allocation);
        p.threads = self.threads.unwrap_or(p.threads);
        p.cpu_slowdown = self.cpu_slowdown.unwrap_or(p.cpu_slowdown);
        if self.bandwidth_kbps.is_some() {
            p.link.bandwidth_kbps = self.bandwidth_kbps;
        }
        p.link.latency_ms = self.latency_ms.unwrap_or(p.link.latency_ms);
        p.link.jitter_ms = self.jitter_ms.unwrap_or(p.link.jitter_ms);
        p.link.drop_rate = self.drop_rate.unwrap_or(p.link.drop_rate);
    }
}

/// The depth format of `bits` (16 or 32).
pub fn depth_format(bits: u8) -> Result<DepthFormat> {
    match bits {
        16 => Ok(DepthFormat::D16),
        32 => Ok(DepthFormat::D32),
        b => Err(Error::setting("depth_bits", b, "16 or 32")),
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    base: Option<String>,
    name: Option<String>,
    width: Option<u32>,
    height: Option<u32>,
    color: Option<String>,
    depth_bits: Option<u8>,
    memory_mb: Option<f64>,
    target_fps: Option<f64>,
    max_error_px: Option<f64>,
    allocation: Option<String>,
    threads: Option<usize>,
    cpu_slowdown: Option<f64>,
    link: Option<LinkFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LinkFile {
    bandwidth_kbps: Option<f64>,
    latency_ms: Option<f64>,
    jitter_ms: Option<f64>,
    drop_rate: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_in_profiles_are_the_papers_machines() {
        let p = DeviceProfile::builtin("pocketpc").unwrap();
        assert_eq!((p.width, p.height), (320, 240));
        assert_eq!((p.color, p.depth), (ColorFormat::Rgb565, DepthFormat::D16));
        assert_eq!(
            (p.memory_limit_bytes(), p.target_fps, p.threads),
            (20_000_000, 7.0, 1)
        );
        assert!(p.cpu_slowdown > 1.0);
        let w = DeviceProfile::builtin("workstation").unwrap();
        assert_eq!((w.target_fps, w.cpu_slowdown), (25.0, 1.0));
        assert!(DeviceProfile::builtin("pda").is_none());
        let n = DeviceProfile::builtin("native").unwrap();
        assert!(n.link.is_unlimited() && n.threads == 0 && n.cpu_slowdown == 1.0);
        for p in [p, w] {
            p.check().unwrap();
        }
    }

    #[test]
    fn a_toml_profile_changes_only_what_it_names() {
        let text = "base = \"pocketpc\"\nname = \"wifi\"\nmemory_mb = 32.0\n\
                    [link]\nbandwidth_kbps = 5000.0\njitter_ms = 15.0\n";
        let p = DeviceProfile::parse_toml(text, "wifi.toml").unwrap();
        let base = DeviceProfile::pocketpc();
        assert_eq!(p.name, "wifi");
        assert_eq!(p.memory_mb, 32.0);
        assert_eq!(p.link.bandwidth_kbps, Some(5000.0));
        assert_eq!(p.link.latency_ms, base.link.latency_ms);
        assert_eq!(p.link.jitter_ms, 15.0);
        assert_eq!(p.link.to_link_profile(1).jitter, Duration::from_millis(15));
        assert_eq!(
            (p.width, p.target_fps, p.cpu_slowdown),
            (320, 7.0, base.cpu_slowdown)
        );
        let plain = DeviceProfile::parse_toml("color = \"rgb565\"\n", "x.toml").unwrap();
        assert_eq!(plain.width, 1280);
        assert_eq!(plain.color, ColorFormat::Rgb565);
        assert_eq!(plain.allocation, Allocation::Error);
        let paper = DeviceProfile::parse_toml("allocation = \"importance\"\n", "i.toml").unwrap();
        assert_eq!(paper.allocation, Allocation::Importance);
    }

    #[test]
    fn command_line_values_win_over_the_profile() {
        let o = Overrides {
            target_fps: Some(10.0),
            bandwidth_kbps: Some(64.0),
            size: Some((160, 120)),
            ..Overrides::default()
        };
        let p = DeviceProfile::resolve("pocketpc", None, &o).unwrap();
        assert_eq!((p.target_fps, p.width, p.height), (10.0, 160, 120));
        assert_eq!(p.max_error().unwrap(), ErrorBound::default());
        let off = Overrides {
            max_error_px: Some(0.0),
            ..o
        };
        let p = DeviceProfile::resolve("pocketpc", None, &off).unwrap();
        assert_eq!(p.max_error().unwrap(), ErrorBound::Off);
        assert_eq!(p.allocation, Allocation::default());
        let paper = Overrides {
            allocation: Some(Allocation::Importance),
            ..o
        };
        let p = DeviceProfile::resolve("pocketpc", None, &paper).unwrap();
        assert_eq!(p.allocation, Allocation::Importance);
        assert_eq!(p.link.bandwidth_kbps, Some(64.0));
        assert_eq!(p.memory_mb, 20.0);
        let bad = Overrides {
            drop_rate: Some(1.5),
            ..Overrides::default()
        };
        let e = DeviceProfile::resolve("pocketpc", None, &bad).unwrap_err();
        assert!(e.to_string().contains("drop_rate"), "{e}");
        let e = DeviceProfile::resolve("pda", None, &o).unwrap_err();
        assert!(e.to_string().contains("pda"), "{e}");
    }

    #[test]
    fn bad_toml_profiles_name_the_file_and_the_problem() {
        for (text, problem) in [
            ("base = \"pda\"\n", "not a built-in"),
            ("target_fps = -1.0\n", "target_fps"),
            ("max_error_px = -0.5\n", "max_error_px"),
            ("depth_bits = 24\n", "depth_bits 24"),
            ("[link]\ndrop_rate = 2.0\n", "drop_rate"),
            ("[link]\njitter_ms = -1.0\n", "jitter_ms"),
            ("cpu_speed = 3.0\n", "cpu_speed"),
            ("width = 0\n", "sides"),
            ("color = \"rgb555\"\n", "colour format rgb555"),
            ("allocation = \"height\"\n", "allocation height"),
        ] {
            let e = DeviceProfile::parse_toml(text, "bad.toml")
                .unwrap_err()
                .to_string();
            assert!(e.contains("bad.toml") && e.contains(problem), "{text}: {e}");
        }
        let missing = DeviceProfile::from_toml(Path::new("/nonexistent/p.toml")).unwrap_err();
        assert!(missing.to_string().contains("p.toml"));
    }
}
