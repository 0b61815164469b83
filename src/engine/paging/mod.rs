//! Paging: which tiles are resident, fetched beside the frame loop under a memory limit.
//!
//! Two strategies share one core. [`BeltPager`] is the paper's: Algorithm 1 ([`belts`]) keeps
//! the largest complete square of belts of whole level-0 tiles that fits the limit — the near
//! field — and the tiles of the pyramid's levels above that the frame's cut asks for come
//! whole beside it (`far.rs`). [`StreamPager`] streams progressive levels of the tiles of every
//! level as the view needs them ([`stream`]). Both keep the top of the pyramid resident
//! (`top.rs`), and both hold a [`Residency`] — the [`Ledger`] that accounts every byte before it
//! is fetched, the resident tiles, the viewpoint's tile and square, and the counters — and send
//! their requests over a [`Link`]: a fetch thread ([`PagerMode::Threaded`]) or,
//! deterministically, this thread ([`PagerMode::Stepped`], [`PagerMode::Simulated`]). Each
//! keeps only what differs: what to fetch next and how an arrival joins the resident tile. The
//! engine drives either through the [`Paging`] trait.

mod belt_pager;
pub mod belts;
mod config;
mod far;
mod ledger;
mod link;
mod loader;
mod meminfo;
mod pager;
mod residency;
pub mod stream;
mod top;
mod worker;

pub use belt_pager::{BeltPager, Belts, TileLoader};
pub use config::{PagerConfig, PagerMode, TransferClock};
pub use far::{FAR_SHARE, far_share};
pub use ledger::{Failure, Fetch, Ledger, Loaded, Record, Reservation, RetryPolicy};
pub use link::{Link, Received};
pub use loader::ArchiveLoader;
pub use meminfo::{memory_limit_from_available, parse_mem_available};
pub use pager::{Pager, Paging, ResidentLoader, Strategy};
pub use residency::{FIRST_ERRORS, PagerStats, Residency, TileState};
pub use stream::{Progressive, StreamPager, StreamStats};
pub use worker::{Job, Request};
