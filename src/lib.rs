//! stripmask: adaptive streaming and CPU rendering of large terrains with strip masks.
