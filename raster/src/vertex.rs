//! Vertices, index buffers and the assembly of triangle strips into triangles.

use crate::fixed_point::TexCoord;

/// One vertex as the host hands it over. Positions are integers in model units (the host folds
/// grid spacing and height scale into the transform), so the fixed path starts exact.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vertex {
    /// Position in model units.
    pub position: [i32; 3],
    /// Texture coordinates, 1.0 spanning the texture once.
    pub uv: [TexCoord; 2],
    /// Colour (or light intensity in all three channels) for Gouraud shading.
    pub color: [u8; 3],
}

impl Vertex {
    /// A vertex from plain numbers; `uv` is in texture repeats.
    pub fn new(position: [i32; 3], uv: [f32; 2], color: [u8; 3]) -> Self {
        Self {
            position,
            uv: uv.map(TexCoord::saturating_from_num),
            color,
        }
    }
}

/// How the index buffer is read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Topology {
    /// Triangle strips: each index after the second makes a triangle with the two before it.
    /// The all-ones index (`0xFFFF` / `0xFFFF_FFFF`) restarts the strip; degenerate triangles
    /// (a repeated index) are dropped before they cost anything.
    TriangleStrip,
    /// Independent triangles, three indices each.
    TriangleList,
}

/// An index buffer in either width.
#[derive(Clone, Copy, Debug)]
pub enum Indices<'a> {
    /// 16-bit indices, restart `0xFFFF`.
    U16(&'a [u16]),
    /// 32-bit indices, restart `0xFFFF_FFFF`.
    U32(&'a [u32]),
}

impl Indices<'_> {
    /// Number of indices.
    pub fn len(&self) -> usize {
        match self {
            Indices::U16(i) => i.len(),
            Indices::U32(i) => i.len(),
        }
    }

    /// True when there are no indices.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index `k` widened, with restart markers as `None`.
    #[inline]
    fn get(&self, k: usize) -> Option<u32> {
        match self {
            Indices::U16(i) => Some(i[k]).filter(|&v| v != u16::MAX).map(u32::from),
            Indices::U32(i) => Some(i[k]).filter(|&v| v != u32::MAX),
        }
    }
}

/// What one draw call renders.
#[derive(Clone, Copy, Debug)]
pub struct Mesh<'a> {
    /// Vertex buffer.
    pub vertices: &'a [Vertex],
    /// Index buffer.
    pub indices: Indices<'a>,
    /// How the indices form triangles.
    pub topology: Topology,
}

/// A triangle as three vertex indices, in the winding the application gave.
pub(crate) type IndexTriangle = [u32; 3];

/// Calls `emit` for every non-degenerate triangle of `mesh`, in order. Strip triangles alternate
/// their vertex order so that every triangle keeps the strip's winding. Returns the first index
/// that is out of range, if any (nothing is emitted after it).
pub(crate) fn assemble(
    mesh: &Mesh,
    mut emit: impl FnMut(IndexTriangle),
) -> Result<(), (usize, u32)> {
    let n = mesh.vertices.len() as u64;
    let check = |k: usize, v: u32| if (v as u64) < n { Ok(v) } else { Err((k, v)) };
    match mesh.topology {
        Topology::TriangleList => {
            for k in (0..mesh.indices.len() / 3).map(|t| t * 3) {
                let (Some(a), Some(b), Some(c)) = (
                    mesh.indices.get(k),
                    mesh.indices.get(k + 1),
                    mesh.indices.get(k + 2),
                ) else {
                    continue;
                };
                let t = [check(k, a)?, check(k + 1, b)?, check(k + 2, c)?];
                if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                    emit(t);
                }
            }
        }
        Topology::TriangleStrip => {
            let mut window = [0u32; 2];
            let mut run = 0usize; // indices since the last restart
            for k in 0..mesh.indices.len() {
                let Some(v) = mesh.indices.get(k) else {
                    run = 0;
                    continue;
                };
                let v = check(k, v)?;
                if run >= 2 {
                    let [a, b] = window;
                    if a != b && b != v && a != v {
                        // Odd triangles of a strip are wound the other way round.
                        emit(if run % 2 == 0 { [a, b, v] } else { [b, a, v] });
                    }
                }
                window = [window[1], v];
                run += 1;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangles(indices: Indices, topology: Topology, n: usize) -> Vec<IndexTriangle> {
        let vertices = vec![Vertex::default(); n];
        let mut out = vec![];
        assemble(
            &Mesh {
                vertices: &vertices,
                indices,
                topology,
            },
            |t| out.push(t),
        )
        .unwrap();
        out
    }

    #[test]
    fn strips_alternate_winding_and_skip_degenerates() {
        let idx = [0u16, 1, 2, 3, 3, 4, 4, 5, 6];
        let t = triangles(Indices::U16(&idx), Topology::TriangleStrip, 7);
        assert_eq!(t, vec![[0, 1, 2], [2, 1, 3], [4, 5, 6]]);
    }

    #[test]
    fn restart_index_starts_a_new_strip_in_both_widths() {
        let t16 = triangles(
            Indices::U16(&[0, 1, 2, 0xFFFF, 3, 4, 5]),
            Topology::TriangleStrip,
            6,
        );
        let t32 = triangles(
            Indices::U32(&[0, 1, 2, u32::MAX, 3, 4, 5]),
            Topology::TriangleStrip,
            6,
        );
        assert_eq!(t16, vec![[0, 1, 2], [3, 4, 5]]);
        assert_eq!(t16, t32);
    }

    #[test]
    fn out_of_range_index_is_reported_with_its_position() {
        let v = vec![Vertex::default(); 3];
        let mesh = Mesh {
            vertices: &v,
            indices: Indices::U32(&[0, 1, 7]),
            topology: Topology::TriangleList,
        };
        assert_eq!(assemble(&mesh, |_| {}), Err((2, 7)));
    }
}
