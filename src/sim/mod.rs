//! The laboratory: devices, simulated time and links, flights, statistics, reports and the
//! experiments built on them.

pub mod clock;
pub mod crack_metric;
pub mod demo;
pub mod device;
pub mod flight;
pub mod fly;
pub mod holes;
pub mod hud;
pub mod popping;
pub mod pose;
pub mod report;
pub mod stats;
pub mod stream_compare;
pub mod tradeoff;
pub mod viewer;
