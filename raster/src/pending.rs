//! The geometry of the draws a batch has not flushed yet, and the triangle assembly that
//! gathers it.

use crate::RasterError;
use crate::vertex::{Mesh, Vertex, assemble};

/// The geometry of the pending draws: copies of the vertices they use, and their triangles as
/// indices into those copies.
#[derive(Debug, Default)]
pub(crate) struct Pending {
    pub vertices: Vec<Vertex>,
    pub triangles: Vec<[u32; 3]>,
}

/// Triangle assembly, copying the vertices a draw uses.
#[derive(Debug, Default)]
pub(crate) struct Gather {
    /// Per-vertex stamp of the draw that last referenced it.
    stamp: Vec<u32>,
    /// Per-vertex position in the pending vertices, valid where the stamp is current.
    slot: Vec<u32>,
    generation: u32,
}

impl Gather {
    /// Assembles `mesh`'s triangles into `pending`, copying its vertices (all of them, or the
    /// used ones once each when the mesh has more vertices than indices). With `in_place` (only
    /// into an empty `pending`, for a draw that is flushed before its mesh goes), a mesh whose
    /// vertices would all be copied is not: its triangles index `mesh.vertices` itself. Returns
    /// the number of triangles and whether the vertices were left in place; on an index out of
    /// range, `pending` is left as it was.
    pub fn append(
        &mut self,
        mesh: &Mesh,
        pending: &mut Pending,
        in_place: bool,
    ) -> Result<(usize, bool), RasterError> {
        debug_assert!(!in_place || pending.vertices.is_empty() && pending.triangles.is_empty());
        let n = mesh.vertices.len();
        let (first_vertex, first_triangle) = (pending.vertices.len(), pending.triangles.len());
        let all = n <= mesh.indices.len() && first_vertex + n <= u32::MAX as usize;
        let result = if all {
            // No more vertices than indices (a strip or list over its own grid): copying them
            // all costs less than finding the used ones, and the vertex stage's extra work is
            // bounded by the assembly's.
            if !in_place {
                pending.vertices.extend_from_slice(mesh.vertices);
            }
            let base = first_vertex as u32;
            let triangles = &mut pending.triangles;
            assemble(mesh, |t| triangles.push(t.map(|v| base + v)))
        } else {
            self.append_used(mesh, pending)
        };
        match result {
            Ok(()) => Ok((pending.triangles.len() - first_triangle, all && in_place)),
            Err((position, value)) => {
                pending.vertices.truncate(first_vertex);
                pending.triangles.truncate(first_triangle);
                Err(RasterError::IndexOutOfRange {
                    position,
                    value,
                    vertices: n,
                })
            }
        }
    }

    /// `append` copying only the vertices the triangles use, each once.
    fn append_used(&mut self, mesh: &Mesh, pending: &mut Pending) -> Result<(), (usize, u32)> {
        let n = mesh.vertices.len();
        if self.stamp.len() < n {
            self.stamp.resize(n, 0);
            self.slot.resize(n, 0);
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.fill(0);
            self.generation = 1;
        }
        let (stamp, slot, generation) = (&mut self.stamp, &mut self.slot, self.generation);
        let Pending {
            vertices,
            triangles,
        } = pending;
        assemble(mesh, |t| {
            triangles.push(t.map(|v| {
                let v = v as usize;
                if stamp[v] != generation {
                    stamp[v] = generation;
                    slot[v] = vertices.len() as u32;
                    vertices.push(mesh.vertices[v]);
                }
                slot[v]
            }))
        })
    }
}
