//! The rasterizer: its settings (threads, tiles, passes, instruction set), the scratch buffers
//! it reuses from draw to draw, and what a draw reports. Its draw calls are in `batch`: a draw
//! is a batch of one, so a single draw and a frame of many take the same path: assembly, the
//! vertex stage once per vertex, set-up in chunks that bin triangles into screen tiles, and
//! tiles drawn in parallel.
//!
//! Determinism: every pixel is computed from its triangles' set-up data alone (coverage, and
//! attribute planes evaluated exactly at the pixel), and each tile draws its triangles in
//! submission order, so any thread count and any batching give the same bytes.

use crate::isa::{Cpu, InstructionSet};
use crate::pending::{Gather, Pending};
use crate::pipeline::Pipeline;
use crate::pipeline::fixed::FixedPipeline;
use crate::pipeline::float::FloatPipeline;
use crate::setup::{ChunkOut, Transformed};

/// Triangles set up and drawn per pass of a flush. A pass ends when its last tile is drawn, and
/// on several threads its last tiles leave the other threads waiting, once per pass, so bigger
/// passes wait fewer times (`examples/pass_size.rs`, docs/raster.md). What they cost is memory: the
/// set-up data of two passes (the one drawn and the next, set up beside it), some 200 bytes a
/// triangle, 13 MB a pass at this size.
pub(crate) const PASS_TRIANGLES: usize = 64 * 1024;
/// Below this many triangles a flush is drawn on the calling thread: handing a smaller flush to
/// a second thread costs more than the thread saves (`examples/split_threshold.rs`, measured in
/// docs/raster.md).
pub(crate) const SPLIT_TRIANGLES: usize = 4096;

/// What a draw did, for statistics and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DrawStats {
    /// Non-degenerate triangles assembled from the indices.
    pub triangles: u64,
    /// Triangles (after clipping, a clipped triangle may count several) that reached the tiles:
    /// they own at least a row of pixels inside the scissor, and a pixel if they have only one
    /// row there (slivers of one row that own none are dropped at set-up).
    pub rasterized: u64,
    /// Pixels written (that passed the depth test).
    pub fragments: u64,
}

impl std::ops::AddAssign for DrawStats {
    fn add_assign(&mut self, o: Self) {
        self.triangles += o.triangles;
        self.rasterized += o.rasterized;
        self.fragments += o.fragments;
    }
}

/// The rasterizer with its scratch buffers, reused from draw to draw.
pub struct Rasterizer {
    pub(crate) gather: Gather,
    pub(crate) pending: Pending,
    pub(crate) fixed: Stages<FixedPipeline>,
    pub(crate) float: Stages<FloatPipeline>,
    threads: Option<usize>,
    /// Fewest triangles a flush needs to be split between threads (`SPLIT_TRIANGLES`).
    split_triangles: usize,
    /// Side of the screen tiles, or by the thread count (`bin::tile_size`) when `None`.
    pub(crate) tile_size: Option<u32>,
    /// Triangles per pass of a flush, `PASS_TRIANGLES` unless set (`with_pass_triangles`).
    pub(crate) pass_triangles: usize,
    /// The loops its flushes run (`with_instruction_set`).
    pub(crate) cpu: Cpu,
}

/// One pipeline's scratch: transformed vertices, and the set-up chunks of two passes (the one
/// being drawn and the next, set up beside it).
pub(crate) struct Stages<P: Pipeline> {
    pub transformed: Vec<Transformed<P>>,
    pub passes: [Vec<ChunkOut<P>>; 2],
    /// A pass's triangles, when a draw is assembled pass by pass (`batch::Source::Mesh`).
    pub assembled: Vec<[u32; 3]>,
}

impl<P: Pipeline> Default for Stages<P> {
    fn default() -> Self {
        Self {
            transformed: Vec::new(),
            passes: [Vec::new(), Vec::new()],
            assembled: Vec::new(),
        }
    }
}

impl Default for Rasterizer {
    fn default() -> Self {
        Self {
            gather: Gather::default(),
            pending: Pending::default(),
            fixed: Stages::default(),
            float: Stages::default(),
            threads: None,
            split_triangles: SPLIT_TRIANGLES,
            tile_size: None,
            pass_triangles: PASS_TRIANGLES,
            cpu: Cpu::new(InstructionSet::Detected),
        }
    }
}

impl std::fmt::Debug for Rasterizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rasterizer")
            .field("threads", &self.threads)
            .field("cpu", &self.cpu)
            .finish_non_exhaustive()
    }
}

impl Rasterizer {
    /// A rasterizer that uses the current rayon pool.
    pub fn new() -> Self {
        Self::default()
    }

    /// A rasterizer that runs on at most `threads` threads of the current rayon pool (1 draws on
    /// the calling thread). The picture does not depend on it.
    pub fn with_threads(threads: usize) -> Self {
        Self {
            threads: Some(threads.max(1)),
            ..Self::default()
        }
    }

    /// A rasterizer that splits a flush between threads only from `triangles` triangles up,
    /// and draws smaller ones on the calling thread. The default is the measured point below
    /// which a second thread costs more than it saves (`examples/split_threshold.rs`); a caller
    /// on another machine can measure its own. The picture does not depend on it.
    pub fn with_split_from(self, triangles: usize) -> Self {
        Self {
            split_triangles: triangles,
            ..self
        }
    }

    /// Sets up and draws a flush in passes of `triangles` triangles (at least 1) instead of the
    /// default 65,536. A pass ends when its last tile is drawn, so on several threads bigger
    /// passes wait less (`examples/pass_size.rs`); the rasterizer keeps the set-up data of two
    /// passes, some 200 bytes a triangle, so a device short of memory may want smaller ones. The
    /// picture does not depend on it.
    pub fn with_pass_triangles(self, triangles: usize) -> Self {
        Self {
            pass_triangles: triangles.max(1),
            ..self
        }
    }

    /// Draws in screen tiles of `side` pixels (rounded up to a power of two from 8 to 8,192)
    /// instead of the default: 128, or 64 where tiles of 128 would give each thread fewer than
    /// eight (`examples/tile_size.rs`). A device with a small data cache may want smaller ones.
    /// The picture does not depend on it.
    pub fn with_tile_size(self, side: u32) -> Self {
        Self {
            tile_size: Some(side.clamp(8, 8192).next_power_of_two()),
            ..self
        }
    }

    /// Restricts the hot loops to the build target's baseline instructions
    /// (`InstructionSet::Baseline`) or lets them use what the CPU has (`Detected`, the
    /// default: AVX2 and its companions on x86-64 CPUs that have them, checked once here). The
    /// picture does not depend on it.
    pub fn with_instruction_set(self, set: InstructionSet) -> Self {
        Self {
            cpu: Cpu::new(set),
            ..self
        }
    }

    /// The threads a flush of `triangles` triangles is drawn on.
    pub(crate) fn thread_count(&self, triangles: usize) -> usize {
        if triangles < self.split_triangles {
            return 1;
        }
        self.threads
            .unwrap_or_else(rayon::current_num_threads)
            .min(rayon::current_num_threads())
            .max(1)
    }
}
