//! Settings chosen by name. Each type says once what its values are called, and everything that
//! reads a name — the command line (its possible values and help), TOML files — asks it.

use stripmask_platform::Fit;
use stripmask_raster::ColorFormat;

use crate::error::{Error, Result};

/// A setting whose values have names, such as [`crate::engine::cracks::CrackMode`]
/// (`none`, `shadow`, `skirts`, `stitch`).
pub trait Named: Sized + Clone + 'static {
    /// What a value is, in messages: `"crack mode"`.
    const KIND: &'static str;

    /// Every value, in the order a list of them shows; a value that carries settings comes with
    /// their defaults.
    fn all() -> Vec<Self>;

    /// This value's name.
    fn name(&self) -> &'static str;

    /// The value called `name`, or an [`Error::InvalidSetting`] that lists the names.
    fn from_name(name: &str) -> Result<Self> {
        let all = Self::all();
        all.iter()
            .find(|v| v.name() == name)
            .cloned()
            .ok_or_else(|| {
                let names: Vec<&str> = all.iter().map(Self::name).collect();
                Error::setting(Self::KIND, name, format!("one of {}", names.join(", ")))
            })
    }
}

/// Implements [`Named`] for an enum of unit variants from its kind and each variant's name, in
/// the order [`Named::all`] lists them.
macro_rules! named_enum {
    ($type:ident, $kind:literal, { $($variant:ident => $name:literal),+ $(,)? }) => {
        impl $crate::named::Named for $type {
            const KIND: &'static str = $kind;

            fn all() -> Vec<Self> {
                vec![$($type::$variant),+]
            }

            fn name(&self) -> &'static str {
                match self {
                    $($type::$variant => $name),+
                }
            }
        }
    };
}

pub(crate) use named_enum;

// The rasterizer's colour formats, as device profiles and the command line name them.
named_enum!(ColorFormat, "colour format", {
    Rgb565 => "rgb565",
    Rgba8888 => "rgba8888",
});

// How a presenter fits a frame to a screen of another size, as the command line names it.
named_enum!(Fit, "fit", { Center => "center", Scale => "scale" });

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_an_unknown_one_lists_them() {
        for format in ColorFormat::all() {
            assert_eq!(ColorFormat::from_name(format.name()).unwrap(), format);
        }
        let e = Fit::from_name("stretch").unwrap_err();
        assert!(e.is_usage());
        assert_eq!(e.to_string(), "fit stretch: expected one of center, scale");
    }
}
