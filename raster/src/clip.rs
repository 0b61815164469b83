//! Homogeneous clipping (Sutherland–Hodgman) against the planes a vertex actually crosses.
//!
//! Near and far planes and `w > 0` are always enforced; the sides are enforced only at the guard
//! band, far outside the viewport, so almost every triangle skips side clipping and the scissor does
//! the rest. Intersections are always computed from the inside vertex towards the outside one, so
//! an edge shared by two triangles is cut at the same point in both (watertight after clipping).

/// The clip planes, as bits of an outcode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum Plane {
    /// `w` above its minimum: keeps the perspective divide finite.
    WMin = 1,
    /// `z >= 0`.
    Near = 2,
    /// `z <= w`.
    Far = 4,
    /// Guard band, `x >= -g w`.
    Left = 8,
    /// Guard band, `x <= g w`.
    Right = 16,
    /// Guard band, `y >= -g w`.
    Bottom = 32,
    /// Guard band, `y <= g w`.
    Top = 64,
}

/// Planes in the order they are applied.
pub(crate) const PLANES: [Plane; 7] = [
    Plane::WMin,
    Plane::Near,
    Plane::Far,
    Plane::Left,
    Plane::Right,
    Plane::Bottom,
    Plane::Top,
];

/// A vertex in clip space that the clipper can cut.
pub(crate) trait ClipVertex: Copy + Default {
    /// The arithmetic's own description of the guard band and viewport.
    type Space;
    /// True when the vertex is on the kept side of `plane`.
    fn inside(&self, plane: Plane, space: &Self::Space) -> bool;
    /// The point where the segment from `inside` to `outside` meets `plane`, attributes included.
    fn intersect(inside: &Self, outside: &Self, plane: Plane, space: &Self::Space) -> Self;

    /// Bit set of the planes this vertex is outside of.
    fn outcode(&self, space: &Self::Space) -> u8 {
        outcode_by_planes(self, space)
    }
}

/// The outcode from `inside`, plane by plane: `ClipVertex::outcode` unless a precision computes
/// it faster.
pub(crate) fn outcode_by_planes<V: ClipVertex>(v: &V, space: &V::Space) -> u8 {
    PLANES
        .iter()
        .filter(|&&p| !v.inside(p, space))
        .fold(0, |m, &p| m | p as u8)
}

/// Most vertices a triangle can have after seven planes.
pub(crate) const MAX_POLYGON: usize = 3 + PLANES.len();

/// A convex polygon being clipped.
pub(crate) struct Polygon<V> {
    pub vertices: [V; MAX_POLYGON],
    pub len: usize,
}

/// Clips triangle `tri` against the planes set in `mask`; the result may be empty.
pub(crate) fn clip_triangle<V: ClipVertex>(tri: [V; 3], mask: u8, space: &V::Space) -> Polygon<V> {
    let mut poly = Polygon {
        vertices: [V::default(); MAX_POLYGON],
        len: 3,
    };
    poly.vertices[..3].copy_from_slice(&tri);
    let mut next = Polygon {
        vertices: [V::default(); MAX_POLYGON],
        len: 0,
    };
    for plane in PLANES.into_iter().filter(|&p| mask & p as u8 != 0) {
        next.len = 0;
        for i in 0..poly.len {
            let a = &poly.vertices[i];
            let b = &poly.vertices[(i + 1) % poly.len];
            let (ia, ib) = (a.inside(plane, space), b.inside(plane, space));
            if ia {
                next.vertices[next.len] = *a;
                next.len += 1;
            }
            if ia != ib {
                let v = if ia {
                    V::intersect(a, b, plane, space)
                } else {
                    V::intersect(b, a, plane, space)
                };
                next.vertices[next.len] = v;
                next.len += 1;
            }
        }
        std::mem::swap(&mut poly, &mut next);
        if poly.len < 3 {
            poly.len = 0;
            break;
        }
    }
    poly
}
