//! Device profiles read from TOML files: a built-in profile (`base`), and the settings the file
//! names, each a key of [`super::settings::SETTINGS`] (those of the link under `[link]`):
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
//! Names (`color = "rgb565"`, `allocation = "error"`) are strings, numbers are numbers.

use std::path::Path;

use toml::{Table, Value};

use super::DeviceProfile;
use super::settings::Setting;
use crate::error::{Error, Result};

impl DeviceProfile {
    /// Reads a TOML profile (format in the module documentation).
    pub fn from_toml(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(&name, e))?;
        Self::parse_toml(&text, &name)
    }

    /// Parses a TOML profile; `name` (the file) goes into error messages.
    pub fn parse_toml(text: &str, name: &str) -> Result<Self> {
        let mut file: Table =
            toml::from_str(text).map_err(|e| Error::invalid(name, e.to_string()))?;
        let base = match file.remove("base") {
            Some(Value::String(base)) => base,
            Some(other) => return Err(Error::invalid(name, format!("base {other} is not a name"))),
            None => "workstation".to_string(),
        };
        let mut p = Self::builtin(&base).ok_or_else(|| {
            Error::invalid(
                name,
                format!("base {base:?} is not a built-in profile (pocketpc, workstation)"),
            )
        })?;
        let link = match file.remove("link") {
            Some(Value::Table(link)) => link,
            Some(other) => {
                return Err(Error::invalid(name, format!("link {other} is not a table")));
            }
            None => Table::new(),
        };
        let settings = file.iter().map(|kv| (false, kv));
        for (in_link, (key, value)) in settings.chain(link.iter().map(|kv| (true, kv))) {
            set(&mut p, in_link, key, value).map_err(|e| Error::invalid(name, e.to_string()))?;
        }
        Ok(p)
    }
}

/// Sets the setting `key` (of the `[link]` table when `in_link`) to the TOML `value`.
fn set(p: &mut DeviceProfile, in_link: bool, key: &str, value: &Value) -> Result<()> {
    let setting = Setting::named(key)?;
    if setting.link != in_link {
        let table = if setting.link {
            "[link]"
        } else {
            "the top level"
        };
        return Err(Error::setting(
            "device setting",
            key,
            format!("{key} under {table}"),
        ));
    }
    let text = match value {
        Value::String(s) => s.clone(),
        Value::Integer(n) => n.to_string(),
        Value::Float(x) => x.to_string(),
        other => {
            return Err(Error::setting(setting.key, other, "a string or a number"));
        }
    };
    setting.set(p, &text)
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use stripmask_raster::ColorFormat;

    use super::*;
    use crate::engine::allocation::Allocation;

    #[test]
    fn a_toml_profile_changes_only_what_it_names() {
        let text = "base = \"pocketpc\"\nname = \"wifi\"\nmemory_mb = 32.0\n\
                    [link]\nbandwidth_kbps = 5000.0\njitter_ms = 15.0\n";
        let p = DeviceProfile::parse_toml(text, "wifi.toml").unwrap();
        let base = DeviceProfile::pocketpc();
        assert_eq!(p.name, "wifi");
        assert_eq!(p.memory_mb, 32.0);
        assert_eq!(p.link.bandwidth_kbps, Some(5000.0));
        assert_eq!(p.link.latency, base.link.latency);
        assert_eq!(p.link.jitter, Duration::from_millis(15));
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
            ("drop_rate = 0.5\n", "under [link]"),
            ("[link]\nwidth = 5\n", "under the top level"),
            ("threads = true\n", "a string or a number"),
            ("link = 3\n", "not a table"),
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
