//! Device profiles: the screen, memory, frame rate, threads, link and CPU speed of a target device,
//! so that a run on this machine behaves as the paper's runs did on theirs.
//!
//! Three are built in. The paper's two machines: [`DeviceProfile::pocketpc`] (a 400 MHz PocketPC
//! with 20 MB free, 320x240 RGB565, 7 fps, tiles over a 1 Mbit/s line) and
//! [`DeviceProfile::workstation`] (this machine as it is, 1280x720 at 25 fps); and
//! [`DeviceProfile::native`], the PocketPC's screen on this machine's CPU. Others start from a
//! built-in one and change what they name, setting by setting ([`settings::SETTINGS`]): a TOML
//! file (`file`, with the `lab` feature) or the command line.
//!
//! The CPU slowdown factor multiplies the cost of every frame — measured on the wall clock, or
//! modelled by [`crate::sim::clock::CostModel`] on the simulated clock — before the budget
//! controller and the flight clock see it. See `docs/pocketpc.md` for how the PocketPC's factor
//! was chosen and what it does and does not model.

#[cfg(feature = "lab")]
pub mod file;
pub mod settings;

use std::time::Duration;

use stripmask_raster::{ColorFormat, DepthFormat};

use crate::db::source::throttle::LinkProfile;
use crate::engine::allocation::Allocation;
use crate::engine::budget::BudgetSettings;
use crate::engine::error_bound::ErrorBound;
use crate::error::{Error, Result};
use crate::sim::clock::Clock;
use settings::{SETTINGS, Setting};

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
    /// The link tiles come over; its seed decides the delays and drops.
    pub link: LinkProfile,
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
            link: LinkProfile {
                bandwidth_kbps: Some(1000.0),
                latency: Duration::from_millis(50),
                ..LinkProfile::default()
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
            link: LinkProfile::default(),
            cpu_slowdown: 1.0,
        }
    }

    /// The PocketPC's screen, memory and frame rate on this machine as it is: all cores, no
    /// slowdown, tiles straight from the source (what `fly` does without a profile).
    pub fn native() -> Self {
        DeviceProfile {
            name: "native".into(),
            threads: 0,
            link: LinkProfile::default(),
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

    /// The built-in profile `name`, or an [`Error::InvalidSetting`] listing the built-in ones.
    pub fn named(name: &str) -> Result<Self> {
        Self::builtin(name).ok_or_else(|| {
            Error::setting(
                "device profile",
                name,
                format!("one of {}", Self::BUILTIN.join(", ")),
            )
        })
    }

    /// Sets the setting `key` (one of [`settings::SETTINGS`]) from its text, as a TOML profile
    /// or the command line spells it.
    pub fn set(&mut self, key: &str, text: &str) -> Result<()> {
        Setting::named(key)?.set(self, text)
    }

    /// Checks that every value is in range: an [`Error::InvalidSetting`] naming the setting
    /// otherwise.
    pub fn check(&self) -> Result<()> {
        SETTINGS.iter().try_for_each(|s| s.check(self))
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
    fn settings_given_by_name_win_over_the_profile() {
        let mut p = DeviceProfile::named("pocketpc").unwrap();
        for (key, text) in [
            ("target_fps", "10"),
            ("bandwidth_kbps", "64"),
            ("width", "160"),
            ("height", "120"),
        ] {
            p.set(key, text).unwrap();
        }
        assert_eq!((p.target_fps, p.width, p.height), (10.0, 160, 120));
        assert_eq!(p.max_error().unwrap(), ErrorBound::default());
        assert_eq!(p.allocation, Allocation::default());
        assert_eq!(p.link.bandwidth_kbps, Some(64.0));
        assert_eq!(p.memory_mb, 20.0);
        p.set("max_error_px", "0").unwrap();
        assert_eq!(p.max_error().unwrap(), ErrorBound::Off);
        p.set("allocation", "importance").unwrap();
        assert_eq!(p.allocation, Allocation::Importance);
        p.set("jitter_ms", "15").unwrap();
        assert_eq!(p.link.jitter, Duration::from_millis(15));
        p.set("bandwidth_kbps", "unlimited").unwrap();
        assert_eq!(p.link.bandwidth_kbps, None);
        p.check().unwrap();
        let e = p.set("drop_rate", "1.5").unwrap_err();
        assert!(e.to_string().contains("drop_rate"), "{e}");
        assert_eq!(p.link.drop_rate, 0.0);
        let e = DeviceProfile::named("pda").unwrap_err();
        assert!(e.to_string().contains("pda"), "{e}");
    }

    #[test]
    fn a_check_names_the_setting_out_of_range() {
        let mut p = DeviceProfile::pocketpc();
        p.link.latency = LinkProfile::MAX_DELAY * 2;
        let e = p.check().unwrap_err().to_string();
        assert!(e.contains("latency_ms 7200000"), "{e}");
        p.link.latency = Duration::ZERO;
        p.width = 0;
        assert!(p.check().unwrap_err().to_string().contains("width"));
    }
}
