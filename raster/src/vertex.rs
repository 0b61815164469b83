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
    Assembly::default().resume(mesh, |t| {
        emit(t);
        true
    })
}

/// True when every index of `mesh` but the restart marker is below its vertex count, so that
/// `assemble` cannot fail on it: a draw whose triangles are assembled while it is drawn is
/// checked before any of its pixels (one pass over the indices, where assembling them all would
/// run alone before any tile).
pub(crate) fn indices_in_range(mesh: &Mesh) -> bool {
    let n = mesh.vertices.len() as u64;
    // The marker (all ones) wraps to 0 when one is added: the largest index plus one, in one
    // maximum the compiler keeps in lanes.
    let most = match mesh.indices {
        Indices::U16(i) => i.iter().map(|&v| v.wrapping_add(1)).max().map(u64::from),
        Indices::U32(i) => i.iter().map(|&v| v.wrapping_add(1)).max().map(u64::from),
    };
    most.is_none_or(|m| m <= n)
}

/// Where an assembly of a mesh's indices stands, so that it can stop after any triangle and go
/// on later: a big draw is assembled pass by pass while the tiles of the pass before are drawn.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Assembly {
    /// The next index to read.
    next: usize,
    /// A strip's last two indices, and how many indices it has read since its last restart.
    window: [u32; 2],
    run: usize,
}

impl Assembly {
    /// True when every triangle of `mesh` has been emitted.
    pub fn done(&self, mesh: &Mesh) -> bool {
        let len = mesh.indices.len();
        match mesh.topology {
            Topology::TriangleList => self.next + 3 > len,
            Topology::TriangleStrip => self.next >= len,
        }
    }

    /// Goes on with `mesh` where the last call stopped, calling `emit` for every non-degenerate
    /// triangle until it returns false or the indices end (see `assemble`). Returns the first
    /// index that is out of range, if any.
    pub fn resume(
        &mut self,
        mesh: &Mesh,
        mut emit: impl FnMut(IndexTriangle) -> bool,
    ) -> Result<(), (usize, u32)> {
        let n = mesh.vertices.len() as u64;
        let check = |k: usize, v: u32| if (v as u64) < n { Ok(v) } else { Err((k, v)) };
        let len = mesh.indices.len();
        // In locals while the loop runs: `emit` may not see them, but the compiler would store
        // them at every index if they stayed in `self`.
        let (mut k, mut more) = (self.next, true);
        match mesh.topology {
            Topology::TriangleList => {
                while more && k + 3 <= len {
                    let (a, b, c) = (
                        mesh.indices.get(k),
                        mesh.indices.get(k + 1),
                        mesh.indices.get(k + 2),
                    );
                    k += 3;
                    let (Some(a), Some(b), Some(c)) = (a, b, c) else {
                        continue;
                    };
                    let t = [check(k - 3, a)?, check(k - 2, b)?, check(k - 1, c)?];
                    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                        more = emit(t);
                    }
                }
            }
            Topology::TriangleStrip => {
                let (mut window, mut run) = (self.window, self.run);
                while more && k < len {
                    let v = mesh.indices.get(k);
                    k += 1;
                    let Some(v) = v else {
                        run = 0;
                        continue;
                    };
                    let v = check(k - 1, v)?;
                    if run >= 2 {
                        let [a, b] = window;
                        if a != b && b != v && a != v {
                            // Odd triangles of a strip are wound the other way round.
                            more = emit(if run % 2 == 0 { [a, b, v] } else { [b, a, v] });
                        }
                    }
                    window = [window[1], v];
                    run += 1;
                }
                (self.window, self.run) = (window, run);
            }
        }
        self.next = k;
        Ok(())
    }
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

    /// A mesh over `v` with the indices `i32` (`u32::MAX` restarts), or the same in 16 bits
    /// (`i16`).
    fn with_indices<'a>(
        v: &'a [Vertex],
        (i16, i32): (&'a [u16], &'a [u32]),
        wide: bool,
        topology: Topology,
    ) -> Mesh<'a> {
        Mesh {
            vertices: v,
            indices: if wide {
                Indices::U32(i32)
            } else {
                Indices::U16(i16)
            },
            topology,
        }
    }

    /// Up to `most` indices below `below`, with a restart about every ninth.
    fn some_indices(
        below: u32,
        most: usize,
    ) -> impl proptest::strategy::Strategy<Value = Vec<u32>> {
        proptest::collection::vec(
            proptest::prop_oneof![8 => 0..below, 1 => proptest::strategy::Just(u32::MAX)],
            0..most,
        )
    }

    fn narrow(indices: &[u32]) -> Vec<u16> {
        indices
            .iter()
            .map(|&i| if i == u32::MAX { u16::MAX } else { i as u16 })
            .collect()
    }

    proptest::proptest! {
        /// Assembled in pieces of any size, each going on where the last stopped, a mesh gives
        /// the triangles of one assembly, and the assembly is done after the last.
        #[test]
        fn an_assembly_resumed_in_pieces_equals_one_assembly(
            indices in some_indices(12, 80),
            piece in 1usize..10,
            strip: bool,
            wide: bool,
        ) {
            let v = vec![Vertex::default(); 12];
            let short = narrow(&indices);
            let topology = if strip { Topology::TriangleStrip } else { Topology::TriangleList };
            let mesh = with_indices(&v, (&short, &indices), wide, topology);
            let mut whole = vec![];
            assemble(&mesh, |t| whole.push(t)).unwrap();
            let (mut a, mut pieces) = (Assembly::default(), vec![]);
            while !a.done(&mesh) {
                let before = pieces.len();
                a.resume(&mesh, |t| {
                    pieces.push(t);
                    pieces.len() - before < piece
                })
                .unwrap();
                proptest::prop_assert!(pieces.len() - before == piece || a.done(&mesh));
            }
            proptest::prop_assert_eq!(pieces, whole);
        }

        /// `indices_in_range` says a strip's assembly succeeds exactly when it does; for a list
        /// (which skips a triangle holding a restart, and indices past its last triangle) it
        /// may refuse one that would succeed, never the other way round.
        #[test]
        fn indices_in_range_exactly_when_a_strip_assembles(
            indices in some_indices(16, 40),
            n in 0usize..16,
            wide: bool,
        ) {
            let v = vec![Vertex::default(); n];
            let short = narrow(&indices);
            let strip = with_indices(&v, (&short, &indices), wide, Topology::TriangleStrip);
            let ok = indices_in_range(&strip);
            proptest::prop_assert_eq!(ok, assemble(&strip, |_| {}).is_ok());
            let list = with_indices(&v, (&short, &indices), wide, Topology::TriangleList);
            let list_ok = assemble(&list, |_| {}).is_ok();
            proptest::prop_assert!(!ok || list_ok);
        }
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
