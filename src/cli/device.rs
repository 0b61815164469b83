//! The device a run is: a profile (built in, or a TOML file) and the command line's values of
//! its settings, one flag per setting of the library's table, which win over the profile's.

use std::path::{Path, PathBuf};

use clap::{Arg, ArgMatches, Args, Command, FromArgMatches};
use stripmask::Named;
use stripmask::error::Result;
use stripmask::sim::clock::Clock;
use stripmask::sim::device::DeviceProfile;
use stripmask::sim::device::settings::{SETTINGS, Setting};

use super::args::{named, profile_name};

/// The device a flight runs as: a profile, the clock, and values that override the profile.
#[derive(Args, Debug)]
pub(super) struct DeviceArgs {
    /// Device profile (native: the handheld's screen on this CPU).
    #[arg(long, value_parser = profile_name(), default_value_t = DeviceProfile::native().name)]
    profile: String,
    /// A TOML device profile (see docs/pocketpc.md) instead of a built-in one.
    #[arg(long, conflicts_with = "profile")]
    profile_file: Option<PathBuf>,
    /// wall: frame costs measured; simulated: modelled, so the run is reproducible.
    #[arg(long, value_parser = named::<Clock>(), default_value = Clock::default().name())]
    pub(super) clock: Clock,
    /// Framebuffer size, WxH (the profile's width and height).
    #[arg(long, value_parser = super::args::parse_size, conflicts_with_all = ["width", "height"])]
    size: Option<(u32, u32)>,
    #[command(flatten)]
    overrides: Overrides,
}

impl DeviceArgs {
    /// The profile with the values given on the command line.
    pub(super) fn resolve(&self) -> Result<DeviceProfile> {
        let mut p = profile(&self.profile, self.profile_file.as_deref(), &self.overrides)?;
        if let Some((w, h)) = self.size {
            (p.width, p.height) = (w, h);
        }
        Ok(p)
    }
}

/// The built-in profile `name`, or the TOML profile `file` when given, with `overrides`
/// applied.
pub(super) fn profile(
    name: &str,
    file: Option<&Path>,
    overrides: &Overrides,
) -> Result<DeviceProfile> {
    let mut p = match file {
        Some(path) => DeviceProfile::from_toml(path)?,
        None => DeviceProfile::named(name)?,
    };
    for (setting, text) in &overrides.given {
        setting.set(&mut p, text)?;
    }
    Ok(p)
}

/// The settings given on the command line: `--KEY VALUE` for each key of [`SETTINGS`], its
/// underscores as dashes (`--memory-mb 32`, `--latency-ms 50`).
#[derive(Debug, Default)]
pub(super) struct Overrides {
    given: Vec<(&'static Setting, String)>,
}

impl FromArgMatches for Overrides {
    fn from_arg_matches(matches: &ArgMatches) -> std::result::Result<Self, clap::Error> {
        let given = SETTINGS
            .iter()
            .filter_map(|s| Some((s, matches.get_one::<String>(s.key)?.clone())))
            .collect();
        Ok(Overrides { given })
    }

    fn update_from_arg_matches(
        &mut self,
        matches: &ArgMatches,
    ) -> std::result::Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
    }
}

impl Args for Overrides {
    fn augment_args(command: Command) -> Command {
        SETTINGS.iter().fold(command, |command, s| {
            command.arg(
                Arg::new(s.key)
                    .long(s.key.replace('_', "-"))
                    .value_name("VALUE")
                    .allow_negative_numbers(true)
                    .help(format!("{} [profile]", s.help)),
            )
        })
    }

    fn augment_args_for_update(command: Command) -> Command {
        Self::augment_args(command)
    }
}
