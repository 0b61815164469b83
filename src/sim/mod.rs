//! The laboratory: devices, simulated time and links, flights, statistics, reports and the
//! experiments built on them. The runs that write files and draw plots (`fly`, the demo, the
//! reports, tradeoff, stream-compare) and the TOML device profiles and flights come with the
//! `lab` feature.

pub mod clock;
#[cfg(feature = "lab")]
pub mod crack_metric;
#[cfg(feature = "lab")]
pub mod demo;
pub mod device;
pub mod flight;
#[cfg(feature = "lab")]
pub mod flight_file;
#[cfg(feature = "lab")]
pub mod fly;
#[cfg(feature = "lab")]
pub mod holes;
pub mod hud;
#[cfg(feature = "lab")]
pub mod popping;
pub mod pose;
#[cfg(feature = "lab")]
pub mod report;
#[cfg(feature = "lab")]
pub mod stats;
#[cfg(feature = "lab")]
pub mod stream_compare;
#[cfg(feature = "lab")]
pub mod tradeoff;
#[cfg(feature = "lab")]
pub mod viewer;
