//! The terrain database: elevation models in, tiles cut and encoded, one archive out, and the
//! sources that read it back.

pub mod archive;
pub mod backoff;
pub mod builder;
pub mod dem;
pub mod georef;
pub mod grid;
pub mod level_error;
pub mod mask_level;
pub mod pyramid;
pub mod rgb565;
#[cfg(feature = "server")]
pub mod server;
pub mod source;
pub mod texture_gen;
pub mod tile;
pub mod tiling;
