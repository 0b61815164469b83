//! From a draw list to pixels: one shared eye-relative matrix, one integer origin per tile, and
//! a draw order that suits the depth mode.
//!
//! The matrix is built in f64 around an *anchor* tile (the one under the eye): world positions
//! are never formed, only `anchor origin - eye`, which is small wherever the terrain sits in the
//! world. Each tile then draws with the same matrix and the integer offset of its grid position
//! from the anchor (`Transform::with_origin`), so shared border vertices of neighbouring tiles
//! land on bit-identical sub-pixel positions and no crack opens between tiles at the same level.

use glam::{DMat4, DVec3};
use stripmask_raster::{
    CullMode, DepthMode, DrawBatch, DrawStats, DrawTarget, Fog, Indices, LineDepth, LineState,
    LineStats, Mesh, Perspective, Precision, RasterError, RenderState, Sampler, Shading,
    TextureBinding, Topology, Transform, Vertex,
};

use crate::db::grid::TileId;
use crate::db::tile::PartialGrid;
use crate::engine::camera::View;
use crate::engine::cracks::{CrackMode, TileIndices, shadow};
use crate::engine::geomorph::{self, MorphView, Morpher};
use crate::engine::masks::{FRONT_FACE, MaskSet};
use crate::engine::partial_meshes::{PartialMeshes, compact_level};
use crate::engine::resident::ResidentTile;
use crate::engine::terrain::TerrainFrame;

/// Whether the tiles' triangle edges are drawn (the viewer's L key cycles through these).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wireframe {
    /// Shaded terrain only: no line is drawn and nothing is paid.
    #[default]
    Off,
    /// The edges in [`Wireframe::OVER_COLOR`] over the shaded terrain.
    Over,
    /// The edges in [`Wireframe::ONLY_COLOR`] over the terrain filled in white (untextured,
    /// unlit, no fog): a hidden-line drawing of the triangles alone.
    Only,
}

impl Wireframe {
    /// Line colour over the shaded terrain.
    pub const OVER_COLOR: [u8; 3] = [255, 255, 255];
    /// Line colour over the white terrain.
    pub const ONLY_COLOR: [u8; 3] = [24, 24, 48];

    /// The next mode: off, over, only, off.
    pub fn next(self) -> Wireframe {
        match self {
            Wireframe::Off => Wireframe::Over,
            Wireframe::Over => Wireframe::Only,
            Wireframe::Only => Wireframe::Off,
        }
    }

    /// The lines' state, `None` when off.
    fn lines(self, depth_test: bool) -> Option<LineState> {
        let color = match self {
            Wireframe::Off => return None,
            Wireframe::Over => Wireframe::OVER_COLOR,
            Wireframe::Only => Wireframe::ONLY_COLOR,
        };
        Some(LineState {
            color,
            // In painter's order each tile's edges are drawn right after it, and nearer tiles
            // drawn later cover them: no depth test needed (the depth buffer is not written).
            depth: if depth_test {
                LineDepth::ON_SURFACE
            } else {
                LineDepth::Always
            },
            scissor: None,
        })
    }
}

/// The rendering knobs a user trades speed for accuracy with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Fixed-point or f32 pipeline.
    pub precision: Precision,
    /// Perspective correction of texture coordinates.
    pub perspective: Perspective,
    /// Texture sampling; `None` draws untextured (shading colour only).
    pub sampler: Option<Sampler>,
    /// Per-vertex lighting (Gouraud) over the texture. Off by default: the archive's textures
    /// carry the hill shading, prefiltered in their mips, so the texture alone shades the terrain
    /// continuously where tiles of different levels meet, whose vertex normals (each level's
    /// own grid) differ. Without a texture the terrain is lit whatever this says.
    pub lighting: bool,
    /// Depth test: tiles drawn front to back. Off: back to front, painter's order.
    pub depth_test: bool,
    /// Distance fog towards the sky colour, starting at `fog_start` of the far distance.
    pub fog: bool,
    /// Where fog starts, as a fraction of the far plane.
    pub fog_start: f64,
    /// Background and fog colour.
    pub sky: [u8; 3],
    /// The tiles' triangle edges over (or instead of) the shaded terrain.
    pub wireframe: Wireframe,
}

impl RenderSettings {
    /// Whether the surface is drawn with vertex lighting: when asked for, or without a
    /// texture; never under the plain white of a wireframe alone. Tiles hold their normals
    /// and shades only while it is.
    pub fn lights_vertices(&self) -> bool {
        match self.wireframe {
            Wireframe::Only => false,
            Wireframe::Off | Wireframe::Over => self.lighting || self.sampler.is_none(),
        }
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            precision: Precision::Fixed,
            perspective: Perspective::Spans(16),
            sampler: Some(Sampler::BILINEAR_MIPMAP),
            lighting: false,
            depth_test: true,
            fog: true,
            fog_start: 0.6,
            sky: [150, 180, 215],
            wireframe: Wireframe::Off,
        }
    }
}

/// One tile in the draw list.
#[derive(Clone, Copy, Debug)]
pub struct TileDraw<'a> {
    /// Which tile of the pyramid.
    pub id: TileId,
    /// Its resident data.
    pub tile: &'a ResidentTile,
    /// The strip-mask level chosen for it, a whole-tile level (see [`crate::engine::partial_meshes`] for
    /// how a partial tile draws it; `level + 1` must then be a multiple of its stride).
    pub level: usize,
    /// The whole-tile levels of its neighbours this frame (`crate::engine::cracks::Side::ALL`
    /// order), counted in its own samples
    /// ([`neighbour_levels`](crate::engine::cracks::neighbours::neighbour_levels)).
    pub neighbours: [usize; 4],
    /// Eye distance to its bounding box, metres: the draw order key.
    pub distance: f64,
}

/// The shared part of every tile's transform this frame.
#[derive(Clone, Copy, Debug)]
pub struct FrameTransform {
    base: Transform,
    anchor: (i64, i64),
    cells: i64,
}

impl FrameTransform {
    /// The matrix for `view` over `terrain`, for vertices in grid steps and height quanta.
    pub fn new(view: &View, terrain: &TerrainFrame) -> Result<FrameTransform, RasterError> {
        FrameTransform::subdivided(view, terrain, 1)
    }

    /// The same for vertices in `1 / subdivision` of a grid step and of a height quantum.
    pub fn subdivided(
        view: &View,
        terrain: &TerrainFrame,
        subdivision: i32,
    ) -> Result<FrameTransform, RasterError> {
        let camera = &view.camera;
        let unit = 1.0 / f64::from(subdivision);
        let (px, py) = terrain.tile_position(camera.position);
        let clamp = |v: f64, n: u32| (v.floor().max(0.0) as i64).min(i64::from(n) - 1);
        let anchor = (clamp(px, terrain.tiles_x), clamp(py, terrain.tiles_y));
        let origin = terrain.tile_origin(TileId::new(anchor.0 as u32, anchor.1 as u32));
        let model = DMat4::from_translation(origin - camera.position)
            * DMat4::from_scale(
                DVec3::new(terrain.spacing, terrain.quantum, terrain.spacing) * unit,
            );
        Ok(FrameTransform {
            base: Transform::new(view.view_projection() * model)?,
            anchor,
            cells: (terrain.tile_size as i64 - 1) * i64::from(subdivision),
        })
    }

    /// Tile `id`'s transform: the shared matrix with the integer offset of the tile's
    /// north-west sample (a tile of level `k` starts at level-0 tile `2^k` times its column and
    /// row).
    pub fn tile(&self, id: TileId) -> Result<Transform, RasterError> {
        let span = i64::from(id.span());
        let offset = |t: u32, a: i64| {
            ((i64::from(t) * span - a) * self.cells).clamp(i32::MIN.into(), i32::MAX.into()) as i32
        };
        self.base
            .with_origin([offset(id.x, self.anchor.0), 0, offset(id.y, self.anchor.1)])
    }
}

/// The indices every tile is drawn with: the shared strip masks, and the crack mode's pieces.
pub struct TileMeshes<'m> {
    /// The strip masks of whole tiles.
    pub masks: &'m MaskSet,
    /// The crack mode's index buffers for whole tiles.
    pub cracks: &'m mut TileIndices,
    /// The masks and crack pieces of partial tiles, kept between frames; `None` builds them for
    /// this frame only when a partial tile is drawn.
    pub partial: Option<&'m mut PartialMeshes>,
    /// The geomorph state when geomorphing is on: tiles, whole or partial, are then drawn
    /// morphed, in [`geomorph::SUBDIVISION`] units.
    pub morph: Option<&'m mut Morpher>,
}

/// What drawing a frame's tiles did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TilesDrawn {
    /// The triangles: tiles and the crack mode's geometry.
    pub triangles: DrawStats,
    /// The wireframe's lines (zero when it is off).
    pub lines: LineStats,
}

/// Clears `target` to the sky and draws `tiles` (reordered for the depth mode) into it, each
/// followed by its wireframe when that is on: the CPU rasterizer's framebuffer or any other
/// [`DrawTarget`], with the same draws.
pub fn draw_tiles<T: DrawTarget>(
    target: &mut T,
    view: &View,
    terrain: &TerrainFrame,
    tiles: &mut [TileDraw<'_>],
    meshes: TileMeshes<'_>,
    settings: &RenderSettings,
) -> Result<TilesDrawn, T::Error> {
    target.clear(settings.sky);
    let transform = FrameTransform::new(view, terrain)?;
    if settings.depth_test {
        tiles.sort_by(|a, b| a.distance.total_cmp(&b.distance));
    } else {
        tiles.sort_by(|a, b| b.distance.total_cmp(&a.distance));
    }
    let fog = settings.fog.then_some(Fog {
        color: settings.sky,
        start: settings.fog_start * view.far,
        end: view.far,
    });
    let shadows = meshes.cracks.mode() == CrackMode::Shadow;
    let wire = settings.wireframe.lines(settings.depth_test);
    let (surface, fog) = surface_settings(settings, fog);
    let settings = &surface;
    // One batch for the frame's draws: the CPU rasterizer sets them up and bins them into
    // screen tiles together, instead of paying for threads and tiles per tile draw.
    let ((stats, lines), done) = target.batch(|target| {
        let mut stats = DrawStats::default();
        let mut lines = LineStats::default();
        if shadows && !settings.depth_test {
            stats += draw_shadows(target, view, terrain, tiles, settings, fog)?;
        }
        let mut morph = match meshes.morph {
            Some(morpher) => Some((
                morpher.view(view, terrain),
                FrameTransform::subdivided(view, terrain, geomorph::SUBDIVISION)?,
                morpher,
            )),
            None => None,
        };
        let mode = meshes.cracks.mode();
        let mut frame_held = PartialMeshes::new();
        let held = meshes.partial.unwrap_or(&mut frame_held);
        // The vertices of a tile lit for a coarser level than it holds, reused tile after tile.
        let mut relit = Vec::new();
        for t in tiles.iter() {
            let stride = t.tile.stride();
            let (indices, topology) = if stride == 1 {
                meshes.cracks.tile(meshes.masks, t.level, t.neighbours)
            } else {
                partial_indices(held, mode, t)
            };
            let lit = drawn_vertices(t, settings.lighting, &mut relit);
            let (vertices, tile_transform) = match &mut morph {
                Some((view, fine, morpher)) => (morphed(morpher, view, t, lit), fine.tile(t.id)?),
                None => (lit, transform.tile(t.id)?),
            };
            let mesh = Mesh {
                vertices,
                indices,
                topology,
            };
            stats += target.draw(&mesh, &tile_transform, &tile_state(settings, fog, t))?;
            if let Some(wire) = &wire {
                lines += target.draw_edges(&mesh, &tile_transform, wire)?;
            }
        }
        if shadows && settings.depth_test {
            stats += draw_shadows(target, view, terrain, tiles, settings, fog)?;
        }
        Ok((stats, lines))
    })?;
    let mut triangles = stats;
    triangles += done;
    Ok(TilesDrawn { triangles, lines })
}

/// The render state of the terrain surface and its fog: as set (lit when untextured), or, with
/// only the wireframe shown, plain white without texture, lighting or fog under the lines.
fn surface_settings(settings: &RenderSettings, fog: Option<Fog>) -> (RenderSettings, Option<Fog>) {
    match settings.wireframe {
        Wireframe::Only => (
            RenderSettings {
                sampler: None,
                lighting: false,
                fog: false,
                ..*settings
            },
            None,
        ),
        Wireframe::Off | Wireframe::Over => (
            RenderSettings {
                lighting: settings.lights_vertices(),
                ..*settings
            },
            fog,
        ),
    }
}

/// Tile `t`'s `vertices` (lit for its level; the grid it holds, whole or partial) morphed for
/// this frame, only the samples its level's mask reads (its stitches read a subset of them).
fn morphed<'m>(
    morpher: &'m mut Morpher,
    view: &MorphView,
    t: &TileDraw<'_>,
    vertices: &[Vertex],
) -> &'m [Vertex] {
    morpher.tile(view, vertices, t.id, t.level, t.tile.stride())
}

/// The strip indices of partial tile `t` (levels held at a stride above one): its levels and
/// its neighbours' counted in the tile's own compact grid.
fn partial_indices<'h>(
    held: &'h mut PartialMeshes,
    mode: CrackMode,
    t: &TileDraw<'_>,
) -> (Indices<'h>, Topology) {
    let stride = t.tile.stride();
    let (masks, cracks) = held.get(mode, t.tile.side());
    let neighbours = t.neighbours.map(|n| compact_level(n, stride));
    cracks.tile(masks, compact_level(t.level, stride), neighbours)
}

/// The vertices of `t` as drawn at its level: lit for that level when the surface is `lit`,
/// else as held, whose colours the draw does not read (so an unlit frame lights nothing).
fn drawn_vertices<'v>(t: &TileDraw<'v>, lit: bool, scratch: &'v mut Vec<Vertex>) -> &'v [Vertex] {
    if lit {
        t.tile.lit_vertices(t.level, scratch)
    } else {
        &t.tile.vertices
    }
}

/// Draws the shadow quad of every tile in `tiles` ([`crate::engine::cracks::shadow`]), in their order,
/// with each tile's render state; a quad that grazes or lies beyond the subdivided transform's
/// reach is skipped.
fn draw_shadows<'t, E: From<RasterError>>(
    target: &mut dyn DrawBatch<'t, Error = E>,
    view: &View,
    terrain: &TerrainFrame,
    tiles: &[TileDraw<'t>],
    settings: &RenderSettings,
    fog: Option<Fog>,
) -> Result<DrawStats, E> {
    let camera = &view.camera;
    let fine = FrameTransform::subdivided(view, terrain, shadow::SUBDIVISION)?;
    let mut stats = DrawStats::default();
    let mut relit = Vec::new();
    for t in tiles {
        let origin = terrain.tile_origin(t.id);
        let eye = (camera.position - origin)
            / DVec3::new(terrain.spacing, terrain.quantum, terrain.spacing);
        let (Some(mut vertices), Ok(transform)) = (
            shadow::quad(&t.tile.vertices, t.tile.side(), eye),
            fine.tile(t.id),
        ) else {
            continue;
        };
        // Lit like the tile's corners at the level it is drawn at.
        let lit = drawn_vertices(t, settings.lighting, &mut relit);
        for (v, k) in vertices.iter_mut().zip(shadow::corners(t.tile.side())) {
            v.color = lit[k].color;
        }
        let mesh = Mesh {
            vertices: &vertices,
            indices: Indices::U16(&shadow::QUAD_STRIP),
            topology: Topology::TriangleStrip,
        };
        stats += target.draw(&mesh, &transform, &tile_state(settings, fog, t))?;
    }
    Ok(stats)
}

/// The render state of a tile's draws. Its texture's mip is chosen per triangle by its size on
/// screen, whatever the tile's mask level, so that two tiles drawn at different levels (or of
/// different levels of the pyramid) show the same texels where they meet.
fn tile_state<'t>(
    settings: &RenderSettings,
    fog: Option<Fog>,
    draw: &TileDraw<'t>,
) -> RenderState<'t> {
    let tile = draw.tile;
    RenderState {
        precision: settings.precision,
        cull: CullMode::Back,
        front_face: FRONT_FACE,
        depth: if settings.depth_test {
            DepthMode::LESS_WRITE
        } else {
            DepthMode::NONE
        },
        shading: if settings.lighting {
            Shading::Gouraud
        } else {
            Shading::Flat([255; 3])
        },
        texture: settings
            .sampler
            .map(|sampler| TextureBinding::new(&tile.texture, sampler)),
        perspective: settings.perspective,
        fog,
        ..RenderState::default()
    }
}
