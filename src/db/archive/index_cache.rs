//! The index pages and page-table chunks a reader has fetched, kept up to a byte limit, the
//! least recently used dropped first: what a view needs of the index stays, whatever the
//! archive's size.

use std::collections::HashMap;
use std::sync::Arc;

use super::{IndexEntry, PageRef};

/// A piece of the index: one chunk of a level's page table, or one page.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Piece {
    /// Chunk `chunk` of level `level`'s page table.
    Table { level: u8, chunk: u64 },
    /// Page `page` of level `level`.
    Page { level: u8, page: u64 },
}

/// What a piece holds.
#[derive(Clone, Debug)]
pub enum Held {
    /// A chunk's page references.
    Table(Arc<[PageRef]>),
    /// A page's entries.
    Page(Arc<[IndexEntry]>),
}

impl Held {
    /// Bytes it takes in memory.
    fn bytes(&self) -> usize {
        match self {
            Held::Table(refs) => refs.len() * std::mem::size_of::<PageRef>(),
            Held::Page(entries) => entries
                .iter()
                .map(|e| {
                    std::mem::size_of::<IndexEntry>()
                        + e.levels.len() * std::mem::size_of::<super::LevelEntry>()
                })
                .sum(),
        }
    }
}

/// The cache: pieces with the use they were last put to, and their bytes under a limit.
#[derive(Debug)]
pub struct IndexCache {
    pieces: HashMap<Piece, (Held, u64)>,
    uses: u64,
    bytes: usize,
    limit: usize,
    /// Stored bytes read from the source for pieces, all told.
    read: u64,
}

impl IndexCache {
    /// An empty cache holding at most `limit` bytes (at least the last piece put in).
    pub fn new(limit: usize) -> IndexCache {
        IndexCache {
            pieces: HashMap::new(),
            uses: 0,
            bytes: 0,
            limit,
            read: 0,
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// The limit.
    pub fn limit(&self) -> usize {
        self.limit
    }

    /// Stored bytes read for the pieces ever put in.
    pub fn read(&self) -> u64 {
        self.read
    }

    /// Holds at most `limit` bytes from now on, dropping the least recently used pieces.
    pub fn set_limit(&mut self, limit: usize) {
        self.limit = limit;
        self.trim(None);
    }

    /// The piece, if held; counts as a use.
    pub fn get(&mut self, piece: Piece) -> Option<Held> {
        self.uses += 1;
        let uses = self.uses;
        self.pieces.get_mut(&piece).map(|(held, used)| {
            *used = uses;
            held.clone()
        })
    }

    /// Holds `held` as `piece`, read with `stored` bytes, dropping the least recently used
    /// other pieces while over the limit.
    pub fn put(&mut self, piece: Piece, held: Held, stored: u64) {
        self.uses += 1;
        self.read += stored;
        self.bytes += held.bytes();
        if let Some((old, _)) = self.pieces.insert(piece, (held, self.uses)) {
            self.bytes -= old.bytes();
        }
        self.trim(Some(piece));
    }

    /// Drops the least recently used pieces but `keep` while over the limit.
    fn trim(&mut self, keep: Option<Piece>) {
        while self.bytes > self.limit {
            let oldest = self
                .pieces
                .iter()
                .filter(|(p, _)| Some(**p) != keep)
                .min_by_key(|(_, (_, used))| *used)
                .map(|(p, _)| *p);
            let Some(piece) = oldest else {
                return;
            };
            if let Some((held, _)) = self.pieces.remove(&piece) {
                self.bytes -= held.bytes();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn page(n: usize) -> Held {
        Held::Page(vec![IndexEntry::absent(3); n].into())
    }

    #[test]
    fn the_least_recently_used_pieces_go_first_and_the_bytes_stay_under_the_limit() {
        let one = page(4).bytes();
        let mut cache = IndexCache::new(2 * one);
        let p = |k: u64| Piece::Page { level: 0, page: k };
        cache.put(p(1), page(4), 10);
        cache.put(p(2), page(4), 10);
        assert!(cache.get(p(1)).is_some());
        cache.put(p(3), page(4), 10);
        assert!(cache.get(p(2)).is_none(), "page 2 was used least recently");
        assert!(cache.get(p(1)).is_some() && cache.get(p(3)).is_some());
        assert_eq!((cache.bytes(), cache.read()), (2 * one, 30));
        cache.set_limit(one);
        assert_eq!(cache.bytes(), one);
        assert!(cache.get(p(3)).is_some(), "the most recent piece stays");
    }

    #[test]
    fn a_piece_larger_than_the_limit_is_still_held_until_the_next() {
        let mut cache = IndexCache::new(1);
        let t = Piece::Table { level: 2, chunk: 0 };
        cache.put(t, Held::Table(vec![PageRef::default(); 8].into()), 132);
        assert!(cache.get(t).is_some());
        cache.put(Piece::Page { level: 0, page: 0 }, page(1), 72);
        assert!(cache.get(t).is_none());
    }
}
