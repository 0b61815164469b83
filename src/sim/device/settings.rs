//! The settings of a device profile, each written once in [`SETTINGS`]: its key, the field it
//! sets, the type of its value, the values it takes and what it means. The profile's checks, the
//! TOML profiles and the command line's overrides all read this one table.

use std::time::Duration;

use stripmask_raster::{ColorFormat, DepthFormat};

use super::{DeviceProfile, MIN_CPU_SLOWDOWN};
use crate::db::source::throttle::LinkProfile;
use crate::engine::allocation::Allocation;
use crate::error::{Error, Result};
use crate::named::Named;

/// One setting of a device profile.
#[derive(Debug)]
pub struct Setting {
    /// The key in a TOML profile (under `[link]` when [`Setting::link`]); with `-` for `_`, the
    /// command line's flag.
    pub key: &'static str,
    /// Whether the key belongs to the TOML profile's `[link]` table.
    pub link: bool,
    /// What the setting is, in a line of help.
    pub help: &'static str,
    set: fn(&mut DeviceProfile, &str) -> Result<()>,
    check: fn(&DeviceProfile) -> Result<()>,
}

impl Setting {
    /// Sets the profile's value from `text`, when it spells one this setting takes.
    pub fn set(&self, profile: &mut DeviceProfile, text: &str) -> Result<()> {
        (self.set)(profile, text)
    }

    /// Whether the profile's value is one this setting takes: an [`Error::InvalidSetting`]
    /// naming the key otherwise.
    pub fn check(&self, profile: &DeviceProfile) -> Result<()> {
        (self.check)(profile)
    }

    /// The setting called `key`, or an [`Error::InvalidSetting`] listing the keys.
    pub fn named(key: &str) -> Result<&'static Setting> {
        SETTINGS.iter().find(|s| s.key == key).ok_or_else(|| {
            let keys: Vec<&str> = SETTINGS.iter().map(|s| s.key).collect();
            Error::setting("device setting", key, format!("one of {}", keys.join(", ")))
        })
    }
}

/// A setting's value as text: read from a TOML profile or the command line, shown in errors.
trait Value: Sized {
    /// The value `text` spells; an error saying that `key` takes `expected` otherwise.
    fn parse(key: &'static str, text: &str, expected: &str) -> Result<Self>;
    /// The value as text.
    fn show(&self) -> String;
}

/// A value any [`std::str::FromStr`] number reads.
macro_rules! from_str_value {
    ($($type:ty),+) => {$(
        impl Value for $type {
            fn parse(key: &'static str, text: &str, expected: &str) -> Result<Self> {
                text.parse().map_err(|_| Error::setting(key, text, expected))
            }
            fn show(&self) -> String {
                self.to_string()
            }
        }
    )+};
}

from_str_value!(String, u32, u64, usize, f64);

/// A value chosen by name: its own error lists the names.
macro_rules! named_value {
    ($($type:ty),+) => {$(
        impl Value for $type {
            fn parse(_: &'static str, text: &str, _: &str) -> Result<Self> {
                Self::from_name(text)
            }
            fn show(&self) -> String {
                self.name().to_string()
            }
        }
    )+};
}

named_value!(ColorFormat, Allocation);

/// A depth format by its bits.
impl Value for DepthFormat {
    fn parse(key: &'static str, text: &str, expected: &str) -> Result<Self> {
        match text {
            "16" => Ok(DepthFormat::D16),
            "32" => Ok(DepthFormat::D32),
            _ => Err(Error::setting(key, text, expected)),
        }
    }
    fn show(&self) -> String {
        match self {
            DepthFormat::D16 => "16",
            DepthFormat::D32 => "32",
            DepthFormat::None => "none",
        }
        .to_string()
    }
}

/// A bandwidth, or `unlimited`.
impl Value for Option<f64> {
    fn parse(key: &'static str, text: &str, expected: &str) -> Result<Self> {
        match text {
            "unlimited" => Ok(None),
            _ => f64::parse(key, text, expected).map(Some),
        }
    }
    fn show(&self) -> String {
        self.map_or("unlimited".to_string(), |v| v.to_string())
    }
}

/// A delay in milliseconds.
impl Value for Duration {
    fn parse(key: &'static str, text: &str, expected: &str) -> Result<Self> {
        let ms = f64::parse(key, text, expected)?;
        Duration::try_from_secs_f64(ms / 1e3).map_err(|_| Error::setting(key, text, expected))
    }
    fn show(&self) -> String {
        (self.as_nanos() as f64 / 1e6).to_string()
    }
}

/// The table: for each setting, `key => field: type, values it takes (in words), the test of
/// a value, help`; `[link]` before the key puts it in the TOML profile's `[link]` table.
macro_rules! settings {
    ($(
        $([$link:ident])? $key:literal => $($field:ident).+ : $type:ty,
        $expected:expr, $valid:expr, $help:literal;
    )+) => {
        /// Every setting of a device profile, in the order help lists them.
        pub static SETTINGS: &[Setting] = &[$(
            Setting {
                key: $key,
                link: settings!(@link $($link)?),
                help: $help,
                set: |p, text| {
                    let value = <$type as Value>::parse($key, text, $expected)?;
                    if !($valid)(&value) {
                        return Err(Error::setting($key, text, $expected));
                    }
                    p.$($field).+ = value;
                    Ok(())
                },
                check: |p| {
                    let value: &$type = &p.$($field).+;
                    if ($valid)(value) {
                        Ok(())
                    } else {
                        Err(Error::setting($key, value.show(), $expected))
                    }
                },
            },
        )+];
    };
    (@link link) => { true };
    (@link) => { false };
}

/// Each within what a run can finish with: a slowdown of 1e-30 on the simulated clock would
/// never reach the end of a flight, a latency of 1e300 ms never starts it.
fn up_to(most: f64) -> impl Fn(&f64) -> bool {
    move |&v| v.is_finite() && v > 0.0 && v <= most
}

/// A screen side, pixels.
fn side(v: &u32) -> bool {
    (1..=8192).contains(v)
}

/// A delay a link may have.
fn delay(d: &Duration) -> bool {
    *d <= LinkProfile::MAX_DELAY
}

settings! {
    "name" => name: String, "a name", |_: &String| true, "Name for reports";
    "width" => width: u32, "sides of 1 ..= 8192 pixels", side, "Screen width, pixels";
    "height" => height: u32, "sides of 1 ..= 8192 pixels", side, "Screen height, pixels";
    "color" => color: ColorFormat, "", |_: &ColorFormat| true,
        "Colour format: rgb565 (the handheld's) or rgba8888";
    "depth_bits" => depth: DepthFormat, "16 or 32", |_: &DepthFormat| true,
        "Depth buffer bits: 16 or 32";
    "memory_mb" => memory_mb: f64, "a positive number up to 1000000000", up_to(1e9),
        "Memory limit on loaded tiles, MB (10^6 bytes)";
    "target_fps" => target_fps: f64, "a positive number up to 10000", up_to(1e4),
        "The frame rate the triangle budget aims at";
    "max_error_px" => max_error_px: f64, "0 (off) or a positive number of pixels",
        |&v: &f64| v.is_finite() && v >= 0.0,
        "The pixel-error bound τ: no tile is drawn finer than needs this many pixels of \
         geometric error; 0 turns it off";
    "allocation" => allocation: Allocation, "", |_: &Allocation| true,
        "How the tiles in view share the triangle budget: importance (the paper's distance \
         and height shares) or error (the largest projected error first)";
    "threads" => threads: usize, "a number of threads", |_: &usize| true,
        "Rasterizer threads (0: all cores)";
    "cpu_slowdown" => cpu_slowdown: f64, "a number from 0.001 up to 10000",
        |&v: &f64| up_to(1e4)(&v) && v >= MIN_CPU_SLOWDOWN,
        "Frame costs are multiplied by this (the device's CPU is this many times slower)";
    [link] "bandwidth_kbps" => link.bandwidth_kbps: Option<f64>,
        "unlimited or a finite number of kbit/s of at least 0.1",
        |b: &Option<f64>| b.is_none_or(|b| b.is_finite() && b >= LinkProfile::MIN_BANDWIDTH_KBPS),
        "Link bandwidth, kilobits per second (unlimited: no cap)";
    [link] "latency_ms" => link.latency: Duration, "0 ..= 3600000 milliseconds", delay,
        "Link latency per request, milliseconds";
    [link] "jitter_ms" => link.jitter: Duration, "0 ..= 3600000 milliseconds", delay,
        "Each request's latency varies within ± this many milliseconds (seeded)";
    [link] "drop_rate" => link.drop_rate: f64, "a fraction between 0 and 1",
        |v: &f64| (0.0..=1.0).contains(v),
        "Fraction of requests the link drops, 0..1";
    [link] "seed" => link.seed: u64, "a whole number", |_: &u64| true,
        "Seed of the link's delays and drop decisions";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ranges_in_words_are_the_ranges_checked() {
        assert_eq!(LinkProfile::MAX_DELAY.as_millis(), 3_600_000);
        assert_eq!(LinkProfile::MIN_BANDWIDTH_KBPS, 0.1);
        assert_eq!(MIN_CPU_SLOWDOWN, 0.001);
        let mut p = DeviceProfile::workstation();
        for (key, limit, beyond) in [
            ("latency_ms", "3600000", "3600000.1"),
            ("bandwidth_kbps", "0.1", "0.09"),
            ("cpu_slowdown", "0.001", "0.0009"),
            ("width", "8192", "8193"),
        ] {
            let setting = Setting::named(key).unwrap();
            setting.set(&mut p, limit).unwrap();
            let e = setting.set(&mut p, beyond).unwrap_err().to_string();
            assert!(e.contains(key) && e.contains(beyond), "{e}");
        }
    }

    #[test]
    fn every_key_is_one_setting() {
        for s in SETTINGS {
            assert!(std::ptr::eq(Setting::named(s.key).unwrap(), s), "{}", s.key);
        }
        let e = Setting::named("cpu_speed").unwrap_err().to_string();
        assert!(e.contains("cpu_speed") && e.contains("cpu_slowdown"), "{e}");
    }
}
