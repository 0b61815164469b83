//! How the memory limit is shared before paging starts: the archive's top and its index pages.

use crate::db::grid::Pyramid;
use crate::engine::paging::{ArchiveLoader, ResidentLoader};
use crate::engine::settings::EngineSettings;

/// The most of the memory limit the top may take: the rest is for paging.
pub(super) const TOP_SHARE: usize = 4;

/// The most of the memory limit set aside for the archive's index pages, and at most
/// [`MAX_INDEX_BYTES`]: a view's pages, a few kilobytes each.
pub(super) const INDEX_SHARE: usize = 16;

/// The most bytes set aside for the archive's index pages: a few hundred pages.
pub(super) const MAX_INDEX_BYTES: usize = 1 << 20;

/// The bytes the engine sets aside for the archive's index pages under a memory limit of
/// `limit` bytes.
pub fn index_allowance(limit: usize) -> usize {
    (limit / INDEX_SHARE).min(MAX_INDEX_BYTES)
}

/// Which levels of the archive's top the engine keeps: all of them, fewer (the root and the
/// levels just below it) while they would take more than a quarter of the memory limit, none
/// when even the root would.
pub(super) fn choose_top(loader: &mut ArchiveLoader, settings: &EngineSettings, pyramid: &Pyramid) {
    let root = pyramid.root().level;
    let mut level = loader.use_top(Some(0));
    while let Some(l) = level {
        if loader.top_bytes() <= settings.memory_limit_bytes / TOP_SHARE {
            return;
        }
        level = if l < root {
            loader.use_top(Some(l + 1))
        } else {
            loader.use_top(None)
        };
    }
}
