//! The paper's planar shadows: under each tile a quad of two triangles, its corners projected
//! from the viewpoint onto a horizontal plane just below the tile, textured like the tile.
//!
//! A corner `P` goes to `P' = eye + (P - eye) (eye.y - y) / (eye.y - P.y)` on the plane at
//! height `y`: on screen it lands where `P` does, only farther away. The shadow therefore covers
//! the screen quadrilateral of the tile's corners behind the tile itself, and the depth test
//! (or, without one, drawing every shadow before the tiles) lets it show only where the tile and
//! its neighbours leave a gap. Projected corners fall between grid points, so shadow vertices
//! are in [`SUBDIVISION`]ths of a grid step and of a height quantum, drawn with their own frame
//! transform.
//!
//! Where it fails: the projection needs the eye above every corner. When the eye is at or
//! below a corner, or so little above it that the corner would be thrown more than
//! [`MAX_STRETCH`] times its distance from the eye, the quad is skipped and that tile's cracks
//! stay open: low, grazing views over relief higher than the eye. The quad's edges are
//! straight between the corners, so a crack along a border that bulges out of that quadrilateral
//! on screen is not covered either, and a shadow quad is flat: what shows through a crack is
//! the texture stretched on a plane, not the missing relief.

use glam::DVec3;
use stripmask_raster::Vertex;

/// Shadow vertices count positions in 1/256 of a grid step and of a height quantum.
pub const SUBDIVISION: i32 = 256;

/// The farthest a corner is thrown, as a multiple of its distance from the eye; beyond, the view
/// is grazing and the quad is skipped.
pub const MAX_STRETCH: f64 = 64.0;

/// How far below the tile's lowest sample the shadow plane lies, in quanta.
const DEPTH_QUANTA: f64 = 1.0;

/// The shadow quad of a tile whose held grid (whole or partial: its corners are held at every
/// level) is `grid`, row-major with `side` samples per side, seen from `eye`, given in
/// whole-tile grid units (`(i, quanta, j)` with the tile's north-west sample at height 0 as
/// origin), as vertices in [`SUBDIVISION`] units: north-west, north-east, south-west,
/// south-east. `None` at grazing angles (see the module documentation).
pub fn quad(grid: &[Vertex], side: usize, eye: DVec3) -> Option<[Vertex; 4]> {
    let s = side;
    let plane = f64::from(
        grid[..s * s]
            .iter()
            .map(|v| v.position[1])
            .min()
            .expect("a tile has vertices"),
    ) - DEPTH_QUANTA;
    let corners = corners(s).map(|k| grid[k]);
    let mut out = corners;
    for (v, corner) in out.iter_mut().zip(corners) {
        let p = DVec3::from_array(corner.position.map(f64::from));
        let above = eye.y - p.y;
        let stretch = (eye.y - plane) / above;
        if above <= 0.0 || stretch > MAX_STRETCH {
            return None;
        }
        let projected = (eye + (p - eye) * stretch) * f64::from(SUBDIVISION);
        v.position = projected.round().as_ivec3().to_array();
    }
    Some(out)
}

/// The grid indices of a tile's corners, `side` samples per side, in [`quad`]'s order.
pub fn corners(side: usize) -> [usize; 4] {
    let last = side - 1;
    [0, last, last * side, last * side + last]
}

/// Indices of the quad as one clockwise strip over [`quad`]'s vertex order, as the masks wind.
pub const QUAD_STRIP: [u16; 4] = [2, 0, 3, 1];

#[cfg(test)]
mod tests {
    use super::*;

    /// A 5 x 5 grid with heights 10 ..= 16 quanta, each vertex its own texel and colour.
    fn grid() -> Vec<Vertex> {
        (0..25i32)
            .map(|k| {
                let t = k as u8;
                Vertex::new(
                    [k % 5, 10 + k % 7, k / 5],
                    [k as f32 / 25.0, k as f32 / 50.0],
                    [t, 2 * t, 3 * t],
                )
            })
            .collect()
    }

    #[test]
    fn corners_go_along_their_eye_ray_onto_the_plane_below_the_tile() {
        let grid = grid();
        let eye = DVec3::new(1.0, 400.0, 9.0);
        let q = quad(&grid, 5, eye).unwrap();
        let low = grid.iter().map(|v| v.position[1]).min().unwrap();
        let sub = f64::from(SUBDIVISION);
        for (v, k) in q.iter().zip([0, 4, 20, 24]) {
            let corner = DVec3::from_array(grid[k].position.map(f64::from));
            let p = DVec3::from_array(v.position.map(f64::from)) / sub;
            assert!((p.y - (f64::from(low) - DEPTH_QUANTA)).abs() <= 0.5 / sub);
            let (a, b) = ((corner - eye).normalize(), (p - eye).normalize());
            assert!(a.dot(b) > 1.0 - 1e-9, "corner {k} off its ray");
            assert!((p - eye).length() > (corner - eye).length());
            assert_eq!((v.uv, v.color), (grid[k].uv, grid[k].color));
        }
    }

    #[test]
    fn no_quad_when_the_eye_is_not_above_every_corner_or_the_view_grazes() {
        let grid = grid();
        let top = f64::from(grid.iter().map(|v| v.position[1]).max().unwrap());
        assert!(quad(&grid, 5, DVec3::new(2.0, top, 2.0)).is_none());
        assert!(quad(&grid, 5, DVec3::new(2.0, top - 10.0, 2.0)).is_none());
        assert!(quad(&grid, 5, DVec3::new(2.0, top + 0.01, 2.0)).is_none());
        assert!(quad(&grid, 5, DVec3::new(2.0, top + 100.0, 2.0)).is_some());
    }
}
